"""Fig. 18-19: campaigns compared (:mod:`isokinetic.stages.compare`).

Fig. 18 overlays the campaigns' steady characteristics, |F| against |v| on logarithmic axes (as
Fig. 11 and 14), one panel per direction: each campaign's measured points with bars of +-1.96 SE
(window noise and repeatability) and its fitted model over its measured speeds with the 95 %
prediction band. Fig. 19 draws, per direction, each campaign's difference to the reference against
|v| with bars of +-1.96 SE of the difference; filled markers are measured rows, open ones model rows,
and a red ring marks a significant row. A campaign keeps its colour in both figures (the reference
first). Artists carrying data have a ``gid`` (``points:<campaign>:+``, ``model:<campaign>:-``,
``band:...``, ``difference:<campaign>:+:measured``, ``significant:<campaign>:-``) for tests.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from isokinetic.plots.style import MM, footnote, force_unit, new_figure, plain_log_ticks, say_missing
from isokinetic.stats import Z_95

PANELS = (("+", "v > 0"), ("-", "v < 0, folded: |v|, |F|"))
COLOURS = ("black", "tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:olive")


def colour_of(campaigns: Sequence[str], campaign: str) -> str:
    """A campaign's colour, by its place in the comparison (the reference is black)."""
    return COLOURS[list(campaigns).index(campaign) % len(COLOURS)] if campaign in campaigns else "0.5"


def _folded(df: pd.DataFrame, direction: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """|v| [m/s], the force in the direction's sense (F for +, -F for -) and the SE, ordered by speed."""
    sub = df[df["direction"] == direction]
    sign = 1.0 if direction == "+" else -1.0
    v = np.abs(sub["velocity_m_s"].to_numpy(float))
    order = np.argsort(v, kind="stable")
    return v[order], sign * sub["force_N"].to_numpy(float)[order], sub["se_N"].to_numpy(float)[order]


def _draw_overlay_panel(ax, points: pd.DataFrame, curves: pd.DataFrame, campaigns: Sequence[str], direction: str,
                        fs: float) -> int:
    """One direction of Fig. 18; returns the number of points or curve samples not drawable on log axes."""
    dropped = 0
    for c in campaigns:
        colour = colour_of(campaigns, c)
        cv = curves[curves["campaign"] == c] if len(curves) else curves
        if len(cv):
            v, f, se = _folded(cv, direction)
            ok = f > 0
            dropped += int((~ok).sum())
            if ok.any():
                model = cv["model"].iloc[0]
                low = np.maximum(f - Z_95 * se, f * 1e-3)
                ax.fill_between(v[ok] * MM, low[ok] / fs, (f + Z_95 * se)[ok] / fs, color=colour, alpha=0.15, lw=0,
                                gid=f"band:{c}:{direction}")
                ax.plot(v[ok] * MM, f[ok] / fs, color=colour, lw=1.0, ls="--", gid=f"model:{c}:{direction}",
                        label=f"{c}: {model} fit, 95 % band")
        v, f, se = _folded(points[points["campaign"] == c], direction)
        ok = (f > 0) & (v > 0)
        dropped += int((~ok).sum())
        if ok.any():
            bars = ax.errorbar(v[ok] * MM, f[ok] / fs, yerr=Z_95 * se[ok] / fs, fmt="o", ms=4, color=colour,
                               mfc="white" if c != campaigns[0] else colour, capsize=2, lw=0.8,
                               label=f"{c}: measured" + (" (reference)" if c == campaigns[0] else ""))
            bars.lines[0].set_gid(f"points:{c}:{direction}")
    return dropped


def overlay_figure(points: pd.DataFrame, curves: pd.DataFrame, campaigns: Sequence[str], *, name: str = "") -> Figure:
    """Fig. 18: the campaigns' measured points and fitted models with their 95 % bands, both directions."""
    fig = new_figure(12.0, 5.5)
    fig.suptitle(f"{name}: steady characteristics of {len(campaigns)} campaigns (reference {campaigns[0]})",
                 fontsize=12)
    forces = np.abs(points["force_N"].to_numpy(float)) if len(points) else np.empty(0)
    fs, fu = force_unit(forces)
    for k, (direction, label) in enumerate(PANELS):
        ax = fig.add_subplot(1, 2, k + 1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"direction {direction} ({label})", fontsize=10)
        ax.set_xlabel("Piston velocity |v| [mm/s]")
        ax.set_ylabel(f"Steady force |F| [{fu}]")
        has = len(points) and (points["direction"] == direction).any()
        if not has:
            say_missing(ax, f"no points in direction {direction}")
            continue
        dropped = _draw_overlay_panel(ax, points, curves, campaigns, direction, fs)
        if dropped:
            ax.set_title(f"{dropped} point(s) with |F| <= 0 in this direction not drawn", fontsize=8, loc="right",
                         color="tab:red")
        plain_log_ticks(ax)
        ax.grid(True, which="major", color="0.88", lw=0.5)
        ax.legend(fontsize=7, loc="upper left")
    footnote(fig, "Points: each case's mean steady force, bars +-1.96 SE (window noise and period-to-period "
                  "repeatability). Dashed lines and bands: each campaign's fitted model over its own measured speeds "
                  "with its 95 % prediction band (parameter covariance and the scatter of the points about the "
                  "model).")
    return fig


def _draw_difference_panel(ax, table: pd.DataFrame, campaigns: Sequence[str], direction: str, fs: float) -> None:
    for c in campaigns[1:]:
        colour = colour_of(campaigns, c)
        sub = table[(table["campaign"] == c) & (table["direction"] == direction)]
        for measured, marker in ((True, "o"), (False, "s")):
            part = sub[(sub["basis"] == "measured") == measured]
            if part.empty:
                continue
            v = np.abs(part["velocity_m_s"].to_numpy(float)) * MM
            bars = ax.errorbar(v, part["difference_N"].to_numpy(float) / fs,
                               yerr=Z_95 * part["difference_se_N"].to_numpy(float) / fs, fmt=marker, ms=4.5,
                               color=colour, mfc=colour if measured else "white", capsize=2, lw=0.8,
                               label=f"{c}: " + ("measured" if measured else
                                                 f"both through the {part['basis'].iloc[0][6:]} fit"))
            bars.lines[0].set_gid(f"difference:{c}:{direction}:{'measured' if measured else 'model'}")
        sig = sub[sub["significant"]]
        if len(sig):
            ax.plot(np.abs(sig["velocity_m_s"].to_numpy(float)) * MM, sig["difference_N"].to_numpy(float) / fs,
                    ls="none", marker="o", ms=11, mfc="none", mec="tab:red", mew=1.4,
                    gid=f"significant:{c}:{direction}", label=f"{c}: significant")


def difference_figure(table: pd.DataFrame, campaigns: Sequence[str], *, name: str = "") -> Figure:
    """Fig. 19: each campaign's force minus the reference's against |v|, +-1.96 SE, both directions."""
    fig = new_figure(12.0, 5.0)
    fig.suptitle(f"{name}: force difference to the reference {campaigns[0]}", fontsize=12)
    extent = (table["difference_N"].abs() + Z_95 * table["difference_se_N"]).to_numpy(float) if len(table) else []
    fs, fu = force_unit(extent)
    for k, (direction, label) in enumerate(PANELS):
        ax = fig.add_subplot(1, 2, k + 1)
        ax.set_xscale("log")
        ax.set_title(f"direction {direction} ({label.split(',')[0]})", fontsize=10)
        ax.set_xlabel("Piston velocity |v| [mm/s]")
        ax.set_ylabel(f"F(campaign) - F(reference) [{fu}]")
        ax.axhline(0.0, color="0.4", lw=0.8)
        if not len(table) or not (table["direction"] == direction).any():
            say_missing(ax, f"no rows to compare in direction {direction}")
            continue
        _draw_difference_panel(ax, table, campaigns, direction, fs)
        plain_log_ticks(ax)
        ax.grid(True, which="major", color="0.88", lw=0.5)
        ax.legend(fontsize=7, loc="best")
    n, n_sig = len(table), int(table["significant"].sum()) if len(table) else 0
    alpha = float(table["alpha"].iloc[0]) if n else float("nan")
    footnote(fig, f"Bars: +-1.96 SE of the difference. Filled markers: measured points at matching velocities; open: "
                  f"both campaigns through their fitted model (velocities that do not match). Red rings: significant "
                  f"(two-sided z-test, alpha = {alpha:g}): {n_sig} of {n} rows, about {alpha * n:.1f} expected by "
                  "chance alone.")
    return fig


__all__ = ["COLOURS", "PANELS", "colour_of", "difference_figure", "overlay_figure"]
