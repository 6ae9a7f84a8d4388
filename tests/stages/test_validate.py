"""Input checks: NaN/inf, time order, record length, sample rate, sample count."""

from __future__ import annotations

import dataclasses
import math
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import CAMPAIGN, assert_quarantine, set_cell
from isokinetic.contracts import tables
from isokinetic.contracts.campaign import timeseries_relpath, write_ingested
from isokinetic.measurement.motion import Motion
from isokinetic.measurement.repeatability import repeatability
from isokinetic.physics.plan import CasePlan, triangle_displacement
from isokinetic.stages.characteristic import assemble, windows_stage
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.validate import (
    INVERT_HINT,
    MAX_MOTION_RMS_FRACTION,
    GapTolerance,
    Problem,
    motion_problems,
    quarantine_frame,
    quarantine_rows,
    record_problems,
    validate_campaign,
    write_validated,
)
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign
from rigfiles import dropout_rows
from testconfig import TEST_CONFIG as CONFIG


def _swap_rows(column, a, b):
    def edit(t):
        t.loc[[a, b], column] = t.loc[[b, a], column].to_numpy()
        return t
    return edit


def _scale_time(factor):
    def edit(t):
        t["time_s"] = (t["time_s"].astype(float) * factor).map("{:.10g}".format)
        return t
    return edit


# a blank or NaN cell and a repeated time stamp are no longer here: ingest leaves their row out as a gap and
# keeps the case (issue 34, format 1.5; tests/stages/test_damage.py)
@pytest.mark.parametrize("case, edit, column, row, message", [
    ("T03", set_cell(40, "force_inv_kN", "-inf"), "force_inv_kN", 40, "non-finite value inf"),  # inverted
    ("T01", _swap_rows("time_s", 50, 51), "time_s", 51, "time 1.0 s is not above the previous row's 1.02 s"),
], ids=["inf", "time-swapped"])
def test_schema_failures_name_the_first_bad_row(raw_campaign, case, edit, column, row, message):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    # campaign.write_ingested only takes schema-valid series, so ingest quarantines these.
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, case, "ingest", column, row)])
    assert quarantine["reason"].tolist() == [f"campaign demo, case {case}, column {column!r}, row {row}: {message}"]


def test_validate_rechecks_the_schema_of_ingested_series(raw_campaign):
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    path = raw_campaign.root / timeseries_relpath("T02")
    df = pd.read_parquet(path)
    df.loc[23:30, "force_N"] = math.nan
    df.to_parquet(path, index=False)            # written by something that did not check it
    cases, quarantine = write_validated(raw_campaign.root)
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "validate", "force_N", 23)])


def test_record_that_ends_early_keeps_its_complete_windows_equal_to_the_full_records(raw_campaign):
    raw_campaign.run()
    full = _windows(raw_campaign).loc["T02"]
    raw_campaign.edit_table("T02", lambda t: t.iloc[:300])      # 2.99 s of the plan's 4 s: window 4 lost
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    assert "record ends at 2.99 s, before the plan's 4 s: window 4 missing" in cases.set_index("case").loc["T02",
                                                                                                            "quality"]
    cut = _windows(raw_campaign).loc["T02"]
    assert cut.index.tolist() == [1, 2, 3]
    assert cut[["row_start", "row_stop"]].equals(full.loc[[1, 2, 3], ["row_start", "row_stop"]])
    se = full["force_std_N"] / np.sqrt(full["n_samples"])
    assert (np.abs(cut["force_N"] - full.loc[[1, 2, 3], "force_N"]) <= se.loc[[1, 2, 3]]).all()


@pytest.mark.parametrize("keep", [80, 130])       # before window 1 ends (0.95 s); before hp 2's middle (1.5 s)
def test_record_too_short_for_its_motion_start_is_set_aside(raw_campaign, keep):
    raw_campaign.edit_table("T02", lambda t: t.iloc[:keep])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "validate", "time_s", None)])
    assert f"record ends at {(keep - 1) / 100:.6g} s, before the middle of its second half-period" in \
        quarantine["reason"].iloc[0]


def test_sine_needs_one_period(raw_campaign):
    raw_campaign.edit_table("H01", lambda t: t.iloc[:100])    # 0.5 s < 1/1.75 Hz
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "H01", "validate", "time_s", None)])


def test_sample_rate_far_from_the_manifest(raw_campaign):
    raw_campaign.edit_table("T01", _scale_time(1.25))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "validate", "time_s", None)])
    assert quarantine["reason"].iloc[0] == ("campaign demo, case T01, column 'time_s': sample interval "
                                           "0.025 s is +25.0% off 1/sample_rate_Hz = 0.02 s (tolerance 5.0%)")
    # a looser tolerance passes the rate, but on the stretched time axis the piston is slower than planned
    cases, quarantine = write_validated(raw_campaign.root, sample_rate_tolerance=0.3)
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "validate", "displacement_m", None)])
    assert "off the planned 4Y/T = 0.3 mm/s (Eq. 26; tolerance 5%)" in quarantine["reason"].iloc[0]


def test_sample_rate_tolerance_is_a_parameter(raw_campaign):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T01").update(sample_rate_Hz=40.0))
    cases, quarantine = raw_campaign.run()     # the data are sampled at 50 Hz
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "validate", "time_s", None)])
    assert quarantine["reason"].iloc[0] == ("campaign demo, case T01, column 'time_s': sample interval "
                                           "0.02 s is -20.0% off 1/sample_rate_Hz = 0.025 s (tolerance 5.0%)")
    cases, quarantine = write_validated(raw_campaign.root, sample_rate_tolerance=0.3)
    assert quarantine.empty and (cases["status"] == "ok").all()


def test_too_few_samples(raw_campaign):
    raw_campaign.edit_table("F01", lambda t: t.iloc[:5])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "F01", "validate", "time_s", None)])
    assert quarantine["reason"].iloc[0].endswith("only 5 samples, at least 10 needed")


def test_ingest_and_validation_rows_together(raw_campaign):
    raw_campaign.edit_table("T01", set_cell(17, "force_kN", "inf"))
    raw_campaign.edit_table("F01", lambda t: t.iloc[:5])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "force_kN", 17),
                                                        (CAMPAIGN, "F01", "validate", "time_s", None)])
    on_disk = pd.read_parquet(raw_campaign.root / "quarantine.parquet")
    pd.testing.assert_frame_equal(on_disk, quarantine)
    tables.validate_table(pd.read_parquet(raw_campaign.root / "cases.parquet"), tables.CASES)


def _simulated_case(plan: CasePlan, n: int) -> tuple[dict, pd.DataFrame]:
    t = np.arange(n) / plan.sample_rate_Hz
    y = triangle_displacement(t, plan.amplitude_m, plan.period_s)
    df = pd.DataFrame({"row": np.arange(n), "time_s": t, "displacement_m": y, "force_N": np.gradient(y, t) * 1e6,
                       "command_m": y})
    row = {"campaign": "sim", **dataclasses.asdict(plan), "raw_file": "", "raw_sha256": "",
           "timeseries_file": timeseries_relpath(plan.case), "n_samples": n, "status": "ok"}
    return row, df


def test_simulated_campaign_is_validated_the_same_way(tmp_path):
    plans = [CasePlan("T01", "triangle", 100.0, amplitude_m=1e-4, period_s=2.0, duration_s=4.0),
             CasePlan("T02", "triangle", 100.0, amplitude_m=1e-4, period_s=2.0, duration_s=4.0)]
    built = [_simulated_case(plans[0], 400), _simulated_case(plans[1], 80)]   # T02 ends before its first window
    meta = {"format_version": 1, "campaign": "sim", "source": "simulation", "description": None,
            "temperature_C": 40.0, "damper": None, "manifest_file": "", "manifest_sha256": "", "metadata": {}}
    earlier = quarantine_rows("sim", "T00", "ingest", [Problem("file", "missing", kind="key")])
    write_ingested(tmp_path / "ingest", meta, pd.DataFrame([row for row, _ in built]), quarantine_frame(earlier),
                   {p.case: df for p, (_, df) in zip(plans, built)})
    cases, quarantine = validate_campaign(tmp_path)
    assert cases.set_index("case")["status"].to_dict() == {"T01": "ok", "T02": "quarantined"}
    assert list(zip(quarantine["case"], quarantine["stage"], quarantine["column"])) == [
        ("T00", "ingest", "file"), ("T02", "validate", "time_s")]
    tables.validate_table(quarantine, tables.QUARANTINE)


# --- timing from the record ------------------------------------------------------------------------

def _windows(campaign) -> pd.DataFrame:
    return windows_stage(campaign.root).set_index(["case", "segment"])


def _characteristic(campaign) -> pd.DataFrame:
    win = windows_stage(campaign.root)
    return assemble(win, repeatability(win, 0.05))


def _shift_time(seconds):
    def edit(t):
        t["time_s"] = (t["time_s"].astype(float) + seconds).map("{:.10g}".format)
        return t
    return edit


def _delay_rows(rows):
    """Displacement and force ``rows`` samples later (piston held at its start before); command unchanged."""
    def edit(t):
        for column in ("disp_mm", "force_kN"):
            values = t[column].tolist()
            t[column] = values[:1] * rows + values[:-rows]
        return t
    return edit


def _triangles(manifest):
    return [c for c in manifest["cases"] if c["waveform"] == "triangle"]


@pytest.mark.parametrize("phase_rad", [-1.5707963, -1.5708])
def test_rounded_phase_gives_the_same_windows_and_characteristic(raw_campaign, phase_rad):
    raw_campaign.run()
    windows, char = _windows(raw_campaign), _characteristic(raw_campaign)
    raw_campaign.edit_manifest(lambda m: [c.update(phase_rad=phase_rad) for c in _triangles(m)])
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty and (cases["quality"] == "ok").all()
    assert (cases.loc[cases["waveform"] == "triangle", "phase_rad"] == phase_rad).all()
    pd.testing.assert_frame_equal(_windows(raw_campaign), windows)
    pd.testing.assert_frame_equal(_characteristic(raw_campaign), char)


def test_time_column_offset_is_aligned_to_the_motion_and_noted(raw_campaign):
    raw_campaign.run()
    before = _windows(raw_campaign)
    raw_campaign.edit_table("T01", _shift_time(7.3))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    t01 = cases.set_index("case").loc["T01"]
    assert (t01["status"], t01["motion_start_s"], t01["delay_s"]) == ("ok", 7.3, 0.0)
    assert t01["quality"] == ("time axis offset: the motion starts at t = 7.3 s of the record (first sample at "
                              "t = 7.3 s, delay 0 ms); windows aligned to the measured motion")
    after = _windows(raw_campaign)
    for column in ("force_N", "force_std_N", "n_samples", "row_start", "row_stop"):
        np.testing.assert_array_equal(after.loc["T01", column], before.loc["T01", column])
    np.testing.assert_allclose(after.loc["T01", "window_start_s"], before.loc["T01", "window_start_s"] + 7.3)
    np.testing.assert_allclose(after.loc["T01", "velocity_m_s"], before.loc["T01", "velocity_m_s"], rtol=1e-9)
    assert (after.loc["T01", "quality"] == t01["quality"]).all()
    pd.testing.assert_frame_equal(after.drop(index="T01"), before.drop(index="T01"))


def test_actuator_delay_is_measured_and_the_windows_follow_the_motion(raw_campaign):
    raw_campaign.run()
    before = _windows(raw_campaign)
    raw_campaign.edit_table("T01", _delay_rows(2))           # 40 ms at 50 Hz
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    t01 = cases.set_index("case").loc["T01"]
    assert t01["quality"] == "ok" and t01["delay_s"] == pytest.approx(0.040, abs=0.002)
    after = _windows(raw_campaign)
    # the windows moved with the motion, to within a sample at their edges (measured, not whole-sample, start)
    for edge in ("row_start", "row_stop"):
        assert (np.abs(after.loc["T01", edge] - (before.loc["T01", edge] + 2)) <= 1).all()
    np.testing.assert_allclose(after.loc["T01", "force_N"], before.loc["T01", "force_N"], rtol=1e-3)
    np.testing.assert_allclose(after.loc["T01", "window_start_s"], before.loc["T01", "window_start_s"] + 0.04,
                               atol=0.02)
    pd.testing.assert_frame_equal(after.drop(index="T01"), before.drop(index="T01"))


def test_motion_columns_of_the_cases_table(raw_campaign):
    cases, _ = raw_campaign.run()
    table = cases.set_index("case")
    tri = table.loc[["T01", "T02", "T03"]]
    assert (tri["motion_start_s"] == 0.0).all() and (tri["delay_s"] == 0.0).all()
    np.testing.assert_allclose(tri["velocity_ratio"], 1.0, atol=1e-3)
    np.testing.assert_allclose(tri["motion_rms_m"], 1e-6, rtol=0.1)     # the fixture's LVDT noise
    assert table.loc[["H01", "F01"], ["motion_start_s", "delay_s", "velocity_ratio", "motion_rms_m"]].isna().all().all()
    tables.validate_table(pd.read_parquet(raw_campaign.root / "cases.parquet"), tables.CASES)


def _motion(plan: CasePlan, ratios=(1.0, 1.0, 1.0, 1.0), rms_m=1e-6, start_s=0.0) -> Motion:
    w = plan.velocity_m_s
    planned = (w, -w, w, -w)
    return Motion(motion_start_s=start_s, delay_s=0.01, delay_std_s=1e-4,
                  velocities_m_s=tuple(r * v for r, v in zip(ratios, planned)), planned_velocities_m_s=planned,
                  amplitude_m=plan.amplitude_m, mid_stroke_m=0.0, rms_m=rms_m, noise_m=1e-6)


PLAN = CasePlan("T01", "triangle", 100.0, amplitude_m=1e-3, period_s=20.0, duration_s=40.0)


def test_displacement_departing_from_the_planned_triangle_is_a_problem():
    problems, _ = motion_problems(_motion(PLAN, rms_m=2 * MAX_MOTION_RMS_FRACTION * 1e-3), PLAN)
    assert [p.column for p in problems] == ["displacement_m"]
    assert problems[0].message.startswith("the displacement departs from the planned triangle (Eq. 26, shifted "
                                          "to the measured motion start t = 0 s) by 0.1 mm rms, 10.0% of the 1 mm "
                                          "amplitude beyond the LVDT noise")


def test_one_half_period_off_its_speed_is_flagged_but_usable():
    problems, warnings = motion_problems(_motion(PLAN, ratios=(1.07, 1.0, 1.0, 1.0)), PLAN)
    assert problems == []
    assert warnings == ["half-period 1 moves at +0.214 mm/s, +7.0% off the planned 0.2 mm/s"]


def test_small_motion_start_is_not_noted():
    assert motion_problems(_motion(PLAN, start_s=0.09), PLAN) == ([], [])
    assert INVERT_HINT == "the rig's sign convention looks opposite: add `invert: true`"


# --- dropped samples -------------------------------------------------------------------------------

#: Triangle cases of periods 80 s and 20 s and a sine case of the paper's plan, recorded at 500 Hz.
VIRTUAL_CASES = ["T08", "T17", "T23", "H01"]
RATE_HZ = 500.0


def drop_data_rows(path: Path, rows) -> None:
    """Remove the data rows ``rows`` (0-based, after the header line) of a case CSV, as a logger that dropped them."""
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    gone = {1 + int(r) for r in rows}
    path.write_text("".join(line for i, line in enumerate(lines) if i not in gone), encoding="utf-8")


@pytest.fixture(scope="module")
def lag_campaign(tmp_path_factory) -> Path:
    """Raw campaign of the virtual rig (paper-lag-damper) with VIRTUAL_CASES at RATE_HZ."""
    config = yaml.safe_load(CONFIG.read_text(encoding="utf-8"))["virtual_campaigns"]["paper-lag-damper"]
    vc = VirtualCampaign.from_config("paper-lag-damper", config)
    return export_raw_campaign(vc, tmp_path_factory.mktemp("virtual") / "lag", cases=VIRTUAL_CASES,
                               sample_rate_Hz=RATE_HZ)


def _run(raw_dir: Path, root: Path, gap_tolerance: GapTolerance = GapTolerance()):
    ingest_campaign(raw_dir, root)
    cases, quarantine = write_validated(root, gap_tolerance=gap_tolerance)
    return cases.set_index("case"), quarantine


@pytest.fixture(scope="module")
def lag_full(lag_campaign, tmp_path_factory):
    """(cases, windows) of the complete records."""
    root = tmp_path_factory.mktemp("full") / "lag"
    cases, quarantine = _run(lag_campaign, root)
    assert quarantine.empty and (cases["quality"] == "ok").all()
    return cases, windows_stage(root).set_index(["case", "segment"])


def _copy(lag_campaign: Path, tmp_path: Path) -> Path:
    raw = tmp_path / "raw" / "lag"
    shutil.copytree(lag_campaign, raw)
    return raw


def _series_time(lag_campaign: Path, case: str) -> np.ndarray:
    return pd.read_csv(lag_campaign / f"{case}.csv")["time_s"].to_numpy()


@pytest.mark.slow
def test_one_percent_dropped_in_singles_and_bursts_sets_no_case_aside(lag_campaign, lag_full, tmp_path):
    raw = _copy(lag_campaign, tmp_path)
    dropped = {}
    for k, case in enumerate(VIRTUAL_CASES):
        n = len(_series_time(lag_campaign, case))
        dropped[case] = dropout_rows(n, seed=100 + k)
        drop_data_rows(raw / f"{case}.csv", dropped[case])
    cases, quarantine = _run(raw, tmp_path / "results" / "lag")
    assert quarantine.empty
    assert (cases["status"] == "ok").all()
    full_cases, full_windows = lag_full
    for case, rows in dropped.items():          # what was dropped, counted from the drop itself
        n = full_cases.loc[case, "n_samples"]
        runs = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
        assert cases.loc[case, "missing_samples"] == rows.size
        assert cases.loc[case, "missing_fraction"] == pytest.approx(rows.size / n)
        assert cases.loc[case, "longest_gap_s"] == pytest.approx((max(map(len, runs)) + 1) / RATE_HZ)
        assert cases.loc[case, "quality"].startswith(f"{rows.size} sample(s) missing in {len(runs)} gap(s)")
    tables.validate_table(pd.read_parquet(tmp_path / "results" / "lag" / "cases.parquet"), tables.CASES)
    windows = windows_stage(tmp_path / "results" / "lag").set_index(["case", "segment"])
    assert list(windows.index) == list(full_windows.index)
    se = full_windows["force_std_N"] / np.sqrt(full_windows["n_samples"])
    assert (np.abs(windows["force_N"] - full_windows["force_N"]) < se).all()
    np.testing.assert_allclose(windows["velocity_m_s"], full_windows["velocity_m_s"], rtol=1e-3)
    keys = ["case", "segment"]
    char = assemble(windows.reset_index(), repeatability(windows.reset_index(), 0.05)).set_index(keys)
    full_char = assemble(full_windows.reset_index(), repeatability(full_windows.reset_index(), 0.05)).set_index(keys)
    assert (np.abs(char["force_N"] - full_char["force_N"]) < se.reindex(char.index)).all()
    pd.testing.assert_series_equal(char["repeatability_flagged"], full_char["repeatability_flagged"])
    for (case, segment), w in full_windows.iterrows():    # the window's missing samples: dropped in its time span
        t = _series_time(lag_campaign, case)[dropped[case]]
        inside = int(((t >= w["window_start_s"]) & (t <= w["window_end_s"])).sum())
        assert windows.loc[(case, segment), "missing_samples"] == inside
        assert windows.loc[(case, segment), "n_samples"] == w["n_samples"] - inside


def test_window_missing_over_the_tolerance_sets_its_case_aside(lag_campaign, lag_full, tmp_path):
    _, full_windows = lag_full
    w = full_windows.loc[("T17", 2)]
    first = int(w["row_start"]) + 100
    rows = np.arange(first, int(w["row_stop"]), 14)[:170]      # singles: 170 of the window's 2501 samples, 6.8 %
    assert rows.size == 170 and w["n_samples"] == 2501
    raw = _copy(lag_campaign, tmp_path)
    drop_data_rows(raw / "T17.csv", rows)
    cases, quarantine = _run(raw, tmp_path / "results" / "lag")
    assert cases["status"].to_dict() == {"T08": "ok", "T17": "quarantined", "T23": "ok", "H01": "ok"}
    assert quarantine[["case", "stage", "column", "row"]].values.tolist() == [["T17", "validate", "time_s", first]]
    assert quarantine["reason"].iloc[0] == (
        f"campaign lag, case T17, column 'time_s', row {first}: 170 of the {int(w['n_samples'])} samples (6.8%) "
        f"missing inside the window of segment 2 (t = {w['window_start_s']:.6g} .. {w['window_end_s']:.6g} s), "
        "more than the 5.0% tolerated (validation.max_missing_fraction)")


def _long_gap(lag_campaign, lag_full, tmp_path):
    """T17 (T/2 = 10 s: 0.2 s tolerated) missing a burst of 110 samples (0.222 s, 4.4 % of window 3)."""
    _, full_windows = lag_full
    first = int(full_windows.loc[("T17", 3), "row_start"]) + 1000
    raw = _copy(lag_campaign, tmp_path)
    drop_data_rows(raw / "T17.csv", range(first, first + 110))
    return raw, first


def test_a_gap_longer_than_tolerated_sets_its_case_aside(lag_campaign, lag_full, tmp_path):
    raw, first = _long_gap(lag_campaign, lag_full, tmp_path)
    cases, quarantine = _run(raw, tmp_path / "results" / "lag")
    assert cases["status"].to_dict() == {"T08": "ok", "T17": "quarantined", "T23": "ok", "H01": "ok"}
    assert quarantine[["case", "column", "row"]].values.tolist() == [["T17", "time_s", first]]
    t0 = (first - 1) / RATE_HZ          # window 3: the third half-period starts at T = 20 s, + [0.45, 0.95]·10 s
    assert quarantine["reason"].iloc[0] == (
        f"campaign lag, case T17, column 'time_s', row {first}: gap in time: 110 sample(s) missing between "
        f"t = {t0:.6g} s and {t0 + 0.222:.6g} s (interval 0.222 s, sample interval 0.002 s), inside the window of "
        f"segment 3 (t = 24.5 .. 29.5 s): longer than the 0.2 s tolerated (validation.max_gap_s, or 2% of the "
        "half-period)")


@pytest.mark.slow
def test_gap_tolerances_are_parameters(lag_campaign, lag_full, tmp_path):
    raw, _ = _long_gap(lag_campaign, lag_full, tmp_path)
    cases, quarantine = _run(raw, tmp_path / "results" / "lag", GapTolerance(max_gap_s=0.5))
    assert quarantine.empty
    assert cases.loc["T17", "quality"].startswith("110 sample(s) missing in 1 gap(s)")
    cases, quarantine = write_validated(tmp_path / "results" / "lag", gap_tolerance=GapTolerance(
        max_missing_fraction=0.04, max_gap_s=0.5))
    assert quarantine["reason"].iloc[0].endswith("more than the 4.0% tolerated (validation.max_missing_fraction)")


def test_sample_rate_check_is_not_tripped_by_dropouts():
    plan = CasePlan("T01", "triangle", 100.0, amplitude_m=1e-3, period_s=20.0, duration_s=40.0)
    t = np.delete(np.arange(4001) / 100.0, np.arange(1, 4000, 4))     # a quarter of the samples lost in singles
    assert np.mean(np.diff(t)) == pytest.approx(1.0 / 75.0, rel=0.01)  # the mean interval is 33 % off
    assert record_problems(t, plan) == []


@pytest.mark.parametrize("plan, limit_s", [
    (CasePlan("T", "triangle", 100.0, amplitude_m=1e-3, period_s=20.0, duration_s=40.0), 0.2),
    (CasePlan("T", "triangle", 100.0, amplitude_m=1e-3, period_s=4.0, duration_s=8.0), 0.1),
    (CasePlan("H", "sine", 100.0, amplitude_m=1e-3, frequency_Hz=1.75, duration_s=4.0), 0.1),
    (CasePlan("H", "sine", 100.0, amplitude_m=1e-3, frequency_Hz=0.05, duration_s=40.0), 0.2),
    (CasePlan("F", "free", 100.0, duration_s=40.0), 0.1),
])
def test_longest_gap_tolerated_is_max_gap_s_or_2_percent_of_the_half_period(plan, limit_s):
    assert GapTolerance().limit_s(plan) == pytest.approx(limit_s)


def test_sine_and_free_records_with_dropouts_are_validated(raw_campaign):
    drops = {"H01": [20, *range(100, 110), 250, 251, 333], "F01": [30, *range(120, 123), 200]}   # <= 0.1 s each
    for case, rows in drops.items():
        raw_campaign.edit_table(case, lambda t, rows=rows: t.drop(index=rows).reset_index(drop=True))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty and (cases["status"] == "ok").all()
    table = cases.set_index("case")
    for case, rows in drops.items():
        assert table.loc[case, "missing_samples"] == len(rows)
        assert "sample(s) missing" in table.loc[case, "quality"]
    assert (table.loc[["T01", "T02", "T03"], "missing_samples"] == 0).all()
    assert (table.loc[["T01", "T02", "T03"], "quality"] == "ok").all()


def test_a_long_gap_at_a_reversal_outside_windows_and_motion_fits_is_only_flagged(lag_campaign, lag_full, tmp_path):
    # T17 reverses at t = 10 s; window 1 ends at 9.5 s, the motion fit of half-period 2 starts at 11 s
    raw = _copy(lag_campaign, tmp_path)
    drop_data_rows(raw / "T17.csv", range(5000, 5250))               # t = 10.0 .. 10.498 s: 0.5 s without a sample
    cases, quarantine = _run(raw, tmp_path / "results" / "lag")
    assert quarantine.empty
    assert cases.loc["T17", "quality"] == ("250 sample(s) missing in 1 gap(s), 1.25% of the record; longest gap "
                                           "0.502 s at t = 9.998 s; at most 0.0% of an analysed span (tolerance 5.0%)")
    assert cases.loc["T17", "longest_gap_s"] == pytest.approx(0.502)
    _, full_windows = lag_full
    windows = windows_stage(tmp_path / "results" / "lag").set_index(["case", "segment"])
    np.testing.assert_array_equal(windows.loc["T17", "force_N"], full_windows.loc["T17", "force_N"])
    assert (windows.loc["T17", "missing_samples"] == 0).all()


def test_one_wild_displacement_sample_is_named_at_its_row():
    """Issue 20: one sample far off the stroke moved the mid-stroke with it, and row 0 was named for a bad value
    at row 500. The row is found around the median position."""
    from isokinetic.stages.validate import plausibility_problems

    t = np.arange(2000) / PLAN.sample_rate_Hz
    y = triangle_displacement(t, PLAN.amplitude_m, PLAN.period_s)
    y[500] = 1.0                                                  # 1 m in a 1 mm stroke
    df = pd.DataFrame({"row": np.arange(t.size), "time_s": t, "displacement_m": y, "force_N": np.ones(t.size)})
    problems = plausibility_problems(df, PLAN, None)
    assert [(p.column, p.row) for p in problems] == [("displacement_m", 500)]


def test_a_smooth_crest_read_at_the_channels_resolution_is_not_saturation():
    # a 0.28 Hz sine of 35 um at 2 kHz, read to 1 nm, stays within a step of its crest for ~20 samples
    from isokinetic.stages.validate import clipped

    t = np.arange(0, 4.0, 1 / 2000.0)
    smooth = np.round(35e-6 * np.sin(2 * np.pi * 0.28 * t) / 1e-9) * 1e-9
    at = np.flatnonzero(smooth == smooth.max())
    assert at.size >= 10 and not clipped(t, smooth, at[0], at[-1] + 1, smooth.max(), True)
    cut = np.minimum(smooth, 0.97 * smooth.max())   # the same sine through a channel that ends at 97 %
    at = np.flatnonzero(cut == cut.max())
    assert clipped(t, cut, at[0], at[-1] + 1, cut.max(), True)
