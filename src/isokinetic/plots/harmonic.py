"""Fig. 15: the hysteresis loops of the harmonic (sine) and free-waveform cases of one campaign.

The paper "A method for the identification of hydraulic damper characteristics from steady
velocity inputs" (Titurus et al.) shows the harmonic-excitation loops and their peak-to-peak curve
inside its Fig. 13 (Sec. 4.5); this pipeline figure draws them case by case, with the sense of
circulation of each loop and, for free records, the velocity-binned and peak-velocity curves. The
rule ``harmonic`` (:mod:`isokinetic.stages.harmonic`) computes the table and the loops drawn here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from isokinetic.plots.style import MM, footnote, force_unit, new_figure, say_missing

#: At most this many cases get a row of their own (all of them appear in the top row).
MAX_CASE_ROWS = 12


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------

def _arrow(ax, x: np.ndarray, y: np.ndarray, colour: str) -> None:
    """An arrow along the curve showing its sense of circulation."""
    if x.size < 8:
        return
    i = int(np.argmax(x))                                    # the right-hand tip of the loop
    j = min(i + max(2, x.size // 16), x.size - 1)
    if j == i:
        return
    ax.annotate("", xy=(x[j], y[j]), xytext=(x[i], y[i]),
                arrowprops={"arrowstyle": "-|>", "color": "black", "lw": 1.6, "mutation_scale": 20}, zorder=5)


def _axes_style(ax, xlabel: str, ylabel: str, title: str) -> None:
    ax.axhline(0.0, color="0.6", lw=0.5, zorder=0)
    ax.axvline(0.0, color="0.6", lw=0.5, zorder=0)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10, loc="center", pad=8)  # centred over its own panel: titles never run together


def _case_label(row: Mapping, lp: pd.DataFrame) -> str:
    case = str(row.get("case", "?"))
    if row.get("waveform") == "sine":
        amp = row.get("amplitude_m")
        f = lp.attrs.get("frequency_Hz", math.nan)
        amp_txt = f", Y = {float(amp) * MM:.3g} mm" if amp is not None and pd.notna(amp) else ""
        return f"{case}: sine {f:.3g} Hz{amp_txt}"
    return f"{case}: free record (dominant {lp.attrs.get('frequency_Hz', math.nan):.3g} Hz)"


def _empty_panel(ax, text: str) -> None:
    """A panel with nothing to draw: the reason in its middle (the figures' style), no ticks."""
    say_missing(ax, text)
    ax.set_xticks([])
    ax.set_yticks([])


def _of_kind(table: pd.DataFrame, kind: str) -> pd.DataFrame:
    return table[table["kind"] == kind] if len(table) else table


# ----------------------------------------------------------------------------------------------
# the top row: every case together
# ----------------------------------------------------------------------------------------------

def _draw_sine_overview(ax, table: pd.DataFrame, loops: Mapping[str, pd.DataFrame], rows: Mapping,
                        colours: Mapping[str, str], sine_ids: list[str], fs: float, any_case: bool) -> None:
    """Every sine loop in the force-velocity plane, with the peak-to-peak curve."""
    p2p = _of_kind(table, "peak_to_peak")
    for c in sine_ids:
        lp = loops[c]
        ax.plot(lp["velocity_m_s"] * MM, lp["force_N"] / fs, color=colours[c], lw=0.6, alpha=0.8,
                label=_case_label(rows.get(c, {"case": c, "waveform": "sine"}), lp), gid=f"loop-{c}")
    if len(p2p):
        curve = p2p.sort_values("velocity_m_s", kind="stable")
        ax.plot(curve["velocity_m_s"] * MM, curve["force_N"] / fs, color="black", lw=1.4, marker="o", ms=5,
                mfc="white", label="peak-to-peak curve", zorder=4, gid="peak-to-peak-curve")
    if sine_ids:
        ax.legend(fontsize=7.5, loc="upper left", frameon=False)
    elif any_case:
        _empty_panel(ax, "no status-ok sine case")


def _draw_free_overview(ax, table: pd.DataFrame, colours: Mapping[str, str], free_ids: list[str], fs: float,
                        any_case: bool) -> None:
    """Every free case's velocity-binned characteristic."""
    binned = _of_kind(table, "binned")
    for c in free_ids:
        b = binned[binned["case"] == c].sort_values("velocity_m_s", kind="stable")
        ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color=colours[c], lw=1.2, marker=".",
                label=f"{c} (binned)", gid=f"binned-{c}")
    if free_ids:
        ax.legend(fontsize=7.5, loc="upper left", frameon=False)
    elif any_case:
        _empty_panel(ax, "no status-ok free case")


# ----------------------------------------------------------------------------------------------
# one row per case
# ----------------------------------------------------------------------------------------------

def _annotate_lag(ax, pts: pd.DataFrame, fs: float) -> None:
    """The lag of the force extreme behind the velocity extreme, next to each peak-to-peak point."""
    for r in pts.itertuples():
        right = r.velocity_m_s > 0
        ax.annotate(f"F lags v by {r.lag_s * 1e3:.3g} ms ({math.degrees(r.phase_lag_rad):.0f}\u00b0)",
                    xy=(r.velocity_m_s * MM, r.force_N / fs), xytext=(-9 if right else 9, 0),
                    textcoords="offset points", ha="right" if right else "left", va="center",
                    fontsize=7, bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.8", "alpha": 0.85})


def _draw_sine_row(ax_v, ax_y, c: str, lp: pd.DataFrame, table: pd.DataFrame, colour: str, fs: float) -> None:
    """A sine case: its loop with the peak-to-peak points (force-velocity) and in force-displacement."""
    v_mm, y_mm, f = lp["velocity_m_s"].to_numpy() * MM, lp["displacement_m"].to_numpy() * MM, \
        lp["force_N"].to_numpy() / fs
    ax_v.plot(v_mm, f, color=colour, lw=0.7, gid=f"loop-{c}")
    p2p = _of_kind(table, "peak_to_peak")
    pts = p2p[p2p["case"] == c] if len(p2p) else p2p
    if len(pts):
        ax_v.plot(pts["velocity_m_s"] * MM, pts["force_N"] / fs, ls="none", marker="o", ms=7, mfc="white",
                  mec="black", mew=1.4, zorder=4, gid=f"peak-to-peak-{c}")
        _annotate_lag(ax_v, pts, fs)
    first = lp["period"].to_numpy() == lp["period"].min()
    _arrow(ax_v, v_mm[first], f[first], colour)
    ax_v.legend(handles=[Line2D([], [], color=colour, lw=0.7, label=f"loop, periods {lp['period'].min()}"
                                f"\u2013{lp['period'].max()} (arrow: sense)"),
                         Line2D([], [], ls="none", marker="o", mfc="white", mec="black",
                                label="peak-to-peak point (v, F extremes)")],
                fontsize=7.5, loc="upper left", frameon=False)
    ax_y.plot(y_mm, f, color=colour, lw=0.7, gid=f"loop-{c}-displacement")
    _arrow(ax_y, y_mm[first], f[first], colour)


def _draw_free_row(ax_v, ax_y, c: str, lp: pd.DataFrame, table: pd.DataFrame, colour: str, fs: float) -> None:
    """A free case: samples, binned curve and peak-velocity points (force-velocity), force-displacement."""
    v_mm, y_mm, f = lp["velocity_m_s"].to_numpy() * MM, lp["displacement_m"].to_numpy() * MM, \
        lp["force_N"].to_numpy() / fs
    ax_v.plot(v_mm, f, color="0.6", lw=0, marker=".", ms=1.5, alpha=0.5, gid=f"loop-{c}")
    binned = _of_kind(table, "binned")
    b = binned[binned["case"] == c].sort_values("velocity_m_s", kind="stable") if len(binned) else binned
    ax_v.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color=colour, lw=1.4, marker="s", ms=3,
              gid=f"binned-{c}")
    pv = table[(table["kind"] == "peak_velocity") & (table["case"] == c)] if len(table) else table
    ax_v.plot(pv["velocity_m_s"] * MM, pv["force_N"] / fs, ls="none", marker="^", ms=5, color="black",
              gid=f"peak-velocity-{c}")
    ax_v.legend(handles=[Line2D([], [], color="0.6", ls="none", marker=".", label="samples"),
                         Line2D([], [], color=colour, marker="s", ms=3, label="velocity-binned mean"),
                         Line2D([], [], color="black", ls="none", marker="^", label="force at velocity peaks")],
                fontsize=7.5, loc="upper left", frameon=False)
    ax_y.plot(y_mm, f, color=colour, lw=0.5, gid=f"loop-{c}-displacement")


# ----------------------------------------------------------------------------------------------
# Fig. 15
# ----------------------------------------------------------------------------------------------

def harmonic_figure(table: pd.DataFrame, loops: Mapping[str, pd.DataFrame], cases: pd.DataFrame | None = None,
                    *, campaign: str = "campaign ?", note: str = "") -> Figure:
    """Fig. 15: loops of the sine and free cases.

    Top row: every sine loop in the force-velocity plane with the peak-to-peak points and curve
    (left), every free case's binned curve (right). Then one row per case (at most
    :data:`MAX_CASE_ROWS`): force-velocity (left: loop, peak-to-peak points, or for free records the
    samples, the binned curve and the peak-velocity points) and force-displacement (right). An
    arrow on each per-case loop shows its sense. Artists carry gids: ``loop-<case>``,
    ``peak-to-peak-<case>``, ``peak-to-peak-curve``, ``binned-<case>``, ``peak-velocity-<case>``.
    """
    case_ids = list(loops)
    shown = case_ids[:MAX_CASE_ROWS]
    n_rows = 1 + len(shown)
    fig = new_figure(11.0, 1.4 + 3.0 * n_rows)
    axes = fig.subplots(n_rows, 2, squeeze=False)
    fig.suptitle(f"{campaign}: harmonic and free-waveform loops", fontsize=12)
    forces = [lp["force_N"].to_numpy() for lp in loops.values()]
    fs, fu = force_unit(np.concatenate(forces) if forces else [])
    rows = {} if cases is None or cases.empty else {str(r["case"]): r for _, r in cases.iterrows()}
    colours = {c: f"C{i % 10}" for i, c in enumerate(case_ids)}
    sine_ids = [c for c in case_ids if rows.get(c, {}).get("waveform", "sine") == "sine"]
    free_ids = [c for c in case_ids if c not in sine_ids]

    ax_s, ax_f = axes[0]
    if case_ids and not (sine_ids and free_ids):   # one kind only: its overview spans the top row, no empty panel
        grid = ax_s.get_gridspec()
        ax_s.remove()
        ax_f.remove()
        ax_s = ax_f = fig.add_subplot(grid[0, :])
    if sine_ids or not case_ids:
        _axes_style(ax_s, "Velocity v [mm/s]", f"Force F [{fu}]", "All sine cases: loops, peak-to-peak curve")
    if free_ids or not case_ids:
        _axes_style(ax_f, "Velocity v [mm/s]", f"Force F [{fu}]", "All free records: velocity-binned force")
    if not case_ids:
        msg = "no status-ok sine or free case in this campaign: nothing to show"
        for ax in (ax_s, ax_f):
            _empty_panel(ax, msg)
    if sine_ids or not case_ids:
        _draw_sine_overview(ax_s, table, loops, rows, colours, sine_ids, fs, bool(case_ids))
    if free_ids or not case_ids:
        _draw_free_overview(ax_f, table, colours, free_ids, fs, bool(case_ids))

    for (ax_v, ax_y), c in zip(axes[1:], shown, strict=True):
        row = rows.get(c, {"case": c, "waveform": "sine" if c in sine_ids else "free"})
        label = _case_label(row, loops[c])
        _axes_style(ax_v, "Velocity v [mm/s]", f"Force F [{fu}]", f"{label}\nforce against velocity")
        _axes_style(ax_y, "Displacement y [mm]", f"Force F [{fu}]", f"{c}\nforce against displacement")
        draw_row = _draw_sine_row if c in sine_ids else _draw_free_row
        draw_row(ax_v, ax_y, c, loops[c], table, colours[c], fs)
    if len(case_ids) > len(shown):
        note = (f"{len(case_ids) - len(shown)} more case(s) in the top panels only; " + note).strip("; ")
    footnote(fig, note, width=110)
    return fig


__all__ = ["MAX_CASE_ROWS", "harmonic_figure"]
