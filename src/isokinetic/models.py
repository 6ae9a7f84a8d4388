"""Models of the steady characteristic (paper Sec. 4.5, Eq. 31-32, Fig. 13-14).

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
    use Student's t with n - p degrees of freedom. The Surace directions are two separate fits
    (own residual variance each). ``weighting='force_std'`` (1/s_i²) or ``'none'`` are available.

Physical readings (rows with ``kind='derived'`` right after the parameter they come from)
    From D_L = A_p² c1: c1, the equivalent viscosity μ = c1 A_O² / (8π l_O) (nominal l_O, A_O) and the
    equivalent orifice area A_O = sqrt(8π μ l_O / c1) (nominal μ, l_O); from D_Q = A_p³ c2: c2 and the
    equivalent discharge coefficient C_D = sqrt(ρ / (2 c2 A_O²)) (nominal A_O, ρ). Intervals are the
    monotone transforms of the parameter interval ends (ends swap for decreasing transforms; an end
    at or below zero maps to 0 or +inf). Needs the damper block (A_p at least).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from scipy import stats

from . import tables
from .damper import Damper, nominal_force
from .figures import plain_log_ticks, save_figure
from .lineage import row_keys
from .windows import WindowSpec

log = logging.getLogger("isokinetic.models")

MODEL_NAMES = ("wallaschek", "surace")
PARAMETERS = ("F_C", "D_L", "D_Q")
CONFIDENCE = 0.95
DISCHARGE_COEFFICIENTS = (0.6, 0.7, 0.8)
FAMILIES = ("T", "L-T")
WEIGHTINGS = ("standard_error", "force_std", "none")

#: Files written by :func:`write_models`, in order.
TABLE_FILES = ("models.parquet", "model_residuals.parquet", "comparison.parquet")
FIGURE_FILES = ("fig13_comparison.png", "fig14_comparison_loglog.png")

_PARAM_INFO = {
    "F_C": ("N", "Coulomb friction force"),
    "D_L": ("N s/m", "laminar coefficient D_L = A_p^2 c1"),
    "D_Q": ("N s^2/m^2", "quadratic (turbulent) coefficient D_Q = A_p^3 c2"),
}

MODEL_COLUMNS = ["campaign", "model", "direction", "parameter", "kind", "derived_from", "estimate", "ci_low",
                 "ci_high", "std_error", "unit", "description", "assumption", "n_points", "dof",
                 "rms_residual_N", "residual_scale", "weighting", "confidence", "source_file", "source_rows"]
RESIDUAL_COLUMNS = ["campaign", "model", "case", "segment", "direction", "velocity_m_s", "force_N",
                    "predicted_N", "residual_N", "standard_error_N", "normalized_residual"]

MM = 1e3


# ----------------------------------------------------------------------------------------------
# nominal curves
# ----------------------------------------------------------------------------------------------

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


# ----------------------------------------------------------------------------------------------
# weighted least squares
# ----------------------------------------------------------------------------------------------

def design_matrix(velocity_m_s) -> np.ndarray:
    """Columns sign(v), v, v|v| (F_C, D_L, D_Q); the same form serves each Surace direction."""
    v = np.asarray(velocity_m_s, dtype=float)
    return np.column_stack([np.sign(v), v, v * np.abs(v)])


def standard_errors(force_std_N, n_samples, force_N, weighting: str = "standard_error") -> np.ndarray:
    """σ_i of each window for the weights 1/σ_i² (see module doc).

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

    Returns estimate, std_error, ci_low, ci_high (arrays), dof, residual_scale (sqrt of the reduced
    chi-square), predicted. Columns are scaled to unit norm before a QR solve (v and v|v| span many
    decades). Intervals are NaN when dof < 1.
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
        tq = float(stats.t.ppf(0.5 + confidence / 2.0, dof))
        lo, hi = est - tq * se, est + tq * se
        rs = math.sqrt(s2)
    else:
        se = lo = hi = np.full(p, np.nan)
        rs = math.nan
    return {"estimate": est, "std_error": se, "ci_low": lo, "ci_high": hi, "dof": dof, "residual_scale": rs,
            "predicted": pred}


# ----------------------------------------------------------------------------------------------
# physical readings
# ----------------------------------------------------------------------------------------------

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
    """Derived rows (parameter, estimate, ci_low, ci_high, unit, description, assumption) of D_L or D_Q."""
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


# ----------------------------------------------------------------------------------------------
# fitting
# ----------------------------------------------------------------------------------------------

def _empty_models() -> pd.DataFrame:
    df = pd.DataFrame({c: pd.Series(dtype=object if c in ("campaign", "model", "direction", "parameter", "kind",
                                                           "derived_from", "unit", "description", "assumption",
                                                           "weighting", "source_file", "source_rows") else
                                     "int64" if c in ("n_points", "dof") else float)
                       for c in MODEL_COLUMNS})
    return df


def _empty_residuals() -> pd.DataFrame:
    return pd.DataFrame({c: pd.Series(dtype=object if c in ("campaign", "model", "case", "direction") else
                                      "int64" if c == "segment" else float) for c in RESIDUAL_COLUMNS})


def fit_models(char: pd.DataFrame, damper: Damper | None = None, weighting: str = "standard_error",
               confidence: float = CONFIDENCE, source_file: str = "characteristic.parquet"
               ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Wallaschek and Surace fits of a CHARACTERISTIC (or WINDOWS) table: (models_df, residuals_df).

    models_df follows tables.MODELS plus kind ('fitted' | 'derived'), derived_from, std_error, unit,
    description, assumption, n_points, dof, rms_residual_N, residual_scale, weighting, confidence,
    and the row-level lineage: source_file (``source_file``, the table ``char`` was read from) and
    source_rows, the (case, segment) keys of the rows that fit used, sorted, 'T01/1,T01/2,...'
    (:func:`lineage.row_keys`; n_points of them). A derived row carries its parameter's sources.
    Derived physical readings need ``damper``; without it only the fitted rows are written. A model
    (or Surace direction) with fewer than 4 points or a rank-deficient design is skipped (logged).
    """
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
    models = pd.DataFrame(model_rows, columns=MODEL_COLUMNS) if model_rows else _empty_models()
    models = models.astype({"n_points": "int64", "dof": "int64"})
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
    """Force of a fitted model at the given velocities (NaN where the model/direction is missing)."""
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


# ----------------------------------------------------------------------------------------------
# comparison table
# ----------------------------------------------------------------------------------------------

def _rel(pred, meas):
    pred, meas = np.asarray(pred, dtype=float), np.asarray(meas, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(meas != 0, (pred - meas) / np.abs(meas), np.nan)


def comparison_table(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, models_df: pd.DataFrame | None,
                     damper: Damper | None) -> pd.DataFrame:
    """One row per characteristic point, in the characteristic's order.

    force_N (measured), nominal_plan_N (the nominal model through the plan: the model window of the
    same case and segment, :mod:`isokinetic.nominal`), nominal_eq31_N (incompressible Eq. 31 at the
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


# ----------------------------------------------------------------------------------------------
# figures
# ----------------------------------------------------------------------------------------------

_CD_COLOURS = {0.6: "tab:blue", 0.7: "tab:green", 0.8: "tab:olive"}
_NOTE = dict(ha="center", va="center", fontsize=10, color="tab:red", wrap=True)


def _force_unit(values) -> tuple[float, str]:
    a = np.abs(np.asarray(list(values), dtype=float))
    a = a[np.isfinite(a)]
    return (1e3, "kN") if a.size and a.max() >= 1e3 else (1.0, "N")


def _campaign(*frames) -> str:
    for df in frames:
        if df is not None and isinstance(df, pd.DataFrame) and "campaign" in df and len(df):
            return "+".join(sorted(set(df["campaign"].astype(str))))
    return "campaign ?"


def _cd_colour(cd: float, i: int) -> str:
    return _CD_COLOURS.get(round(float(cd), 6), f"C{i + 2}")


def _peak_to_peak(harmonic: pd.DataFrame | None) -> pd.DataFrame:
    if harmonic is None or harmonic.empty or "kind" not in harmonic:
        return pd.DataFrame(columns=["velocity_m_s", "force_N", "direction"])
    return harmonic[harmonic["kind"] == "peak_to_peak"].sort_values("velocity_m_s")


def _notes(damper_missing: bool, char, nominal_windows, models_df) -> list[str]:
    notes = []
    if damper_missing:
        notes.append("no damper block in campaign.json: nominal curves (Eq. 32, model through the plan) not drawn")
    elif nominal_windows is None or len(nominal_windows) == 0:
        notes.append("no nominal model windows")
    if models_df is None or models_df.empty:
        notes.append("no fitted models (too few characteristic points)")
    return notes


def comparison_figure(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, families: pd.DataFrame | None,
                      models_df: pd.DataFrame | None, harmonic: pd.DataFrame | None = None,
                      loops: Mapping[str, pd.DataFrame] | None = None, *, campaign: str | None = None) -> Figure:
    """Fig. 13: measured characteristic, nominal model (through the plan and Eq. 32 families), fits, HE data.

    Linear axes, velocity in mm/s, force in N or kN. ``families`` from :func:`nominal_families` (None or
    empty: no damper block, said on the figure). Lines carry gids: measured+, measured-, nominal-plan,
    family-T-0.6 ..., wallaschek, surace+, surace-, peak-to-peak, loop-<case>.
    """
    name = campaign or _campaign(char, nominal_windows, models_df)
    fig = Figure(figsize=(9.0, 6.5), layout="constrained")
    ax = fig.add_subplot()
    fig.suptitle(f"{name}: measured and modelled damper characteristics (cf. paper Fig. 13)", fontsize=12)
    have_char = char is not None and len(char) > 0
    fs, fu = _force_unit(char["force_N"] if have_char else [])
    ax.set_xlabel("Piston velocity v [mm/s]")
    ax.set_ylabel(f"Force F [{fu}]")
    damper_missing = families is None or len(families) == 0
    notes = _notes(damper_missing, char, nominal_windows, models_df)
    if not have_char:
        ax.text(0.5, 0.5, "no characteristic points (no usable triangle case)", transform=ax.transAxes, **_NOTE)
        if notes:
            fig.supxlabel("; ".join(notes), x=0.01, ha="left", fontsize=8, color="0.3")
        return fig
    # axes span the measured data (characteristic, HE loops and peak-to-peak points); model curves are clipped
    p2p = _peak_to_peak(harmonic)
    loop_items = [(c, lp) for c, lp in sorted((loops or {}).items()) if lp is not None and len(lp)]
    spans_v = [char["velocity_m_s"], p2p["velocity_m_s"]] + [lp["velocity_m_s"] for _, lp in loop_items]
    spans_f = [char["force_N"], p2p["force_N"]] + [lp["force_N"] for _, lp in loop_items]
    vmax = max(float(np.nanmax(np.abs(np.asarray(s, dtype=float)))) for s in spans_v if len(s)) * 1.05
    fmax = max(float(np.nanmax(np.abs(np.asarray(s, dtype=float)))) for s in spans_f if len(s))
    fs, fu = _force_unit([fmax])
    ax.set_ylabel(f"Force F [{fu}]")
    ylim = fmax * 1.15 / fs
    # hysteresis loops (thin, behind)
    for i, (case, loop) in enumerate(loop_items):
        ax.plot(loop["velocity_m_s"].to_numpy(float) * MM, loop["force_N"].to_numpy(float) / fs, color="0.6", lw=0.5,
                alpha=0.8, zorder=1, gid=f"loop-{case}", label="HE hysteresis loops (sine tests)" if i == 0 else None)
    vx = np.linspace(-vmax, vmax, 401)
    # nominal families, Eq. (32)
    if not damper_missing:
        for fam, ls in (("T", "--"), ("L-T", "-")):
            sub = families[families["family"] == fam]
            for i, (cd, g) in enumerate(sub.groupby("discharge_coefficient", sort=True)):
                g = g.sort_values("velocity_m_s")
                ax.plot(g["velocity_m_s"] * MM, g["force_N"] / fs, ls=ls, lw=0.9, color=_cd_colour(cd, i), zorder=2,
                        gid=f"family-{fam}-{cd:g}",
                        label=f"theoretic {fam.replace('-', '–')}, C_D = {cd:g} (Eq. 32)")
    # fitted models
    if models_df is not None and len(models_df):
        fw = model_force(models_df, "wallaschek", vx)
        if np.isfinite(fw).any():
            ax.plot(vx * MM, fw / fs, color="black", lw=1.3, zorder=4, gid="wallaschek",
                    label="Wallaschek fit (symmetric L–T + Coulomb)")
        for dirn, sel in (("+", vx > 0), ("-", vx < 0)):
            fsur = model_force(models_df, "surace", vx[sel])
            if np.isfinite(fsur).any():
                ax.plot(vx[sel] * MM, fsur / fs, color="tab:purple", lw=1.3, ls="-.", zorder=4, gid=f"surace{dirn}",
                        label="Surace fit (one parameter set per direction)" if dirn == "+" else None)
    # harmonic peak-to-peak curve
    if len(p2p):
        ax.plot(p2p["velocity_m_s"].to_numpy(float) * MM, p2p["force_N"].to_numpy(float) / fs, color="tab:orange",
                lw=1.2, marker="D", ms=5, zorder=5, gid="peak-to-peak", label="HE peak-to-peak curve")
    # nominal model through the plan
    if nominal_windows is not None and len(nominal_windows):
        ax.plot(nominal_windows["velocity_m_s"] * MM, nominal_windows["force_N"] / fs, ls="none", marker="x", ms=6,
                color="tab:brown", zorder=5, gid="nominal-plan",
                label="nominal model through the test plan (compressible, same windows)")
    # measured characteristic
    for d, style in (("+", dict(marker="o", ls="-", label="damper curve, v > 0 (triangle tests)")),
                     ("-", dict(marker="*", ls="--", ms=8, label="damper curve, v < 0"))):
        b = char[char["velocity_m_s"] > 0] if d == "+" else char[char["velocity_m_s"] < 0]
        b = b.sort_values("velocity_m_s")
        if len(b):
            ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color="black", lw=0.8, mfc="white", zorder=6,
                    gid=f"measured{d}", **{"ms": 5, **style})
    ax.set_xlim(-vmax * MM, vmax * MM)
    ax.set_ylim(-ylim, ylim)
    ax.axhline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.axvline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.grid(True, color="0.9", lw=0.5, zorder=0)
    ax.legend(loc="upper left", fontsize=7.5)
    if notes:
        fig.supxlabel("; ".join(notes), x=0.01, ha="left", fontsize=8, color="0.3")
    return fig


def comparison_loglog_figure(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, families: pd.DataFrame | None,
                             models_df: pd.DataFrame | None, harmonic: pd.DataFrame | None = None, *,
                             campaign: str | None = None) -> Figure:
    """Fig. 14: the comparison of :func:`comparison_figure` as |F| against |v| (quadrant 3 folded).

    Quadrant-1 data solid with circles, quadrant-3 data dashed with stars; the Surace '-' branch and
    the nominal points are folded likewise. HE loops are not drawn here (folded, a loop is a band,
    not a curve); the peak-to-peak curve is.
    """
    name = campaign or _campaign(char, nominal_windows, models_df)
    fig = Figure(figsize=(9.0, 7.0), layout="constrained")
    ax = fig.add_subplot()
    fig.suptitle(f"{name}: damper characteristics in the logarithmic domain (cf. paper Fig. 14)", fontsize=12)
    have_char = char is not None and len(char) > 0
    fs, fu = _force_unit(char["force_N"] if have_char else [])
    ax.set_xlabel("Piston velocity |v| [mm/s]")
    ax.set_ylabel(f"Force |F| [{fu}]")
    ax.set_xscale("log")
    ax.set_yscale("log")
    damper_missing = families is None or len(families) == 0
    notes = _notes(damper_missing, char, nominal_windows, models_df)
    av = np.abs(char["velocity_m_s"].to_numpy(float)) if have_char else np.empty(0)
    af = np.abs(char["force_N"].to_numpy(float)) if have_char else np.empty(0)
    keep = (av > 0) & (af > 0)
    if not keep.any():
        ax.text(0.5, 0.5, "no characteristic points with non-zero velocity and force", transform=ax.transAxes,
                **_NOTE)
        if notes:
            fig.supxlabel("; ".join(notes), x=0.01, ha="left", fontsize=8, color="0.3")
        return fig
    p2p = _peak_to_peak(harmonic)
    pv, pf = np.abs(p2p["velocity_m_s"].to_numpy(float)), np.abs(p2p["force_N"].to_numpy(float))
    p_ok = (pv > 0) & (pf > 0)
    sv, sf = np.concatenate([av[keep], pv[p_ok]]), np.concatenate([af[keep], pf[p_ok]])
    v_lo, v_hi = sv.min() / 1.5, sv.max() * 1.5
    f_lo, f_hi = sf.min() / 2.0, sf.max() * 3.0
    vx = np.geomspace(v_lo, v_hi, 200)
    if not damper_missing:
        for fam, ls in (("T", "--"), ("L-T", "-")):
            sub = families[(families["family"] == fam) & (families["velocity_m_s"] > 0)]
            for i, (cd, g) in enumerate(sub.groupby("discharge_coefficient", sort=True)):
                g = g.sort_values("velocity_m_s")
                ax.plot(g["velocity_m_s"] * MM, g["force_N"] / fs, ls=ls, lw=0.9, color=_cd_colour(cd, i), zorder=2,
                        gid=f"family-{fam}-{cd:g}", label=f"theoretic {fam.replace('-', '–')}, C_D = {cd:g} (Eq. 32)")
    if models_df is not None and len(models_df):
        fw = model_force(models_df, "wallaschek", vx)
        if np.isfinite(fw).any():
            ax.plot(vx * MM, np.abs(fw) / fs, color="black", lw=1.3, zorder=4, gid="wallaschek",
                    label="Wallaschek fit")
        for dirn, sgn, ls in (("+", 1.0, "-."), ("-", -1.0, ":")):
            fsur = model_force(models_df, "surace", sgn * vx)
            if np.isfinite(fsur).any():
                ax.plot(vx * MM, np.abs(fsur) / fs, color="tab:purple", lw=1.3, ls=ls, zorder=4, gid=f"surace{dirn}",
                        label=f"Surace fit, {'v > 0' if dirn == '+' else 'v < 0 folded'}")
    if p_ok.any():
        pvel = p2p["velocity_m_s"].to_numpy(float)
        labelled = False
        for dirn, sel in (("+", pvel > 0), ("-", pvel < 0)):
            ok = p_ok & sel
            if not ok.any():
                continue
            o = np.argsort(pv[ok])
            ax.plot(pv[ok][o] * MM, pf[ok][o] / fs, ls="-" if dirn == "+" else "--", color="tab:orange", lw=1.2,
                    marker="D", ms=5, zorder=5, gid=f"peak-to-peak{dirn}",
                    label=None if labelled else "HE peak-to-peak curve (v < 0 folded, dashed)")
            labelled = True
    if nominal_windows is not None and len(nominal_windows):
        nv = np.abs(nominal_windows["velocity_m_s"].to_numpy(float))
        nf = np.abs(nominal_windows["force_N"].to_numpy(float))
        ok = (nv > 0) & (nf > 0)
        ax.plot(nv[ok] * MM, nf[ok] / fs, ls="none", marker="x", ms=6, color="tab:brown", zorder=5, gid="nominal-plan",
                label="nominal model through the test plan, folded")
        if ok.any():
            f_lo, f_hi = min(f_lo, nf[ok].min() / 2.0), max(f_hi, nf[ok].max() * 1.5)
    for d, style in (("+", dict(marker="o", ls="-", ms=5, color="black", label="quadrant 1 (v > 0)")),
                     ("-", dict(marker="*", ls="--", ms=8, color="tab:red", label="quadrant 3 folded (|v|, |F|)"))):
        b = char[char["velocity_m_s"] > 0] if d == "+" else char[char["velocity_m_s"] < 0]
        bv, bf = np.abs(b["velocity_m_s"].to_numpy(float)), np.abs(b["force_N"].to_numpy(float))
        ok = (bv > 0) & (bf > 0)
        o = np.argsort(bv[ok])
        if ok.any():
            ax.plot(bv[ok][o] * MM, bf[ok][o] / fs, lw=0.8, mfc="white", zorder=6, gid=f"measured{d}", **style)
    ax.set_xlim(v_lo * MM, v_hi * MM)
    ax.set_ylim(f_lo / fs, f_hi / fs)
    plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.88", lw=0.5)
    ax.grid(True, which="minor", color="0.95", lw=0.4)
    ax.legend(loc="upper left", fontsize=7.5)
    if notes:
        fig.supxlabel("; ".join(notes), x=0.01, ha="left", fontsize=8, color="0.3")
    return fig


# ----------------------------------------------------------------------------------------------
# stage
# ----------------------------------------------------------------------------------------------

def family_velocities(char: pd.DataFrame | None, harmonic: pd.DataFrame | None = None, n: int = 121) -> np.ndarray:
    """Symmetric velocity grid for the families: geometric over the data's |v| range, both signs."""
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


def sine_loops(campaign_root, max_cases: int = 8) -> dict[str, pd.DataFrame]:
    """Force against velocity of the status-ok sine cases, first period (start from rest) left out.

    Uses :func:`isokinetic.harmonic.loop` (the harmonic stage's velocity estimator, so the loops
    agree with its peak-to-peak points) when that module is installed; otherwise a Savitzky-Golay
    derivative (cubic, window ~1/20 of the period) of the measured displacement.
    """
    try:
        from .harmonic import loop as harmonic_loop
    except ImportError:                                  # harmonic stage not installed
        harmonic_loop = None
    from scipy.signal import savgol_filter

    root = Path(campaign_root)
    path = root / "cases.parquet"
    if not path.exists():
        return {}
    cases = pd.read_parquet(path)
    sines = cases[(cases["waveform"] == "sine") & (cases["status"] == "ok")].head(max_cases)
    out = {}
    for _, row in sines.iterrows():
        try:
            ts = pd.read_parquet(root / row["timeseries_file"], columns=["time_s", "displacement_m", "force_N"])
        except (FileNotFoundError, OSError) as exc:
            log.warning("sine loop of case %s not read: %s", row["case"], exc)
            continue
        f_hz = float(row["frequency_Hz"])
        if harmonic_loop is not None:
            try:
                lp = harmonic_loop(ts, f_hz)
            except ValueError as exc:
                log.warning("sine loop of case %s skipped: %s", row["case"], exc)
                continue
            out[str(row["case"])] = lp[["velocity_m_s", "force_N"]].reset_index(drop=True)
            continue
        t = ts["time_s"].to_numpy(float)
        if t.size < 10 or not math.isfinite(f_hz) or f_hz <= 0:
            continue
        dt = float(np.median(np.diff(t)))
        win = max(5, int(round(1.0 / f_hz / 20.0 / dt)) | 1)
        if win >= t.size:
            continue
        vel = savgol_filter(ts["displacement_m"].to_numpy(float), win, 3, deriv=1, delta=dt)
        keep = t >= t[0] + 1.0 / f_hz
        if keep.sum() < 10:
            keep = np.ones(t.size, dtype=bool)
        out[str(row["case"])] = pd.DataFrame({"velocity_m_s": vel[keep],
                                              "force_N": ts["force_N"].to_numpy(float)[keep]})
    return out


def write_models(campaign_root, out_dir, spec: WindowSpec = WindowSpec(), figures_dir=None,
                 loops: bool = True) -> list[Path]:
    """Fit, compare and draw one campaign; returns the written paths (TABLE_FILES then FIGURE_FILES).

    Reads ``characteristic.parquet``, ``nominal_windows.parquet`` (computed with ``spec`` by
    :func:`nominal.nominal_stage` when absent), ``ingest/campaign.json`` and, when present,
    ``harmonic/harmonic.parquet`` (or ``harmonic.parquet``) and the sine cases' time series (loops).
    Tables go to ``out_dir``, figures to ``figures_dir`` (default ``out_dir``). Without a damper
    block: no nominal curves or physical readings, said on the figures.
    """
    from .io import write_parquet
    from .nominal import nominal_stage

    root = Path(campaign_root)
    out = Path(out_dir)
    fig_dir = out if figures_dir is None else Path(figures_dir)
    meta = json.loads((root / "ingest" / "campaign.json").read_text(encoding="utf-8"))
    campaign = str(meta.get("campaign") or root.name)
    damper = None if meta.get("damper") is None else Damper.from_mapping(meta["damper"])
    char = pd.read_parquet(root / "characteristic.parquet")
    nw_path = root / "nominal_windows.parquet"
    if nw_path.exists():
        nominal_windows = pd.read_parquet(nw_path)
    elif damper is not None:
        nominal_windows = nominal_stage(root, spec)
    else:
        nominal_windows = tables.empty(tables.WINDOWS)
    harmonic = None
    for path in (root / "harmonic" / "harmonic.parquet", root / "harmonic.parquet"):
        if path.exists():
            harmonic = tables.validate_table(pd.read_parquet(path), tables.HARMONIC)
            break
    loop_data = sine_loops(root) if loops else {}

    models_df, residuals = fit_models(char, damper)
    comparison = comparison_table(char, nominal_windows, models_df, damper)
    families = nominal_families(damper, family_velocities(char, harmonic)) if damper is not None else None
    if damper is None:
        log.info("campaign %s: no damper block; nominal curves and physical readings skipped", campaign)
    for m in MODEL_NAMES:
        sub = models_df[(models_df["model"] == m) & (models_df["kind"] == "fitted")]
        for r in sub.itertuples():
            log.info("campaign %s: %s %s %s = %.6g [%.6g, %.6g] %s", campaign, m, r.direction, r.parameter, r.estimate,
                     r.ci_low, r.ci_high, r.unit)
    paths = [write_parquet(models_df, out / TABLE_FILES[0]),
             write_parquet(residuals, out / TABLE_FILES[1]),
             write_parquet(comparison, out / TABLE_FILES[2])]
    figs = [comparison_figure(char, nominal_windows, families, models_df, harmonic, loop_data, campaign=campaign),
            comparison_loglog_figure(char, nominal_windows, families, models_df, harmonic, campaign=campaign)]
    paths += [save_figure(fig, fig_dir / fname) for fig, fname in zip(figs, FIGURE_FILES, strict=True)]
    return paths


__all__ = ["nominal_families", "design_matrix", "standard_errors", "wls", "physical_readings", "fit_models",
           "model_parameters", "model_force", "comparison_table", "comparison_figure", "comparison_loglog_figure",
           "family_velocities", "sine_loops", "write_models", "TABLE_FILES", "FIGURE_FILES"]
