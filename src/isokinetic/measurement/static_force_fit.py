"""The static force of a campaign: the force at v -> 0 (a gas force, a load-cell zero), with its interval.

Definition
    F_static = lim_{v -> 0} (F+(v) + F-(-v)) / 2, the mean of the + and - branches of the steady
    characteristic at the same speed, extrapolated to zero speed. The sign convention is the
    characteristic's (force positive when it resists positive velocity), so a characteristic that
    sits 25 N below zero near v = 0 has F_static = -25 N.

Why the branch mean
    A symmetric damper's characteristic is odd, F(-v) = -F(v): Coulomb friction sign(v)·F_C (Eq. 8's
    F_f), the laminar and the turbulent pressure losses (Eq. 7's c_1 and c_2 terms) all cancel in the
    mean at matched speeds, whatever their size, and what is left is the even part of the
    characteristic. A static
    force (gas force on the rod, load-cell zero offset F_0 of F_meas = g·F + F_0) adds the same
    constant to both branches and is all of the even part at v = 0. A direction asymmetry does not
    cancel: an orifice that resists more one way (the diagnosis' ``asymmetry``) makes the branch mean
    grow with |v| (its laminar part linearly, its turbulent part like v²) but vanish at v = 0, so the
    linear extrapolation removes its linear part and its curvature over the fitted speeds biases the
    intercept by about -c2·v_1·v_k (c2 the mean's v² coefficient, v_1..v_k the fitted speeds): hence
    the lowest speeds only. A friction that differs by direction (F_C+ != F_C-) does not vanish at
    v = 0: half its difference, (F_C+ - F_C-)/2, is part of F_static and cannot be told from a gas
    force or a zero offset by the characteristic alone (nor by the diagnosis, whose friction is
    symmetric: its offset term absorbs it alike).

Method (:func:`estimate_static_force`)
    1. Branch points (:func:`branch_points`): the characteristic's windows per case and direction
       (both periods averaged), each with the standard error of its mean: the larger of the window
       noise, sqrt(Σ σ_i²)/k with σ_i = s_i/sqrt(n_i) (s_i the window's force_std_N, n_i its samples,
       as :func:`isokinetic.measurement.model_fit.standard_errors`), and the period-to-period scatter
       std(F_i)/sqrt(k). Without triangle windows, the sine cases' peak-velocity points serve alike (a
       point's n_i counts cycles, s_i is their scatter). Without either in both directions, the free records' binned
       characteristic (``harmonic.parquet``, kind ``binned``) serves instead, bins paired by rank.
    2. Matched speeds (:func:`matched_means`): a case's + and - windows run at the same planned
       speed; their mean m = (F+ + F-)/2 with σ_m = sqrt(σ+² + σ-²)/2 at the speed (|v+| + |v-|)/2.
    3. A weighted linear fit m = F_static + b·|v| over the lowest ``k`` matched speeds: its intercept.
       k starts at clip(ceil(fraction·n), min_points, max_points) (:class:`StaticForceSpec`) and drops,
       one speed at a time down to ``min_points``, while the line does not fit (χ² test at
       ``lack_of_fit_alpha``): where the branch mean curves (a direction asymmetry, above), fewer and
       lower speeds bias the intercept less. The statistical standard error is the fit's from the σ_m,
       scaled by sqrt(χ²/(k-2)) when the scatter about the line is larger than the window noise
       explains (never scaled down). Two speeds: the line through both (no scatter check). One speed:
       the mean there, not extrapolated. None (no speed with both directions): not estimated, with the
       reason in ``note``.
    4. The extrapolation below the lowest measured speed v_1 rests on the line: a mean that curves
       there (above) moves the intercept by more than the noise says (on the simulated paper campaign,
       by about 0.2 N, several statistical standard errors, from a mean that is flat near 5 µm/s). How
       far the line carries the answer beyond the data, |F_static - m(v_1)|, is therefore added in
       quadrature to the statistical standard error as a systematic one (``extrapolation_N``): a
       static force is called non-zero only when it stands out of both. The 95 % interval is
       ±1.96 times that total: normal, not Student's t, because the total is largely systematic where
       the scatter is large (with 3 speeds, t at 1 degree of freedom would multiply a curvature that
       the extrapolation term already counts by 12.7).

A manifest's ``gas_force_N`` is subtracted at ingest, before all this: F_static is then what is
left beyond the declared gas force (``gas_force_N`` is carried in the table for the report).

Standstill cases (manifest 1.2, waveform ``standstill``)
    A stretch of record with no motion gives the static force directly
    (:func:`isokinetic.stages.static_force.standstill_points`): the
    mean force over the stretch, with the standard error of the means of :data:`STANDSTILL_BLOCKS`
    consecutive blocks (robust to correlated noise). When a campaign has standstill cases, their
    inverse-variance weighted mean is F_static (source ``standstill``, method ``standstill_mean``); the
    characteristic is not extrapolated then. At rest a rod held by Coulomb friction can sit anywhere
    within ±F_C of its static force, so a standstill reading is the static force only as far as the
    friction lets go of the rod (``note`` says so).

Checking the declared gas forces (:func:`gas_force_check`)
    What is left after ingest subtracted a case's ``gas_force_N`` (its own, else the campaign's) should be
    about 0. Each standstill case that declares one is checked alone; the moving cases that declare one are
    checked together through F_static of the characteristic (a moving case alone cannot tell a gas force
    from the even part of the characteristic at its speed). A check agrees when |left| <= z·SE +
    max(:data:`GAS_TOLERANCE_N`, :data:`GAS_TOLERANCE_REL`·|gas force|) (z of ``confidence``; the
    tolerance covers a declaration rounded to a few N). ``gas_force_check`` (agrees | disagrees |
    not_checked) and one line per check in ``gas_force_cases`` go into the table.

Coordination with the diagnosis (:func:`offset_check`)
    The diagnosis fits F_meas = g·(m + F_C·s) + F_0 (:mod:`isokinetic.diagnosis.instrument`): its
    branch mean at v -> 0 is exactly F_0, so F_static and ``instrument.force_offset_N`` estimate the
    same number. :func:`offset_check` compares them, at the diagnosis' own significance level (its
    ``noise.alpha``, the level at which it decides that an offset is needed), and says so in one line
    for the report.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from statistics import NormalDist

import numpy as np
import pandas as pd

from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.stats import ALPHA, chi2_sf

CONFIDENCE = 0.95
SOURCES = ("characteristic", "harmonic_binned", "standstill", "none")
METHODS = ("linear_fit", "two_speeds", "lowest_speed", "standstill_mean", "none")
#: Blocks a standstill stretch is cut into for the standard error of its mean force.
STANDSTILL_BLOCKS = 20
#: Gas-force check tolerance (module doc): absolute [N] and relative to the declared gas force.
GAS_TOLERANCE_N = 2.0
GAS_TOLERANCE_REL = 0.05
GAS_CHECKS = ("agrees", "disagrees", "not_checked")
#: offset_check statuses: what the report shows beside the static force.
OFFSET_STATUSES = ("consistent", "disagree", "no_offset_fitted", "no_diagnosis", "not_estimated")

_POINT_COLUMNS = ["key", "case", "direction", "speed_m_s", "force_N", "std_error_N", "n_windows", "rows"]
_MATCHED_COLUMNS = ["key", "speed_m_s", "force_pos_N", "force_neg_N", "mean_N", "std_error_N",
                    "speed_mismatch_rel", "rows"]


@dataclass(frozen=True)
class StaticForceSpec:
    """Which matched speeds the fit uses: the lowest ``fraction`` of them, at least ``min_points`` and at
    most ``max_points`` (all of them when there are fewer), and the interval's confidence."""

    fraction: float = 1.0 / 3.0
    min_points: int = 3
    max_points: int = 8
    confidence: float = CONFIDENCE
    lack_of_fit_alpha: float = 0.01

    def n_used(self, n: int) -> int:
        """How many of ``n`` matched speeds (lowest first) the fit uses."""
        return min(n, max(self.min_points, min(self.max_points, math.ceil(self.fraction * n))))


@dataclass(frozen=True)
class StaticForce:
    """The static force of one campaign (one row of ``static_force.parquet``, tables.STATIC_FORCE)."""

    campaign: str
    static_force_N: float          # NaN: not estimated (see note)
    std_error_N: float             # statistical_error_N and extrapolation_N in quadrature
    ci_low_N: float
    ci_high_N: float
    confidence: float
    source: str                    # SOURCES
    method: str                    # METHODS
    n_speeds: int                  # matched speeds the estimate uses
    n_matched: int                 # matched speeds available
    v_min_m_s: float               # lowest and highest speed used
    v_max_m_s: float
    slope_N_s_m: float             # d(branch mean)/d|v| of the fit: the direction asymmetry near v = 0
    statistical_error_N: float     # the intercept's standard error from the window noise or the scatter
    extrapolation_N: float         # |intercept - branch mean at the lowest speed| (NaN: not extrapolated)
    residual_scale: float          # sqrt(chi2/dof) of the fit (NaN without dof); SE scaled by max(1, it)
    fit_p_value: float             # P(chi2 >= observed) of the line under the window noise (NaN without dof)
    gas_force_N: float             # declared gas force subtracted at ingest (NaN: none declared)
    source_file: str               # the table the points come from
    source_rows: str               # its rows the estimate used ('T01/1,T01/2,...')
    note: str                      # '' or why the estimate is missing or weaker
    n_standstill: int = 0          # standstill cases (manifest 1.2) found ok
    gas_force_check: str = "not_checked"   # GAS_CHECKS: the declared gas forces against what is left (module doc)
    gas_force_cases: str = ""      # one '; '-joined line per check ('Z01: -0.3 ± 0.1 N left of 120 N: agrees')

    @property
    def significant(self) -> bool:
        """Whether the interval excludes zero."""
        return bool(np.isfinite(self.static_force_N) and (self.ci_low_N > 0 or self.ci_high_N < 0))

    def to_frame(self) -> pd.DataFrame:
        """The one-row table (tables.STATIC_FORCE)."""
        row = asdict(self)
        row["significant"] = self.significant
        df = pd.DataFrame([row])
        return df.astype({"n_speeds": "int64", "n_matched": "int64", "n_standstill": "int64"})


def _z(confidence: float) -> float:
    return NormalDist().inv_cdf(0.5 + confidence / 2.0)


def _window_errors(force_std_N, n_samples, force_N) -> np.ndarray:
    """σ_i = s_i / sqrt(n_i) of each window mean, a zero spread floored at 1e-6 |F| + 1e-9 N."""
    s = np.asarray(force_std_N, dtype=float)
    s = np.maximum(np.where(np.isfinite(s), s, 0.0), 1e-6 * np.abs(np.asarray(force_N, dtype=float)) + 1e-9)
    return s / np.sqrt(np.maximum(np.asarray(n_samples, dtype=float), 1.0))


def _branch(frame: pd.DataFrame, keys: list[str], sigma: np.ndarray, rows: pd.Series) -> pd.DataFrame:
    """Per ``keys`` group: mean speed |v|, mean force, SE = max(noise, scatter), windows, row keys."""
    g = frame.assign(_speed=frame["velocity_m_s"].abs(), _var=sigma ** 2, _rows=rows).groupby(keys, sort=True)
    k = g["force_N"].count().astype("int64")
    noise = np.sqrt(g["_var"].sum()) / k
    scatter = (g["force_N"].std(ddof=1) / np.sqrt(k)).fillna(0.0)
    out = pd.DataFrame({"speed_m_s": g["_speed"].mean(), "force_N": g["force_N"].mean(),
                        "std_error_N": np.maximum(noise, scatter), "n_windows": k,
                        "rows": g["_rows"].agg(",".join)}).reset_index()
    return out


def branch_points(char: pd.DataFrame) -> pd.DataFrame:
    """One point per case and direction of a CHARACTERISTIC (or WINDOWS) table (module doc, step 1).

    Columns: key (the case: what pairs a + point with a - point), case, direction, speed_m_s (mean
    |v|), force_N (mean of the windows), std_error_N, n_windows, rows ('T01/1,T01/3').
    """
    if char is not None and "method" in char:
        # the triangle windows; without any, the sine cases' peak-velocity points (free records' bins are
        # no point a case: binned_points pairs them)
        tri = char["method"] == "triangle_window"
        char = char[tri] if tri.any() else char[char["method"] == "sine_peak"]
    if char is None or char.empty:
        return pd.DataFrame(columns=_POINT_COLUMNS)
    char = char[np.isfinite(char["force_N"].to_numpy(float)) & np.isfinite(char["velocity_m_s"].to_numpy(float))]
    char = char.sort_values(["case", "segment"], kind="stable")
    sigma = _window_errors(char["force_std_N"], char["n_samples"], char["force_N"])
    rows = char["case"].astype(str) + "/" + char["segment"].astype(str)
    out = _branch(char, ["case", "direction"], sigma, rows)
    return out.assign(key=out["case"].astype(str))[_POINT_COLUMNS]


def binned_points(harmonic: pd.DataFrame) -> pd.DataFrame:
    """One point per bin of the free records' binned characteristic (HARMONIC, kind ``binned``).

    The standard error is force_std_N / sqrt(n_points), which understates it (neighbouring samples
    are correlated, a hysteretic loop's branches are averaged together): the fit's residual scale
    then widens it. Bins are paired by rank within a case (``key`` 'F01#0' is the lowest bin of
    either direction): the binning spans each direction's own speed range, so the speeds of a pair
    nearly match for a symmetric excitation (``speed_mismatch_rel`` of :func:`matched_means` says
    how nearly).
    """
    if harmonic is None or harmonic.empty or "kind" not in harmonic:
        return pd.DataFrame(columns=_POINT_COLUMNS)
    b = harmonic[harmonic["kind"] == "binned"]
    if b.empty:
        return pd.DataFrame(columns=_POINT_COLUMNS)
    b = b.assign(_speed=b["velocity_m_s"].abs()).sort_values(["case", "direction", "_speed"], kind="stable")
    rank = b.groupby(["case", "direction"]).cumcount()
    n = b["n_points"] if "n_points" in b else pd.Series(1, index=b.index)
    std = b["force_std_N"] if "force_std_N" in b else pd.Series(np.nan, index=b.index)
    sigma = _window_errors(std, n, b["force_N"])
    key = b["case"].astype(str) + "#" + rank.astype(str)
    out = pd.DataFrame({"key": key, "case": b["case"].astype(str), "direction": b["direction"],
                        "speed_m_s": b["_speed"], "force_N": b["force_N"].astype(float), "std_error_N": sigma,
                        "n_windows": np.ones(len(b), dtype="int64"),
                        "rows": b["case"].astype(str) + "/" + b["direction"] + "/" + rank.astype(str)})
    return out.reset_index(drop=True)[_POINT_COLUMNS]


def matched_means(points: pd.DataFrame) -> pd.DataFrame:
    """The branch mean at each matched speed (module doc, step 2), lowest speed first.

    Columns: key, speed_m_s, force_pos_N, force_neg_N, mean_N, std_error_N, speed_mismatch_rel
    (| |v+| - |v-| | / their mean), rows (both points' row keys).
    """
    if points is None or points.empty:
        return pd.DataFrame(columns=_MATCHED_COLUMNS)
    pos = points[points["direction"] == "+"].set_index("key")
    neg = points[points["direction"] == "-"].set_index("key")
    both = pos.join(neg, how="inner", lsuffix="_pos", rsuffix="_neg")
    if both.empty:
        return pd.DataFrame(columns=_MATCHED_COLUMNS)
    speed = (both["speed_m_s_pos"] + both["speed_m_s_neg"]) / 2.0
    out = pd.DataFrame({
        "key": both.index.astype(str), "speed_m_s": speed.to_numpy(float),
        "force_pos_N": both["force_N_pos"].to_numpy(float), "force_neg_N": both["force_N_neg"].to_numpy(float),
        "mean_N": ((both["force_N_pos"] + both["force_N_neg"]) / 2.0).to_numpy(float),
        "std_error_N": (np.hypot(both["std_error_N_pos"], both["std_error_N_neg"]) / 2.0).to_numpy(float),
        "speed_mismatch_rel": ((both["speed_m_s_pos"] - both["speed_m_s_neg"]).abs()
                               / np.where(speed > 0, speed, np.nan)).to_numpy(float),
        "rows": (both["rows_pos"] + "," + both["rows_neg"]).to_numpy(object)})
    return out.sort_values(["speed_m_s", "key"], kind="stable").reset_index(drop=True)


def intercept_fit(speed_m_s, mean_N, std_error_N, confidence: float = CONFIDENCE) -> dict:
    """Weighted straight line m = a + b·|v| through the matched means; a with its standard error and
    interval (module doc, steps 3-4). Keys: static_force_N, std_error_N (statistical and extrapolation
    parts in quadrature), statistical_error_N, extrapolation_N, ci_low_N, ci_high_N, slope_N_s_m,
    residual_scale, fit_p_value, method."""
    x = np.asarray(speed_m_s, dtype=float)
    y = np.asarray(mean_N, dtype=float)
    s = np.asarray(std_error_N, dtype=float)
    n = x.size
    if n == 0:
        raise ValueError("no matched speed")
    if n == 1:
        half = _z(confidence) * s[0]
        return {"static_force_N": float(y[0]), "std_error_N": float(s[0]), "statistical_error_N": float(s[0]),
                "extrapolation_N": math.nan, "ci_low_N": float(y[0] - half), "ci_high_N": float(y[0] + half),
                "slope_N_s_m": math.nan, "residual_scale": math.nan, "fit_p_value": math.nan,
                "method": "lowest_speed"}
    w = 1.0 / s
    a = np.column_stack([np.ones(n), x]) * w[:, None]
    coef, *_ = np.linalg.lstsq(a, y * w, rcond=None)
    cov = np.linalg.pinv(a.T @ a)
    se = math.sqrt(max(float(cov[0, 0]), 0.0))
    dof = n - 2
    scale, p_value, quantile = math.nan, math.nan, _z(confidence)
    if dof > 0:
        chi2 = float(np.sum((a @ coef - y * w) ** 2))
        scale, p_value = math.sqrt(chi2 / dof), float(chi2_sf(chi2, dof))
        se *= max(1.0, scale)
    a0 = float(coef[0])
    extrapolation = abs(a0 - float(y[np.argmin(x)]))
    total = math.hypot(se, extrapolation)
    return {"static_force_N": a0, "std_error_N": total, "statistical_error_N": se, "extrapolation_N": extrapolation,
            "ci_low_N": a0 - quantile * total, "ci_high_N": a0 + quantile * total, "slope_N_s_m": float(coef[1]),
            "residual_scale": scale, "fit_p_value": p_value, "method": "linear_fit" if dof > 0 else "two_speeds"}


def lowest_straight(matched: pd.DataFrame, spec: StaticForceSpec = StaticForceSpec()) -> tuple[pd.DataFrame, dict]:
    """The lowest matched speeds the intercept is fitted over, and that fit (module doc, step 3): the
    most of them, up to ``spec.n_used``, over which a straight line passes the χ² test at
    ``spec.lack_of_fit_alpha``, and never fewer than ``spec.min_points`` (or all there are)."""
    k = spec.n_used(len(matched))
    while True:
        used = matched.iloc[:k]
        fit = intercept_fit(used["speed_m_s"], used["mean_N"], used["std_error_N"], spec.confidence)
        if k <= min(spec.min_points, len(matched)) or not fit["fit_p_value"] < spec.lack_of_fit_alpha:
            return used, fit
        k -= 1


def _missing_reason(points: pd.DataFrame, what: str) -> str:
    if points.empty:
        return f"no {what}"
    have = set(points["direction"])
    if have == {"+"} or have == {"-"}:
        return f"only {'+' if have == {'+'} else '-'} {what}: one direction missing"
    return f"no speed with {what} in both directions"


def estimate_static_force(campaign: str, char: pd.DataFrame | None, harmonic: pd.DataFrame | None = None,
                          gas_force_N: float | None = None, spec: StaticForceSpec = StaticForceSpec(),
                          char_file: str = STAGE_OUTPUTS["characteristic"]["characteristic"],
                          harmonic_file: str = STAGE_OUTPUTS["harmonic"]["table"]) -> StaticForce:
    """The static force of a campaign from its characteristic, else its free records' binned points
    (module doc). ``gas_force_N`` is only carried along (ingest has subtracted it already)."""
    gas = math.nan if gas_force_N is None else float(gas_force_N)
    notes = []
    matched = matched_means(branch_points(char))
    source, source_file = "characteristic", char_file
    if matched.empty:
        notes.append(_missing_reason(branch_points(char), "triangle windows"))
        matched = matched_means(binned_points(harmonic))
        source, source_file = "harmonic_binned", harmonic_file
        if matched.empty:
            notes.append(_missing_reason(binned_points(harmonic), "binned free-record points"))
        else:
            notes.append("from the free records' binned characteristic, bins paired by rank")
    if matched.empty:
        return StaticForce(campaign, math.nan, math.nan, math.nan, math.nan, spec.confidence, "none", "none", 0, 0,
                           math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, gas, "", "",
                           "not estimated: " + "; ".join(notes))
    used, fit = lowest_straight(matched, spec)
    if fit["fit_p_value"] < spec.lack_of_fit_alpha:
        notes.append(f"the branch mean is not straight even over the lowest {len(used)} speeds "
                     f"(p = {fit['fit_p_value']:.2g}): interval widened by the scatter")
    if fit["method"] == "lowest_speed":
        notes.append("one matched speed: the branch mean there, not extrapolated to v -> 0")
    elif fit["method"] == "two_speeds":
        notes.append("two matched speeds: the line through both, no scatter check")
    mismatch = float(np.nanmax(used["speed_mismatch_rel"])) if used["speed_mismatch_rel"].notna().any() else 0.0
    if mismatch > 0.05:
        notes.append(f"+ and - speeds differ by up to {100 * mismatch:.0f} %")
    return StaticForce(campaign=campaign, static_force_N=fit["static_force_N"], std_error_N=fit["std_error_N"],
                       ci_low_N=fit["ci_low_N"], ci_high_N=fit["ci_high_N"], confidence=spec.confidence,
                       source=source, method=fit["method"], n_speeds=len(used), n_matched=len(matched),
                       v_min_m_s=float(used["speed_m_s"].min()), v_max_m_s=float(used["speed_m_s"].max()),
                       slope_N_s_m=fit["slope_N_s_m"], statistical_error_N=fit["statistical_error_N"],
                       extrapolation_N=fit["extrapolation_N"], residual_scale=fit["residual_scale"],
                       fit_p_value=fit["fit_p_value"], gas_force_N=gas,
                       source_file=source_file, source_rows=",".join(used["rows"]), note="; ".join(notes))


def block_mean(force_N, n_blocks: int = STANDSTILL_BLOCKS) -> tuple[float, float]:
    """(mean, standard error) [N] of a force record [N]: the SE from the scatter of the means of ``n_blocks``
    consecutive blocks, std(block means)/sqrt(blocks), which holds for correlated noise too; fewer than
    2 samples per block: std/sqrt(n)."""
    f = np.asarray(force_N, dtype=float)
    if f.size == 0:
        return math.nan, math.nan
    if f.size < 2 * n_blocks:
        return float(f.mean()), float(f.std(ddof=1) / math.sqrt(f.size)) if f.size > 1 else math.nan
    means = np.array([b.mean() for b in np.array_split(f, n_blocks)])
    return float(f.mean()), float(means.std(ddof=1) / math.sqrt(n_blocks))


def standstill_estimate(campaign: str, points: pd.DataFrame, gas_force_N: float | None,
                        confidence: float = CONFIDENCE) -> StaticForce:
    """The static force F_static as the inverse-variance weighted mean of the standstill cases' means (module doc); the
    standard error the larger of the weighted mean's and the cases' scatter about it."""
    f = points["force_N"].to_numpy(float)
    se = np.maximum(points["std_error_N"].to_numpy(float), 1e-9)
    se = np.where(np.isfinite(se), se, np.nanmax(np.append(se[np.isfinite(se)], 1.0)))
    w = 1.0 / se ** 2
    mean = float(np.sum(w * f) / np.sum(w))
    error = math.sqrt(1.0 / float(np.sum(w)))
    if len(f) > 1:
        error = max(error, float(np.std(f, ddof=1) / math.sqrt(len(f))))
    half = _z(confidence) * error
    gas = math.nan if gas_force_N is None else float(gas_force_N)
    cases_file = STAGE_OUTPUTS["validate"]["cases"]
    return StaticForce(campaign, mean, error, mean - half, mean + half, confidence, "standstill", "standstill_mean",
                       0, 0, math.nan, math.nan, math.nan, error, math.nan, math.nan, math.nan, gas, cases_file,
                       ",".join(points["case"]), "from the standstill cases' mean force (at rest, friction may hold "
                       "the rod anywhere within ±F_C of it)", n_standstill=len(f))


def _agrees(left_N: float, se_N: float, gas_N: float, confidence: float) -> bool:
    bound = _z(confidence) * (se_N if math.isfinite(se_N) else 0.0) + max(GAS_TOLERANCE_N,
                                                                          GAS_TOLERANCE_REL * abs(gas_N))
    return abs(left_N) <= bound


def gas_force_check(cases: pd.DataFrame | None, standstill: pd.DataFrame, fitted: StaticForce | None,
                    confidence: float = CONFIDENCE) -> tuple[str, str]:
    """(GAS_CHECKS status, one line per check) of the declared gas forces (module doc): each standstill case
    that declares one alone, the moving cases that declare one together through ``fitted`` (F_static of the
    characteristic or the binned points; None: not estimated)."""
    lines, verdicts = [], []
    for _, p in standstill.iterrows():
        if not math.isfinite(p["gas_force_N"]):
            continue
        ok = _agrees(p["force_N"], p["std_error_N"], p["gas_force_N"], confidence)
        verdicts.append(ok)
        lines.append(f"{p['case']}: {p['force_N']:+.2f} ± {p['std_error_N']:.2f} N left of the declared "
                     f"{p['gas_force_N']:g} N: {'agrees' if ok else 'disagrees'}")
    moving = pd.DataFrame()
    if cases is not None and not cases.empty and "gas_force_N" in cases:
        moving = cases[(cases["waveform"] != "standstill") & (cases["status"] == "ok")
                       & cases["gas_force_N"].notna()]
    if not moving.empty:
        names = ",".join(moving["case"].astype(str))
        gas = float(moving["gas_force_N"].abs().max())
        if fitted is None or not math.isfinite(fitted.static_force_N):
            lines.append(f"moving cases {names}: not checked (no static force from the characteristic)")
        else:
            ok = _agrees(fitted.static_force_N, fitted.std_error_N, gas, confidence)
            verdicts.append(ok)
            lines.append(f"moving cases {names}: static force {fitted.static_force_N:+.2f} ± "
                         f"{fitted.std_error_N:.2f} N left of their declared gas forces: "
                         f"{'agrees' if ok else 'disagrees'}")
    if not verdicts:
        return "not_checked", "; ".join(lines)
    return ("agrees" if all(verdicts) else "disagrees"), "; ".join(lines)


@dataclass(frozen=True)
class OffsetCheck:
    """The static force against the diagnosis' load-cell offset: a status (OFFSET_STATUSES) and one line."""

    status: str
    text: str
    offset_N: float | None = None       # the diagnosis' offset compared with (0 when it fitted none)
    difference_N: float | None = None   # static force - offset
    sigma: float | None = None          # |difference| / its standard error


def _finite(value) -> float | None:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def offset_standard_error(diagnosis: Mapping) -> float:
    """The approximate standard error [N] of the diagnosis' offset from its profile test: fixing the offset at 0
    raises χ² by Δχ² ≈ (F_0/σ)², so σ ≈ |F_0| / sqrt(Δχ²) (instrument_tests.force_offset); 0 when
    the test is not there."""
    test = ((diagnosis.get("instrument_tests") or {}).get("force_offset") or {})
    estimate, rise = _finite(test.get("estimate")), _finite(test.get("chi2_rise_if_fixed"))
    if estimate is None or rise is None or rise <= 0:
        return 0.0
    return abs(estimate) / math.sqrt(rise)


def diagnosis_alpha(diagnosis: Mapping | None) -> float:
    """The diagnosis' significance level (diagnosis.json ``noise.alpha``), else :data:`isokinetic.stats.ALPHA`."""
    alpha = _finite(((diagnosis or {}).get("noise") or {}).get("alpha"))
    return alpha if alpha is not None and 0.0 < alpha < 1.0 else ALPHA


def offset_check(static: Mapping, diagnosis: Mapping | None, alpha: float | None = None) -> OffsetCheck:
    """The comparison of a static force (a row of static_force.parquet as a dict, or ``asdict(StaticForce)``)
    with diagnosis.json's ``instrument.force_offset_N``.

    Both estimate the constant in both branches (module doc), after the same gas-force correction.
    They disagree when |F_static - F_0| / sqrt(SE_static² + SE_offset²) (:func:`offset_standard_error`)
    exceeds the two-sided normal quantile at ``alpha`` (default: the diagnosis' own level,
    :func:`diagnosis_alpha`: 3.29 sigma at 0.001), so that neither contradicts the other's test by a
    looser level. Where the diagnosis fitted no offset (it found none needed, ``null``), F_0 = 0 is
    what it assumes, and a static force away from 0 is reported as a disagreement: never silent.
    """
    value, se = _finite(static.get("static_force_N")), _finite(static.get("std_error_N"))
    if value is None or se is None:
        return OffsetCheck("not_estimated", f"static force not estimated ({static.get('note') or 'no reason given'})")
    shown = f"static force {value:+.1f} ± {se:.1f} N"
    if not diagnosis or diagnosis.get("status") not in (None, "ok"):
        reason = (diagnosis or {}).get("reason") or "no diagnosis.json"
        return OffsetCheck("no_diagnosis", f"no diagnosis to compare with ({reason}); {shown}")
    offset = _finite((diagnosis.get("instrument") or {}).get("force_offset_N"))
    z = NormalDist().inv_cdf(1.0 - (diagnosis_alpha(diagnosis) if alpha is None else alpha) / 2.0)
    if offset is None:
        sigma = abs(value) / se if se > 0 else (math.inf if value else 0.0)
        if sigma <= z:
            return OffsetCheck("no_offset_fitted", f"no offset fitted (the diagnosis found none needed; {shown}, "
                                                   f"{sigma:.1f} sigma from 0)", 0.0, value, sigma)
        return OffsetCheck("disagree", f"disagree by {value:+.1f} N ({sigma:.1f} sigma): the diagnosis fitted no "
                                       f"load-cell offset, the {shown} excludes 0", 0.0, value, sigma)
    diff = value - offset
    se_diff = math.hypot(se, offset_standard_error(diagnosis))
    sigma = abs(diff) / se_diff if se_diff > 0 else (math.inf if diff else 0.0)
    offset_shown = f"diagnosis offset {offset:+.1f} N"
    if sigma <= z:
        return OffsetCheck("consistent", f"consistent ({shown}, {offset_shown}, {sigma:.1f} sigma apart)", offset,
                           diff, sigma)
    bound = ((diagnosis.get("instrument_tests") or {}).get("bounds") or {}).get("force_offset_N")
    at_bound = ""
    if isinstance(bound, (list, tuple)) and len(bound) == 2 and _finite(bound[1]) and \
            abs(offset) >= 0.999 * abs(float(bound[1])):
        at_bound = f"; the offset sits at its bound ±{abs(float(bound[1])):.1f} N"
    return OffsetCheck("disagree", f"disagree by {diff:+.1f} N ({sigma:.1f} sigma): {shown}, {offset_shown}{at_bound}",
                       offset, diff, sigma)
