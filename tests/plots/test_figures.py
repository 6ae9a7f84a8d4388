"""Fig. 7-12 (isokinetic.plots.figures): structure and data of each figure."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from fresh_imports import modules_loaded
from isokinetic.plots import figures
from plots.synthetic import synthetic_campaign

MM = 1e3


@pytest.fixture(scope="module")
def camp():
    return synthetic_campaign()


def _lines(ax, gid):
    return [ln for ln in ax.get_lines() if ln.get_gid() == gid]


def _n_points(lines):
    return sum(len(ln.get_xdata()) for ln in lines)


def _has_unit(label):
    return re.search(r"\[[^\]]+\]$", label) is not None


# ----------------------------------------------------------------------------------------------
# Fig. 7 and 8
# ----------------------------------------------------------------------------------------------

def test_time_and_loops_draws_time_and_loop_panel_per_case(camp):
    cases, series, _, _ = camp
    ids = ["T02", "T05", "T09"]
    fig = figures.time_and_loops(cases, series, ids)
    main = [ax for ax in fig.axes if _lines(ax, "force") or _lines(ax, "loop")]
    assert len(main) == 6
    loops = [ax for ax in main if _lines(ax, "loop")]
    for ax, case in zip(loops, ids, strict=True):
        assert len(_lines(ax, "loop")[0].get_xdata()) == len(series[case])
        assert ax.get_xlabel() == "Displacement y [mm]" and _has_unit(ax.get_ylabel())
    twins = [ax for ax in fig.axes if _lines(ax, "displacement")]
    assert len(twins) == 3 and all(ax.get_ylabel() == "Displacement y [mm]" for ax in twins)
    assert "synthetic-damper" in fig.get_suptitle()


def test_time_and_loops_states_missing_series(camp):
    cases, series, _, _ = camp
    fig = figures.time_and_loops(cases, {"T02": series["T02"]}, ["T02", "T05"])
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert any("T05: time series missing" in t for t in texts)


def test_window_selection_highlights_each_window_and_its_mean(camp):
    cases, series, windows, _ = camp
    w = windows[windows["case"] == "T05"]
    fig = figures.window_selection(cases.set_index("case").loc["T05"].rename("T05").to_dict() | {"case": "T05"},
                                   series["T05"], w)
    ax = next(a for a in fig.axes if _lines(a, "window"))
    win_lines = _lines(ax, "window")
    assert len(win_lines) == len(w) == 4
    for ln, (_, row) in zip(win_lines, w.sort_values("window_start_s").iterrows(), strict=True):
        x = np.asarray(ln.get_xdata())
        assert len(x) == row["n_samples"]
        assert row["window_start_s"] <= x.min() and x.max() <= row["window_end_s"]
    scale = 1e3 if ax.get_ylabel().endswith("[kN]") else 1.0
    means = [ln.get_ydata()[0] for ln in _lines(ax, "window-mean")]
    np.testing.assert_allclose(means, w.sort_values("window_start_s")["force_N"] / scale)
    assert len(_lines(ax, "window-std")) == 8
    fits = [ln for a in fig.axes for ln in _lines(a, "velocity-fit")]
    assert len(fits) == 4
    assert ax.get_xlabel() == "Time t [s]" and ax.get_legend() is not None


# ----------------------------------------------------------------------------------------------
# Fig. 9 and 10
# ----------------------------------------------------------------------------------------------

def test_characteristic_plots_one_point_per_window(camp):
    *_, char = camp
    fig = figures.characteristic(char)
    ax = fig.axes[0]
    p1, p2 = _lines(ax, "period1"), _lines(ax, "period2")
    assert _n_points(p1) + _n_points(p2) == len(char)
    assert _n_points(p1) == (char["period"] == 1).sum()
    assert max(ln.get_zorder() for ln in p2) < min(ln.get_zorder() for ln in p1)
    assert all(ln.get_linewidth() > 3 for ln in p2)
    x = np.concatenate([ln.get_xdata() for ln in p1])
    assert x.min() < 0 < x.max()  # both quadrants
    assert ax.get_xlabel() == "Piston velocity v [mm/s]" and ax.get_ylabel() == "Steady force F [N]"
    assert ax.get_legend() is not None and "synthetic-damper" in fig.get_suptitle()


def test_characteristic_rings_repeatability_flagged_points(camp):
    *_, char = camp
    flagged = char.assign(repeatability_flagged=char["case"] == "T03")
    ax = figures.characteristic(flagged).axes[0]
    assert _n_points(_lines(ax, "flagged")) == (flagged["case"] == "T03").sum()


def test_low_velocity_detail_default_is_slowest_third_with_intercepts(camp):
    *_, char = camp
    ax = figures.low_velocity_detail(char).axes[0]
    shown = _n_points(_lines(ax, "period1")) + _n_points(_lines(ax, "period2"))
    assert shown == 3 * 4  # 9 cases -> slowest 3, four windows each
    x = np.concatenate([ln.get_xdata() for ln in _lines(ax, "period1")])
    slowest_3 = char.groupby("case")["velocity_m_s"].apply(lambda s: s.abs().max()).sort_values().iloc[2]
    assert np.abs(x).max() <= slowest_3 * MM
    f0 = sorted(ln.get_ydata()[0] for ln in _lines(ax, "intercept"))
    assert f0[0] < 0 < f0[1]  # non-zero force of either sign as v -> 0
    mirrored = _lines(ax, "mirrored")[0]
    assert (np.asarray(mirrored.get_xdata()) > 0).all() and (np.asarray(mirrored.get_ydata()) > 0).all()
    assert ax.get_ylabel() == "Steady force F [N]"


def test_low_velocity_detail_v_max_keeps_rows_below(camp):
    *_, char = camp
    v_max = 1e-4
    ax = figures.low_velocity_detail(char, v_max_m_s=v_max).axes[0]
    shown = _n_points(_lines(ax, "period1")) + _n_points(_lines(ax, "period2"))
    assert shown == (char["velocity_m_s"].abs() <= v_max).sum()


# ----------------------------------------------------------------------------------------------
# Fig. 11 and 12
# ----------------------------------------------------------------------------------------------

def test_loglog_folds_quadrant3_into_quadrant1(camp):
    *_, char = camp
    ax = figures.loglog_characteristic(char).axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    q1, q3 = _lines(ax, "q1")[0], _lines(ax, "q3-folded")[0]
    neg = char[(char["period"] == 1) & (char["direction"] == "-")]
    assert len(q3.get_xdata()) == len(neg)
    for ln in (q1, q3):
        assert (np.asarray(ln.get_xdata()) > 0).all() and (np.asarray(ln.get_ydata()) > 0).all()
    assert q1.get_marker() == "o" and q1.get_linestyle() == "-"
    assert q3.get_marker() == "*" and q3.get_linestyle() == "--"
    scale = 1e3 if ax.get_ylabel().endswith("[kN]") else 1.0
    np.testing.assert_allclose(sorted(q3.get_ydata()), sorted(neg["force_N"].abs() / scale))


def test_loglog_alpha_families_have_slopes_0_1_2(camp):
    *_, char = camp
    ax = figures.loglog_characteristic(char).axes[0]
    for alpha in (0, 1, 2):
        lines = _lines(ax, f"alpha-{alpha}")
        assert len(lines) >= 3
        for ln in lines:
            x, y = np.log10(ln.get_xdata()), np.log10(ln.get_ydata())
            assert np.polyfit(x, y, 1)[0] == pytest.approx(alpha, abs=1e-9)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert sum("C\u00b7v" in t for t in labels) == 3


def test_noise_has_four_segment_lines_and_relative_std(camp):
    *_, char = camp
    fig = figures.noise(char)
    top, bottom = fig.axes[:2]
    n_cases = char["case"].nunique()
    for seg in (1, 2, 3, 4):
        std = _lines(top, f"std-seg{seg}")[0].get_ydata()
        rel = _lines(bottom, f"rel-seg{seg}")[0].get_ydata()
        assert len(std) == len(rel) == n_cases
        seg_rows = char[char["segment"] == seg].set_index("case")
        order = char.assign(a=char["velocity_m_s"].abs()).groupby("case")["a"].mean().sort_values().index
        np.testing.assert_allclose(std, seg_rows.loc[order, "force_std_N"])
        np.testing.assert_allclose(rel, 100 * seg_rows.loc[order, "force_std_N"] / seg_rows.loc[order, "force_N"].abs())
    assert top.get_ylabel().endswith("[N]") and bottom.get_ylabel().endswith("[%]")
    assert len(top.get_legend().get_texts()) == 4


def test_char_figures_state_missing_data_on_empty_table():
    empty = synthetic_campaign(n=1)[3].iloc[0:0]
    for make in (figures.characteristic, figures.low_velocity_detail, figures.loglog_characteristic, figures.noise):
        fig = make(empty, campaign="x")
        assert any("no characteristic points" in t.get_text() for ax in fig.axes for t in ax.texts), make.__name__


# ----------------------------------------------------------------------------------------------
# sine and free points (issue 19) and which figures apply
# ----------------------------------------------------------------------------------------------

def _sine_rows(char):
    """Two sine cases' peak-velocity rows made from the triangle table's columns (forces off the triangle's)."""
    rows = []
    for k, (case, v) in enumerate((("H01", 2e-3), ("H02", 4e-3))):
        for seg, d, period in ((1, "+", 1), (2, "-", 1), (3, "+", 2), (4, "-", 2)):
            s = 1.0 if d == "+" else -1.0
            rows.append({**char.iloc[0].to_dict(), "case": case, "segment": seg, "direction": d, "period": period,
                         "velocity_m_s": s * v, "force_N": s * (1000.0 + 500.0 * k), "n_samples": 5,
                         "method": "sine_peak", "repeatability_flagged": False})
    return pd.DataFrame(rows)


def test_characteristic_draws_sine_points_one_per_case_and_direction(camp):
    _, _, _, char = camp
    sine = _sine_rows(char)
    both = pd.concat([char.assign(method="triangle_window"), sine], ignore_index=True)
    fig = figures.characteristic(both)
    ax = fig.axes[0]
    lines = _lines(ax, "sine_peak")
    assert len(lines) == 4 and _n_points(lines) == 4
    xs = sorted(float(x) for ln in lines for x in ln.get_xdata())
    assert xs == pytest.approx([-4.0, -2.0, 2.0, 4.0])            # mm/s, the periods' mean
    assert _n_points(_lines(ax, "period1")) == (char["period"] == 1).sum()
    assert "triangle tests; periodic records, force at peak velocity" in fig.get_suptitle()


def test_characteristic_of_a_sine_only_table_is_drawn_not_missing(camp):
    _, _, _, char = camp
    fig = figures.characteristic(_sine_rows(char))
    ax = fig.axes[0]
    assert not ax.texts and _lines(ax, "sine_peak") and not _lines(ax, "period1")
    assert "(periodic records, force at peak velocity)" in fig.get_suptitle()


def test_characteristic_marks_each_method_apart_and_rings_points_on_one_or_two_cycles(camp):
    # issue 33: triangle windows, peak points and quasi-static bins in their own markers; a peak point resting
    # on one or two cycles ringed, one resting on more not
    _, _, _, char = camp
    sine = _sine_rows(char)
    sine.loc[sine["case"] == sine["case"].iloc[0], "n_samples"] = 1     # the first case's four rows: 1 cycle each
    sine = sine[~((sine["case"] == sine["case"].iloc[0]) & (sine["period"] == 2))]   # one period: 1 cycle a point
    bins = char.iloc[:3].assign(case="F01", method="free_bin", segment=[1, 2, 3], direction="+", period=1,
                                velocity_m_s=[0.001, 0.002, 0.003], force_N=[10.0, 20.0, 30.0])
    both = pd.concat([char.assign(method="triangle_window"), sine, bins], ignore_index=True)
    ax = figures.characteristic(both).axes[0]
    markers = {gid: {ln.get_marker() for ln in _lines(ax, gid)} for gid in ("period1", "sine_peak", "free_bin")}
    assert all(len(m) == 1 for m in markers.values()) and len(set.union(*markers.values())) == 3
    ringed = _lines(ax, "few-cycles")
    assert len(ringed) == 1
    first = sine[sine["case"] == sine["case"].iloc[0]]
    assert sorted(float(x) for x in ringed[0].get_xdata()) == pytest.approx(sorted(first["velocity_m_s"] * 1e3))
    assert "2 cycles or fewer" in ringed[0].get_label()


def test_applies_names_why_a_triangle_figure_does_not_apply():
    sine_only = pd.DataFrame({"case": ["H01", "T01"], "waveform": ["sine", "triangle"],
                              "status": ["ok", "quarantined"]})
    assert figures.applies("fig07_time_and_loops", sine_only) == ("no status-ok triangle case: it shows triangle "
                                                                  "records")
    assert figures.applies("fig12_noise", sine_only).startswith("no status-ok triangle case")
    assert figures.applies("fig09_characteristic", sine_only) is None
    assert figures.applies("fig15_harmonic_loops", sine_only) is None
    assert figures.applies("fig20_case_temperature", sine_only) is None
    triangle_only = sine_only.assign(waveform=["triangle", "triangle"])
    assert figures.applies("fig07_time_and_loops", triangle_only) is None
    assert figures.applies("fig15_harmonic_loops", triangle_only) == ("no status-ok sine or free case: it shows sine "
                                                                      "and free records")
    assert figures.applies("fig09_characteristic", None).startswith("no cases")


def test_asking_which_figures_apply_does_not_import_matplotlib():
    # the campaign report's job asks applies() and draws nothing: matplotlib would cost it ~0.3 s (issue 23)
    code = ("import pandas as pd; from isokinetic.plots import figures; "
            "figures.applies('fig07_time_and_loops', pd.DataFrame({'waveform': ['triangle'], 'status': ['ok']}))")
    assert modules_loaded(code, "matplotlib") == []


def test_the_temperature_figure_applies_only_when_a_case_has_a_temperature():
    cases = pd.DataFrame({"case": ["H01", "H02"], "waveform": ["sine", "sine"], "status": ["ok", "ok"],
                          "temperature_C": [float("nan"), float("nan")]})
    assert figures.applies("fig20_case_temperature", cases).startswith("no temperature known")
    assert figures.applies("fig20_case_temperature", cases.assign(temperature_C=[40.0, float("nan")])) is None
    assert figures.applies("fig20_case_temperature", cases.drop(columns="temperature_C")) is None


def test_loglog_draws_sine_points_as_markers_apart_from_the_window_lines(camp):
    _, _, _, char = camp
    both = pd.concat([char.assign(method="triangle_window"), _sine_rows(char)], ignore_index=True)
    ax = figures.loglog_characteristic(both).axes[0]
    alone = figures.loglog_characteristic(char).axes[0]
    for gid in ("q1", "q3-folded"):
        np.testing.assert_array_equal(_lines(ax, gid)[0].get_xdata(), _lines(alone, gid)[0].get_xdata())
    sine = _lines(ax, "q1-sine_peak") + _lines(ax, "q3-folded-sine_peak")
    assert _n_points(sine) == 4 and all(ln.get_linestyle() == "None" for ln in sine)
