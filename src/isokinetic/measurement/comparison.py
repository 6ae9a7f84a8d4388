"""Two or more campaigns compared point by point (before and after a repair, two dampers of a batch, two
temperatures): the method of stage ``compare`` (config ``comparisons``; its runner :mod:`isokinetic.stages.compare`
reads the campaigns and writes ``results/compare/<name>/``).

The first campaign of a comparison is the *reference*; every other campaign is compared with it, one
row per velocity and direction (table :data:`isokinetic.contracts.tables.COMPARE`).

Points. A campaign's point is one case and direction of its characteristic (``characteristic.parquet``):
the mean force and mean measured velocity of its windows (one per period, usually two). Its standard
error (:func:`campaign_points`) combines in quadrature

- *window noise*: sqrt(sum s_i^2 / n_i) / k over its k windows, s_i the window's ``force_std_N`` and n_i
  its ``n_samples``: the standard error of the mean for uncorrelated sample noise (coloured noise, which
  the diagnosis models from the time series, is not in it);
- *repeatability*: the standard deviation of the k window forces over sqrt(k), for two periods
  |F_2 - F_1| / 2 (the two forces ``repeatability.parquet`` compares); it catches drift between the
  periods and the autocorrelated noise the first term misses. With white noise alone the two terms
  estimate the same spread, so their sum is up to sqrt(2) too large: the SE is conservative.

Matching. A point of the other campaign matches a reference point of the same direction when their
velocities agree within ``velocity_tolerance`` (relative, 1 % by default): nearest pairs first, each
point used once. A matched row's basis is ``measured``: the other campaign's force is moved to the
reference's velocity along its own characteristic (the slope of the parabola through the point and its
two nearest neighbours, :func:`local_slope`; ``velocity_shift_N``, the shift's own uncertainty
neglected), so that a velocity mismatch within the tolerance does not pass for a force difference.

Model path. Velocities without a match (the plans differ) are compared through each campaign's fitted
model (:mod:`isokinetic.stages.models`), evaluated at the unmatched velocities of both campaigns
(basis ``model:<name>``). The model is the comparison's ``model`` (default ``surace``: one parameter set
per direction, so a difference confined to one direction is not averaged away; ``wallaschek`` is taken
for a direction where a campaign lacks the Surace fit). Its parameter covariance is re-derived by the
models stage's own weighted least squares on the characteristic (the estimates are checked against
``models/models.parquet``). A model row's SE is the model's *prediction* standard error at v:
sqrt(x' C x + (s sigma(v))^2), C the residual-scaled parameter covariance, s the fit's residual scale
and sigma(v) the window noise SE at v (interpolated in log |v| over the campaign's points). The
second term is the scatter of the points about the model; it carries the model's misfit, which the
parameter covariance alone (the confidence band of the curve) does not: a curve that misses the
points by 100 N is not known to 5 N. A model is evaluated only within its campaign's measured speed
range (no extrapolation); velocities outside the other campaign's range are listed as excluded.
A model fitted to no more speeds than it has parameters passes through its points and cannot show
its misfit; the summary says so.

Test (:func:`z_test`). difference = campaign - reference, SE = sqrt(SE_campaign^2 + SE_reference^2)
(independent campaigns), z = difference / SE and the two-sided p = erfc(|z| / sqrt 2) of the normal distribution
(a z-test: the SEs are taken as known); significant when p < ``alpha`` (0.05 by default). Rows are
tested one by one: at alpha = 0.05 about one row in twenty is flagged by chance alone, and the model
rows of one pair share two fitted curves, so they are not independent.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.measurement.model_fit import MODEL_NAMES, PARAMETERS, design_matrix, fit_points, standard_errors, wls
from isokinetic.stats import Z_95

log = logging.getLogger(__name__)

ALPHA = 0.05
VELOCITY_TOLERANCE = 0.01
DEFAULT_MODEL = "surace"
TEST = "two-sided z"
#: The smallest standard error of a difference [N]: noise-free data keep a finite z.
MIN_DIFFERENCE_SE_N = 1e-9
#: Speeds of each model curve drawn in the overlay figure.
CURVE_POINTS = 60
COLUMNS = list(tables.COMPARE.columns)


@dataclass(frozen=True)
class CompareSpec:
    """One comparison of the config: its name, campaigns (the first is the reference) and test settings."""

    name: str
    campaigns: tuple[str, ...]
    description: str = ""
    alpha: float = ALPHA
    model: str = DEFAULT_MODEL
    velocity_tolerance: float = VELOCITY_TOLERANCE

    def __post_init__(self):
        object.__setattr__(self, "campaigns", tuple(self.campaigns))
        if len(self.campaigns) < 2:
            raise ValueError(f"comparison {self.name!r}: two or more campaigns needed, got {list(self.campaigns)}")
        if len(set(self.campaigns)) != len(self.campaigns):
            raise ValueError(f"comparison {self.name!r}: a campaign named twice in {list(self.campaigns)}")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"comparison {self.name!r}: alpha must lie in (0, 1), got {self.alpha}")
        if self.model not in MODEL_NAMES:
            raise ValueError(f"comparison {self.name!r}: model must be one of {MODEL_NAMES}, got {self.model!r}")
        if not 0.0 <= self.velocity_tolerance < 0.5:
            raise ValueError(f"comparison {self.name!r}: velocity_tolerance must lie in [0, 0.5), "
                             f"got {self.velocity_tolerance}")

    @property
    def reference(self) -> str:
        """The reference campaign: the first of ``campaigns``."""
        return self.campaigns[0]


# ----------------------------------------------------------------------------------------------
# points and their standard errors
# ----------------------------------------------------------------------------------------------

def campaign_points(char: pd.DataFrame) -> pd.DataFrame:
    """One point per case and direction of a characteristic, with its standard error (module doc).

    Columns: case, direction, velocity_m_s, force_N, n_windows, window_se_N (rms over the windows of
    s_i / sqrt(n_i)), noise_se_N, repeatability_se_N (0 for a single window), se_N, sorted by direction
    and speed.
    """
    cols = ["case", "direction", "velocity_m_s", "force_N", "n_windows", "window_se_N", "noise_se_N",
            "repeatability_se_N", "se_N"]
    char = fit_points(char)   # the points the models fit (models.fit_points)
    if char is not None and "method" in char:  # a free record's velocity bins are not one point a case
        char = char[char["method"] != "free_bin"]
    if char is None or char.empty:
        return pd.DataFrame({c: pd.Series(dtype=object if c in ("case", "direction") else float) for c in cols})
    w = char.assign(_se2=char["force_std_N"].to_numpy(float) ** 2 / np.maximum(char["n_samples"].to_numpy(float), 1))
    g = w.groupby(["case", "direction"], sort=False)
    pts = g.agg(velocity_m_s=("velocity_m_s", "mean"), force_N=("force_N", "mean"), n_windows=("force_N", "size"),
                _se2_sum=("_se2", "sum"), _f_std=("force_N", "std")).reset_index()
    k = pts["n_windows"].to_numpy(float)
    pts["window_se_N"] = np.sqrt(pts["_se2_sum"].to_numpy(float) / k)
    pts["noise_se_N"] = np.sqrt(pts["_se2_sum"].to_numpy(float)) / k
    pts["repeatability_se_N"] = np.where(k > 1, pts["_f_std"].fillna(0.0).to_numpy(float) / np.sqrt(k), 0.0)
    pts["se_N"] = np.hypot(pts["noise_se_N"], pts["repeatability_se_N"])
    pts["n_windows"] = pts["n_windows"].astype("int64")
    pts = pts.assign(_speed=pts["velocity_m_s"].abs()).sort_values(["direction", "_speed"], kind="stable")
    return pts[cols].reset_index(drop=True)


def match_velocities(v_ref, v_other, tolerance: float) -> list[tuple[int, int]]:
    """The index pairs (i, j) of velocities [m/s] agreeing within ``tolerance`` relative to the larger magnitude: the
    nearest pairs first, each velocity in one pair at most."""
    a, b = np.asarray(v_ref, dtype=float), np.asarray(v_other, dtype=float)
    if not a.size or not b.size:
        return []
    scale = np.maximum(np.abs(a)[:, None], np.abs(b)[None, :])
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(scale > 0, np.abs(a[:, None] - b[None, :]) / scale, 0.0)
    order = np.argsort(rel, axis=None, kind="stable")
    used_a, used_b, pairs = set(), set(), []
    for flat in order:
        i, j = divmod(int(flat), b.size)
        if rel[i, j] > tolerance:
            break
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((i, j))
    return sorted(pairs)


def local_slope(velocity_m_s, force_N) -> np.ndarray:
    """dF/dv [N s/m] at each point of one direction: the derivative of the parabola through the point and its two
    nearest neighbours in log |v| (exact for F = a + b v + c v^2, one-sided at the ends); the line to the
    one other point when there are two; 0 for a single point."""
    v, f = np.asarray(velocity_m_s, dtype=float), np.asarray(force_N, dtype=float)
    if v.size < 2:
        return np.zeros(v.size)
    log_s = np.log(np.abs(v))
    slope = np.empty(v.size)
    for j in range(v.size):
        near = np.argsort(np.abs(log_s - log_s[j]), kind="stable")[:3]
        x = (v[near] - v[j]) / abs(v[j])                       # scaled: the system stays well conditioned
        coef = np.linalg.lstsq(np.vander(x, min(near.size, 3), increasing=True), f[near], rcond=None)[0]
        slope[j] = coef[1] / abs(v[j])
    return slope


# ----------------------------------------------------------------------------------------------
# the fitted models with their covariance
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ModelCurve:
    """A campaign's fitted model in one direction, with its residual-scaled parameter covariance and
    the window noise along its measured speeds (for the prediction SE, module doc)."""

    campaign: str
    model: str
    direction: str
    estimate: np.ndarray
    cov: np.ndarray
    residual_scale: float
    speeds_m_s: np.ndarray = field(repr=False)      # sorted |v| of the campaign's points, this direction
    window_se_N: np.ndarray = field(repr=False)     # their window noise SE

    @property
    def speed_range(self) -> tuple[float, float]:
        """(lowest, highest) measured speed [m/s] in this direction."""
        return float(self.speeds_m_s[0]), float(self.speeds_m_s[-1])

    @property
    def n_speeds(self) -> int:
        """The number of distinct speeds (within 1e-6 relative) the model was fitted to in this direction."""
        return int(np.unique(np.round(np.log(self.speeds_m_s), 6)).size)

    def force(self, velocity_m_s) -> np.ndarray:
        """The model's force [N] at each velocity [m/s]."""
        return design_matrix(np.asarray(velocity_m_s, dtype=float)) @ self.estimate

    def se(self, velocity_m_s) -> np.ndarray:
        """The prediction standard error [N] at each velocity [m/s]: parameter covariance and scatter about the fit."""
        v = np.asarray(velocity_m_s, dtype=float)
        x = design_matrix(v)
        curve_var = np.einsum("ij,jk,ik->i", x, self.cov, x)
        sigma = np.exp(np.interp(np.log(np.abs(v)), np.log(self.speeds_m_s), np.log(self.window_se_N)))
        return np.sqrt(np.maximum(curve_var, 0.0) + (self.residual_scale * sigma) ** 2)

    def covers(self, velocity_m_s, tolerance: float) -> np.ndarray:
        """Whether each |v| lies within the measured speed range (widened by the tolerance)."""
        lo, hi = self.speed_range
        s = np.abs(np.asarray(velocity_m_s, dtype=float))
        return (s >= lo * (1 - tolerance)) & (s <= hi * (1 + tolerance))


def weighted_fit(velocity_m_s, force_N, sigma_N) -> tuple[np.ndarray, np.ndarray, float]:
    """(estimate, covariance, residual scale) of F = sign(v) F_C + D_L v + D_Q v|v| by the weighted
    least squares of :func:`isokinetic.measurement.model_fit.wls` (columns scaled, QR, covariance scaled by the
    reduced chi-square); needs more points than parameters."""
    x = design_matrix(velocity_m_s)
    n, p = x.shape
    if n <= p:
        raise ValueError(f"{n} points for {p} parameters: no residual degrees of freedom")
    fit = wls(x, np.asarray(force_N, dtype=float), np.asarray(sigma_N, dtype=float))
    return fit["estimate"], fit["covariance"], fit["residual_scale"]


def _stored_fit(models_df: pd.DataFrame | None, model: str, direction: str) -> tuple[np.ndarray, np.ndarray, str]:
    """(estimates, std errors, weighting) of a model's fitted parameters in models.parquet (empty: none)."""
    fit_dir = "both" if model == "wallaschek" else direction
    if models_df is None or models_df.empty:
        return np.empty(0), np.empty(0), ""
    kind = models_df["kind"] if "kind" in models_df else pd.Series("fitted", index=models_df.index)
    rows = models_df[(models_df["model"] == model) & (models_df["direction"] == fit_dir) & (kind == "fitted")]
    rows = rows.set_index("parameter").reindex(list(PARAMETERS))
    if rows["estimate"].isna().any():
        return np.empty(0), np.empty(0), ""
    weighting = str(rows["weighting"].iloc[0]) if "weighting" in rows else "standard_error"
    return rows["estimate"].to_numpy(float), rows["std_error"].to_numpy(float), weighting


def model_curve(char: pd.DataFrame, points: pd.DataFrame, models_df: pd.DataFrame | None, model: str,
                direction: str, campaign: str = "") -> ModelCurve | None:
    """The fitted ``model`` of a campaign in one direction (None when models.parquet lacks it or it has no
    residual degrees of freedom). Raises ValueError when the re-derived estimates differ from the stored
    ones (the two files come from different runs)."""
    stored, stored_se, weighting = _stored_fit(models_df, model, direction)
    mine = points[points["direction"] == direction]
    if not stored.size or mine.empty:
        return None
    char = fit_points(char)   # the points the stored fit used
    v = char["velocity_m_s"].to_numpy(float)
    mask = np.ones(v.size, bool) if model == "wallaschek" else (v > 0 if direction == "+" else v < 0)
    f = char["force_N"].to_numpy(float)[mask]
    sigma = standard_errors(char["force_std_N"].to_numpy(float)[mask], char["n_samples"].to_numpy(float)[mask], f,
                            weighting)
    try:
        est, cov, scale = weighted_fit(v[mask], f, sigma)
    except ValueError as exc:
        log.warning("campaign %s: %s (%s) not usable for the comparison: %s", campaign, model, direction, exc)
        return None
    if np.any(np.abs(est - stored) > 1e-6 * np.abs(stored) + 1e-6 * np.nan_to_num(stored_se) + 1e-12):
        raise ValueError(f"campaign {campaign}: {model} ({direction}) re-fitted to characteristic.parquet gives "
                         f"{est.tolist()}, models.parquet holds {stored.tolist()}: the files come from different runs")
    speeds = mine["velocity_m_s"].abs().to_numpy(float)
    order = np.argsort(speeds, kind="stable")
    wse = np.maximum(mine["window_se_N"].to_numpy(float)[order], 1e-12)
    return ModelCurve(campaign, model, direction, est, cov, scale, speeds[order], wse)


def campaign_curves(char: pd.DataFrame, points: pd.DataFrame, models_df: pd.DataFrame | None,
                    campaign: str = "") -> dict[tuple[str, str], ModelCurve]:
    """Every usable (model, direction) curve of a campaign."""
    out = {}
    for model in MODEL_NAMES:
        for direction in tables.DIRECTIONS:
            curve = model_curve(char, points, models_df, model, direction, campaign)
            if curve is not None:
                out[(model, direction)] = curve
    return out


def pick_model(preferred: str, direction: str, *curve_sets: Mapping[tuple[str, str], ModelCurve]) -> str | None:
    """The model every campaign has in this direction: ``preferred`` if it can, else the other; None if none."""
    for model in (preferred, *[m for m in MODEL_NAMES if m != preferred]):
        if all((model, direction) in curves for curves in curve_sets):
            return model
    return None


# ----------------------------------------------------------------------------------------------
# one campaign against the reference
# ----------------------------------------------------------------------------------------------

def _side(prefix: str, case: str, velocity: float, force: float, se: float, noise: float, rep: float) -> dict:
    return {f"{prefix}_case": case, f"{prefix}_velocity_m_s": velocity, f"{prefix}_force_N": force,
            f"{prefix}_se_N": se, f"{prefix}_noise_se_N": noise, f"{prefix}_repeatability_se_N": rep}


def _measured_rows(ref: pd.DataFrame, other: pd.DataFrame, pairs: Sequence[tuple[int, int]]) -> list[dict]:
    """Rows of matched points: the other campaign's force moved to the reference's velocity."""
    slope = local_slope(other["velocity_m_s"], other["force_N"])
    rows = []
    for i, j in pairs:
        a, b = ref.iloc[i], other.iloc[j]
        shift = float(slope[j] * (a["velocity_m_s"] - b["velocity_m_s"]))
        rows.append({"direction": a["direction"], "velocity_m_s": float(a["velocity_m_s"]), "basis": "measured",
                     **_side("reference", a["case"], a["velocity_m_s"], a["force_N"], a["se_N"], a["noise_se_N"],
                             a["repeatability_se_N"]),
                     **_side("campaign", b["case"], b["velocity_m_s"], b["force_N"] + shift, b["se_N"],
                             b["noise_se_N"], b["repeatability_se_N"]),
                     "velocity_shift_N": shift})
    return rows


def _model_rows(direction: str, unmatched: pd.DataFrame, ref_curve: ModelCurve, curve: ModelCurve) -> list[dict]:
    """Rows at unmatched velocities, both campaigns through their fitted model."""
    v = unmatched["velocity_m_s"].to_numpy(float)
    fa, fb, sa, sb = ref_curve.force(v), curve.force(v), ref_curve.se(v), curve.se(v)
    rows = []
    for k, r in enumerate(unmatched.itertuples(index=False)):
        rows.append({"direction": direction, "velocity_m_s": float(v[k]), "basis": f"model:{ref_curve.model}",
                     **_side("reference", r.reference_case, v[k], fa[k], sa[k], math.nan, math.nan),
                     **_side("campaign", r.campaign_case, v[k], fb[k], sb[k], math.nan, math.nan),
                     "velocity_shift_N": 0.0})
    return rows


def _unmatched(ref: pd.DataFrame, other: pd.DataFrame, pairs: Sequence[tuple[int, int]]) -> pd.DataFrame:
    """The velocities of either campaign without a match: velocity_m_s, reference_case, campaign_case (the
    point's case on its own side, '' on the other), ordered by speed."""
    used_a, used_b = {i for i, _ in pairs}, {j for _, j in pairs}
    rows = [(float(r["velocity_m_s"]), r["case"], "") for i, r in ref.iterrows() if i not in used_a]
    rows += [(float(r["velocity_m_s"]), "", r["case"]) for j, r in other.iterrows() if j not in used_b]
    out = pd.DataFrame(rows, columns=["velocity_m_s", "reference_case", "campaign_case"])
    return out.iloc[np.argsort(np.abs(out["velocity_m_s"].to_numpy(float)), kind="stable")].reset_index(drop=True)


def _excluded(spec: CompareSpec, campaign: str, direction: str, unmatched: pd.DataFrame, reason: str) -> list[dict]:
    return [{"direction": direction, "velocity_m_s": float(r.velocity_m_s),
             "campaign": spec.reference if r.reference_case else campaign,
             "case": r.reference_case or r.campaign_case, "reason": reason}
            for r in unmatched.itertuples(index=False)]


def _range_text(curve: ModelCurve) -> str:
    lo, hi = curve.speed_range
    return f"{curve.campaign}'s measured speeds ({lo * 1e3:.4g} to {hi * 1e3:.4g} mm/s)"


def compare_pair(spec: CompareSpec, campaign: str, ref_points: pd.DataFrame, points: pd.DataFrame,
                 ref_curves: Mapping[tuple[str, str], ModelCurve], curves: Mapping[tuple[str, str], ModelCurve]
                 ) -> tuple[list[dict], dict]:
    """The rows of one campaign against the reference (module doc), and what the summary says of the pair:
    models used, velocities excluded (outside a campaign's speeds, or no model), notes."""
    rows, excluded, notes, used, few = [], [], [], [], {}
    for direction in tables.DIRECTIONS:
        ref = ref_points[ref_points["direction"] == direction].reset_index(drop=True)
        other = points[points["direction"] == direction].reset_index(drop=True)
        pairs = match_velocities(ref["velocity_m_s"], other["velocity_m_s"], spec.velocity_tolerance)
        rows += _measured_rows(ref, other, pairs)
        unmatched = _unmatched(ref, other, pairs)
        if unmatched.empty:
            continue
        model = pick_model(spec.model, direction, ref_curves, curves)
        if model is None:
            excluded += _excluded(spec, campaign, direction, unmatched, "no fitted model in both campaigns")
            continue
        ca, cb = ref_curves[(model, direction)], curves[(model, direction)]
        v = unmatched["velocity_m_s"].to_numpy(float)
        inside = ca.covers(v, spec.velocity_tolerance) & cb.covers(v, spec.velocity_tolerance)
        rows += _model_rows(direction, unmatched[inside], ca, cb)
        done = inside.copy()
        for c in (ca, cb):
            outside = ~done & ~c.covers(v, spec.velocity_tolerance)
            excluded += _excluded(spec, campaign, direction, unmatched[outside], f"outside {_range_text(c)}")
            done |= outside  # each velocity excluded once
            if c.n_speeds <= len(PARAMETERS):
                few.setdefault((c.campaign, model, c.n_speeds), []).append(direction)
        if model != spec.model:
            notes.append(f"direction {direction}: {spec.model} is not fitted in both campaigns; {model} is used")
        used.append(f"{model} ({direction})")
    notes += [f"{c}: {model} ({', '.join(dirs)}) is fitted to {n} speeds for {len(PARAMETERS)} parameters, so it "
              "passes through its points and its interval cannot show the model's misfit between them"
              for (c, model, n), dirs in few.items()]
    return rows, {"campaign": campaign, "models_used": used, "excluded": excluded, "notes": notes}


def z_test(campaign_force_N, campaign_se_N, reference_force_N, reference_se_N
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The two-sided z-test of each difference of two independent forces with known standard errors.

    d = F_campaign - F_reference [N], SE_d = sqrt(SE_campaign^2 + SE_reference^2) [N] (floored at
    :data:`MIN_DIFFERENCE_SE_N`, so that noise-free data keep a finite z), z = d / SE_d (dimensionless) and
    p = erfc(|z| / sqrt 2), the probability of a |z| at least as large under the normal distribution when the
    forces do not differ. Takes arrays (or scalars) of forces and standard errors in N; returns (d [N],
    SE_d [N], z, p) as float arrays. Example: forces 110 and 100 N with SEs 3 and 4 N give d = 10 N,
    SE_d = 5 N, z = 2, p = 0.0455.
    """
    d = np.asarray(campaign_force_N, dtype=float) - np.asarray(reference_force_N, dtype=float)
    se = np.maximum(np.hypot(np.asarray(campaign_se_N, dtype=float), np.asarray(reference_se_N, dtype=float)),
                    MIN_DIFFERENCE_SE_N)
    z = d / se
    p = np.array([math.erfc(abs(x) / math.sqrt(2.0)) for x in np.ravel(z)], dtype=float).reshape(np.shape(z))
    return d, se, z, p


def significance(table: pd.DataFrame, alpha: float) -> pd.DataFrame:
    """The comparison table with the :func:`z_test` of each row's campaign force against its reference force:
    difference_N, difference_se_N [N], z, p_value, the ``alpha`` it is judged at and the flag p < alpha."""
    t = table.copy()
    d, se, z, p = z_test(t["campaign_force_N"], t["campaign_se_N"], t["reference_force_N"], t["reference_se_N"])
    t["difference_N"], t["difference_se_N"], t["z"] = d, se, z
    t["p_value"] = p
    t["alpha"] = float(alpha)
    t["significant"] = (t["p_value"] < alpha).astype(bool)
    t["test"] = TEST
    return t


def _table(spec: CompareSpec, parts: Sequence[tuple[str, list[dict]]]) -> pd.DataFrame:
    frames = [pd.DataFrame(rows).assign(campaign=c) for c, rows in parts if rows]
    if not frames:
        return tables.empty(tables.COMPARE)[COLUMNS]
    t = pd.concat(frames, ignore_index=True).assign(comparison=spec.name, reference=spec.reference)
    t = significance(t, spec.alpha)
    order = {c: k for k, c in enumerate(spec.campaigns)}
    t = t.assign(_c=t["campaign"].map(order), _d=(t["direction"] == "-").astype(int), _s=t["velocity_m_s"].abs())
    t = t.sort_values(["_c", "_d", "_s"], kind="stable").reset_index(drop=True)
    return tables.validate_table(t[COLUMNS].astype({"significant": bool}), tables.COMPARE)


# ----------------------------------------------------------------------------------------------
# the comparison
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Comparison:
    """A comparison's result: the table, the summary (compare.json) and what the overlay figure draws."""

    table: pd.DataFrame
    summary: dict
    points: pd.DataFrame        # every campaign's points: campaign, direction, velocity_m_s, force_N, se_N
    curves: pd.DataFrame        # every campaign's model curve: campaign, direction, model, velocity_m_s, force_N, se_N


def _pair_summary(info: dict, rows: pd.DataFrame, alpha: float) -> dict:
    n = len(rows)
    return {**info, "n_rows": n, "n_measured": int((rows["basis"] == "measured").sum()) if n else 0,
            "n_model": int(rows["basis"].str.startswith("model:").sum()) if n else 0,
            "n_significant": int(rows["significant"].sum()) if n else 0, "expected_by_chance": alpha * n,
            "max_abs_z": float(rows["z"].abs().max()) if n else None}


def _overlay_curves(spec: CompareSpec, curves: Mapping[str, Mapping[tuple[str, str], ModelCurve]]) -> pd.DataFrame:
    """Each campaign's model (the comparison's, else the other) over its own measured speeds, both directions."""
    parts = []
    for c in spec.campaigns:
        for direction in tables.DIRECTIONS:
            model = pick_model(spec.model, direction, curves[c])
            if model is None:
                continue
            curve = curves[c][(model, direction)]
            lo, hi = curve.speed_range
            v = np.geomspace(lo, hi, CURVE_POINTS) * (1.0 if direction == "+" else -1.0)
            parts.append(pd.DataFrame({"campaign": c, "direction": direction, "model": model, "velocity_m_s": v,
                                       "force_N": curve.force(v), "se_N": curve.se(v)}))
    cols = ["campaign", "direction", "model", "velocity_m_s", "force_N", "se_N"]
    return pd.concat(parts, ignore_index=True)[cols] if parts else pd.DataFrame(columns=cols)


def compare_campaigns(spec: CompareSpec, characteristics: Mapping[str, pd.DataFrame],
                      models: Mapping[str, pd.DataFrame | None]) -> Comparison:
    """Every campaign of ``spec`` against its reference (module doc), from their characteristic and
    models tables (by campaign name)."""
    missing = [c for c in spec.campaigns if c not in characteristics]
    if missing:
        raise ValueError(f"comparison {spec.name!r}: no characteristic for {missing}")
    points = {c: campaign_points(characteristics[c]) for c in spec.campaigns}
    curves = {c: campaign_curves(characteristics[c], points[c], models.get(c), c) for c in spec.campaigns}
    ref = spec.reference
    parts, infos = [], []
    for c in spec.campaigns[1:]:
        rows, info = compare_pair(spec, c, points[ref], points[c], curves[ref], curves[c])
        parts.append((c, rows))
        infos.append(info)
    table = _table(spec, parts)
    summary = {"format_version": 1, "comparison": spec.name, "description": spec.description, "reference": ref,
               "campaigns": list(spec.campaigns), "alpha": spec.alpha, "test": TEST, "z_95": Z_95,
               "velocity_tolerance": spec.velocity_tolerance, "model": spec.model,
               "pairs": [_pair_summary(info, table[table["campaign"] == info["campaign"]], spec.alpha)
                         for info in infos]}
    for pair in summary["pairs"]:
        log.info("%s: %s against %s: %d rows (%d measured, %d through a model), %d significant at alpha %g",
                 spec.name, pair["campaign"], ref, pair["n_rows"], pair["n_measured"], pair["n_model"],
                 pair["n_significant"], spec.alpha)
        for note in pair["notes"]:
            log.info("%s: %s", spec.name, note)
    all_points = pd.concat([p.assign(campaign=c) for c, p in points.items()], ignore_index=True)
    return Comparison(table, summary, all_points, _overlay_curves(spec, curves))

