"""Models of the steady characteristic (Sec. 4.5, Eq. 31-32, Fig. 13-14).

Method of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs" (Titurus et al.); the figures (Fig. 13-14) are drawn by
:mod:`isokinetic.plots.models`, the tables written by the rule ``models`` (:mod:`isokinetic.stages.models`).

Nominal curves
    Eq. (31)-(32) with the campaign's Table 1 data for C_D in {0.6, 0.7, 0.8}: the turbulent family
    'T' (c1 = 0) and the laminar-turbulent family 'L-T' (:func:`nominal_families`).

Fitted models (:func:`fit_models`)
    Wallaschek [25], symmetric:  F = sign(v) F_C + D_L v + D_Q v|v|            (3 parameters)
    Surace et al. [22], asymmetric: the same form with an independent (F_C, D_L, D_Q) for v > 0
    and for v < 0 (F_C is the friction *magnitude* of that direction, so F(v < 0) = -F_C- + ...).
    Both are linear in the parameters and are fitted to every window of both periods by weighted
    least squares. Weights 1/σ_i² with σ_i = s_i / sqrt(n_i), s_i the window's force_std_N and n_i
    its sample count: the standard error of the window mean for uncorrelated sample noise, which is
    what makes a 20 N scatter on a 7 kN window count less than a 5 N scatter on a 100 N window (the
    force noise grows with |F|, Fig. 12) and a 6000-sample window more than a 500-sample one. The
    covariance is scaled by the residual variance (reduced chi-square) so the absolute noise level
    need not be right, only its window-to-window proportions: serial correlation of the noise, which
    inflates every standard error alike, and model error both widen the intervals. 95 % intervals
    use Student's t with n - p degrees of freedom. The points fitted (:func:`fit_points`): the triangle
    windows when the campaign has any, else every point of the characteristic (a sine-only or free-only
    campaign): a sine case's force at peak velocity lies below the steady characteristic (the oil's
    compressibility, paper Sec. 4), so the two are not fitted together. A sine point has n_i its cycles
    and s_i their scatter, a free record's bin its samples and their spread, so s_i / sqrt(n_i) is each
    point's standard error as a window's. The Surace directions are two separate fits (own residual
    variance each). ``weighting='force_std'``
    (1/s_i²) or ``'none'`` are available.

Physical readings (rows with ``kind='derived'`` right after the parameter they come from)
    From D_L = A_p² c1: c1, the equivalent viscosity μ = c1 A_O² / (8π l_O) (nominal l_O, A_O) and the
    equivalent orifice area A_O = sqrt(8π μ l_O / c1) (nominal μ, l_O); from D_Q = A_p³ c2: c2 and the
    equivalent discharge coefficient C_D = sqrt(ρ / (2 c2 A_O²)) (nominal A_O, ρ). Intervals are the
    monotone transforms of the parameter interval ends (ends swap for decreasing transforms; an end
    at or below zero maps to 0 or +inf). Needs the damper block (A_p at least).

Plausibility (columns physical_range, plausible, plausibility; :func:`physical_range`, :func:`plausibility`)
    Every fitted parameter and physical reading is checked against the values it can physically take:
    F_C >= 0 (a friction magnitude; a static force such as a gas force or a load-cell zero larger than the
    friction pushes one Surace direction's F_C below zero), D_L, D_Q, c1, c2 >= 0 (flow resistances
    dissipate energy), viscosity_eq > 0, discharge_coefficient_eq in (0, 1] (real flow over ideal
    orifice flow) and orifice_area_eq in (0, A_p] (an orifice wider than the piston does not throttle).
    A reading is *implausible* (``plausible`` false) only when its whole 95 % interval lies outside the
    range: then ``plausibility`` gives the reason, naming the value, the interval and the bound. A
    reading whose estimate lies outside but whose interval reaches into the range is *not excluded*: it
    stays ``plausible``, and ``plausibility`` says "not excluded: ..." so the report can show it apart.
    An interval end that is missing (NaN) counts as unbounded, so a reading without an interval is
    never called implausible. ``plausibility`` is empty for a reading inside its range, and
    ``physical_range`` is empty (and ``plausible`` true) for a parameter with no known range.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import special

from isokinetic.contracts import tables
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.contracts.row_keys import row_keys
from isokinetic.physics.damper import Damper, nominal_force

log = logging.getLogger("isokinetic.models")


MODEL_NAMES = ("wallaschek", "surace")
PARAMETERS = ("F_C", "D_L", "D_Q")
CONFIDENCE = 0.95
DISCHARGE_COEFFICIENTS = (0.6, 0.7, 0.8)
FAMILIES = ("T", "L-T")
WEIGHTINGS = ("standard_error", "force_std", "none")
_PARAM_INFO = {
    "F_C": ("N", "Coulomb friction force"),
    "D_L": ("N s/m", "laminar coefficient D_L = A_p^2 c1"),
    "D_Q": ("N s^2/m^2", "quadratic (turbulent) coefficient D_Q = A_p^3 c2"),
}
MODEL_COLUMNS = ["campaign", "model", "direction", "parameter", "kind", "derived_from", "estimate", "ci_low",
                 "ci_high", "std_error", "unit", "description", "assumption", "physical_range", "plausible",
                 "plausibility", "n_points", "dof", "rms_residual_N", "residual_scale", "weighting", "confidence",
                 "source_file", "source_rows"]
RESIDUAL_COLUMNS = ["campaign", "model", "case", "segment", "direction", "velocity_m_s", "force_N",
                    "predicted_N", "residual_N", "standard_error_N", "normalized_residual"]


def nominal_families(damper: Damper, velocities_m_s, discharge_coefficients: Sequence[float] = DISCHARGE_COEFFICIENTS
                     ) -> pd.DataFrame:
    """Eq. (31)-(32) forces of the 'T' (c1 = 0) and 'L-T' families, one row per family, C_D, velocity.

    Columns: family, discharge_coefficient, velocity_m_s, force_N.
    """
    v = np.asarray(velocities_m_s, dtype=float).ravel()
    parts = []
    for family in FAMILIES:
        for cd in discharge_coefficients:
            f = nominal_force(v, damper, discharge_coefficient=float(cd), laminar=family == "L-T")
            parts.append(pd.DataFrame({"family": family, "discharge_coefficient": float(cd),
                                       "velocity_m_s": v, "force_N": np.asarray(f, dtype=float)}))
    if not parts:
        return pd.DataFrame({"family": pd.Series(dtype=object), "discharge_coefficient": pd.Series(dtype=float),
                             "velocity_m_s": pd.Series(dtype=float), "force_N": pd.Series(dtype=float)})
    return pd.concat(parts, ignore_index=True)


def design_matrix(velocity_m_s) -> np.ndarray:
    """The design matrix (n, 3): columns sign(v), v, v|v| (F_C, D_L, D_Q), the same for each Surace direction."""
    v = np.asarray(velocity_m_s, dtype=float)
    return np.column_stack([np.sign(v), v, v * np.abs(v)])


def standard_errors(force_std_N, n_samples, force_N, weighting: str = "standard_error") -> np.ndarray:
    """σ_i [N] of each window for the weights 1/σ_i² (see module doc).

    A zero spread (noise-free or quantised data) is floored at 1e-6 |F| + 1e-9 N so no window gets
    an infinite weight.
    """
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting must be one of {WEIGHTINGS}, got {weighting!r}")
    s = np.asarray(force_std_N, dtype=float)
    f = np.abs(np.asarray(force_N, dtype=float))
    s = np.maximum(np.where(np.isfinite(s), s, 0.0), 1e-6 * f + 1e-9)
    if weighting == "none":
        return np.ones_like(s)
    if weighting == "force_std":
        return s
    return s / np.sqrt(np.maximum(np.asarray(n_samples, dtype=float), 1.0))


def wls(x: np.ndarray, y: np.ndarray, sigma: np.ndarray, confidence: float = CONFIDENCE) -> dict:
    """Weighted least squares with residual-variance scaling and t intervals.

    Returns estimate, std_error, ci_low, ci_high (arrays), covariance (of the estimates, scaled by the
    reduced chi-square), dof, residual_scale (sqrt of the reduced chi-square), predicted. Columns are
    scaled to unit norm before a QR solve (v and v|v| span many decades). Intervals are NaN when dof < 1.
    """
    n, p = x.shape
    if n < p:
        raise ValueError(f"{n} points for {p} parameters")
    w = 1.0 / sigma
    xw = x * w[:, None]
    yw = y * w
    scale = np.linalg.norm(xw, axis=0)
    scale[scale == 0] = 1.0
    q, r = np.linalg.qr(xw / scale)
    if np.min(np.abs(np.diag(r))) <= 1e-12 * np.max(np.abs(np.diag(r))):
        raise ValueError("design matrix is rank deficient (too few distinct velocities or one direction only)")
    b = np.linalg.solve(r, q.T @ yw)
    est = b / scale
    pred = x @ est
    res_w = yw - xw @ est
    dof = n - p
    if dof >= 1:
        s2 = float(res_w @ res_w) / dof
        rinv = np.linalg.inv(r)
        cov = s2 * (rinv @ rinv.T) / np.outer(scale, scale)
        se = np.sqrt(np.diag(cov))
        tq = float(special.stdtrit(dof, 0.5 + confidence / 2.0))  # scipy.stats.t.ppf's own function
        lo, hi = est - tq * se, est + tq * se
        rs = math.sqrt(s2)
    else:
        se = lo = hi = np.full(p, np.nan)
        cov = np.full((p, p), np.nan)
        rs = math.nan
    return {"estimate": est, "std_error": se, "ci_low": lo, "ci_high": hi, "covariance": cov, "dof": dof,
            "residual_scale": rs, "predicted": pred}


def _transform_interval(est, lo, hi, g, increasing: bool, positive_only: bool):
    """Map (estimate, ci_low, ci_high) through a monotone g; ends <= 0 of a positive-only g -> 0 / inf."""
    def ok(x):
        return np.isfinite(x) and (x > 0 or not positive_only)
    e = g(est) if ok(est) else math.nan
    if increasing:
        a = g(lo) if ok(lo) else (0.0 if np.isfinite(lo) else math.nan)
        b = g(hi) if ok(hi) else (0.0 if np.isfinite(hi) else math.nan)
    else:
        a = g(hi) if ok(hi) else (math.inf if np.isfinite(hi) else math.nan)
        b = g(lo) if ok(lo) else (math.inf if np.isfinite(lo) else math.nan)
    return float(e), float(a), float(b)


def physical_readings(parameter: str, estimate: float, ci_low: float, ci_high: float, damper: Damper) -> list[dict]:
    """The derived rows (parameter, estimate, ci_low, ci_high, unit, description, assumption) of D_L or D_Q."""
    ap = damper.piston_area_m2
    rows = []
    if parameter == "D_L":
        k = 1.0 / ap**2
        items = [
            ("c1", lambda x: x * k, True, False, "Pa s/m^3", "laminar coefficient c1 = D_L / A_p^2", "A_p"),
            ("viscosity_eq", lambda x: x * k * damper.orifice_area_m2**2 / (8.0 * math.pi * damper.orifice_length_m),
             True, False, "Pa s", "equivalent viscosity c1 A_O^2 / (8 pi l_O)", "nominal A_p, l_O, A_O"),
            ("orifice_area_eq", lambda x: math.sqrt(8.0 * math.pi * damper.viscosity_Pa_s * damper.orifice_length_m
                                                    / (x * k)),
             False, True, "m^2", "equivalent orifice area sqrt(8 pi mu l_O / c1)", "nominal A_p, mu, l_O"),
        ]
    elif parameter == "D_Q":
        k = 1.0 / ap**3
        items = [
            ("c2", lambda x: x * k, True, False, "Pa s^2/m^6", "turbulent coefficient c2 = D_Q / A_p^3", "A_p"),
            ("discharge_coefficient_eq",
             lambda x: math.sqrt(damper.density_kg_m3 / (2.0 * x * k * damper.orifice_area_m2**2)),
             False, True, "-", "equivalent discharge coefficient sqrt(rho / (2 c2 A_O^2))", "nominal A_p, A_O, rho"),
        ]
    else:
        return rows
    for name, g, inc, pos, unit, desc, assumption in items:
        e, a, b = _transform_interval(estimate, ci_low, ci_high, g, inc, pos)
        rows.append({"parameter": name, "estimate": e, "ci_low": a, "ci_high": b, "unit": unit,
                     "description": desc, "assumption": assumption})
    return rows


def _num(x: float) -> str:
    """A value in a reason: 4 significant digits, 'inf' for infinity."""
    return f"{x:.4g}"


@dataclass(frozen=True)
class PhysicalRange:
    """The values a reading can physically take, low .. high (each end open or closed), and why."""

    low: float = 0.0
    high: float = math.inf
    low_open: bool = False
    high_open: bool = True
    why: str = ""

    def text(self) -> str:
        """The range in interval notation: '[0, inf)', '(0, 1]'."""
        right = ")" if self.high_open or math.isinf(self.high) else "]"
        return f"{'(' if self.low_open else '['}{_num(self.low)}, {_num(self.high)}{right}"

    def below(self, x: float) -> bool:
        """Whether x lies below the range."""
        return x < self.low or (self.low_open and x == self.low)

    def above(self, x: float) -> bool:
        """Whether x lies above the range."""
        return x > self.high or (self.high_open and x == self.high)


_FRICTION = ("a friction force opposes the motion, so its magnitude cannot be negative (a static force, gas force "
             "or load-cell zero, larger than the friction pushes one direction's F_C below zero)")
_LAMINAR = "a laminar flow resistance dissipates energy, so it cannot be negative"
_TURBULENT = ("a turbulent (orifice) flow resistance cannot be negative (a digressive curve, e.g. an opening "
              "valve, gives D_Q < 0: the fixed-orifice model does not apply)")
_RANGES = {
    "F_C": PhysicalRange(why=_FRICTION),
    "D_L": PhysicalRange(why=_LAMINAR),
    "c1": PhysicalRange(why=_LAMINAR),
    "D_Q": PhysicalRange(why=_TURBULENT),
    "c2": PhysicalRange(why=_TURBULENT),
    "viscosity_eq": PhysicalRange(low_open=True, why="a viscosity is positive"),
    "discharge_coefficient_eq": PhysicalRange(
        high=1.0, low_open=True, high_open=False,
        why="a discharge coefficient (real over ideal orifice flow) is at most 1; above it, the real orifice is "
            "larger or the quadratic loss smaller than the nominal A_O implies"),
}


def physical_range(parameter: str, damper: Damper | None = None) -> PhysicalRange | None:
    """The physical range of a fitted parameter or reading (module doc); None when it has none.

    orifice_area_eq's upper bound is the piston area A_p, so it needs ``damper``.
    """
    if parameter == "orifice_area_eq":
        if damper is None:
            return None
        return PhysicalRange(high=damper.piston_area_m2, low_open=True, high_open=False,
                             why=f"an orifice wider than the piston (A_p = {_num(damper.piston_area_m2)} m^2) "
                                 "does not throttle the flow")
    return _RANGES.get(parameter)


def plausibility(parameter: str, estimate: float, ci_low: float, ci_high: float, rng: PhysicalRange | None,
                 unit: str = "", confidence: float = CONFIDENCE) -> tuple[bool, str]:
    """(plausible, reason) of a reading against its physical range ``rng`` (module doc).

    False only when the whole interval lies outside the range; a NaN end counts as unbounded. A
    plausible reading whose estimate lies outside the range gets a 'not excluded: ...' note.
    """
    if rng is None:
        return True, ""
    lo = -math.inf if math.isnan(ci_low) else float(ci_low)
    hi = math.inf if math.isnan(ci_high) else float(ci_high)
    has_estimate = math.isfinite(estimate)
    unit_text = "" if unit in ("", "-") else f" {unit}"
    value = f"{parameter} = {_num(estimate)}{unit_text}" if has_estimate else f"{parameter} has no real estimate"
    interval = f"{confidence * 100:g} % interval [{_num(lo)}, {_num(hi)}]"
    if rng.above(lo):
        return False, f"{value}, {interval} wholly above the physical bound {_num(rng.high)}: {rng.why}"
    if rng.below(hi):
        return False, f"{value}, {interval} wholly below the physical bound {_num(rng.low)}: {rng.why}"
    if has_estimate and (rng.above(estimate) or rng.below(estimate)):
        return True, f"not excluded: {value} lies outside {rng.text()}, but its {interval} reaches into it"
    return True, ""


def plausibility_columns(parameter: str, estimate: float, ci_low: float, ci_high: float, damper: Damper | None,
                         unit: str = "", confidence: float = CONFIDENCE) -> dict:
    """The models table's physical_range, plausible and plausibility of one row."""
    rng = physical_range(parameter, damper)
    ok, reason = plausibility(parameter, estimate, ci_low, ci_high, rng, unit, confidence)
    return {"physical_range": "" if rng is None else rng.text(), "plausible": ok, "plausibility": reason}


def _empty_models() -> pd.DataFrame:
    df = pd.DataFrame({c: pd.Series(dtype=object if c in ("campaign", "model", "direction", "parameter", "kind",
                                                           "derived_from", "unit", "description", "assumption",
                                                           "physical_range", "plausibility", "weighting",
                                                           "source_file", "source_rows") else
                                     "int64" if c in ("n_points", "dof") else bool if c == "plausible" else float)
                       for c in MODEL_COLUMNS})
    return df


def _empty_residuals() -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=object if c in ("campaign", "model", "case", "direction") else
                                      "int64" if c == "segment" else float) for c in RESIDUAL_COLUMNS})


def fit_points(char: pd.DataFrame | None) -> pd.DataFrame | None:
    """The characteristic points the models fit (module doc): the triangle windows when the table has any,
    else all of it (a table without a ``method`` column is all windows)."""
    if char is None or "method" not in char:
        return char
    triangle = char["method"] == "triangle_window"
    return char[triangle].reset_index(drop=True) if triangle.any() else char


def fit_models(char: pd.DataFrame, damper: Damper | None = None, weighting: str = "standard_error",
               confidence: float = CONFIDENCE, source_file: str = STAGE_OUTPUTS["characteristic"]["characteristic"]
               ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The Wallaschek and Surace fits of a CHARACTERISTIC (or WINDOWS) table: (models_df, residuals_df).

    models_df follows tables.MODELS plus kind ('fitted' | 'derived'), derived_from, std_error, unit,
    description, assumption, n_points, dof, rms_residual_N, residual_scale, weighting, confidence,
    the plausibility check (physical_range, plausible, plausibility: module doc), and the row-level
    lineage: source_file (``source_file``, the table ``char`` was read from) and
    source_rows, the (case, segment) keys of the rows that fit used, sorted, 'T01/1,T01/2,...'
    (:func:`isokinetic.contracts.row_keys.row_keys`; n_points of them). A derived row carries its parameter's sources.
    Derived physical readings need ``damper``; without it only the fitted rows are written. A model
    (or Surace direction) with fewer than 4 points or a rank-deficient design is skipped (logged).
    """
    char = fit_points(char)
    if char is None or char.empty:
        return tables.validate_table(_empty_models(), tables.MODELS), _empty_residuals()
    campaign = "+".join(sorted(set(char["campaign"].astype(str))))
    v_all = char["velocity_m_s"].to_numpy(float)
    f_all = char["force_N"].to_numpy(float)
    sig_all = standard_errors(char["force_std_N"].to_numpy(float), char["n_samples"].to_numpy(float), f_all,
                              weighting)
    # branch by the sign of the measured velocity (a window's direction column agrees for any sane data)
    direction = np.where(v_all > 0, "+", np.where(v_all < 0, "-", "0"))
    fits = [("wallaschek", "both", np.ones(v_all.size, dtype=bool)),
            ("surace", "+", direction == "+"), ("surace", "-", direction == "-")]
    model_rows, res_parts = [], []
    for model, dirn, mask in fits:
        if mask.sum() < len(PARAMETERS) + 1:
            log.warning("campaign %s: %s (%s): %d point(s), at least %d needed; not fitted", campaign, model, dirn,
                        int(mask.sum()), len(PARAMETERS) + 1)
            continue
        v, f, sig = v_all[mask], f_all[mask], sig_all[mask]
        try:
            r = wls(design_matrix(v), f, sig, confidence)
        except ValueError as exc:
            log.warning("campaign %s: %s (%s) not fitted: %s", campaign, model, dirn, exc)
            continue
        resid = f - r["predicted"]
        rms = float(np.sqrt(np.mean(resid**2)))
        common = {"campaign": campaign, "model": model, "direction": dirn, "n_points": int(mask.sum()),
                  "dof": int(r["dof"]), "rms_residual_N": rms, "residual_scale": r["residual_scale"],
                  "weighting": weighting, "confidence": confidence, "source_file": source_file,
                  "source_rows": row_keys(char.loc[mask].sort_values(["case", "segment"], kind="stable"))}
        for j, name in enumerate(PARAMETERS):
            unit, desc = _PARAM_INFO[name]
            est, lo, hi = float(r["estimate"][j]), float(r["ci_low"][j]), float(r["ci_high"][j])
            model_rows.append({**common, "parameter": name, "kind": "fitted", "derived_from": "", "estimate": est,
                               "ci_low": lo, "ci_high": hi, "std_error": float(r["std_error"][j]), "unit": unit,
                               "description": desc + (" (magnitude, this direction)" if dirn != "both" and
                                                      name == "F_C" else ""),
                               "assumption": ""})
            if damper is not None:
                for d in physical_readings(name, est, lo, hi, damper):
                    model_rows.append({**common, **d, "kind": "derived", "derived_from": name,
                                       "std_error": math.nan})
        sub = char.loc[mask, ["case", "segment", "direction", "velocity_m_s", "force_N"]].copy()
        sub.insert(0, "model", model)
        sub.insert(0, "campaign", campaign)
        sub["predicted_N"] = r["predicted"]
        sub["residual_N"] = resid
        sub["standard_error_N"] = sig
        sub["normalized_residual"] = resid / sig / (r["residual_scale"] if np.isfinite(r["residual_scale"]) and
                                                    r["residual_scale"] > 0 else 1.0)
        res_parts.append(sub)
    for row in model_rows:
        row.update(plausibility_columns(row["parameter"], row["estimate"], row["ci_low"], row["ci_high"], damper,
                                        row["unit"], confidence))
    models = pd.DataFrame(model_rows, columns=MODEL_COLUMNS) if model_rows else _empty_models()
    models = models.astype({"n_points": "int64", "dof": "int64", "plausible": bool})
    residuals = pd.concat(res_parts, ignore_index=True)[RESIDUAL_COLUMNS] if res_parts else _empty_residuals()
    residuals = residuals.astype({"segment": "int64"})
    return tables.validate_table(models, tables.MODELS), residuals


def model_parameters(models_df: pd.DataFrame, model: str) -> dict[str, dict[str, float]]:
    """{direction: {F_C, D_L, D_Q}} of a fitted model ('both' for Wallaschek, '+'/'-' for Surace)."""
    if models_df is None or models_df.empty:
        return {}
    sub = models_df[(models_df["model"] == model) & (models_df.get("kind", "fitted") == "fitted")]
    out: dict[str, dict[str, float]] = {}
    for r in sub.itertuples():
        if r.parameter in PARAMETERS:
            out.setdefault(r.direction, {})[r.parameter] = float(r.estimate)
    return {d: p for d, p in out.items() if set(p) == set(PARAMETERS)}


def model_force(models_df: pd.DataFrame, model: str, velocity_m_s) -> np.ndarray:
    """The force [N] of a fitted model at the given velocities [m/s] (NaN where the model/direction is missing)."""
    v = np.asarray(velocity_m_s, dtype=float)
    params = model_parameters(models_df, model)
    out = np.full(v.shape, np.nan)
    x = design_matrix(v.ravel()).reshape(v.shape + (3,))
    if "both" in params:
        p = params["both"]
        return x @ np.array([p["F_C"], p["D_L"], p["D_Q"]])
    for dirn, sel in (("+", v > 0), ("-", v < 0)):
        if dirn in params and sel.any():
            p = params[dirn]
            out[sel] = x[sel] @ np.array([p["F_C"], p["D_L"], p["D_Q"]])
    return out


def _rel(pred, meas):
    pred, meas = np.asarray(pred, dtype=float), np.asarray(meas, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(meas != 0, (pred - meas) / np.abs(meas), np.nan)


def comparison_table(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, models_df: pd.DataFrame | None,
                     damper: Damper | None) -> pd.DataFrame:
    """One row per characteristic point, in the characteristic's order.

    force_N (measured), nominal_plan_N (the nominal model through the plan: the model window of the
    same case and segment, :mod:`isokinetic.measurement.model_windows`), nominal_eq31_N (incompressible Eq. 31 at the
    measured velocity, nominal C_D, no friction), wallaschek_N and surace_N (fits at the measured
    velocity), and rel_err_<x> = (x - measured) / |measured|. Missing inputs give NaN columns.
    """
    keys = ["campaign", "case", "segment", "direction", "period", "velocity_m_s", "force_N", "force_std_N",
            "repeatability_flagged"]
    base = char[[k for k in keys if k in char]].copy().reset_index(drop=True) if char is not None else pd.DataFrame(
        columns=keys)
    if nominal_windows is not None and len(nominal_windows) and len(base):
        nw = nominal_windows[["case", "segment", "velocity_m_s", "force_N"]].rename(
            columns={"velocity_m_s": "nominal_plan_velocity_m_s", "force_N": "nominal_plan_N"})
        if nw.duplicated(["case", "segment"]).any():
            raise ValueError("nominal windows: more than one row per case and segment")
        base = base.merge(nw, on=["case", "segment"], how="left", validate="many_to_one")
    else:
        base["nominal_plan_velocity_m_s"] = np.nan
        base["nominal_plan_N"] = np.nan
    v = base["velocity_m_s"].to_numpy(float) if len(base) else np.empty(0)
    base["nominal_eq31_N"] = nominal_force(v, damper) if damper is not None else np.full(v.size, np.nan)
    for model in MODEL_NAMES:
        base[f"{model}_N"] = model_force(models_df, model, v) if models_df is not None else np.full(v.size, np.nan)
    meas = base["force_N"].to_numpy(float) if len(base) else np.empty(0)
    for col in ("nominal_plan", "nominal_eq31", "wallaschek", "surace"):
        base[f"rel_err_{col}"] = _rel(base[f"{col}_N"].to_numpy(float), meas)
    return base


def family_velocities(char: pd.DataFrame | None, harmonic: pd.DataFrame | None = None, n: int = 121) -> np.ndarray:
    """A symmetric velocity grid [m/s] for the families: geometric over the data's |v| range, both signs."""
    vals = []
    for df in (char, harmonic):
        if df is not None and len(df) and "velocity_m_s" in df:
            vals.append(np.abs(df["velocity_m_s"].to_numpy(float)))
    a = np.concatenate(vals) if vals else np.empty(0)
    a = a[np.isfinite(a) & (a > 0)]
    if a.size == 0:
        return np.empty(0)
    pos = np.geomspace(a.min() / 1.5, a.max() * 1.5, n)
    return np.concatenate([-pos[::-1], [0.0], pos])


__all__ = ["MODEL_NAMES", "PARAMETERS", "CONFIDENCE", "DISCHARGE_COEFFICIENTS", "FAMILIES", "WEIGHTINGS",
           "MODEL_COLUMNS", "RESIDUAL_COLUMNS", "nominal_families", "design_matrix", "standard_errors", "wls",
           "physical_readings", "PhysicalRange", "physical_range", "plausibility", "plausibility_columns",
           "fit_points", "fit_models", "model_parameters", "model_force", "comparison_table", "family_velocities"]
