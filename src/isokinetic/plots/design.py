"""Figures of the rule ``design``: Fig. 5 (stroke to converge) and Fig. 6 (A-T diagram of the plan).

They reproduce Fig. 5 and Fig. 6 of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.) for a campaign's own plan; the curves
come from :mod:`isokinetic.physics.convergence` (Eq. 3, 19-29). SI inside, mm and mm/s at the plot
edge. File names come from the figure registry (:func:`isokinetic.contracts.outputs.figures_of`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from isokinetic.contracts.outputs import figures_of
from isokinetic.physics.convergence import g1, g2, g3, quasi_steady_boundary, stroke_to_converge
from isokinetic.physics.damper import NOMINAL, Damper, Effects
from isokinetic.plots.style import MM, footnote, new_figure, plain_log_ticks, save_figure, say_missing

#: Air volume fractions of Fig. 5 (0, 0.1, 0.5, 1 %).
FIG5_AIR_FRACTIONS = (0.0, 0.001, 0.005, 0.01)

_FLOW_STYLE = {"laminar": ("tab:blue", "--"), "turbulent": ("tab:purple", ":"), "mixed": ("black", "-")}
_AIR_COLOURS = ("black", "tab:orange", "tab:red", "tab:brown", "tab:pink", "tab:olive")
_PERIOD_STYLE = (("tab:blue", "o"), ("tab:green", "s"), ("tab:orange", "D"), ("tab:purple", "^"),
                 ("tab:cyan", "v"), ("tab:brown", "P"))


def mm_label(x_m: float) -> str:
    """A length in mm to 3 significant digits: '6.75 mm'."""
    return f"{x_m * MM:.3g} mm"


def percent_label(fraction: float) -> str:
    """A fraction as a percentage: 0.999 -> '99.9 %'."""
    return f"{fraction * 100:.6g} %"


def _air_label(frac: float) -> str:
    return "no air" if frac == 0 else f"{frac * 100:g} % air"


def _wrapped_footnote(fig: Figure, text: str) -> None:
    """A footnote wrapped at about half the figure width (7.5 pt)."""
    footnote(fig, text, width=max(40, int(fig.get_figwidth() * 10)))


def planned_triangles(planned: pd.DataFrame | None) -> pd.DataFrame:
    """Triangle rows with finite velocity and amplitude (from a plan check or a cases table)."""
    if planned is None or len(planned) == 0:
        return pd.DataFrame({"case": pd.Series(dtype=object), **{c: pd.Series(dtype=float) for c in
                                                                  ("velocity_m_s", "amplitude_m", "period_s")}})
    df = planned[planned["waveform"] == "triangle"] if "waveform" in planned else planned
    amp = pd.to_numeric(df["amplitude_m"], errors="coerce")
    per = pd.to_numeric(df["period_s"], errors="coerce")
    vel = pd.to_numeric(df["velocity_m_s"], errors="coerce") if "velocity_m_s" in df else 4.0 * amp / per
    out = df.assign(velocity_m_s=vel, amplitude_m=amp, period_s=per)
    return out[np.isfinite(out["velocity_m_s"]) & np.isfinite(out["amplitude_m"]) & (out["velocity_m_s"] > 0)]


def fig5_velocities(plan: pd.DataFrame) -> np.ndarray:
    """Velocity axis of Fig. 5: 1 µm/s to 10 mm/s, widened to cover the planned cases."""
    lo, hi = 1e-6, 1e-2
    if len(plan):
        lo = min(lo, float(plan["velocity_m_s"].min()) / 2.0)
        hi = max(hi, float(plan["velocity_m_s"].max()) * 2.0)
    return np.geomspace(lo, hi, 300)


# ----------------------------------------------------------------------------------------------
# Fig. 5: stroke to converge
# ----------------------------------------------------------------------------------------------

def _draw_convergence_curves(ax, damper: Damper, w: np.ndarray, phi: float, air_fractions: Sequence[float],
                             band: tuple[float, float] | None) -> float:
    """Laminar and turbulent (Eq. 29) and mixed (Eq. 28, per air fraction) strokes; returns the top [m]."""
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
                            label=f"mixed, no air: {percent_label(band[0])} to {percent_label(band[1])}")
        ymax = max(ymax, float(np.nanmax(s, initial=0.0)))
    return ymax


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


def stroke_to_converge_figure(damper: Damper | None, velocities_m_s, *, phi: float,
                              air_fractions: Sequence[float] = FIG5_AIR_FRACTIONS,
                              band: tuple[float, float] = (0.95, 0.99999), planned: pd.DataFrame | None = None,
                              campaign: str | None = None, max_stroke_m: float | None = None) -> Figure:
    """Fig. 5: stroke to reach ϕ of the incompressible Δp against piston velocity (log x).

    Central starting position (V1 = V0,1, V2 = V0,2) as in the paper. Curves (gids): 'laminar',
    'turbulent' (Eq. 29), 'mixed' (Eq. 28) and 'mixed-air-<fraction>' for each nonzero air
    fraction (Eq. 3, Table 1 β_air); a shaded band 'band' (mixed, no air) between ϕ = band[0]
    and band[1]. Curves end where G3 <= 1. ``planned`` (plan check or cases table): triangle
    cases' half-period stroke 2Y ('planned-half-period') and window-start stroke
    ('planned-window-start') at their velocity.
    """
    fig = new_figure(8.5, 6.0)
    ax = fig.add_subplot()
    fig.suptitle(f"{campaign or 'campaign ?'}: piston stroke to reach {percent_label(phi)} of the incompressible "
                 "\u0394p", fontsize=12)
    ax.set_xlabel("Piston velocity W [mm/s]")
    ax.set_ylabel(f"Stroke to reach {percent_label(phi)} of \u0394p\u221e [mm]")
    ax.set_xscale("log")
    w = np.asarray(velocities_m_s, dtype=float)
    w = np.sort(w[np.isfinite(w) & (w > 0)])
    plan = planned_triangles(planned)
    if damper is None:
        say_missing(ax, "no damper data (damper block missing in campaign.json): "
                        "the stroke to converge cannot be computed")
        _draw_planned_strokes(ax, plan)
        if len(plan):
            ax.set_ylim(bottom=0.0)
            ax.legend(loc="upper left", fontsize=8)
        plain_log_ticks(ax)
        return fig
    if w.size == 0:
        say_missing(ax, "no positive velocities to plot")
        return fig
    ymax = _draw_convergence_curves(ax, damper, w, phi, air_fractions, band)
    if len(plan):
        _draw_planned_strokes(ax, plan)
        ymax = 1.6 * float(2.0 * plan["amplitude_m"].max())
    limit = min(damper.chamber_volume_1_m3, damper.chamber_volume_2_m3) / damper.piston_area_m2
    top = max_stroke_m if max_stroke_m is not None else min(max(ymax, 1e-6), limit)
    ax.set_ylim(0.0, top * MM)
    ax.set_xlim(w[0] * MM, w[-1] * MM)
    plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.88", lw=0.5)
    ax.grid(True, which="minor", color="0.95", lw=0.4)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("central starting position (V1 = V0,1, V2 = V0,2); curves end where G \u2264 1; "
                 "left of a curve: design space", fontsize=8.5, loc="right", color="0.3")
    return fig


# ----------------------------------------------------------------------------------------------
# Fig. 6: A-T diagram
# ----------------------------------------------------------------------------------------------

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
                bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8})


def _boundary(plan: pd.DataFrame, damper: Damper | None, phi: float, start_fraction: float,
              effects: Effects) -> tuple[np.ndarray, np.ndarray]:
    """(T [s], Y [mm]) of the quasi-steady constraint over a wide velocity range; empty without damper."""
    if damper is None:
        return np.array([]), np.array([])
    w_pts = plan["velocity_m_s"].to_numpy(float)
    w_lo = min(w_pts.min() / 10, 1e-6) if w_pts.size else 1e-6
    w_hi = max(w_pts.max() * 10, 1e-2) if w_pts.size else 1e-2
    t_b, y_b = quasi_steady_boundary(np.geomspace(w_lo, w_hi, 240), damper, phi=phi,
                                     start_fraction=start_fraction, effects=effects)
    return t_b, y_b * MM


def _at_box(plan: pd.DataFrame, amplitudes_m: Sequence[float], t_b: np.ndarray, y_b: np.ndarray):
    """Axes limits ((T0, T1) [s], (Y0, Y1) [mm]) from the points, the horizontal constraints and the boundary."""
    t_pts = plan["period_s"].to_numpy(float)
    y_pts = plan["amplitude_m"].to_numpy(float) * MM
    ys = [v for v in (*y_pts, *(a * MM for a in amplitudes_m)) if math.isfinite(v) and v > 0]
    ts = list(t_pts) if t_pts.size else [1.0, 100.0]
    fin = np.isfinite(t_b) & np.isfinite(y_b)
    y0 = min(ys) / 3.0 if ys else 1e-2
    y1 = max(ys) * 3.0 if ys else 10.0
    seen = fin & (y_b >= y0) & (y_b <= y1)   # boundary inside the amplitude range shown
    x0 = min(min(ts) / 4.0, float(np.min(t_b[seen])) / 1.5 if seen.any() else math.inf)
    return (x0, max(ts) * 4.0), (y0, y1)


def _draw_planned_points(ax, plan: pd.DataFrame) -> None:
    """Planned triangle cases grouped by period; flagged ones ringed and named."""
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


def _at_notes(plan_check_df: pd.DataFrame | None, damper: Damper | None) -> str:
    notes = []
    if damper is None:
        notes.append("damper block missing in campaign.json: no quasi-steady boundary, convergence not checked")
    if plan_check_df is not None and len(plan_check_df) and "waveform" in plan_check_df:
        other = int((plan_check_df["waveform"] != "triangle").sum())
        if other:
            notes.append(f"{other} sine/free case(s) not on the A–T diagram (no triangle period)")
    return "; ".join(notes)


def at_diagram_figure(campaign: str, plan_check_df: pd.DataFrame, damper: Damper | None,
                      max_amplitude_m: float, min_amplitude_m: float, start_fraction: float,
                      phi: float, *, effects: Effects = NOMINAL) -> Figure:
    """Fig. 6: A-T diagram, log-log: period T [s] against amplitude Y [mm] of the triangle cases.

    Iso-velocity lines (Eq. 27, gid 'iso-velocity', labelled in mm/s); planned points grouped
    by period (gid 'planned-T<period>'); flagged points ringed (gid 'flagged'); constraints:
    'max-travel' and 'noise-floor' (horizontal), 'quasi-steady' (:func:`quasi_steady_boundary`,
    absent without damper data).
    """
    fig = new_figure(11.0, 6.5)
    ax = fig.add_subplot()
    fig.suptitle(f"{campaign}: A\u2013T diagram of the triangle test plan", fontsize=12)
    ax.set_xlabel("Period T [s]")
    ax.set_ylabel("Amplitude Y [mm]")
    ax.set_xscale("log")
    ax.set_yscale("log")
    plan = planned_triangles(plan_check_df)
    plan = plan[np.isfinite(plan["period_s"]) & (plan["period_s"] > 0) & (plan["amplitude_m"] > 0)]
    t_b, y_b = _boundary(plan, damper, phi, start_fraction, effects)
    xlim, ylim = _at_box(plan, (max_amplitude_m, min_amplitude_m), t_b, y_b)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    _iso_velocity_lines(ax, xlim, ylim)
    ax.axhline(max_amplitude_m * MM, color="tab:red", lw=1.6, ls="-", gid="max-travel",
               label=f"maximum allowed travel Y = {mm_label(max_amplitude_m)}")
    if min_amplitude_m > 0:
        ax.axhline(min_amplitude_m * MM, color="tab:brown", lw=1.6, ls="--", gid="noise-floor",
                   label=f"LVDT noise floor Y = {mm_label(min_amplitude_m)}")
    fin = np.isfinite(t_b) & np.isfinite(y_b)
    if fin.any():
        ax.plot(t_b[fin], y_b[fin], color="tab:blue", lw=1.8, ls="-.", gid="quasi-steady",
                label=f"minimum time to quasi-steady:\nwindow start ({start_fraction:g} T/2) = stroke\n"
                      f"to reach {percent_label(phi)} of \u0394p\u221e (Eq. 28)")
    _draw_planned_points(ax, plan)
    if plan.empty:
        say_missing(ax, "no triangle case with a finite amplitude and period in the plan")
    plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.9", lw=0.5)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8)
    _wrapped_footnote(fig, _at_notes(plan_check_df, damper))
    return fig


# ----------------------------------------------------------------------------------------------
# the rule's figures
# ----------------------------------------------------------------------------------------------

def write_design_figures(out_dir: str | os.PathLike, campaign: str, plan_check_df: pd.DataFrame,
                         damper: Damper | None, note: str, *, phi: float, max_amplitude_m: float,
                         min_amplitude_m: float, start_fraction: float, effects: Effects = NOMINAL) -> list[Path]:
    """Draw and write Fig. 5 and Fig. 6 of a campaign into ``out_dir`` (names from the figure registry).

    ``note`` (e.g. an unusable damper block) goes under Fig. 5; without damper data the figures
    are still drawn and say so.
    """
    fig5 = stroke_to_converge_figure(damper, fig5_velocities(planned_triangles(plan_check_df)), phi=phi,
                                     planned=plan_check_df, campaign=campaign)
    notes5 = [note] if note else []
    if damper is None and not note:
        notes5.append("damper block missing in campaign.json: no stroke-to-converge curves")
    _wrapped_footnote(fig5, "; ".join(notes5))
    fig6 = at_diagram_figure(campaign, plan_check_df, damper, max_amplitude_m, min_amplitude_m, start_fraction, phi,
                             effects=effects)
    out = Path(out_dir)
    return [save_figure(fig, out / Path(f.path).name)
            for fig, f in zip((fig5, fig6), figures_of("design"), strict=True)]
