"""Test design before running it: convergence numbers, stroke to converge, plan check, Fig. 5-6.

Equation numbers refer to the reference paper (shared/reference/000_003c8e4a5d3ba538.txt),
Sec. 3.2-3.3 and 4.2-4.3. SI units throughout; mm and mm/s only at the plot edge.

Physics (nominal damper, Eq. 2, 3, 7, 12-29)
    After a velocity step from rest (Δp(0) = 0) to a constant piston speed W > 0, the pressure
    differential approaches the incompressible value Δp∞ = A_p W c1 + (A_p W)² c2 (Eq. 24) as
    the piston moves. The normalised stroke d = A_p s / V1,s (s the stroke in metres, V1,s the
    volume of the chamber being compressed at the start of the segment) needed to reach the
    fraction ϕ of Δp∞ is Eq. (28) for the mixed laminar-turbulent orifice, and the closed forms
    of Eq. (29) for purely laminar (c2 = 0) and purely turbulent (c1 = 0) flow. Convergence is
    governed by G1, G2, G3 (Eq. 19, 21, 22), with B_eff = 1/β_eff from Eq. (3), entrained air
    included (``Effects.air_volume_fraction``).

    The paper prints the turbulent form of Eq. (29) with the exponent 1/G1; setting c1 = 0 in
    Eq. (28) (and the text after Eq. 29) gives 1/G2, which is what is implemented.

Start position
    A triangle record with phase -π/2 starts at y = -Y and its first half-period moves up, so the
    chambers at the start of the segment are V1 = V0,1 + A_p Y (compressed) and V2 = V0,2 - A_p Y
    (Eq. 2); d is converted to metres with that V1 and the ratio V1/V2 replaces V0,1/V0,2 in
    Eq. (28)-(29). Segments moving down compress chamber 2 and swap the roles.

Reversal (an extension, not in the paper)
    Half-periods after the first start from the steady Δp of the opposite direction, not from
    rest: integrating Eq. (15) from -Δp∞ instead of 0 adds ln 2 / G1 + (1 - ln 2) / G2 to
    -ln R, i.e. R_rev = R · exp(-ln 2/G1 - (1 - ln 2)/G2) (symmetric damper). The plan check
    reports this longer stroke for information; its flags follow the paper (from rest).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from . import figures, tables
from .damper import (NOMINAL, Damper, Effects, effective_compressibility, laminar_coefficient,
                     turbulent_coefficient)
from .io import write_parquet
from .plan import CasePlan, half_periods

#: Files written by :func:`write_design`.
PLAN_CHECK_FILE = "plan_check.parquet"
FIGURE_FILES = ("fig05_stroke_to_converge.png", "fig06_at_diagram.png")

FLOWS = ("laminar", "turbulent", "mixed")
#: Air volume fractions of Fig. 5 (0, 0.1, 0.5, 1 %).
FIG5_AIR_FRACTIONS = (0.0, 0.001, 0.005, 0.01)
MM = 1e3
LN2 = math.log(2.0)

_FLOW_STYLE = {"laminar": ("tab:blue", "--"), "turbulent": ("tab:purple", ":"), "mixed": ("black", "-")}
_AIR_COLOURS = ("black", "tab:orange", "tab:red", "tab:brown", "tab:pink", "tab:olive")
_PERIOD_STYLE = (("tab:blue", "o"), ("tab:green", "s"), ("tab:orange", "D"), ("tab:purple", "^"),
                 ("tab:cyan", "v"), ("tab:brown", "P"))


# ----------------------------------------------------------------------------------------------
# coefficients (Eq. 3, 7, 19-25)
# ----------------------------------------------------------------------------------------------

def bulk_modulus(damper: Damper, effects: Effects = NOMINAL) -> float:
    """B_eff = 1/β_eff, β_eff = β_0,F + (V_G/V_C) β_G, Eq. (3) with entrained air [Pa]."""
    return 1.0 / float(effective_compressibility(damper, effects))


def _coefficients(damper: Damper, effects: Effects) -> tuple[float, float, float]:
    """(c1, c2, B_eff): Table 1 loss coefficients (Sec. 2.2) with the nominal C_D, and Eq. (3)."""
    return (float(laminar_coefficient(damper, effects)), float(turbulent_coefficient(damper, effects)),
            bulk_modulus(damper, effects))


def piston_flow(velocity_m_s, damper: Damper):
    """Q_p = A_p |W|, the piston-induced flow of Eq. (2) [m³/s] (the paper takes W > 0)."""
    return damper.piston_area_m2 * np.abs(np.asarray(velocity_m_s, dtype=float))


def _ratio(num, den):
    """num/den with num/0 = inf (a zero speed never leaves the incompressible state)."""
    num, den = np.broadcast_arrays(np.asarray(num, dtype=float), np.asarray(den, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.inf)


def g1(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Laminar convergence number G1 = B_eff / (A_p W c1), Eq. (19); converges iff G1 > 1."""
    c1, _, bulk = _coefficients(damper, effects)
    return _ratio(bulk, piston_flow(velocity_m_s, damper) * c1)


def g2(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Turbulent convergence number G2 = B_eff / (2 (A_p W)² c2), Eq. (21); converges iff G2 > 1."""
    _, c2, bulk = _coefficients(damper, effects)
    return _ratio(bulk, 2.0 * piston_flow(velocity_m_s, damper) ** 2 * c2)


def c3(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Mixed-flow loss coefficient c3 = 2 A_p W c2 + c1, Eq. (22)-(23) [Pa s/m³]."""
    c1, c2, _ = _coefficients(damper, effects)
    return 2.0 * piston_flow(velocity_m_s, damper) * c2 + c1


def g3(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Laminar-turbulent convergence number G3 = B_eff / (A_p W c3), Eq. (22); converges iff G3 > 1."""
    _, _, bulk = _coefficients(damper, effects)
    return _ratio(bulk, piston_flow(velocity_m_s, damper) * c3(velocity_m_s, damper, effects))


def incompressible_pressure(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Δp∞ = A_p W c1 + (A_p W)² c2 for W > 0, Eq. (24) [Pa] (magnitude for W < 0)."""
    c1, c2, _ = _coefficients(damper, effects)
    q = piston_flow(velocity_m_s, damper)
    return q * c1 + q * q * c2


def phi_tilde(phi, velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Adjusted pressure measure φ̃ = ((1 - ϕ) c1² + ϕ c3²)^½ at the fraction ϕ of Δp∞, Eq. (25).

    Equals (c1² + 4 c2 Δp)^½ (Eq. 23) at Δp = ϕ Δp∞ [Pa s/m³].
    """
    c1, _, _ = _coefficients(damper, effects)
    phi = np.asarray(phi, dtype=float)
    return np.sqrt((1.0 - phi) * c1**2 + phi * c3(velocity_m_s, damper, effects) ** 2)


# ----------------------------------------------------------------------------------------------
# normalised stroke to reach ϕ of the incompressible Δp (Eq. 28-29)
# ----------------------------------------------------------------------------------------------

def _check_phi(phi) -> np.ndarray:
    phi = np.asarray(phi, dtype=float)
    if not np.all((phi > 0) & (phi < 1)):
        raise ValueError(f"phi must lie in (0, 1), got {phi!r}")
    return phi


def _stroke_from_log_r(log_r, volume_ratio):
    """d = (1 - R)/(1 + (V1/V2) R) with R = exp(log_r), Eq. (15) inverted; exact for R -> 1."""
    log_r = np.asarray(log_r, dtype=float)
    return -np.expm1(log_r) / (1.0 + np.asarray(volume_ratio, dtype=float) * np.exp(log_r))


def normalised_stroke_laminar(phi, G1, volume_ratio=1.0):
    """d|c2=0 = (1 - (1-ϕ)^(1/G1)) / (1 + (V1/V2)(1-ϕ)^(1/G1)), Eq. (29) left."""
    phi = _check_phi(phi)
    with np.errstate(divide="ignore"):
        return _stroke_from_log_r(np.log1p(-phi) / np.asarray(G1, dtype=float), volume_ratio)


def normalised_stroke_turbulent(phi, G2, volume_ratio=1.0):
    """d|c1=0 = (1 - X^(1/G2)) / (1 + (V1/V2) X^(1/G2)), X = (1 - √ϕ) e^√ϕ, Eq. (29) right.

    The paper prints 1/G1 here; c1 = 0 in Eq. (28) gives G3 = G2 (see the module docstring).
    """
    phi = _check_phi(phi)
    root = np.sqrt(phi)
    log_x = np.log1p(-root) + root
    with np.errstate(divide="ignore"):
        return _stroke_from_log_r(log_x / np.asarray(G2, dtype=float), volume_ratio)


def _log_x_mixed(phi, c1, c2, q, bulk):
    """(ln X, c3, G3) of Eq. (28): X = ((c3 - φ̃)/(2 A_p W c2)) e^((φ̃ - c1)/c3) = R^G3.

    Written without cancellation (c3² - c1² = 4 c2 Q (c1 + c2 Q)):
    (c3 - φ̃)/(2 Q c2) = 2 (1-ϕ)(c1 + c2 Q)/(c3 + φ̃) and (φ̃ - c1)/c3 = ϕ (c3² - c1²)/((φ̃ + c1) c3),
    so c2 = 0 or c1 = 0 are exact (the laminar and turbulent limits of Eq. 29).
    """
    phi = _check_phi(phi)
    c1, c2, q, bulk = (np.asarray(x, dtype=float) for x in (c1, c2, q, bulk))
    c3_ = 2.0 * q * c2 + c1
    excess = 4.0 * c2 * q * (c1 + c2 * q)                      # c3² - c1²
    tilde = np.sqrt(c1 * c1 + phi * excess)                     # Eq. (25)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_x = np.log1p(-phi) + np.log(2.0 * (c1 + c2 * q) / (c3_ + tilde)) + phi * excess / ((tilde + c1) * c3_)
        g3_ = np.where(q > 0, bulk / (q * c3_), np.inf)
    return log_x, c3_, g3_


def normalised_stroke_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa, volume_ratio=1.0):
    """Normalised stroke d to reach ϕ Δp∞ from rest, mixed laminar-turbulent flow, Eq. (28).

    d = (1 - X^(1/G3)) / (1 + (V1/V2) X^(1/G3)), X = ((c3 - φ̃)/(2 A_p W c2)) e^((φ̃ - c1)/c3),
    φ̃ from Eq. (25), G3 = B_eff/(A_p W c3) (Eq. 22). Coefficient-level (c1 or c2 may be 0).
    """
    log_x, _, g3_ = _log_x_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa)
    return _stroke_from_log_r(log_x / g3_, volume_ratio)


def normalised_stroke_reversal(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa, volume_ratio=1.0):
    """Normalised stroke to reach ϕ Δp∞ after a reversal from -Δp∞ (extension of Eq. 28).

    Integrating Eq. (15)-(16) from -Δp∞ adds Q_p (c1 ln 2 + 2 Q_p c2 (1 - ln 2)) / B_eff
    = ln 2/G1 + (1 - ln 2)/G2 to -ln R of Eq. (28) (symmetric damper, steady start).
    """
    log_x, _, g3_ = _log_x_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa)
    q = np.asarray(piston_flow_m3_s, dtype=float)
    extra = q * (np.asarray(c1, dtype=float) * LN2 + 2.0 * q * np.asarray(c2, dtype=float) * (1.0 - LN2))
    return _stroke_from_log_r(log_x / g3_ - extra / np.asarray(bulk_modulus_Pa, dtype=float), volume_ratio)


# ----------------------------------------------------------------------------------------------
# strokes in metres and times (Eq. 2, 15)
# ----------------------------------------------------------------------------------------------

def segment_volumes(damper: Damper, start_position_m=0.0, direction=1.0):
    """(compressed, other) chamber volume at the start of a constant-velocity segment, Eq. (2) [m³].

    y0 = ``start_position_m``: V1 = V0,1 - A_p y0, V2 = V0,2 + A_p y0. Moving up (direction > 0)
    compresses chamber 1; moving down compresses chamber 2. A triangle record with phase -π/2
    starts at y0 = -Y moving up: (V0,1 + A_p Y, V0,2 - A_p Y).
    """
    y0 = np.asarray(start_position_m, dtype=float)
    v1 = damper.chamber_volume_1_m3 - damper.piston_area_m2 * y0
    v2 = damper.chamber_volume_2_m3 + damper.piston_area_m2 * y0
    up = np.asarray(direction, dtype=float) >= 0
    return np.where(up, v1, v2), np.where(up, v2, v1)


def stroke_to_converge(velocity_m_s, damper: Damper, *, phi=0.999, start_position_m=0.0,
                       effects: Effects = NOMINAL, flow: str = "mixed", reversal: bool = False):
    """Piston stroke s = d V1,s / A_p to reach ϕ of the incompressible Δp (Eq. 28-29, 24) [m].

    ``flow``: 'mixed' (Eq. 28), 'laminar' or 'turbulent' (Eq. 29, the damper's c1 or c2 alone).
    The sign of ``velocity_m_s`` gives the direction (which chamber is compressed), with the
    volumes at ``start_position_m`` (:func:`segment_volumes`). ``reversal=True``: starting from the
    opposite steady Δp instead of rest (:func:`normalised_stroke_reversal`). Vectorised.
    """
    if flow not in FLOWS:
        raise ValueError(f"flow must be one of {FLOWS}, got {flow!r}")
    w = np.asarray(velocity_m_s, dtype=float)
    c1, c2, bulk = _coefficients(damper, effects)
    if flow == "laminar":
        c2 = 0.0
    elif flow == "turbulent":
        c1 = 0.0
    v_comp, v_other = segment_volumes(damper, start_position_m, np.sign(w) + (w == 0))
    ratio = v_comp / v_other
    q = piston_flow(w, damper)
    if reversal:
        d = normalised_stroke_reversal(phi, c1, c2, q, bulk, ratio)
    elif flow == "laminar":
        d = normalised_stroke_laminar(phi, _ratio(bulk, q * c1), ratio)
    elif flow == "turbulent":
        d = normalised_stroke_turbulent(phi, _ratio(bulk, 2.0 * q * q * c2), ratio)
    else:
        d = normalised_stroke_mixed(phi, c1, c2, q, bulk, ratio)
    return d * v_comp / damper.piston_area_m2


def time_to_converge(velocity_m_s, damper: Damper, **kwargs):
    """Time after the velocity step to reach ϕ of Δp∞: stroke_to_converge / |W| [s]."""
    s = stroke_to_converge(velocity_m_s, damper, **kwargs)
    return _ratio(s, np.abs(np.asarray(velocity_m_s, dtype=float)))


def first_half_period(case: CasePlan) -> tuple[float, float]:
    """(start position y0 [m], direction ±1) of the first complete half-period of a triangle case.

    From :func:`plan.half_periods`; a record too short for one falls back to the phase -π/2
    convention (start at -Y moving up). Eq. (28) assumes Δp = 0 there, which holds for a record
    starting at a turning point (phase ±π/2, the paper's -π/2); otherwise the stroke is a guide.
    """
    duration = case.duration_s if math.isfinite(case.duration_s) else case.period_s
    rows = half_periods(case.period_s, case.phase_rad, max(duration, case.period_s))
    direction = float(rows[0, 2]) if len(rows) else 1.0
    return -direction * case.amplitude_m, direction


# ----------------------------------------------------------------------------------------------
# plan check
# ----------------------------------------------------------------------------------------------

def _as_damper(damper) -> Damper | None:
    if damper is None or isinstance(damper, Damper):
        return damper
    return Damper.from_mapping(damper)


def _cases_frame(cases) -> pd.DataFrame:
    if isinstance(cases, pd.DataFrame):
        return cases
    return pd.DataFrame([{"case": c.case, "waveform": c.waveform, "sample_rate_Hz": c.sample_rate_Hz,
                          "amplitude_m": c.amplitude_m, "period_s": c.period_s, "frequency_Hz": c.frequency_Hz,
                          "phase_rad": c.phase_rad, "duration_s": c.duration_s} for c in cases])


def _num(row: Mapping, key: str) -> float:
    try:
        x = float(row.get(key, math.nan))
    except (TypeError, ValueError):
        return math.nan
    return x


def _mm(x: float) -> str:
    return f"{x * MM:.3g} mm"


def _pct(phi: float) -> str:
    return f"{phi * 100:.6g} %"


def plan_check(campaign: str, cases, damper, *, phi: float = 0.999, max_amplitude_m: float,
               min_amplitude_m: float, start_fraction: float = 0.45,
               effects: Effects = NOMINAL) -> pd.DataFrame:
    """One row per planned case (tables.PLAN_CHECK plus design columns); flags broken constraints.

    ``cases``: a cases table (tables.CASES columns; ``status`` kept if present) or CasePlans;
    ``damper``: Damper, its SI mapping, or None (no damper data: physics columns NaN, only the
    travel and noise-floor checks, and a reason saying the damper block is missing).

    Triangle cases, at W = 4Y/T (Eq. 26) and the first half-period's start (-Y for phase -π/2):
    G1, G2, G3 (Eq. 19-22); strokes to reach ϕ of Δp∞ for laminar, turbulent (Eq. 29) and mixed
    flow (Eq. 28, = ``stroke_to_converge_m``), the time to converge, and the reversal stroke
    (it counts towards ``flagged``). The window starts at ``start_fraction`` T/2, i.e. after the stroke
    ``window_start_stroke_m`` = start_fraction (T/2) W. Sine cases: G-numbers at the peak velocity
    2πfY, only travel and noise-floor checks. Free cases: nothing planned to check.

    Constraint columns (True = broken): ``travel_exceeded`` (Y > max_amplitude_m),
    ``below_noise_floor`` (Y < min_amplitude_m), ``no_convergence`` (G3 <= 1), ``window_too_early``
    (window start stroke < stroke to converge from rest, Eq. 28), ``window_too_early_after_reversal``
    (the same from the opposite steady pressure, as windows 2-4 start). ``flagged`` = any;
    ``reasons`` '; '-joined text.
    """
    phi = float(_check_phi(phi))
    if not 0.0 <= start_fraction < 1.0:
        raise ValueError(f"start_fraction must lie in [0, 1), got {start_fraction!r}")
    dmp = _as_damper(damper)
    frame = _cases_frame(cases)
    rows = []
    for rec in frame.to_dict("records"):
        rows.append(_check_case(campaign, rec, dmp, phi, max_amplitude_m, min_amplitude_m, start_fraction, effects))
    if not rows:
        out = tables.empty(tables.PLAN_CHECK)
    else:
        out = pd.DataFrame(rows)
    return tables.validate_table(out, tables.PLAN_CHECK)


def _check_case(campaign: str, rec: Mapping, dmp: Damper | None, phi: float, max_amp: float, min_amp: float,
                start_fraction: float, effects: Effects) -> dict:
    nan = math.nan
    waveform = str(rec.get("waveform", ""))
    amp, period, freq = _num(rec, "amplitude_m"), _num(rec, "period_s"), _num(rec, "frequency_Hz")
    phase = _num(rec, "phase_rad")
    duration = _num(rec, "duration_s")
    row = {"campaign": str(campaign), "case": str(rec.get("case", "")), "waveform": waveform,
           "status": str(rec.get("status", "")), "velocity_m_s": nan, "period_s": period, "amplitude_m": amp,
           "frequency_Hz": freq, "phi": phi, "start_fraction": start_fraction,
           "max_amplitude_m": float(max_amp), "min_amplitude_m": float(min_amp),
           "half_period_stroke_m": nan, "start_position_m": nan,
           "G1": nan, "G2": nan, "G3": nan, "stroke_laminar_m": nan, "stroke_turbulent_m": nan,
           "stroke_mixed_m": nan, "stroke_to_converge_m": nan, "time_to_converge_s": nan,
           "stroke_to_converge_reversal_m": nan, "window_start_s": nan, "window_start_stroke_m": nan,
           "travel_exceeded": False, "below_noise_floor": False, "no_convergence": False,
           "window_too_early": False, "window_too_early_after_reversal": False}
    reasons: list[str] = []
    if math.isfinite(amp):
        if amp > max_amp:
            row["travel_exceeded"] = True
            reasons.append(f"amplitude {_mm(amp)} exceeds the allowed piston travel {_mm(max_amp)}")
        if amp < min_amp:
            row["below_noise_floor"] = True
            reasons.append(f"amplitude {_mm(amp)} is below the LVDT noise floor {_mm(min_amp)}")
    elif waveform in ("triangle", "sine"):
        reasons.append("no planned amplitude: travel, noise floor and convergence not checked")
    if waveform == "triangle" and math.isfinite(amp) and math.isfinite(period) and period > 0 and amp > 0:
        w = 4.0 * amp / period
        row.update(velocity_m_s=w, half_period_stroke_m=2.0 * amp, window_start_s=start_fraction * period / 2.0,
                   window_start_stroke_m=start_fraction * period / 2.0 * w)
        plan = CasePlan(case=row["case"], waveform="triangle", sample_rate_Hz=1.0, amplitude_m=amp,
                        period_s=period, phase_rad=phase if math.isfinite(phase) else -math.pi / 2,
                        duration_s=duration)
        y0, direction = first_half_period(plan)
        row["start_position_m"] = y0
        if dmp is not None:
            wd = direction * w
            kw = dict(phi=phi, start_position_m=y0, effects=effects)
            row.update(G1=float(g1(w, dmp, effects)), G2=float(g2(w, dmp, effects)), G3=float(g3(w, dmp, effects)),
                       stroke_laminar_m=float(stroke_to_converge(wd, dmp, flow="laminar", **kw)),
                       stroke_turbulent_m=float(stroke_to_converge(wd, dmp, flow="turbulent", **kw)),
                       stroke_mixed_m=float(stroke_to_converge(wd, dmp, **kw)),
                       stroke_to_converge_reversal_m=float(stroke_to_converge(-wd, dmp, reversal=True, **{
                           **kw, "start_position_m": -y0})))
            row["stroke_to_converge_m"] = row["stroke_mixed_m"]
            row["time_to_converge_s"] = row["stroke_to_converge_m"] / w
            if row["G3"] <= 1.0:
                row["no_convergence"] = True
                reasons.append(f"G3 = {row['G3']:.3g} <= 1: the pressure differential does not converge (Eq. 22)")
            need, start = row["stroke_to_converge_m"], row["window_start_stroke_m"]
            if start < need:
                row["window_too_early"] = True
                text = (f"window starts after {_mm(start)} of stroke ({start_fraction:g} T/2), before the "
                        f"{_mm(need)} needed to reach {_pct(phi)} of the incompressible pressure (Eq. 28)")
                if need > 2.0 * amp:
                    text += f"; not reached within the {_mm(2.0 * amp)} half-period"
                reasons.append(text)
            need_rev = row["stroke_to_converge_reversal_m"]
            row["window_too_early_after_reversal"] = bool(start < need_rev)
            if start < need_rev and not row["window_too_early"]:
                reasons.append(f"window starts after {_mm(start)} of stroke, before the {_mm(need_rev)} needed "
                               f"after a velocity reversal (from the opposite steady pressure) to reach "
                               f"{_pct(phi)} of the incompressible pressure; windows 2-4 follow a reversal")
    elif waveform == "triangle" and math.isfinite(amp):
        reasons.append("no planned period: velocity and convergence not checked")
    elif waveform == "sine" and math.isfinite(amp) and math.isfinite(freq) and freq > 0:
        w = 2.0 * math.pi * freq * amp
        row["velocity_m_s"] = w  # peak velocity of Y sin(2πft)
        if dmp is not None:
            row.update(G1=float(g1(w, dmp, effects)), G2=float(g2(w, dmp, effects)), G3=float(g3(w, dmp, effects)))
    elif waveform == "free":
        reasons.append("free waveform: no planned amplitude or period to check")
    if dmp is None and waveform in ("triangle", "sine"):
        reasons.append("damper block missing in campaign.json: G-numbers and convergence not checked")
    row["flagged"] = bool(row["travel_exceeded"] or row["below_noise_floor"] or row["no_convergence"]
                          or row["window_too_early"] or row["window_too_early_after_reversal"])
    row["reasons"] = "; ".join(reasons)
    return row


def plan_warnings(df: pd.DataFrame) -> list[str]:
    """One readable line per flagged case: 'campaign <c>, case <id> (<W> mm/s, T, Y): <reasons>'."""
    out = []
    if df is None or df.empty:
        return out
    for r in df[df["flagged"].astype(bool)].to_dict("records"):
        what = []
        if math.isfinite(_num(r, "velocity_m_s")):
            what.append(f"{_num(r, 'velocity_m_s') * MM:.3g} mm/s")
        if math.isfinite(_num(r, "period_s")):
            what.append(f"T = {_num(r, 'period_s'):g} s")
        if math.isfinite(_num(r, "amplitude_m")):
            what.append(f"Y = {_mm(_num(r, 'amplitude_m'))}")
        detail = f" ({', '.join(what)})" if what else ""
        out.append(f"campaign {r['campaign']}, case {r['case']}{detail}: {r['reasons']}")
    return out


# ----------------------------------------------------------------------------------------------
# A-T boundary of the quasi-steady constraint
# ----------------------------------------------------------------------------------------------

def quasi_steady_boundary(velocities_m_s, damper: Damper, *, phi: float = 0.999, start_fraction: float = 0.45,
                          effects: Effects = NOMINAL, iterations: int = 80):
    """(T, Y) on the minimum-time constraint of the A-T diagram, one point per velocity [s, m].

    The window of a triangle case starts after the stroke start_fraction (T/2) W = 2 start_fraction Y;
    on the boundary this equals the stroke to converge from -Y (Eq. 28, the start volumes depend
    on Y), solved for Y by bisection on [0, 0.95 V0/A_p]; T = 4Y/W (Eq. 26). NaN where G3 <= 1
    or no such amplitude fits in the cylinder. A case of velocity W with a longer period (larger
    Y) than the boundary point starts its window after convergence.
    """
    w = np.abs(np.asarray(velocities_m_s, dtype=float))
    limit = 0.95 * min(damper.chamber_volume_1_m3, damper.chamber_volume_2_m3) / damper.piston_area_m2

    def excess(y):  # window-start stroke minus stroke to converge, < 0 at y = 0
        return 2.0 * start_fraction * y - stroke_to_converge(w, damper, phi=phi, start_position_m=-y, effects=effects)

    lo, hi = np.zeros_like(w), np.full_like(w, limit)
    ok = (excess(hi) >= 0) & (w > 0) & (g3(w, damper, effects) > 1.0)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = excess(mid) < 0
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    y = np.where(ok, 0.5 * (lo + hi), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(ok, 4.0 * y / np.where(w > 0, w, 1.0), np.nan)
    return t, y


# ----------------------------------------------------------------------------------------------
# figures
# ----------------------------------------------------------------------------------------------

def _new_figure(width_in: float, height_in: float) -> Figure:
    return Figure(figsize=(width_in, height_in), layout="constrained")


def _air_label(frac: float) -> str:
    return "no air" if frac == 0 else f"{frac * 100:g} % air"


def _planned_triangles(planned: pd.DataFrame | None) -> pd.DataFrame:
    """Triangle rows with finite velocity and amplitude (from a plan check or a cases table)."""
    if planned is None or len(planned) == 0:
        return pd.DataFrame(columns=["case", "velocity_m_s", "amplitude_m", "period_s"])
    df = planned[planned["waveform"] == "triangle"] if "waveform" in planned else planned
    amp = pd.to_numeric(df["amplitude_m"], errors="coerce")
    per = pd.to_numeric(df["period_s"], errors="coerce")
    vel = pd.to_numeric(df["velocity_m_s"], errors="coerce") if "velocity_m_s" in df else 4.0 * amp / per
    out = df.assign(velocity_m_s=vel, amplitude_m=amp, period_s=per)
    return out[np.isfinite(out["velocity_m_s"]) & np.isfinite(out["amplitude_m"]) & (out["velocity_m_s"] > 0)]


def stroke_to_converge_figure(damper: Damper | None, velocities_m_s, phi: float = 0.999,
                              air_fractions: Sequence[float] = FIG5_AIR_FRACTIONS,
                              band: tuple[float, float] = (0.95, 0.99999), planned: pd.DataFrame | None = None,
                              *, campaign: str | None = None, max_stroke_m: float | None = None) -> Figure:
    """Fig. 5: stroke to reach ϕ of the incompressible Δp against piston velocity (log x).

    Central starting position (V1 = V0,1, V2 = V0,2) as in the paper. Curves (gids): 'laminar',
    'turbulent' (Eq. 29), 'mixed' (Eq. 28) and 'mixed-air-<fraction>' for each nonzero air
    fraction (Eq. 3, Table 1 β_air); a shaded band 'band' (mixed, no air) between ϕ = band[0]
    and band[1]. Curves end where G3 <= 1. ``planned`` (plan check or cases table): triangle
    cases' half-period stroke 2Y ('planned-half-period') and window-start stroke
    ('planned-window-start') at their velocity.
    """
    name = campaign or "campaign ?"
    fig = _new_figure(8.5, 6.0)
    ax = fig.add_subplot()
    fig.suptitle(f"{name}: piston stroke to reach {_pct(phi)} of the incompressible \u0394p", fontsize=12)
    ax.set_xlabel("Piston velocity W [mm/s]")
    ax.set_ylabel(f"Stroke to reach {_pct(phi)} of \u0394p\u221e [mm]")
    ax.set_xscale("log")
    w = np.asarray(velocities_m_s, dtype=float)
    w = np.sort(w[np.isfinite(w) & (w > 0)])
    plan = _planned_triangles(planned)
    if damper is None:
        figures._say_missing(ax, "no damper data (damper block missing in campaign.json): "
                                 "the stroke to converge cannot be computed")
        _draw_planned_strokes(ax, plan)
        if len(plan):
            ax.set_ylim(bottom=0.0)
            ax.legend(loc="upper left", fontsize=8)
        figures.plain_log_ticks(ax)
        return fig
    if w.size == 0:
        figures._say_missing(ax, "no positive velocities to plot")
        return fig
    ymax = 0.0
    for flow in ("laminar", "turbulent"):
        colour, ls = _FLOW_STYLE[flow]
        s = stroke_to_converge(w, damper, phi=phi, flow=flow)
        gnum = g1(w, damper) if flow == "laminar" else g2(w, damper)
        s = np.where(gnum > 1.0, s, np.nan)
        ax.plot(w * MM, s * MM, color=colour, ls=ls, lw=1.4, gid=flow,
                label=f"{flow} ({'Eq. 29, c2 = 0' if flow == 'laminar' else 'Eq. 29, c1 = 0'})")
        ymax = max(ymax, float(np.nanmax(s, initial=0.0)))
    for i, frac in enumerate(air_fractions):
        eff = Effects(air_volume_fraction=float(frac))
        s = stroke_to_converge(w, damper, phi=phi, effects=eff)
        s = np.where(g3(w, damper, eff) > 1.0, s, np.nan)
        gid = "mixed" if frac == 0 else f"mixed-air-{frac:g}"
        ax.plot(w * MM, s * MM, color=_AIR_COLOURS[i % len(_AIR_COLOURS)], ls="-", lw=2.0 if frac == 0 else 1.2,
                gid=gid, label=f"mixed laminar\u2013turbulent (Eq. 28), {_air_label(float(frac))}")
        if frac == 0 and band is not None:
            lo = stroke_to_converge(w, damper, phi=band[0])
            hi = stroke_to_converge(w, damper, phi=band[1])
            keep = g3(w, damper) > 1.0
            ax.fill_between(w[keep] * MM, lo[keep] * MM, hi[keep] * MM, color="0.6", alpha=0.35, lw=0, gid="band",
                            label=f"mixed, no air: {_pct(band[0])} to {_pct(band[1])}")
        ymax = max(ymax, float(np.nanmax(s, initial=0.0)))
    if len(plan):
        _draw_planned_strokes(ax, plan)
        ymax_plot = 1.6 * float(2.0 * plan["amplitude_m"].max())
    else:
        ymax_plot = ymax
    limit = min(damper.chamber_volume_1_m3, damper.chamber_volume_2_m3) / damper.piston_area_m2
    top = max_stroke_m if max_stroke_m is not None else min(max(ymax_plot, 1e-6), limit)
    ax.set_ylim(0.0, top * MM)
    ax.set_xlim(w[0] * MM, w[-1] * MM)
    figures.plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.88", lw=0.5)
    ax.grid(True, which="minor", color="0.95", lw=0.4)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("central starting position (V1 = V0,1, V2 = V0,2); curves end where G \u2264 1; "
                 "left of a curve: design space", fontsize=8.5, loc="right", color="0.3")
    return fig


def _draw_planned_strokes(ax, plan: pd.DataFrame) -> None:
    if plan is None or plan.empty:
        return
    w = plan["velocity_m_s"].to_numpy(float) * MM
    ax.plot(w, 2.0 * plan["amplitude_m"].to_numpy(float) * MM, ls="none", marker="v", ms=6, mfc="white",
            color="tab:green", gid="planned-half-period", label="planned: stroke of a half-period (2Y)")
    if "window_start_stroke_m" in plan:
        ws = pd.to_numeric(plan["window_start_stroke_m"], errors="coerce").to_numpy(float)
        if np.isfinite(ws).any():
            ax.plot(w, ws * MM, ls="none", marker="|", ms=9, mew=1.5, color="tab:green",
                    gid="planned-window-start", label="planned: stroke at the window start")


def _iso_velocity_lines(ax, xlim, ylim) -> None:
    """Eq. (27): Y = W T / 4, decades of W labelled in mm/s, drawn in the visible box."""
    (x0, x1), (y0, y1) = xlim, ylim  # s, mm
    w_lo, w_hi = 4.0 * y0 / x1, 4.0 * y1 / x0  # mm/s
    first = True
    for k in range(math.floor(math.log10(w_lo)), math.ceil(math.log10(w_hi)) + 1):
        wv = 10.0 ** k
        t = np.geomspace(x0, x1, 100)
        y = wv * t / 4.0
        ax.plot(t, y, color="0.7", lw=0.7, ls="-", zorder=1, gid="iso-velocity",
                label="iso-velocity W = 4Y/T (Eq. 27)" if first else None)
        first = False
        # label near the upper-right end of the visible part
        t_top = min(x1, 4.0 * y1 / wv)
        t_bot = max(x0, 4.0 * y0 / wv)
        if t_top <= t_bot * 3.0:  # less than half a decade visible: no room for a label
            continue
        tl = math.exp(math.log(t_bot) + 0.75 * (math.log(t_top) - math.log(t_bot)))
        ax.text(tl, wv * tl / 4.0, f"{wv:g} mm/s", fontsize=7, color="0.35", ha="center", va="center",
                rotation=0, zorder=2, gid="iso-velocity-label", clip_on=True,
                bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.8))


def at_diagram_figure(campaign: str, plan_check_df: pd.DataFrame, damper: Damper | None,
                      max_amplitude_m: float, min_amplitude_m: float, start_fraction: float = 0.45,
                      phi: float = 0.999, *, effects: Effects = NOMINAL) -> Figure:
    """Fig. 6: A-T diagram, log-log: period T [s] against amplitude Y [mm] of the triangle cases.

    Iso-velocity lines (Eq. 27, gid 'iso-velocity', labelled in mm/s); planned points grouped
    by period (gid 'planned-T<period>'); flagged points ringed (gid 'flagged'); constraints:
    'max-travel' and 'noise-floor' (horizontal), 'quasi-steady' (:func:`quasi_steady_boundary`,
    absent without damper data).
    """
    fig = _new_figure(11.0, 6.5)
    ax = fig.add_subplot()
    fig.suptitle(f"{campaign}: A\u2013T diagram of the triangle test plan", fontsize=12)
    ax.set_xlabel("Period T [s]")
    ax.set_ylabel("Amplitude Y [mm]")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plan = _planned_triangles(plan_check_df)
    plan = plan[np.isfinite(plan["period_s"]) & (plan["period_s"] > 0) & (plan["amplitude_m"] > 0)]
    t_pts = plan["period_s"].to_numpy(float)
    y_pts = plan["amplitude_m"].to_numpy(float) * MM
    # boundary of the quasi-steady constraint over a wide velocity range
    t_b = y_b = np.array([])
    if damper is not None:
        w_pts = plan["velocity_m_s"].to_numpy(float)
        w_lo = min(w_pts.min() / 10, 1e-6) if w_pts.size else 1e-6
        w_hi = max(w_pts.max() * 10, 1e-2) if w_pts.size else 1e-2
        t_b, y_b = quasi_steady_boundary(np.geomspace(w_lo, w_hi, 240), damper, phi=phi,
                                         start_fraction=start_fraction, effects=effects)
        y_b = y_b * MM
    # axes box from the points and the horizontal constraints
    ys = [v for v in (*y_pts, max_amplitude_m * MM, min_amplitude_m * MM) if math.isfinite(v) and v > 0]
    ts = list(t_pts) if t_pts.size else [1.0, 100.0]
    fin = np.isfinite(t_b) & np.isfinite(y_b)
    y0 = min(ys) / 3.0 if ys else 1e-2
    y1 = max(ys) * 3.0 if ys else 10.0
    seen = fin & (y_b >= y0) & (y_b <= y1)   # boundary inside the amplitude range shown
    x0 = min(min(ts) / 4.0, float(np.min(t_b[seen])) / 1.5 if seen.any() else math.inf)
    x1 = max(ts) * 4.0
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    _iso_velocity_lines(ax, (x0, x1), (y0, y1))
    ax.axhline(max_amplitude_m * MM, color="tab:red", lw=1.6, ls="-", gid="max-travel",
               label=f"maximum allowed travel Y = {_mm(max_amplitude_m)}")
    if min_amplitude_m > 0:
        ax.axhline(min_amplitude_m * MM, color="tab:brown", lw=1.6, ls="--", gid="noise-floor",
                   label=f"LVDT noise floor Y = {_mm(min_amplitude_m)}")
    if fin.any():
        ax.plot(t_b[fin], y_b[fin], color="tab:blue", lw=1.8, ls="-.", gid="quasi-steady",
                label=f"minimum time to quasi-steady:\nwindow start ({start_fraction:g} T/2) = stroke\n"
                      f"to reach {_pct(phi)} of \u0394p\u221e (Eq. 28)")
    # planned points by period
    for i, (period, grp) in enumerate(sorted(plan.groupby("period_s"), key=lambda kv: kv[0])):
        colour, marker = _PERIOD_STYLE[i % len(_PERIOD_STYLE)]
        ax.plot(grp["period_s"], grp["amplitude_m"] * MM, ls="none", marker=marker, ms=7, mfc="white", mew=1.4,
                color=colour, zorder=4, gid=f"planned-T{period:g}",
                label=f"planned, T = {period:g} s ({len(grp)} case{'s' if len(grp) != 1 else ''})")
    if "flagged" in plan and plan["flagged"].astype(bool).any():
        bad = plan[plan["flagged"].astype(bool)]
        ax.plot(bad["period_s"], bad["amplitude_m"] * MM, ls="none", marker="o", ms=13, mfc="none", mew=1.6,
                color="tab:red", zorder=5, gid="flagged", label=f"flagged by the plan check ({len(bad)})")
        for r in bad.itertuples():
            ax.annotate(str(r.case), (r.period_s, r.amplitude_m * MM), xytext=(6, -10), textcoords="offset points",
                        fontsize=7, color="tab:red", zorder=6)
    if plan.empty:
        figures._say_missing(ax, "no triangle case with a finite amplitude and period in the plan")
    figures.plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.9", lw=0.5)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8)
    notes = []
    if damper is None:
        notes.append("damper block missing in campaign.json: no quasi-steady boundary, convergence not checked")
    if plan_check_df is not None and len(plan_check_df) and "waveform" in plan_check_df:
        other = int((plan_check_df["waveform"] != "triangle").sum())
        if other:
            notes.append(f"{other} sine/free case(s) not on the A–T diagram (no triangle period)")
    figures._footnote(fig, "; ".join(notes))
    return fig


# ----------------------------------------------------------------------------------------------
# campaign writer
# ----------------------------------------------------------------------------------------------

def _read_cases(root: Path) -> pd.DataFrame:
    for p in (root / "cases.parquet", root / "ingest" / "cases.parquet"):
        if p.is_file():
            return pd.read_parquet(p)
    raise FileNotFoundError(f"{root}: no cases.parquet (validated) or ingest/cases.parquet")


def _fig5_velocities(plan: pd.DataFrame) -> np.ndarray:
    """Velocity axis of Fig. 5: 1 µm/s to 10 mm/s, widened to cover the planned cases."""
    lo, hi = 1e-6, 1e-2
    if len(plan):
        lo = min(lo, float(plan["velocity_m_s"].min()) / 2.0)
        hi = max(hi, float(plan["velocity_m_s"].max()) * 2.0)
    return np.geomspace(lo, hi, 300)


def write_design(campaign_root: str | os.PathLike, out_dir: str | os.PathLike, *, phi: float = 0.999,
                 max_amplitude_m: float, min_amplitude_m: float, start_fraction: float = 0.45,
                 effects: Effects = NOMINAL) -> tuple[pd.DataFrame, list[Path]]:
    """Plan check and Fig. 5-6 of one campaign (``results/<campaign>``) into ``out_dir``.

    Reads ``ingest/campaign.json`` (``campaign`` name and ``damper``, SI or null) and the cases
    table (``cases.parquet``, else ``ingest/cases.parquet``). Writes ``plan_check.parquet``,
    ``fig05_stroke_to_converge.png`` and ``fig06_at_diagram.png``; without damper data the figures
    are still written and say so. Returns (plan check, [paths]).
    """
    root, out = Path(campaign_root), Path(out_dir)
    meta = json.loads((root / "ingest" / "campaign.json").read_text(encoding="utf-8"))
    name = str(meta.get("campaign") or root.name)
    cases = _read_cases(root)
    note = ""
    try:
        dmp = _as_damper(meta.get("damper"))
    except (KeyError, ValueError) as exc:
        dmp, note = None, f"damper block unusable ({exc}): treated as missing"
    df = plan_check(name, cases, dmp, phi=phi, max_amplitude_m=max_amplitude_m, min_amplitude_m=min_amplitude_m,
                    start_fraction=start_fraction, effects=effects)
    if note:
        df["reasons"] = [f"{r}; {note}" if r else note for r in df["reasons"]]
    paths = [write_parquet(df, out / PLAN_CHECK_FILE)]
    plan = _planned_triangles(df)
    fig5 = stroke_to_converge_figure(dmp, _fig5_velocities(plan), phi=phi, planned=df, campaign=name)
    notes5 = [note] if note else []
    if dmp is None and not note:
        notes5.append("damper block missing in campaign.json: no stroke-to-converge curves")
    figures._footnote(fig5, "; ".join(notes5))
    fig6 = at_diagram_figure(name, df, dmp, max_amplitude_m, min_amplitude_m, start_fraction, phi, effects=effects)
    for fig, fname in zip((fig5, fig6), FIGURE_FILES, strict=True):
        paths.append(figures.save_figure(fig, out / fname))
    return df, paths
