"""Rule design (stages.design, Sec. 4.2-4.3 of the paper): the plan-check flags and columns, the
warnings, and the files the rule writes."""

from __future__ import annotations

import dataclasses
import math

import pandas as pd
import pytest

from campaign_meta_fixture import write_campaign_meta
from isokinetic.contracts import tables
from isokinetic.contracts.outputs import figures_of
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.stages import design as ds

PHI = 0.999
MAX_AMP, MIN_AMP = 10.0e-3, 0.1e-3     # the workflow test's design block: 10 mm, 0.1 mm
START = 0.45                          # the paper's window start, a fraction of T/2


def triangle(case, y_m, period_s, rate_Hz=100.0, periods=2.0):
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=y_m, period_s=period_s,
                    phase_rad=-math.pi / 2, duration_s=periods * period_s)


def sine(case, y_m, frequency_Hz, rate_Hz=1000.0, periods=4.0):
    return CasePlan(case=case, waveform="sine", sample_rate_Hz=rate_Hz, amplitude_m=y_m, frequency_Hz=frequency_Hz,
                    phase_rad=0.0, duration_s=periods / frequency_Hz)


def check(cases, damper=TABLE_1, **kw):
    kw = {"phi": PHI, "max_amplitude_m": MAX_AMP, "min_amplitude_m": MIN_AMP, "start_fraction": START, **kw}
    return ds.plan_check("design-test", cases, damper, **kw).set_index("case")


# ----------------------------------------------------------------------------------------------
# plan check
# ----------------------------------------------------------------------------------------------

FLAGS = ("travel_exceeded", "below_noise_floor", "no_convergence", "window_too_early",
         "window_too_early_after_reversal")
FLAG_CASES = {  # case: (Y, T, broken constraints, words in the reason)
    "good": (2.0e-3, 80.0, set(), ""),                                     # 0.1 mm/s, converges after 0.13 mm
    "travel": (12.0e-3, 240.0, {"travel_exceeded"}, "allowed piston travel"),  # 0.2 mm/s
    "noise": (0.05e-3, 80.0, {"below_noise_floor"}, "noise floor"),       # 2.5 µm/s
    "g3": (5.0e-3, 2.0, {"no_convergence", "window_too_early", "window_too_early_after_reversal"}, "G3"),
    "window": (7.5e-3, 20.0, {"window_too_early", "window_too_early_after_reversal"},
               "needed to reach 99.9 %"),                                  # 1.5 mm/s: 6.75 < 21.7 mm
    # 0.41 mm/s, window at 0.225 T W = 1.80 mm: after 1.753 mm (from rest) but before 1.844 mm
    # (after a reversal, from the opposite steady pressure)
    "reversal": (2.0e-3, 1.80e-3 / (0.225 * 0.41e-3), {"window_too_early_after_reversal"},
                 "needed after a velocity reversal"),
}


@pytest.mark.parametrize("name", list(FLAG_CASES))
def test_each_plan_check_flag_fires_only_on_the_case_built_to_break_it(name):
    y, period, broken, words = FLAG_CASES[name]
    row = check([triangle(name, y, period)]).loc[name]
    assert {f for f in FLAGS if row[f]} == broken
    assert bool(row["flagged"]) == bool(broken)
    assert words in row["reasons"]
    if not broken:
        assert row["reasons"] == ""


def test_plan_check_columns_for_a_triangle_case():
    row = check([triangle("T23", 7.5e-3, 20.0)]).loc["T23"]
    assert row["velocity_m_s"] == pytest.approx(1.5e-3)
    assert row["start_position_m"] == pytest.approx(-7.5e-3)
    assert row["window_start_stroke_m"] == pytest.approx(0.45 * 10.0 * 1.5e-3)
    assert row["stroke_to_converge_m"] == pytest.approx(21.68963e-3, rel=1e-6)   # hand value above
    assert row["time_to_converge_s"] == pytest.approx(14.45975, rel=1e-6)
    assert row["G3"] == pytest.approx(11.31025, rel=1e-6)
    assert row["stroke_laminar_m"] < row["stroke_turbulent_m"] < row["stroke_mixed_m"]
    assert "not reached within the 15 mm half-period" in row["reasons"]


def test_sine_case_has_g_numbers_at_peak_velocity_and_only_travel_checks():
    # peak velocity 2π · 1.75 Hz · 0.64 mm = 7.0372 mm/s: G3 < 1, yet a sine case is not checked for it
    h = CasePlan(case="H04", waveform="sine", sample_rate_Hz=1000.0, amplitude_m=0.64e-3, frequency_Hz=1.75,
                 phase_rad=0.0, duration_s=10 / 1.75)
    big = dataclasses.replace(h, case="H99", amplitude_m=12e-3)
    df = check([h, big])
    assert df.loc["H04", "velocity_m_s"] == pytest.approx(7.0372e-3, rel=1e-4)
    assert df.loc["H04", "G3"] < 1 and not df.loc["H04", "flagged"] and df.loc["H04", "reasons"] == ""
    assert math.isnan(df.loc["H04", "stroke_to_converge_m"])
    assert df.loc["H99", "flagged"] and df.loc["H99", "travel_exceeded"]


def test_without_damper_data_physics_is_nan_not_flagged_and_the_reason_says_so():
    df = check([triangle("T23", 7.5e-3, 20.0)], damper=None)
    row = df.loc["T23"]
    assert all(math.isnan(row[c]) for c in ("G1", "G2", "G3", "stroke_to_converge_m", "time_to_converge_s"))
    assert not row["flagged"] and "damper block missing" in row["reasons"]


def test_travel_beyond_the_limit_is_flagged_only_with_a_damper_and_the_reason_names_the_config_key():
    """The limit is the project's rig and damper's: a campaign without a damper block (another rig's record, such
    as a ±12.7 mm MTS sweep) is told its amplitude is beyond it, unflagged; with the damper block it is flagged."""
    cases = [triangle("big", 12.7e-3, 240.0), sine("Hbig", 12.7e-3, 1.0)]
    bare, planned = check(cases, damper=None), check(cases)
    for case in ("big", "Hbig"):
        assert not bare.loc[case, "travel_exceeded"] and not bare.loc[case, "flagged"]
        assert "not flagged: the campaign has no damper block" in bare.loc[case, "reasons"]
        assert "design.max_amplitude_mm" in bare.loc[case, "reasons"] and "12.7 mm" in bare.loc[case, "reasons"]
        assert planned.loc[case, "travel_exceeded"] and planned.loc[case, "flagged"]
        assert "design.max_amplitude_mm" in planned.loc[case, "reasons"]
    assert not ds.plan_warnings(bare.reset_index())


def test_default_plan_flags_only_the_fast_20_s_cases(default_plan):
    df = check(list(default_plan.cases), damper=default_plan.damper)
    tables.validate_table(df.reset_index(), tables.PLAN_CHECK)
    assert sorted(df.index[df["flagged"]]) == ["T19", "T20", "T21", "T22", "T23"]
    assert df.loc[df["flagged"], "window_too_early"].all()


def test_plan_warnings_name_campaign_and_case_one_line_per_flagged_case():
    df = ds.plan_check("camp-x", [triangle("T01", 2e-3, 80.0), triangle("T02", 7.5e-3, 20.0),
                                  triangle("T03", 12e-3, 240.0)], TABLE_1, phi=PHI, max_amplitude_m=MAX_AMP,
                       min_amplitude_m=MIN_AMP, start_fraction=START)
    lines = ds.plan_warnings(df)
    assert len(lines) == 2
    assert lines[0].startswith("campaign camp-x, case T02 ") and "99.9 %" in lines[0]
    assert lines[1].startswith("campaign camp-x, case T03 ") and "allowed piston travel" in lines[1]


# ----------------------------------------------------------------------------------------------
# the rule's outputs
# ----------------------------------------------------------------------------------------------

def _campaign_root(tmp_path, damper):
    root = tmp_path / "results" / "camp-y"
    write_campaign_meta(root, "camp-y", damper=None if damper is None else damper.to_dict())
    cases = pd.DataFrame({"campaign": "camp-y", "case": ["T01", "T02"], "waveform": "triangle",
                          "sample_rate_Hz": 100.0, "amplitude_m": [2e-3, 7.5e-3], "period_s": [80.0, 20.0],
                          "frequency_Hz": math.nan, "phase_rad": -math.pi / 2, "duration_s": [160.0, 40.0],
                          "status": "ok"})
    cases.to_parquet(root / "cases.parquet")
    return root


@pytest.mark.parametrize("with_damper", [True, False])
def test_write_design_writes_table_and_both_figures(tmp_path, with_damper):
    root = _campaign_root(tmp_path, TABLE_1 if with_damper else None)
    df, paths = ds.write_design(root, root / "design", phi=PHI, max_amplitude_m=MAX_AMP, min_amplitude_m=MIN_AMP,
                                start_fraction=0.45)
    assert [p.name for p in paths] == ["plan_check.parquet", *(f"{f.name}.png" for f in figures_of("design"))]
    assert all(p.stat().st_size > 0 for p in paths)
    back = tables.validate_table(pd.read_parquet(paths[0]), tables.PLAN_CHECK).set_index("case")
    assert list(back.index) == ["T01", "T02"] and set(back["campaign"]) == {"camp-y"}
    assert bool(back.loc["T02", "flagged"]) == with_damper
    assert ("damper block missing" in back.loc["T01", "reasons"]) != with_damper
