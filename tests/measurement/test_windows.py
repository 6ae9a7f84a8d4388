import math

import numpy as np
import pandas as pd
import pytest

from isokinetic.measurement.windows import (
    WindowSpec,
    case_windows,
    extract_windows,
    line_slope,
    missing_windows_note,
    motion_start,
    window_ranges,
    windowed_half_periods,
)
from isokinetic.physics.plan import CasePlan, triangle_displacement

LEVELS_N = [100.0, -80.0, 101.0, -81.0]


def make_series(period_s=20.0, amplitude_m=1e-3, rate_Hz=10.0, transient_s=3.0):
    """Two periods with a steady level per half-period and a large transient that the window skips."""
    t = np.arange(0, round(2 * period_s * rate_Hz) + 1) / rate_Hz
    seg = np.minimum((t // (period_s / 2)).astype(int), 3)
    since = t - seg * period_s / 2
    force = np.take(LEVELS_N, seg) + np.where(since < transient_s, 5000.0, 0.0)
    return pd.DataFrame({"row": np.arange(t.size), "time_s": t,
                         "displacement_m": triangle_displacement(t, amplitude_m, period_s), "force_N": force})


def plan(period_s=20.0, amplitude_m=1e-3, phase_rad=-math.pi / 2):
    return CasePlan(case="T01", waveform="triangle", sample_rate_Hz=10.0, amplitude_m=amplitude_m,
                    period_s=period_s, phase_rad=phase_rad, duration_s=2 * period_s)


def shifted(series: pd.DataFrame, time_s: float) -> pd.DataFrame:
    """The same samples on a time axis moved by ``time_s`` (as a rig's CSV would give them)."""
    out = series.copy()
    out["time_s"] = [float(f"{x:.10g}") for x in series["time_s"] + time_s]
    return out


def delayed(series: pd.DataFrame, samples: int) -> pd.DataFrame:
    """The motion and force ``samples`` later on the same time axis (held at the start value before)."""
    out = series.copy()
    for column in ("displacement_m", "force_N"):
        values = series[column].to_numpy()
        out[column] = np.concatenate([np.full(samples, values[0]), values[:-samples]])
    return out


def test_window_covers_045_to_095_of_each_half_period():
    rows = case_windows(plan(), make_series())
    # T/2 = 10 s at 10 Hz: window [4.5, 9.5] s of segment k holds rows 45..95 (+100 k)
    assert [(r["row_start"], r["row_stop"]) for r in rows] == [(45, 96), (145, 196), (245, 296), (345, 396)]
    assert all(r["n_samples"] == 51 for r in rows)
    assert rows[0]["window_start_s"] == pytest.approx(4.5) and rows[0]["window_end_s"] == pytest.approx(9.5)


def test_window_mean_excludes_transient():
    rows = case_windows(plan(), make_series())
    assert [r["force_N"] for r in rows] == pytest.approx(LEVELS_N, abs=1e-12)
    assert all(r["force_std_N"] == pytest.approx(0.0, abs=1e-9) for r in rows)


def test_segments_alternate_direction_and_period():
    rows = case_windows(plan(), make_series())
    assert [r["direction"] for r in rows] == ["+", "-", "+", "-"]
    assert [r["period"] for r in rows] == [1, 1, 2, 2]
    assert [r["segment"] for r in rows] == [1, 2, 3, 4]


def test_window_velocity_is_least_squares_slope_of_displacement():
    rows = case_windows(plan(amplitude_m=1e-3), make_series(amplitude_m=1e-3))
    expected = 4 * 1e-3 / 20.0  # W = 4Y/T, Eq. (26)
    assert [r["velocity_m_s"] for r in rows] == pytest.approx([expected, -expected] * 2, rel=1e-9)
    assert rows[1]["planned_velocity_m_s"] == pytest.approx(-expected)


def test_line_slope_matches_numpy_polyfit():
    rng = np.random.default_rng(1)
    t = np.linspace(0, 5, 40)
    y = 0.3 * t + rng.normal(size=t.size)
    assert line_slope(t, y) == pytest.approx(np.polyfit(t, y, 1)[0], rel=1e-12)


def test_configurable_window_fractions():
    rows = case_windows(plan(), make_series(), WindowSpec(0.2, 0.5))
    assert (rows[0]["row_start"], rows[0]["row_stop"]) == (20, 51)
    # the transient (first 3 s) is inside [2, 5] s now and raises the mean
    assert rows[0]["force_N"] > LEVELS_N[0] + 1000


def test_record_that_ends_early_keeps_its_complete_windows_unchanged():
    series = make_series()
    full = case_windows(plan(), series)
    assert case_windows(plan(), series[series.time_s <= 35.0]) == full[:3]      # window 4 ends at 39.5 s
    assert case_windows(plan(), series[series.time_s <= 9.5]) == full[:1]


def test_record_that_ends_before_its_first_window_is_refused():
    series = make_series()
    with pytest.raises(ValueError, match=r"holds the windows of 0 half-periods of T = 20 s, 1 needed \(the first "
                                         r"window ends at t = 9.5 s\)"):
        case_windows(plan(), series[series.time_s <= 9.4])


def test_missing_windows_are_named():
    assert missing_windows_note(plan(), 35.0, [1, 2, 3]) == (
        "record ends at 35 s, before the plan's 40 s: window 4 missing")
    assert missing_windows_note(plan(), 12.0, [1], motion_start_s=0.2) == (
        "record ends at 12 s, before the plan's 40.2 s: windows 2, 3, 4 missing")
    assert missing_windows_note(plan(), 39.9, [1, 2, 3, 4]) == ""


def test_invalid_window_fractions_are_refused():
    with pytest.raises(ValueError, match="window fractions"):
        WindowSpec(0.9, 0.4)


def test_extract_windows_skips_quarantined_and_non_triangle_cases():
    base = dict(campaign="c", sample_rate_Hz=10.0, amplitude_m=1e-3, period_s=20.0, frequency_Hz=math.nan,
                phase_rad=-math.pi / 2, duration_s=40.0, raw_file="f.csv", raw_sha256="ab",
                timeseries_file="x", n_samples=401)
    cases = pd.DataFrame([
        {**base, "case": "T01", "waveform": "triangle", "status": "ok"},
        {**base, "case": "T02", "waveform": "triangle", "status": "quarantined"},
        {**base, "case": "H01", "waveform": "sine", "status": "ok", "frequency_Hz": 1.75},
    ])
    out = extract_windows(cases, lambda row: make_series(), WindowSpec())
    assert out["case"].unique().tolist() == ["T01"]
    assert len(out) == 4 and (out["raw_file"] == "f.csv").all() and (out["campaign"] == "c").all()


@pytest.mark.parametrize("phase_rad", [-1.5707963, -1.5708])
def test_rounded_phase_gives_the_same_windows_as_the_default_phase(phase_rad):
    assert case_windows(plan(phase_rad=phase_rad), make_series()) == case_windows(plan(), make_series())


def test_rounded_phase_of_a_300_s_period_keeps_four_windows():
    # the reported crash: "record of 600 s holds the windows of 3 half-periods of T = 300 s, 4 needed"
    t = np.arange(0, 60001) / 100.0
    rounded = CasePlan(case="T01", waveform="triangle", sample_rate_Hz=100.0, amplitude_m=1e-3, period_s=300.0,
                       phase_rad=-1.5707963, duration_s=600.0)
    exact = CasePlan(case="T01", waveform="triangle", sample_rate_Hz=100.0, amplitude_m=1e-3, period_s=300.0,
                     duration_s=600.0)
    assert window_ranges(rounded, t, WindowSpec()) == window_ranges(exact, t, WindowSpec())
    assert [k for k, *_ in window_ranges(rounded, t, WindowSpec())] == [1, 2, 3, 4]


def test_windows_are_cut_at_the_motion_start_on_a_shifted_time_axis():
    base = case_windows(plan(), make_series())
    moved = case_windows(plan(), shifted(make_series(), 7.3), motion_start_s=7.3)
    assert [(r["row_start"], r["row_stop"], r["force_N"]) for r in moved] == \
        [(r["row_start"], r["row_stop"], r["force_N"]) for r in base]
    assert [r["velocity_m_s"] for r in moved] == pytest.approx([r["velocity_m_s"] for r in base], rel=1e-9)
    assert moved[0]["window_start_s"] == pytest.approx(7.3 + 4.5)     # on the record's own time axis


def test_windows_follow_a_delayed_motion():
    base = case_windows(plan(), make_series())
    late = case_windows(plan(), delayed(make_series(), 2), motion_start_s=0.2)
    assert [(r["row_start"], r["row_stop"]) for r in late] == [(r["row_start"] + 2, r["row_stop"] + 2) for r in base]
    assert [r["force_N"] for r in late] == [r["force_N"] for r in base]


def test_a_shifted_time_axis_without_its_motion_start_is_refused():
    with pytest.raises(ValueError, match=r"window of segment 1 starts at t = 4.5 s, before the record's first "
                                         r"sample at 7.3 s"):
        case_windows(plan(), shifted(make_series(), 7.3))


def test_window_ranges_default_is_plan_time():
    t = make_series()["time_s"].to_numpy()
    assert window_ranges(plan(), t, WindowSpec()) == window_ranges(plan(), t, WindowSpec(), 0.0)
    assert window_ranges(plan(), t, WindowSpec())[0] == (1, 1.0, 45, 96)


def test_windowed_half_periods_are_on_the_record_time_axis():
    rows = windowed_half_periods(plan(), 47.3, WindowSpec(), motion_start_s=7.3)
    np.testing.assert_allclose(rows[:, :2], [[7.3, 17.3], [17.3, 27.3], [27.3, 37.3], [37.3, 47.3]])


def test_delay_too_large_for_the_record_leaves_three_windows():
    late = case_windows(plan(), delayed(make_series(), 6), motion_start_s=0.6)
    base = case_windows(plan(), make_series())
    assert [(r["row_start"], r["row_stop"]) for r in late] == \
        [(r["row_start"] + 6, r["row_stop"] + 6) for r in base[:3]]


def test_extract_windows_cuts_each_case_at_its_motion_start():
    base = dict(campaign="c", sample_rate_Hz=10.0, amplitude_m=1e-3, period_s=20.0, frequency_Hz=math.nan,
                phase_rad=-math.pi / 2, duration_s=40.0, raw_file="f.csv", raw_sha256="ab",
                timeseries_file="x", n_samples=401, waveform="triangle", status="ok")
    cases = pd.DataFrame([{**base, "case": "T01", "motion_start_s": 0.0},
                          {**base, "case": "T02", "motion_start_s": 7.3},
                          {**base, "case": "T03", "motion_start_s": math.nan}])
    series = {"T01": make_series(), "T02": shifted(make_series(), 7.3), "T03": make_series()}
    out = extract_windows(cases, lambda row: series[row["case"]], WindowSpec()).set_index(["case", "segment"])
    for case in ("T02", "T03"):
        np.testing.assert_array_equal(out.loc[case, "force_N"], out.loc["T01", "force_N"])
    assert out.loc[("T02", 1), "window_start_s"] == pytest.approx(11.8)
    assert out.loc[("T03", 1), "window_start_s"] == pytest.approx(4.5)   # NaN: plan time, as without the column


# --- dropped samples: the windows on the real time axis ----------------------------------------------

def dropped(series: pd.DataFrame, rows) -> pd.DataFrame:
    """The series without the samples of ``rows`` (a logger's dropouts); the rest keep their row numbers."""
    return series[~series["row"].isin(list(rows))].reset_index(drop=True)


def test_complete_window_mean_is_the_plain_mean_of_its_samples():
    series = make_series()
    series["force_N"] += np.random.default_rng(5).normal(0.0, 3.0, len(series))
    rows = case_windows(plan(), series)
    for r in rows:
        assert r["force_N"] == series["force_N"].iloc[r["row_start"]:r["row_stop"]].mean()
        assert r["missing_samples"] == 0


def test_window_with_a_burst_missing_gives_the_time_mean_of_a_drifting_force():
    series = make_series()
    series["force_N"] += 2.0 * series["time_s"]                 # a slow drift, 2 N/s
    burst = range(46, 53)                                       # 7 samples early in window 1 (t = 4.5 .. 9.5 s)
    row = case_windows(plan(), dropped(series, burst))[0]
    time_mean = LEVELS_N[0] + 2.0 * (4.5 + 9.5) / 2             # the drift's mean over the whole window
    kept = series[(series.time_s >= 4.5) & (series.time_s <= 9.5) & ~series.row.isin(list(burst))]
    assert kept["force_N"].mean() > time_mean + 0.5             # the plain mean leans to the window's end
    assert row["force_N"] == pytest.approx(time_mean, abs=1e-9)


def test_missing_samples_of_each_window_are_the_dropped_rows_inside_it():
    series = make_series()
    rows = case_windows(plan(), dropped(series, [*range(40, 50), 150, 151, 230, *range(393, 398)]))
    # window k holds rows 45..95 (+100 k): 5 of the first burst, 2, 0, and 3 of the burst 393..397
    assert [r["missing_samples"] for r in rows] == [5, 2, 0, 3]
    assert [r["n_samples"] for r in rows] == [46, 49, 51, 48]


def test_window_velocity_uses_the_real_time_stamps():
    rows = case_windows(plan(), dropped(make_series(), [*range(50, 60), 70, 160, *range(300, 320)]))
    expected = 4 * 1e-3 / 20.0                                  # noise-free triangle: W = 4Y/T exactly
    assert [r["velocity_m_s"] for r in rows] == pytest.approx([expected, -expected] * 2, rel=1e-9)


def test_motion_start_is_the_cases_column_and_zero_when_absent_or_not_a_number():
    assert motion_start(pd.Series({"motion_start_s": 7.3})) == 7.3
    assert motion_start({"motion_start_s": 0.25}) == 0.25
    for row in ({}, {"motion_start_s": None}, {"motion_start_s": math.nan}, pd.Series({"case": "T01"})):
        assert motion_start(row) == 0.0


def noisy_series(sigma_N: float = 9.0, seed: int = 11) -> pd.DataFrame:
    """make_series with white force noise (the issue's window: a 759 N level, 9 N of noise)."""
    series = make_series()
    series["force_N"] += 659.0 + np.random.default_rng(seed).normal(0.0, sigma_N, len(series))
    return series


def test_a_spike_in_a_window_gives_the_clean_twins_point_within_its_standard_error_counted():
    clean = noisy_series()
    spiked = clean.copy()
    spiked.loc[70, "force_N"] += 10_000.0                      # one 10 kN sample in window 1 (rows 45..95)
    before, after = case_windows(plan(), clean), case_windows(plan(), spiked)
    naive = spiked["force_N"].iloc[45:96].mean()
    se = before[0]["force_std_N"] / math.sqrt(before[0]["n_samples"])
    assert abs(naive - before[0]["force_N"]) > 100 * se          # what the plain mean did: 196 N off
    assert abs(after[0]["force_N"] - before[0]["force_N"]) < se
    assert after[0]["force_std_N"] == pytest.approx(before[0]["force_std_N"], rel=0.1)
    assert after[0]["spikes_excluded"] == 1 and after[0]["n_samples"] == 50 and not after[0]["set_aside"]
    assert before[1:] == after[1:] and all(r["spikes_excluded"] == 0 for r in before)


def test_a_window_without_a_spike_is_reduced_exactly_as_before():
    series = noisy_series(seed=12)
    for r in case_windows(plan(), series):
        samples = series["force_N"].iloc[r["row_start"]:r["row_stop"]]
        assert r["force_N"] == samples.mean() and r["force_std_N"] == samples.std(ddof=1)
        assert r["n_samples"] == len(samples) and r["spikes_excluded"] == 0 and r["set_aside"] == ""


def test_too_many_spikes_set_a_window_aside_with_its_reason():
    series = noisy_series(seed=13)
    series.loc[[150, 160, 170], "force_N"] -= 8000.0           # three spikes in window 2 (rows 145..195)
    cases = pd.DataFrame([dict(campaign="c", case="T01", waveform="triangle", status="ok", sample_rate_Hz=10.0,
                               amplitude_m=1e-3, period_s=20.0, frequency_Hz=math.nan, phase_rad=-math.pi / 2,
                               duration_s=40.0, raw_file="f.csv", raw_sha256="ab", timeseries_file="x",
                               n_samples=401)])
    notes: dict[str, str] = {}
    win = extract_windows(cases, lambda row: series, WindowSpec(), notes)
    assert win["segment"].tolist() == [1, 3, 4]
    assert "window 2 (-, period 1): 3 spike samples of 51" in notes["T01"] and "set aside" in notes["T01"]


def test_a_force_step_or_transient_inside_a_window_is_not_clipped():
    series = noisy_series(seed=14)
    series.loc[60:, "force_N"] += 400.0                         # a step in window 1
    series.loc[250:262, "force_N"] += 300.0 * np.exp(-np.arange(13) / 3.0)   # a relaxation in window 3
    for r in case_windows(plan(), series):
        assert r["spikes_excluded"] == 0
        assert r["force_N"] == series["force_N"].iloc[r["row_start"]:r["row_stop"]].mean()
