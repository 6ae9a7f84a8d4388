"""Fig. 13-14: the identified characteristic against the nominal model, the fits and the harmonic data.

Figures of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs" (Titurus et al.), Sec. 4.5: Fig. 13 compares, on linear axes, the
measured characteristic with the nominal model (through the test plan and the Eq. (32) families
for C_D in {0.6, 0.7, 0.8}), the Wallaschek and Surace fits, and the harmonic-excitation (HE)
loops and peak-to-peak curve; Fig. 14 shows the same on log-log axes with quadrant 3 folded
into quadrant 1. The fitted models are evaluated by :func:`isokinetic.measurement.model_fit.model_force`;
the rule ``models`` (:mod:`isokinetic.stages.models`) fits them and writes both figures.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from isokinetic.measurement.model_fit import model_force
from isokinetic.plots.style import MM, footnote, force_unit, new_figure, plain_log_ticks, say_missing

_CD_COLOURS = {0.6: "tab:blue", 0.7: "tab:green", 0.8: "tab:olive"}


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------

def _has_rows(df: pd.DataFrame | None) -> bool:
    return df is not None and len(df) > 0


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


def _folded(df: pd.DataFrame | None) -> tuple[np.ndarray, np.ndarray]:
    """(|v|, |F|) of a table with velocity_m_s and force_N; empty arrays for no table."""
    if not _has_rows(df):
        return np.empty(0), np.empty(0)
    return np.abs(df["velocity_m_s"].to_numpy(float)), np.abs(df["force_N"].to_numpy(float))


def _new_comparison(title: str, size: tuple[float, float], char: pd.DataFrame | None, xlabel: str,
                    ylabel: str) -> tuple[Figure, Axes, float]:
    """Figure, axes and force divisor of Fig. 13/14; ``ylabel`` has a ``{}`` for the force unit."""
    fig = new_figure(*size)
    ax = fig.add_subplot()
    fig.suptitle(title, fontsize=12)
    fs, fu = force_unit(char["force_N"] if _has_rows(char) else [])
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel.format(fu))
    return fig, ax, fs


#: What the legends' abbreviation stands for (the paper's term for its sine tests, Sec. 4).
HE_NOTE = "HE: harmonic excitation (the sine tests, paper Sec. 4)"
#: What the nominal families' labels stand for (Eq. 32).
FAMILY_NOTE = "theory (Eq. 32): laminar-turbulent orifice flow solid, turbulent only dashed"


def _finish(fig: Figure, ax, notes: list[str]) -> Figure:
    """The legend right of the axes (off the data), the notes and what its abbreviations mean under them."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside right center", fontsize=7.5, frameon=False)
    if any(label.startswith("theory,") for label in labels):
        notes = [FAMILY_NOTE, *notes]
    if any("HE " in label for label in labels):
        notes = [HE_NOTE, *notes]
    footnote(fig, "; ".join(notes), fontsize=8)
    return fig


def _draw_families(ax, families: pd.DataFrame, fs: float) -> None:
    """The Eq. (32) nominal curves: 'T' dashed, 'L-T' solid, one colour (and one legend entry) per C_D."""
    for fam, ls in (("T", "--"), ("L-T", "-")):
        sub = families[families["family"] == fam]
        for i, (cd, g) in enumerate(sub.groupby("discharge_coefficient", sort=True)):
            g = g.sort_values("velocity_m_s")
            ax.plot(g["velocity_m_s"] * MM, g["force_N"] / fs, ls=ls, lw=0.9, color=_cd_colour(cd, i), zorder=2,
                    gid=f"family-{fam}-{cd:g}", label=f"theory, C_D = {cd:g} (Eq. 32)" if fam == "L-T" else None)


# ----------------------------------------------------------------------------------------------
# Fig. 13: linear axes
# ----------------------------------------------------------------------------------------------

def _linear_spans(char: pd.DataFrame, p2p: pd.DataFrame, loop_items) -> tuple[float, float]:
    """(largest |v| x 1.05, largest |F|) of the measured data: characteristic, HE loops and points."""
    spans_v = [char["velocity_m_s"], p2p["velocity_m_s"]] + [lp["velocity_m_s"] for _, lp in loop_items]
    spans_f = [char["force_N"], p2p["force_N"]] + [lp["force_N"] for _, lp in loop_items]
    vmax = max(float(np.nanmax(np.abs(np.asarray(s, dtype=float)))) for s in spans_v if len(s)) * 1.05
    fmax = max(float(np.nanmax(np.abs(np.asarray(s, dtype=float)))) for s in spans_f if len(s))
    return vmax, fmax


def _draw_fits(ax, models_df: pd.DataFrame, vx: np.ndarray, fs: float) -> None:
    fw = model_force(models_df, "wallaschek", vx)
    if np.isfinite(fw).any():
        ax.plot(vx * MM, fw / fs, color="black", lw=1.3, zorder=4, gid="wallaschek",
                label="Wallaschek fit (L–T + Coulomb)")
    for dirn, sel in (("+", vx > 0), ("-", vx < 0)):
        fsur = model_force(models_df, "surace", vx[sel])
        if np.isfinite(fsur).any():
            ax.plot(vx[sel] * MM, fsur / fs, color="tab:purple", lw=1.3, ls="-.", zorder=4, gid=f"surace{dirn}",
                    label="Surace fit (per direction)" if dirn == "+" else None)


#: How each method's measured points are drawn (the characteristic's ``method``; a table without it is all
#: triangle windows): name in the legend, colour, marker for v > 0 and for v < 0.
METHOD_STYLE = {"triangle_window": ("triangle", "black", "o", "*"), "sine_peak": ("sine peak", "tab:green", "D", "d"),
                "free_bin": ("free bin", "tab:blue", "s", "P")}


def _by_method(char: pd.DataFrame):
    """(method, its rows, its gid suffix, its legend name) per method of the characteristic, triangle first; the
    triangle windows keep the plain gids measured+/measured- (and so does a single method)."""
    methods = char["method"].fillna("triangle_window") if "method" in char else pd.Series("triangle_window",
                                                                                         index=char.index)
    present = [m for m in METHOD_STYLE if (methods == m).any()]
    for m in present:
        name = METHOD_STYLE[m][0]
        plain = m == "triangle_window" or len(present) == 1
        yield m, char[methods == m], "" if plain else f"-{m}", "" if len(present) == 1 else f" ({name})"


def _draw_measured(ax, char: pd.DataFrame, fs: float) -> None:
    """The measured points per method and direction, each method its own line (they are not one curve)."""
    for m, rows, suffix, name in _by_method(char):
        _, colour, up, down = METHOD_STYLE[m]
        for d, style in (("+", {"marker": up, "ls": "-", "label": f"measured{name}, v > 0"}),
                         ("-", {"marker": down, "ls": "--", "ms": 8, "label": f"measured{name}, v < 0"})):
            b = rows[rows["velocity_m_s"] > 0] if d == "+" else rows[rows["velocity_m_s"] < 0]
            b = b.sort_values("velocity_m_s")
            if len(b):
                ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color=colour, lw=0.8, mfc="white", zorder=6,
                        gid=f"measured{suffix}{d}", **{"ms": 5, **style})


def comparison_figure(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, families: pd.DataFrame | None,
                      models_df: pd.DataFrame | None, harmonic: pd.DataFrame | None = None,
                      loops: Mapping[str, pd.DataFrame] | None = None, *, campaign: str | None = None) -> Figure:
    """Fig. 13: measured characteristic, nominal model (through the plan and Eq. 32 families), fits, HE data.

    Linear axes, velocity in mm/s, force in N. ``families`` from
    :func:`isokinetic.measurement.model_fit.nominal_families` (None or empty: no damper block, said on the
    figure). Lines carry gids: measured+, measured-, nominal-plan, family-T-0.6 ..., wallaschek,
    surace+, surace-, peak-to-peak, loop-<case>. The axes span the measured data (characteristic,
    HE loops and peak-to-peak points); model curves are clipped.
    """
    name = campaign or _campaign(char, nominal_windows, models_df)
    fig, ax, _ = _new_comparison(f"{name}: measured and modelled damper characteristics (cf. paper Fig. 13)",
                                 (10.5, 6.5), char, "Piston velocity v [mm/s]", "Force F [{}]")
    damper_missing = families is None or len(families) == 0
    notes = _notes(damper_missing, char, nominal_windows, models_df)
    if not _has_rows(char):
        say_missing(ax, "no characteristic points (no usable triangle case)")
        footnote(fig, "; ".join(notes), width=0, fontsize=8)
        return fig
    p2p = _peak_to_peak(harmonic)
    loop_items = [(c, lp) for c, lp in sorted((loops or {}).items()) if lp is not None and len(lp)]
    vmax, fmax = _linear_spans(char, p2p, loop_items)
    fs, fu = force_unit([fmax])
    ax.set_ylabel(f"Force F [{fu}]")
    ylim = fmax * 1.15 / fs
    for i, (case, loop) in enumerate(loop_items):  # hysteresis loops (thin, behind)
        ax.plot(loop["velocity_m_s"].to_numpy(float) * MM, loop["force_N"].to_numpy(float) / fs, color="0.6", lw=0.5,
                alpha=0.8, zorder=1, gid=f"loop-{case}", label="HE force-velocity loops" if i == 0 else None)
    vx = np.linspace(-vmax, vmax, 401)
    if not damper_missing:
        _draw_families(ax, families, fs)
    if _has_rows(models_df):
        _draw_fits(ax, models_df, vx, fs)
    if len(p2p):
        ax.plot(p2p["velocity_m_s"].to_numpy(float) * MM, p2p["force_N"].to_numpy(float) / fs, color="tab:orange",
                lw=1.2, marker="D", ms=5, zorder=5, gid="peak-to-peak", label="HE peak-to-peak curve")
    if _has_rows(nominal_windows):
        ax.plot(nominal_windows["velocity_m_s"] * MM, nominal_windows["force_N"] / fs, ls="none", marker="x", ms=6,
                color="tab:brown", zorder=5, gid="nominal-plan",
                label="nominal model through the plan (same windows)")
    _draw_measured(ax, char, fs)
    ax.set_xlim(-vmax * MM, vmax * MM)
    ax.set_ylim(-ylim, ylim)
    ax.axhline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.axvline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.grid(True, color="0.9", lw=0.5, zorder=0)
    return _finish(fig, ax, notes)


# ----------------------------------------------------------------------------------------------
# Fig. 14: log-log axes, quadrant 3 folded
# ----------------------------------------------------------------------------------------------

def _draw_fits_folded(ax, models_df: pd.DataFrame, vx: np.ndarray, fs: float) -> None:
    fw = model_force(models_df, "wallaschek", vx)
    if np.isfinite(fw).any():
        ax.plot(vx * MM, np.abs(fw) / fs, color="black", lw=1.3, zorder=4, gid="wallaschek", label="Wallaschek fit")
    for dirn, sgn, ls in (("+", 1.0, "-."), ("-", -1.0, ":")):
        fsur = model_force(models_df, "surace", sgn * vx)
        if np.isfinite(fsur).any():
            ax.plot(vx * MM, np.abs(fsur) / fs, color="tab:purple", lw=1.3, ls=ls, zorder=4, gid=f"surace{dirn}",
                    label=f"Surace fit, {'v > 0' if dirn == '+' else 'v < 0 folded'}")


def _draw_peak_to_peak_folded(ax, p2p: pd.DataFrame, fs: float) -> None:
    """The HE peak-to-peak curve, v > 0 solid and v < 0 folded dashed (gids peak-to-peak+/-)."""
    pv, pf = _folded(p2p)
    p_ok = (pv > 0) & (pf > 0)
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


def _draw_nominal_folded(ax, nominal_windows: pd.DataFrame, fs: float, f_lo: float, f_hi: float
                         ) -> tuple[float, float]:
    """The nominal model through the plan, folded; returns the force range widened to show it."""
    nv, nf = _folded(nominal_windows)
    ok = (nv > 0) & (nf > 0)
    ax.plot(nv[ok] * MM, nf[ok] / fs, ls="none", marker="x", ms=6, color="tab:brown", zorder=5, gid="nominal-plan",
            label="nominal model through the test plan, folded")
    if ok.any():
        f_lo, f_hi = min(f_lo, nf[ok].min() / 2.0), max(f_hi, nf[ok].max() * 1.5)
    return f_lo, f_hi


def _draw_measured_folded(ax, char: pd.DataFrame, fs: float) -> None:
    for m, rows, suffix, name in _by_method(char):
        _, colour, up, down = METHOD_STYLE[m]
        for d, style in (("+", {"marker": up, "ls": "-", "ms": 5, "color": colour,
                                "label": f"measured{name}, quadrant 1 (v > 0)"}),
                         ("-", {"marker": down, "ls": "--", "ms": 8, "color": "tab:red" if suffix == "" else colour,
                                "label": f"measured{name}, quadrant 3 folded (|v|, |F|)"})):
            bv, bf = _folded(rows[rows["velocity_m_s"] > 0] if d == "+" else rows[rows["velocity_m_s"] < 0])
            ok = (bv > 0) & (bf > 0)
            o = np.argsort(bv[ok])
            if ok.any():
                ax.plot(bv[ok][o] * MM, bf[ok][o] / fs, lw=0.8, mfc="white", zorder=6, gid=f"measured{suffix}{d}",
                        **style)


def comparison_loglog_figure(char: pd.DataFrame, nominal_windows: pd.DataFrame | None, families: pd.DataFrame | None,
                             models_df: pd.DataFrame | None, harmonic: pd.DataFrame | None = None, *,
                             campaign: str | None = None) -> Figure:
    """Fig. 14: the comparison of :func:`comparison_figure` as |F| against |v| (quadrant 3 folded).

    Quadrant-1 data solid with circles, quadrant-3 data dashed with stars; the Surace '-' branch and
    the nominal points are folded likewise. HE loops are not drawn here (folded, a loop is a band,
    not a curve); the peak-to-peak curve is.
    """
    name = campaign or _campaign(char, nominal_windows, models_df)
    fig, ax, fs = _new_comparison(f"{name}: damper characteristics in the logarithmic domain (cf. paper Fig. 14)",
                                  (10.5, 7.0), char, "Piston velocity |v| [mm/s]", "Force |F| [{}]")
    ax.set_xscale("log")
    ax.set_yscale("log")
    damper_missing = families is None or len(families) == 0
    notes = _notes(damper_missing, char, nominal_windows, models_df)
    av, af = _folded(char)
    keep = (av > 0) & (af > 0)
    if not keep.any():
        say_missing(ax, "no characteristic points with non-zero velocity and force")
        footnote(fig, "; ".join(notes), width=0, fontsize=8)
        return fig
    pv, pf = _folded(_peak_to_peak(harmonic))
    p_ok = (pv > 0) & (pf > 0)
    sv, sf = np.concatenate([av[keep], pv[p_ok]]), np.concatenate([af[keep], pf[p_ok]])
    v_lo, v_hi = sv.min() / 1.5, sv.max() * 1.5
    f_lo, f_hi = sf.min() / 2.0, sf.max() * 3.0
    vx = np.geomspace(v_lo, v_hi, 200)
    if not damper_missing:
        _draw_families(ax, families[families["velocity_m_s"] > 0], fs)
    if _has_rows(models_df):
        _draw_fits_folded(ax, models_df, vx, fs)
    if p_ok.any():
        _draw_peak_to_peak_folded(ax, _peak_to_peak(harmonic), fs)
    if _has_rows(nominal_windows):
        f_lo, f_hi = _draw_nominal_folded(ax, nominal_windows, fs, f_lo, f_hi)
    _draw_measured_folded(ax, char, fs)
    ax.set_xlim(v_lo * MM, v_hi * MM)
    ax.set_ylim(f_lo / fs, f_hi / fs)
    plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.88", lw=0.5)
    ax.grid(True, which="minor", color="0.95", lw=0.4)
    return _finish(fig, ax, notes)


__all__ = ["comparison_figure", "comparison_loglog_figure"]
