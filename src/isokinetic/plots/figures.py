"""Fig. 7-12: the primary processing and the steady characteristic of one campaign.

Figures of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs" (Titurus et al.), Sec. 4.4-4.5: Fig. 7 (three triangle cases in the time
and displacement-force domains), Fig. 8 (window selection), Fig. 9 (steady characteristic),
Fig. 10 (its low-velocity detail), Fig. 11 (log-log with the alpha families) and Fig. 12 (force
noise per segment).

Every public function takes DataFrames in the pipeline's SI schemas (:mod:`isokinetic.contracts.tables`) and
returns a :class:`matplotlib.figure.Figure` (:func:`isokinetic.plots.style.new_figure`). Units are
converted only here, at the plot edge: time in s, displacement in mm, velocity in mm/s, force in N
(as in every table; :func:`isokinetic.plots.style.force_unit`). Functions never raise on thin data: when a
campaign has few or no usable cases, they draw what exists and say on the figure what is missing.

The rule ``figures`` (:mod:`isokinetic.stages.figures`) reads a campaign's tables, chooses the
cases and writes the six PNGs. Lines carrying data have a ``gid`` (``"period1"``, ``"window"``,
``"alpha-1"``, ...) so tests and callers can find them without relying on colours or order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from isokinetic.plots.style import MM, force_unit, new_figure, plain_log_ticks, say_missing

if TYPE_CHECKING:  # matplotlib only where a figure is drawn: the campaign report asks applies() alone
    from matplotlib.figure import Figure

ALPHAS = (0, 1, 2)
_ALPHA_STYLE = {0: ("tab:green", "friction-like"), 1: ("tab:blue", "laminar"), 2: ("tab:purple", "turbulent")}
_SEGMENT_STYLE = {  # (colour, linestyle, marker): the two '+' segments alike, the two '-' segments alike
    1: ("tab:blue", "-", "o"), 3: ("tab:cyan", "--", "s"),
    2: ("tab:red", "-", "o"), 4: ("tab:orange", "--", "s"),
}


# ----------------------------------------------------------------------------------------------
# small helpers
# ----------------------------------------------------------------------------------------------

def campaign_name(campaign: str | None, *frames: pd.DataFrame | None) -> str:
    """Explicit name, else the single value of a ``campaign`` column, else 'campaign ?'."""
    if campaign:
        return str(campaign)
    for df in frames:
        if df is not None and "campaign" in df and len(df):
            names = sorted(set(df["campaign"].dropna().astype(str)))
            if names:
                return "+".join(names)
    return "campaign ?"


def _markevery(n: int, target: int = 40) -> int:
    return max(1, int(math.ceil(n / target)))


def _sym_lim(values, pad: float = 1.12) -> float:
    a = np.abs(np.asarray(values, dtype=float))
    a = a[np.isfinite(a)]
    m = float(a.max()) if a.size else 0.0
    return m * pad if m > 0 else 1.0


def case_speed_m_s(char: pd.DataFrame) -> pd.Series:
    """Mean measured |velocity| of each case in a windows/characteristic table, ascending."""
    if char is None or char.empty:
        return pd.Series(dtype=float)
    return char.assign(_a=char["velocity_m_s"].abs()).groupby("case")["_a"].mean().sort_values(kind="stable")


def _branch(df: pd.DataFrame, direction: str) -> pd.DataFrame:
    return df[df["direction"] == direction].sort_values("velocity_m_s", kind="stable")


def _case_row_dict(case_row) -> dict:
    if case_row is None:
        return {}
    if isinstance(case_row, pd.DataFrame):
        return case_row.iloc[0].to_dict() if len(case_row) else {}
    if isinstance(case_row, pd.Series):
        return case_row.to_dict()
    return dict(case_row)


def _case_title(row: Mapping) -> str:
    case = str(row.get("case") or "")
    amp, per = row.get("amplitude_m"), row.get("period_s")
    try:
        amp, per = float(amp), float(per)
    except (TypeError, ValueError):
        return case
    if not (math.isfinite(amp) and math.isfinite(per) and per > 0):
        return case
    return f"{case}: |v| = {4 * amp / per * MM:.3g} mm/s (T = {per:g} s, Y = {amp * MM:.3g} mm)"


def _window_mask(series: pd.DataFrame, w: Mapping) -> np.ndarray:
    """Samples of one window: the half-open ``row`` range, else (no ``row`` column) the time range."""
    if "row" in series:
        rows = series["row"].to_numpy()
        return (rows >= int(w["row_start"])) & (rows < int(w["row_stop"]))
    t = series["time_s"].to_numpy()
    return (t >= float(w["window_start_s"])) & (t <= float(w["window_end_s"]))


# ----------------------------------------------------------------------------------------------
# Fig. 7: three cases in the time and displacement-force domains
# ----------------------------------------------------------------------------------------------

def time_and_loops(cases: pd.DataFrame, series_by_case: Mapping[str, pd.DataFrame], case_ids: Sequence[str],
                   *, campaign: str | None = None) -> Figure:
    """Fig. 7: per case, force and displacement vs time (left) and the displacement-force loop (right).

    Force is on the left axis, displacement on a secondary axis; both are symmetric about zero, so
    the displacement triangle is a symmetric guide for the force asymmetry (as in the paper).
    """
    name = campaign_name(campaign, cases)
    case_ids = [str(c) for c in case_ids]
    n_rows = max(1, len(case_ids))
    fig = new_figure(11.0, 1.2 + 2.7 * n_rows)
    axes = fig.subplots(n_rows, 2, squeeze=False, gridspec_kw={"width_ratios": [2.2, 1.0]})
    fig.suptitle(f"{name}: triangle test cases in the time and displacement\u2013force domains", fontsize=12)
    by_case = {} if cases is None or cases.empty else {str(r["case"]): r for _, r in cases.iterrows()}

    if not case_ids:
        for ax in axes[0]:
            say_missing(ax, "no status-ok triangle case to show")
            ax.set_axis_off()
        return fig

    for (ax_t, ax_l), case in zip(axes, case_ids, strict=True):
        row = by_case.get(case, {"case": case})
        title = _case_title(row)
        s = series_by_case.get(case)
        if s is None or s.empty:
            ax_t.set_title(title, fontsize=10, loc="left")
            say_missing(ax_t, f"{case}: time series missing")
            say_missing(ax_l, f"{case}: time series missing")
            for ax in (ax_t, ax_l):
                ax.set_xticks([])
                ax.set_yticks([])
            continue
        t = s["time_s"].to_numpy(dtype=float)
        f_N = s["force_N"].to_numpy(dtype=float)
        y_mm = s["displacement_m"].to_numpy(dtype=float) * MM
        fs, fu = force_unit(f_N)
        f = f_N / fs

        ax_t.plot(t, f, color="black", lw=0.6, label="force", gid="force")
        ax_t.set_ylim(-_sym_lim(f), _sym_lim(f))
        ax_t.axhline(0.0, color="0.6", lw=0.5, zorder=0)
        ax_t.set_xlabel("Time t [s]")
        ax_t.set_ylabel(f"Force F [{fu}]")
        ax_t.set_xlim(t.min(), t.max())
        ax_t.set_title(title, fontsize=10, loc="left")
        ax_y = ax_t.twinx()
        ax_y.plot(t, y_mm, color="tab:blue", lw=1.0, alpha=0.8, label="displacement (right axis)",
                  gid="displacement")
        ax_y.set_ylim(-_sym_lim(y_mm), _sym_lim(y_mm))
        ax_y.set_ylabel("Displacement y [mm]", color="tab:blue")
        ax_y.tick_params(axis="y", colors="tab:blue")
        if not fig.legends:  # one legend for all rows, under the title, clear of the data
            handles = ax_t.get_lines()[:1] + ax_y.get_lines()[:1]
            fig.legend(handles=handles, loc="outside lower right", ncol=2, fontsize=8.5, frameon=False)

        ax_l.plot(y_mm, f, color="black", lw=0.6, gid="loop")
        ax_l.axhline(0.0, color="0.6", lw=0.5, zorder=0)
        ax_l.axvline(0.0, color="0.6", lw=0.5, zorder=0)
        ax_l.set_ylim(-_sym_lim(f), _sym_lim(f))
        ax_l.set_xlabel("Displacement y [mm]")
        ax_l.set_ylabel(f"Force F [{fu}]")
        ax_l.set_title("displacement\u2013force", fontsize=10, loc="left")
    return fig


# ----------------------------------------------------------------------------------------------
# Fig. 8: window selection of one case
# ----------------------------------------------------------------------------------------------

def window_selection(case_row, series: pd.DataFrame | None, windows_of_case: pd.DataFrame | None,
                     *, campaign: str | None = None) -> Figure:
    """Fig. 8: force vs time with the steady-force windows, displacement with the velocity-fit samples.

    Window samples are black lines with dots (gid ``window``), the velocity-fit samples thick grey
    lines with dots on the displacement axis (gid ``velocity-fit``; the same row range as the
    window), and mean +/- std as lines with '+' markers (gids ``window-mean``, ``window-std``).
    """
    from matplotlib.lines import Line2D

    row = _case_row_dict(case_row)
    w = windows_of_case if windows_of_case is not None else pd.DataFrame()
    name = campaign_name(campaign, w, pd.DataFrame([row]) if row else None)
    fig = new_figure(11.0, 5.2)
    ax = fig.add_subplot()
    fig.suptitle(f"{name}: identification of the steady force levels", fontsize=12)
    ax.set_title(_case_title(row), fontsize=10, loc="left")
    ax.set_xlabel("Time t [s]")
    if series is None or series.empty:
        ax.set_ylabel("Force F [N]")
        say_missing(ax, f"{row['case']}: time series missing" if row.get("case") else
                     "no status-ok triangle case to show")
        return fig

    t = series["time_s"].to_numpy(dtype=float)
    f_N = series["force_N"].to_numpy(dtype=float)
    y_mm = series["displacement_m"].to_numpy(dtype=float) * MM
    fs, fu = force_unit(f_N)
    f = f_N / fs
    ax.plot(t, f, color="0.55", lw=0.5, label="measured force", zorder=1, gid="force")
    ax.axhline(0.0, color="0.6", lw=0.5, zorder=0)
    ax.set_ylabel(f"Force F [{fu}]")
    ax.set_xlim(t.min(), t.max())
    ax.set_ylim(-_sym_lim(f, 1.75), _sym_lim(f, 1.75))
    ax_y = ax.twinx()
    ax_y.plot(t, y_mm, color="tab:blue", lw=0.8, label="displacement (right axis)", zorder=1, gid="displacement")
    ax_y.set_ylim(-_sym_lim(y_mm, 1.75), _sym_lim(y_mm, 1.75))
    ax_y.set_ylabel("Displacement y [mm]", color="tab:blue")
    ax_y.tick_params(axis="y", colors="tab:blue")

    if w.empty:
        say_missing(ax, f"{row.get('case', '?')}: no constant-velocity windows identified")
    for _, win in w.sort_values(["window_start_s", "segment"], kind="stable").iterrows():
        m = _window_mask(series, win)
        if not m.any():
            continue
        tw = t[m]
        ax.plot(tw, f[m], color="black", lw=1.0, marker=".", ms=4, markevery=_markevery(m.sum()),
                zorder=3, gid="window")
        ax_y.plot(tw, y_mm[m], color="0.45", lw=4.0, alpha=0.6, marker=".", ms=4, mfc="black", mec="black",
                  markevery=_markevery(m.sum()), zorder=2, gid="velocity-fit")
        mean, std = float(win["force_N"]) / fs, float(win["force_std_N"]) / fs
        t0, t1 = float(win["window_start_s"]), float(win["window_end_s"])
        ax.plot([t0, t1], [mean, mean], color="tab:orange", lw=1.6, zorder=4, gid="window-mean")
        for level in (mean - std, mean + std):
            ax.plot([t0, (t0 + t1) / 2, t1], [level] * 3, color="tab:orange", lw=0.9, marker="+", ms=8,
                    zorder=4, gid="window-std")
        sign = 1.0 if mean >= 0 else -1.0
        ax.annotate(f"seg {int(win['segment'])} ({win['direction']})\nv = {float(win['velocity_m_s']) * MM:+.3g} mm/s"
                    f"\nF = {mean:.3g} \u00b1 {std:.2g} {fu}",
                    xy=((t0 + t1) / 2, mean), xytext=(0, 10 * sign), textcoords="offset points",
                    ha="center", va="bottom" if sign > 0 else "top", fontsize=7.5,
                    bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.7", "alpha": 0.85}, zorder=5)

    handles = [Line2D([], [], color="0.55", lw=0.8, label="measured force"),
               Line2D([], [], color="black", lw=1.0, marker=".", label="window samples (steady force)"),
               Line2D([], [], color="tab:orange", lw=1.6, label="window mean force"),
               Line2D([], [], color="tab:orange", lw=0.9, marker="+", ms=8, label="mean \u00b1 std"),
               Line2D([], [], color="tab:blue", lw=0.8, label="displacement (right axis)"),
               Line2D([], [], color="0.45", lw=4.0, alpha=0.6, marker=".", mfc="black", mec="black",
                      label="velocity-fit samples (right axis)")]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, fontsize=8, frameon=False)
    return fig


# ----------------------------------------------------------------------------------------------
# Fig. 9 / 10: the characteristic and its low-velocity detail
# ----------------------------------------------------------------------------------------------

#: Markers of the characteristic's non-triangle points: method -> (label, plot style).
_METHOD_STYLE = {
    "sine_peak": ("periodic records: force at peak velocity", {"color": "tab:green", "marker": "D", "ms": 5,
                                                                "lw": 1.0, "mfc": "white", "mew": 1.1}),
    "free_bin": ("quasi-static free records: velocity bins", {"color": "tab:purple", "marker": ".", "ms": 5,
                                                              "lw": 0.8}),
}
#: What each method's points are called in a title.
_METHOD_WORDS = {"triangle_window": "triangle tests", "sine_peak": "periodic records, force at peak velocity",
                 "free_bin": "quasi-static free records, velocity bins"}
#: A peak point resting on this many cycles or fewer is marked (it has little or no standard error).
FEW_CYCLES = 2


def methods_of(char: pd.DataFrame | None) -> list[str]:
    """The measuring methods of a characteristic's rows, in :data:`_METHOD_WORDS` order (triangle windows
    when the table has no ``method`` column)."""
    if char is None or char.empty:
        return []
    if "method" not in char:
        return ["triangle_window"]
    present = set(char["method"].astype(str))
    return [m for m in _METHOD_WORDS if m in present]


def _draw_other_methods(ax, char: pd.DataFrame, fs: float) -> None:
    """Peak-velocity points of periodic records and quasi-static free records' bins, one line per case and
    direction (gid = the method); peak points resting on ``FEW_CYCLES`` cycles or fewer ringed (gid
    'few-cycles')."""
    few = []
    for method, (label, style) in _METHOD_STYLE.items():
        rows = char[char["method"] == method]
        labelled = False
        for (_case, d), g in rows.groupby(["case", "direction"], sort=True):
            b = _branch(g, d)
            if method == "sine_peak":                 # one point a direction: the periods' mean
                b = pd.DataFrame({"velocity_m_s": [b["velocity_m_s"].mean()], "force_N": [b["force_N"].mean()]})
                if int(g["n_samples"].sum()) <= FEW_CYCLES:
                    few.append((float(b["velocity_m_s"].iloc[0]), float(b["force_N"].iloc[0])))
            ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, zorder=3, gid=method,
                    label=None if labelled else label, **style)
            labelled = True
        if method == "sine_peak" and len(rows):     # the steps joined, per direction
            for d in ("+", "-"):
                m = _branch(rows, d).groupby("case")[["velocity_m_s", "force_N"]].mean().sort_values("velocity_m_s")
                if len(m) > 1:
                    ax.plot(m["velocity_m_s"] * MM, m["force_N"] / fs, color=style["color"], lw=0.8, zorder=2,
                            gid="sine_peak-curve")
    if few:
        v, f = np.array(few).T
        ax.plot(v * MM, f / fs, ls="none", marker="o", ms=11, mfc="none", mec="tab:orange", mew=1.3, zorder=4,
                gid="few-cycles", label=f"resting on {FEW_CYCLES} cycles or fewer ({len(few)} point(s))")


def _draw_characteristic(ax, char: pd.DataFrame, fs: float) -> None:
    """Period 2 as a thick grey line behind, period 1 as circles + line in front, flagged ringed; sine and
    free points (``method``) in their own markers (:func:`_draw_other_methods`)."""
    if "method" in char:
        _draw_other_methods(ax, char, fs)
        char = char[char["method"] == "triangle_window"]
    p2, p1 = char[char["period"] == 2], char[char["period"] == 1]
    labelled = False
    for d in ("+", "-"):
        b = _branch(p2, d)
        if len(b):
            ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color="0.72", lw=5.0, solid_capstyle="round",
                    marker="o", ms=7, zorder=1, gid="period2",  # marker: a lone point still shows
                    label=None if labelled else "period 2 (segments 3, 4)")
            labelled = True
    labelled = False
    for d in ("+", "-"):
        b = _branch(p1, d)
        if len(b):
            ax.plot(b["velocity_m_s"] * MM, b["force_N"] / fs, color="black", lw=1.0, marker="o", ms=5,
                    mfc="white", mew=1.1, zorder=3, gid="period1",
                    label=None if labelled else "period 1 (segments 1, 2)")
            labelled = True
    if "repeatability_flagged" in char:
        fl = char[char["repeatability_flagged"].astype(bool)]
        if len(fl):
            ax.plot(fl["velocity_m_s"] * MM, fl["force_N"] / fs, ls="none", marker="s", ms=10, mfc="none",
                    mec="tab:red", mew=1.2, zorder=4, gid="flagged",
                    label=f"repeatability flagged ({fl['case'].nunique()} case(s))")
    ax.axhline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.axvline(0.0, color="0.5", lw=0.6, zorder=0)
    ax.grid(True, color="0.9", lw=0.5, zorder=0)


def characteristic(char: pd.DataFrame, *, campaign: str | None = None) -> Figure:
    """Fig. 9: steady force vs velocity, quadrants 1 and 3; period 1 in front, period 2 behind (grey)."""
    name = campaign_name(campaign, char)
    fig = new_figure(8.0, 6.0)
    ax = fig.add_subplot()
    how = "; ".join(_METHOD_WORDS[m] for m in methods_of(char)) or "triangle tests"
    fig.suptitle(f"{name}: steady damper characteristic ({how})", fontsize=12)
    fs, fu = force_unit(char["force_N"] if char is not None and len(char) else [])
    ax.set_xlabel("Piston velocity v [mm/s]")
    ax.set_ylabel(f"Steady force F [{fu}]")
    if char is None or char.empty:
        say_missing(ax, "no characteristic points (no usable triangle, sine or free case)")
        return fig
    _draw_characteristic(ax, char, fs)
    ax.legend(loc="upper left", fontsize=9)
    n = char["case"].nunique()
    ax.set_title(f"{n} case(s), {len(char)} {'windows' if methods_of(char) == ['triangle_window'] else 'points'}",
                 fontsize=9, loc="right", color="0.3")
    return fig


def _low_velocity_cut(char: pd.DataFrame) -> tuple[pd.DataFrame, float]:
    """Rows of the slowest ceil(n/3) cases and the largest |v| among them."""
    speed = case_speed_m_s(char)
    k = max(1, math.ceil(len(speed) / 3))
    slow = set(speed.index[:k])
    sub = char[char["case"].isin(slow)]
    return sub, float(sub["velocity_m_s"].abs().max()) if len(sub) else math.nan


def _intercept(b: pd.DataFrame, k: int = 3) -> tuple[float, float, float] | None:
    """Straight line through the k slowest points of a branch: (F at v=0, slope, farthest fitted v)."""
    b = b.assign(_a=b["velocity_m_s"].abs()).sort_values("_a", kind="stable").head(k)
    v, f = b["velocity_m_s"].to_numpy(float), b["force_N"].to_numpy(float)
    if len(v) < 2 or np.ptp(v) <= 0:
        return None
    slope, f0 = np.polyfit(v, f, 1)
    return float(f0), float(slope), float(v[np.argmax(np.abs(v))])


def low_velocity_detail(char: pd.DataFrame, v_max_m_s: float | None = None, *, campaign: str | None = None) -> Figure:
    """Fig. 10: the low-velocity part of the characteristic, non-zero force as v -> 0 and asymmetry.

    Default range: the slowest third of the cases (by mean measured |v|); else rows with
    |v| <= ``v_max_m_s``. Besides the characteristic (as in Fig. 9), quadrant 3 is mirrored into
    quadrant 1 (dashed, gid ``mirrored``) to show the asymmetry, and a straight line through the three
    slowest period-1 points of each direction is extended to v = 0 (dotted, gid ``extrapolation``).
    """
    name = campaign_name(campaign, char)
    fig = new_figure(8.0, 6.0)
    ax = fig.add_subplot()
    ax.set_xlabel("Piston velocity v [mm/s]")
    if char is None or char.empty:
        fig.suptitle(f"{name}: low-velocity detail of the characteristic", fontsize=12)
        ax.set_ylabel("Steady force F [N]")
        say_missing(ax, "no characteristic points (no usable triangle case)")
        return fig
    if v_max_m_s is None:
        sub, vmax = _low_velocity_cut(char)
        how = f"slowest {sub['case'].nunique()} of {char['case'].nunique()} cases"
    else:
        vmax = float(v_max_m_s)
        sub = char[char["velocity_m_s"].abs() <= vmax]
        how = f"|v| \u2264 {vmax * MM:.3g} mm/s"
    fig.suptitle(f"{name}: low-velocity detail of the characteristic ({how})", fontsize=12)
    fs, fu = force_unit(sub["force_N"] if len(sub) else [])
    ax.set_ylabel(f"Steady force F [{fu}]")
    if sub.empty:
        say_missing(ax, f"no characteristic points with {how}")
        return fig
    _draw_characteristic(ax, sub, fs)
    p1 = sub[sub["period"] == 1]
    neg = _branch(p1, "-")
    if len(neg):
        ax.plot(-neg["velocity_m_s"] * MM, -neg["force_N"] / fs, color="tab:red", lw=1.0, ls="--", marker="*",
                ms=7, zorder=2, gid="mirrored", label="quadrant 3 mirrored (\u2212v, \u2212F), period 1")
    no_fit = []
    for d, colour, side in (("+", "black", "0\u207a"), ("-", "tab:red", "0\u207b")):
        fit = _intercept(_branch(p1, d))
        if fit is None:
            no_fit.append(d)
            continue
        f0, slope, v_far = fit
        vv = np.array([0.0, v_far])
        ax.plot(vv * MM, (f0 + slope * vv) / fs, color=colour, lw=0.9, ls=":", zorder=2, gid="extrapolation")
        ax.plot([0.0], [f0 / fs], ls="none", marker="X", ms=8, color=colour, zorder=5, gid="intercept",
                label=f"linear extrapolation of 3 slowest points: F(v\u2192{side}) = {f0 / fs:.3g} {fu}")
    if no_fit:
        ax.set_title(f"fewer than 2 speeds in direction {' and '.join(no_fit)}: no extrapolation to v = 0",
                     fontsize=9, loc="right", color="tab:red")
    ax.legend(loc="lower right", fontsize=8.5)
    return fig


# ----------------------------------------------------------------------------------------------
# Fig. 11: log-log with the alpha families
# ----------------------------------------------------------------------------------------------

def loglog_characteristic(char: pd.DataFrame, *, campaign: str | None = None, n_lines: int = 4) -> Figure:
    """Fig. 11: |F| vs |v| log-log; quadrant 1 circles + solid, quadrant 3 folded stars + dashed.

    Period 1 only (period 2 is compared in Fig. 9 and the repeatability table). Thin families of
    lines F = C v^alpha, alpha in {0, 1, 2}, with ``n_lines`` C values each spanning the data
    (gids ``alpha-0``, ``alpha-1``, ``alpha-2``). Points with zero |v| or |F| cannot be drawn and are
    counted in the title.
    """
    name = campaign_name(campaign, char)
    fig = new_figure(8.0, 6.5)
    ax = fig.add_subplot()
    fig.suptitle(f"{name}: characteristic in the logarithmic domain", fontsize=12)
    ax.set_xlabel("Piston velocity |v| [mm/s]")
    p1 = char[char["period"] == 1] if char is not None and len(char) else pd.DataFrame()
    fs, fu = force_unit(p1["force_N"] if len(p1) else [])
    ax.set_ylabel(f"Steady force |F| [{fu}]")
    pts = []
    # triangle windows as lines (gids q1, q3-folded); sine and free points as markers of their own
    groups = [(m, p1[p1["method"] == m]) for m in methods_of(p1)] if "method" in p1 else [("triangle_window", p1)]
    for method, rows in groups or [("triangle_window", p1)]:
        for d, style in (("+", {"color": "black", "ls": "-", "marker": "o", "ms": 6, "mfc": "white", "mew": 1.1,
                                    "label": "quadrant 1 (v > 0)"}),
                         ("-", {"color": "tab:red", "ls": "--", "marker": "*", "ms": 9,
                                    "label": "quadrant 3 folded (|v|, |F|)"})):
            gid = "q1" if d == "+" else "q3-folded"
            if method != "triangle_window":
                label, own = _METHOD_STYLE[method]
                style = {**style, "color": own["color"], "ls": "none", "label": f"{label}, {style['label']}"}
                gid = f"{gid}-{method}"
            b = _branch(rows, d) if len(rows) else pd.DataFrame(columns=["velocity_m_s", "force_N"])
            v = np.abs(b["velocity_m_s"].to_numpy(float)) * MM
            f = np.abs(b["force_N"].to_numpy(float)) / fs
            keep = (v > 0) & (f > 0) & np.isfinite(v) & np.isfinite(f)
            order = np.argsort(v[keep], kind="stable")
            pts.append((v[keep][order], f[keep][order], int((~keep).sum())))
            if keep.any():
                ax.plot(v[keep][order], f[keep][order], lw=1.0, zorder=3, gid=gid, **style)
    v_all = np.concatenate([p[0] for p in pts])
    f_all = np.concatenate([p[1] for p in pts])
    dropped = sum(p[2] for p in pts)
    if v_all.size == 0:
        ax.set_xscale("log")
        ax.set_yscale("log")
        say_missing(ax, "no characteristic points with non-zero velocity and force")
        return fig
    ax.set_xscale("log")
    ax.set_yscale("log")
    v_lo, v_hi = v_all.min() / 1.6, v_all.max() * 1.6
    f_lo, f_hi = f_all.min() / 2.5, f_all.max() * 2.5
    if v_hi / v_lo < 100:  # few speeds: keep two decades so the slopes read and two ticks are labelled
        c = math.sqrt(v_lo * v_hi)
        v_lo, v_hi = c / 10, c * 10
    if f_hi / f_lo < 100:
        c = math.sqrt(f_lo * f_hi)
        f_lo, f_hi = c / 10, c * 10
    vx = np.geomspace(v_lo, v_hi, 50)
    for alpha in ALPHAS:
        colour, meaning = _ALPHA_STYLE[alpha]
        log_c = np.log10(f_all) - alpha * np.log10(v_all)
        lo, hi = float(log_c.min()), float(log_c.max())
        if hi - lo < 0.3:
            lo, hi = lo - 0.5, hi + 0.5
        for i, lc in enumerate(np.linspace(lo, hi, n_lines)):
            ax.plot(vx, 10 ** lc * vx ** alpha, color=colour, lw=0.6, alpha=0.7, zorder=1, gid=f"alpha-{alpha}",
                    label=f"\u03b1 = {alpha}: F = C\u00b7v$^{alpha}$ ({meaning}), {n_lines} values of C"
                    if i == 0 else None)
    ax.set_xlim(v_lo, v_hi)
    ax.set_ylim(f_lo, f_hi)
    plain_log_ticks(ax)
    ax.grid(True, which="major", color="0.88", lw=0.5)
    ax.grid(True, which="minor", color="0.95", lw=0.4)
    ax.legend(loc="upper left", fontsize=8)
    if dropped:
        ax.set_title(f"{dropped} point(s) with zero |v| or |F| not drawn", fontsize=9, loc="right", color="tab:red")
    return fig


# ----------------------------------------------------------------------------------------------
# Fig. 12: noise
# ----------------------------------------------------------------------------------------------

def noise(char: pd.DataFrame, *, campaign: str | None = None) -> Figure:
    """Fig. 12: force std within each window per case and segment (top), std / |mean force| (bottom).

    Cases are ordered by mean measured |v| (the paper's test number), one line per segment 1-4.
    """
    name = campaign_name(campaign, char)
    fig = new_figure(9.0, 7.0)
    ax_s, ax_r = fig.subplots(2, 1, sharex=True)
    fig.suptitle(f"{name}: force variability within the steady windows", fontsize=12)
    ax_s.set_ylabel("Force std \u03c3$_F$ [N]")
    ax_r.set_ylabel("\u03c3$_F$ / |mean F| [%]")
    ax_r.set_xlabel("Test case and its mean |v| [mm/s], ordered by piston speed")
    if char is None or char.empty:
        say_missing(ax_s, "no characteristic points (no usable triangle case)")
        return fig
    speed = case_speed_m_s(char)
    order = list(speed.index)
    x = np.arange(len(order))
    std = char.pivot_table(index="case", columns="segment", values="force_std_N", aggfunc="mean").reindex(order)
    mean = char.pivot_table(index="case", columns="segment", values="force_N", aggfunc="mean").reindex(order)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = 100.0 * std / mean.abs().where(mean.abs() > 0)
    dirs = char.groupby("segment")["direction"].first().to_dict()
    for seg in (1, 2, 3, 4):
        colour, ls, marker = _SEGMENT_STYLE[seg]
        label = f"segment {seg} ({dirs.get(seg, '+' if seg % 2 else '-')}, period {1 if seg <= 2 else 2})"
        if seg not in std:
            continue
        ax_s.plot(x, std[seg].to_numpy(float), color=colour, ls=ls, marker=marker, ms=4, lw=1.1, label=label,
                  gid=f"std-seg{seg}")
        ax_r.plot(x, rel[seg].to_numpy(float), color=colour, ls=ls, marker=marker, ms=4, lw=1.1, label=label,
                  gid=f"rel-seg{seg}")
    for ax in (ax_s, ax_r):
        vals = np.asarray([ln.get_ydata() for ln in ax.get_lines()], dtype=float).ravel() if ax.get_lines() else []
        vals = np.asarray(vals)[np.isfinite(vals) & (np.asarray(vals) > 0)] if len(vals) else np.array([])
        if vals.size and vals.max() / vals.min() > 20:
            ax.set_yscale("log")
        ax.grid(True, color="0.9", lw=0.5)
    missing = [s for s in (1, 2, 3, 4) if s not in std]
    if missing:
        ax_s.set_title(f"no windows for segment(s) {', '.join(map(str, missing))}", fontsize=9, loc="right",
                       color="tab:red")
    ax_s.legend(fontsize=8, ncol=2, loc="upper left")
    step = max(1, math.ceil(len(order) / 30))
    ax_r.set_xticks(x[::step])
    ax_r.set_xticklabels([f"{c}\n{speed[c] * MM:.2g}" for c in order[::step]], fontsize=7,
                         rotation=90 if len(order) > 12 else 0)
    ax_r.set_xlim(-0.5, len(order) - 0.5)
    return fig


# ----------------------------------------------------------------------------------------------
# which figures apply to a campaign
# ----------------------------------------------------------------------------------------------

#: Figure name -> (the waveforms of which a status-ok case makes it apply, why it does not without one).
_NEEDS = {
    "fig07_time_and_loops": (("triangle",), "it shows triangle records"),
    "fig08_window_selection": (("triangle",), "it shows the constant-velocity windows of a triangle record"),
    "fig12_noise": (("triangle",), "it shows the force noise within triangle windows"),
    "fig09_characteristic": (("triangle", "sine", "free"), "the characteristic needs a triangle, sine or free case"),
    "fig10_low_velocity": (("triangle", "sine", "free"), "the characteristic needs a triangle, sine or free case"),
    "fig11_loglog": (("triangle", "sine", "free"), "the characteristic needs a triangle, sine or free case"),
    "fig13_comparison": (("triangle", "sine", "free"), "the models need a triangle, sine or free case"),
    "fig14_comparison_loglog": (("triangle", "sine", "free"), "the models need a triangle, sine or free case"),
    "fig15_harmonic_loops": (("sine", "free"), "it shows sine and free records"),
}


def applies(figure_name: str, cases: pd.DataFrame | None) -> str | None:
    """None when the figure ``figure_name`` (e.g. 'fig07_time_and_loops') applies to a campaign with this
    cases table, else one line saying why not (the report leaves the figure out with it). A figure drawn
    from any campaign (the design figures, ...) always applies; Fig. 20 applies when a case has a temperature."""
    if figure_name == "fig20_case_temperature":
        known = cases is None or "temperature_C" not in cases or np.isfinite(   # no column: a table of before 1.1
            pd.to_numeric(cases["temperature_C"], errors="coerce").to_numpy(float)).any()
        return None if known else ("no temperature known: neither a temperature channel nor a temperature_C in "
                                   "the manifest")
    if figure_name not in _NEEDS:
        return None
    waveforms, why = _NEEDS[figure_name]
    if cases is None or cases.empty or "waveform" not in cases:
        return f"no cases: {why}"
    ok = cases[cases["status"] == "ok"] if "status" in cases else cases
    if ok["waveform"].isin(waveforms).any():
        return None
    names = " or ".join(waveforms)
    return f"no status-ok {names} case: {why}"


__all__ = ["ALPHAS", "applies", "campaign_name", "case_speed_m_s", "characteristic", "loglog_characteristic",
           "low_velocity_detail", "methods_of", "noise", "time_and_loops", "window_selection"]
