"""The measured drive of a case (isokinetic.measurement.drive): speeds of its windows, sample-grid offset."""

import math

import pandas as pd
import pytest

from isokinetic.measurement.drive import case_drives, grid_offset, measured_drive


def test_grid_offset_is_the_plan_time_of_the_first_sample_after_the_motion_start():
    # samples at 10.0037 + k/1000 s, motion start 10.0 s: the grid lies 0.7 ms after each plan millisecond
    assert grid_offset(10.0037, 10.0, 1000.0) == pytest.approx(0.0007)
    assert grid_offset(9.9963, 10.0, 1000.0) == pytest.approx(0.0003)  # a first sample before the start
    assert grid_offset(12.0, 10.0, 1000.0) == 0.0                        # on the plan's own grid


def test_measured_drive_takes_the_speeds_in_segment_order():
    drive = measured_drive([3, 1, 4, 2], [0.3, 0.1, -0.4, -0.2], 0.0, 0.0, 100.0)
    assert drive.speeds_m_s == (0.1, 0.2, 0.3, 0.4)


@pytest.mark.parametrize(("segments", "speeds"), [([1, 2, 3], [0.1, 0.2, 0.3]),
                                                  ([1, 2, 3, 4], [0.1, 0.0, 0.3, 0.4]),
                                                  ([1, 2, 3, 4], [0.1, math.nan, 0.3, 0.4])])
def test_no_drive_without_four_finite_non_zero_speeds(segments, speeds):
    assert measured_drive(segments, speeds, 0.0, 0.0, 100.0) is None


def test_case_drives_of_the_ok_triangle_cases_start_at_their_first_sample():
    cases = pd.DataFrame({"case": ["T01", "T02", "S01"], "status": ["ok", "quarantined", "ok"],
                          "waveform": ["triangle", "triangle", "sine"], "sample_rate_Hz": [1000.0] * 3,
                          "motion_start_s": [2.0004, 0.0, 0.0], "delay_s": [0.0, 0.0, 0.0]})
    windows = pd.DataFrame({"case": ["T01"] * 4 + ["T02"] * 4, "segment": [1, 2, 3, 4] * 2,
                            "velocity_m_s": [0.1, -0.1, 0.1, -0.1] * 2})
    drives = case_drives(cases, windows)
    assert set(drives) == {"T01"}
    assert drives["T01"].grid_offset_s == pytest.approx(0.0)      # first sample (motion_start - delay) at the start
    # first sample 0.4 ms before the motion start: it lies 0.6 ms after a plan millisecond
    delayed = case_drives(cases.assign(delay_s=[0.0004, 0.0, 0.0]), windows)
    assert delayed["T01"].grid_offset_s == pytest.approx(0.0006)
    assert case_drives(cases, None) == {}
