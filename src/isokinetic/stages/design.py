"""Rule ``design``: check a campaign's test plan before running it, and draw Fig. 5-6.

Sec. 3.2-3.3 and 4.2-4.3 of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.); equation numbers are the paper's.
The convergence formulas (G-numbers, strokes and times to converge, Eq. 15-29) are in
:mod:`isokinetic.physics.convergence`, the figures in :mod:`isokinetic.plots.design`; this module
checks each planned case against them (:func:`plan_check`) and writes the rule's outputs
(:func:`write_design`). The reversal stroke (an extension, not in the paper: a half-period after the
first starts from the opposite steady Δp, not from rest) is reported and flagged too, while the
paper's flag is the start from rest.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_parquet
from isokinetic.physics.convergence import check_phi, g1, g2, g3, stroke_to_converge, strokes_to_converge_in_a_cycle
from isokinetic.physics.damper import NOMINAL, Damper, Effects
from isokinetic.physics.plan import CasePlan, first_half_period
from isokinetic.plots.design import mm_label, percent_label, write_design_figures
from isokinetic.plots.style import MM

#: Table written by :func:`write_design` (figures: ``figures_of("design")``).
PLAN_CHECK_FILE = Path(STAGE_OUTPUTS["design"]["plan_check"]).name


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


def plan_check(campaign: str, cases, damper, *, phi: float, max_amplitude_m: float,
               min_amplitude_m: float, start_fraction: float,
               effects: Effects = NOMINAL) -> pd.DataFrame:
    """One row per planned case (tables.PLAN_CHECK plus design columns); flags broken constraints.

    ``cases``: a cases table (tables.CASES columns; ``status`` kept if present) or CasePlans;
    ``damper``: Damper, its SI mapping, or None (no damper data: physics columns NaN, only the
    noise-floor check, the travel said but not flagged, and a reason saying the damper block is missing).

    Triangle cases, at W = 4Y/T (Eq. 26) and the first half-period's start (-Y for phase -π/2):
    G1, G2, G3 (Eq. 19-22); strokes to reach ϕ of Δp∞ for laminar, turbulent (Eq. 29) and mixed
    flow (Eq. 28, = ``stroke_to_converge_m``), the time to converge, and the reversal stroke
    (the larger of the two reversals', at either end, :func:`strokes_to_converge_in_a_cycle`; it counts towards
    ``flagged``). The window starts at ``start_fraction`` T/2, i.e. after the stroke
    ``window_start_stroke_m`` = start_fraction (T/2) W. Sine cases: G-numbers at the peak velocity
    2πfY, only travel and noise-floor checks. Free cases: nothing planned to check.

    Constraint columns (True = broken): ``travel_exceeded`` (Y > max_amplitude_m, with a damper),
    ``below_noise_floor`` (Y < min_amplitude_m), ``no_convergence`` (G3 <= 1), ``window_too_early``
    (window start stroke < stroke to converge from rest, Eq. 28), ``window_too_early_after_reversal``
    (the same from the opposite steady pressure, as windows 2-4 start). ``flagged`` = any;
    ``reasons`` '; '-joined text.
    """
    phi = float(check_phi(phi))
    if not 0.0 <= start_fraction < 1.0:
        raise ValueError(f"start_fraction must lie in [0, 1), got {start_fraction!r}")
    dmp = _as_damper(damper)
    frame = _cases_frame(cases)
    rows = []
    for rec in frame.to_dict("records"):
        rows.append(_check_case(campaign, rec, dmp, phi, max_amplitude_m, min_amplitude_m, start_fraction, effects))
    out = pd.DataFrame(rows) if rows else tables.empty(tables.PLAN_CHECK)
    return tables.validate_table(out, tables.PLAN_CHECK)


def _empty_row(campaign: str, rec: Mapping, phi: float, max_amp: float, min_amp: float,
               start_fraction: float) -> dict:
    """The plan-check row of a case before any check: planned values, NaN physics, no flag."""
    nan = math.nan
    return {"campaign": str(campaign), "case": str(rec.get("case", "")), "waveform": str(rec.get("waveform", "")),
            "status": str(rec.get("status", "")), "velocity_m_s": nan, "period_s": _num(rec, "period_s"),
            "amplitude_m": _num(rec, "amplitude_m"), "frequency_Hz": _num(rec, "frequency_Hz"), "phi": phi,
            "start_fraction": start_fraction, "max_amplitude_m": float(max_amp), "min_amplitude_m": float(min_amp),
            "half_period_stroke_m": nan, "start_position_m": nan,
            "G1": nan, "G2": nan, "G3": nan, "stroke_laminar_m": nan, "stroke_turbulent_m": nan,
            "stroke_mixed_m": nan, "stroke_to_converge_m": nan, "time_to_converge_s": nan,
            "stroke_to_converge_reversal_m": nan, "window_start_s": nan, "window_start_stroke_m": nan,
            "travel_exceeded": False, "below_noise_floor": False, "no_convergence": False,
            "window_too_early": False, "window_too_early_after_reversal": False}


#: Where the travel limit comes from, for messages.
TRAVEL_SOURCE = "design.max_amplitude_mm in the config"


def _check_travel(row: dict, max_amp: float, min_amp: float, reasons: list[str], has_damper: bool) -> None:
    """Amplitude against the allowed piston travel and the LVDT noise floor. The travel limit
    (:data:`TRAVEL_SOURCE`) is the project's: the rig and damper it plans for. A campaign without a damper block
    is a record of a damper the project knows nothing of (often another rig's file): its amplitude is compared,
    said, but not flagged."""
    amp = row["amplitude_m"]
    if math.isfinite(amp):
        if amp > max_amp and has_damper:
            row["travel_exceeded"] = True
            reasons.append(f"amplitude {mm_label(amp)} exceeds the allowed piston travel {mm_label(max_amp)} "
                           f"({TRAVEL_SOURCE}): plan a smaller amplitude, or raise the limit if the rig and damper "
                           "allow more")
        elif amp > max_amp:
            reasons.append(f"amplitude {mm_label(amp)} is beyond the {mm_label(max_amp)} travel of the project's rig "
                           f"and damper ({TRAVEL_SOURCE}); not flagged: the campaign has no damper block, so nothing "
                           "ties it to that rig (with a damper block it is flagged)")
        if amp < min_amp:
            row["below_noise_floor"] = True
            reasons.append(f"amplitude {mm_label(amp)} is below the LVDT noise floor {mm_label(min_amp)}")
    elif row["waveform"] in ("triangle", "sine"):
        reasons.append("no planned amplitude: travel, noise floor and convergence not checked")


def _check_triangle(row: dict, rec: Mapping, dmp: Damper | None, phi: float, start_fraction: float,
                    effects: Effects, reasons: list[str]) -> None:
    """Velocity, window start, G-numbers and strokes to converge of a triangle case (Eq. 19-29)."""
    amp, period = row["amplitude_m"], row["period_s"]
    w = 4.0 * amp / period
    row.update(velocity_m_s=w, half_period_stroke_m=2.0 * amp, window_start_s=start_fraction * period / 2.0,
               window_start_stroke_m=start_fraction * period / 2.0 * w)
    phase = _num(rec, "phase_rad")
    plan = CasePlan(case=row["case"], waveform="triangle", sample_rate_Hz=1.0, amplitude_m=amp,
                    period_s=period, phase_rad=phase if math.isfinite(phase) else -math.pi / 2,
                    duration_s=_num(rec, "duration_s"))
    y0, direction = first_half_period(plan)
    row["start_position_m"] = y0
    if dmp is None:
        return
    wd = direction * w
    kw = {"phi": phi, "start_position_m": y0, "effects": effects}
    row.update(G1=float(g1(w, dmp, effects)), G2=float(g2(w, dmp, effects)), G3=float(g3(w, dmp, effects)),
               stroke_laminar_m=float(stroke_to_converge(wd, dmp, flow="laminar", **kw)),
               stroke_turbulent_m=float(stroke_to_converge(wd, dmp, flow="turbulent", **kw)),
               stroke_mixed_m=float(stroke_to_converge(wd, dmp, **kw)),
               stroke_to_converge_reversal_m=max(strokes_to_converge_in_a_cycle(wd, dmp, **kw)[1:], key=_unreached))
    row["stroke_to_converge_m"] = row["stroke_mixed_m"]
    row["time_to_converge_s"] = row["stroke_to_converge_m"] / w
    _check_convergence(row, phi, start_fraction, reasons)


def _unreached(stroke_m: float) -> float:
    """A stroke's order as the larger need: one never reached (NaN, from G3 <= 1) counts as infinite."""
    return stroke_m if stroke_m == stroke_m else math.inf


def _check_convergence(row: dict, phi: float, start_fraction: float, reasons: list[str]) -> None:
    """G3 > 1 (Eq. 22) and the window start after the stroke to converge, from rest and after a reversal."""
    amp = row["amplitude_m"]
    if row["G3"] <= 1.0:
        row["no_convergence"] = True
        reasons.append(f"G3 = {row['G3']:.3g} <= 1: the pressure differential does not converge (Eq. 22)")
    need, start = row["stroke_to_converge_m"], row["window_start_stroke_m"]
    if start < need:
        row["window_too_early"] = True
        text = (f"window starts after {mm_label(start)} of stroke ({start_fraction:g} T/2), before the "
                f"{mm_label(need)} needed to reach {percent_label(phi)} of the incompressible pressure (Eq. 28)")
        if need > 2.0 * amp:
            text += f"; not reached within the {mm_label(2.0 * amp)} half-period"
        reasons.append(text)
    need_rev = row["stroke_to_converge_reversal_m"]
    row["window_too_early_after_reversal"] = bool(start < need_rev)
    if start < need_rev and not row["window_too_early"]:
        reasons.append(f"window starts after {mm_label(start)} of stroke, before the {mm_label(need_rev)} needed "
                       f"after a velocity reversal (from the opposite steady pressure) to reach "
                       f"{percent_label(phi)} of the incompressible pressure; windows 2-4 follow a reversal")


def _check_case(campaign: str, rec: Mapping, dmp: Damper | None, phi: float, max_amp: float, min_amp: float,
                start_fraction: float, effects: Effects) -> dict:
    row = _empty_row(campaign, rec, phi, max_amp, min_amp, start_fraction)
    waveform, amp, period, freq = row["waveform"], row["amplitude_m"], row["period_s"], row["frequency_Hz"]
    reasons: list[str] = []
    _check_travel(row, max_amp, min_amp, reasons, dmp is not None)
    if waveform == "triangle" and math.isfinite(amp) and math.isfinite(period) and period > 0 and amp > 0:
        _check_triangle(row, rec, dmp, phi, start_fraction, effects, reasons)
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
            what.append(f"Y = {mm_label(_num(r, 'amplitude_m'))}")
        detail = f" ({', '.join(what)})" if what else ""
        out.append(f"campaign {r['campaign']}, case {r['case']}{detail}: {r['reasons']}")
    return out


def write_design(campaign_root: str | os.PathLike, out_dir: str | os.PathLike, *, phi: float,
                 max_amplitude_m: float, min_amplitude_m: float, start_fraction: float,
                 effects: Effects = NOMINAL) -> tuple[pd.DataFrame, list[Path]]:
    """Plan check and Fig. 5-6 of one campaign (``results/<campaign>``) into ``out_dir``.

    Reads ``ingest/campaign.json`` (``campaign`` name and ``damper``, SI or null) and the cases
    table (``cases.parquet``, else ``ingest/cases.parquet``). Writes ``plan_check.parquet``,
    ``fig05_stroke_to_converge.png`` and ``fig06_at_diagram.png``; without damper data the figures
    are still written and say so. Returns (plan check, [paths]).
    """
    folder, out = CampaignFolder.at(campaign_root), Path(out_dir)
    name, dmp = folder.campaign, folder.damper
    cases = folder.cases()
    df = plan_check(name, cases, dmp, phi=phi, max_amplitude_m=max_amplitude_m, min_amplitude_m=min_amplitude_m,
                    start_fraction=start_fraction, effects=effects)
    paths = [write_parquet(df, out / PLAN_CHECK_FILE)]
    paths += write_design_figures(out, name, df, dmp, "", phi=phi, max_amplitude_m=max_amplitude_m,
                                  min_amplitude_m=min_amplitude_m, start_fraction=start_fraction, effects=effects)
    return df, paths
