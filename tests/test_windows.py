import math

import numpy as np
import pandas as pd
import pytest

from isokinetic.plan import CasePlan, triangle_displacement
from isokinetic.windows import WindowSpec, case_windows, extract_windows, line_slope

LEVELS_N = [100.0, -80.0, 101.0, -81.0]


def make_series(period_s=20.0, amplitude_m=1e-3, rate_Hz=10.0, transient_s=3.0):
    """Two periods with a steady level per half-period and a large transient that the window skips."""
    t = np.arange(0, round(2 * period_s * rate_Hz) + 1) / rate_Hz
    seg = np.minimum((t // (period_s / 2)).astype(int), 3)
    since = t - seg * period_s / 2
    force = np.take(LEVELS_N, seg) + np.where(since < transient_s, 5000.0, 0.0)
    return pd.DataFrame({"row": np.arange(t.size), "time_s": t,
                         "displacement_m": triangle_displacement(t, amplitude_m, period_s), "force_N": force})


def plan(period_s=20.0, amplitude_m=1e-3):
    return CasePlan(case="T01", waveform="triangle", sample_rate_Hz=10.0, amplitude_m=amplitude_m,
                    period_s=period_s, duration_s=2 * period_s)


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


def test_short_record_is_refused():
    series = make_series()
    with pytest.raises(ValueError, match="holds the windows of 3 half-periods"):
        case_windows(plan(), series[series.time_s <= 35.0])


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
    out = extract_windows(cases, lambda row: make_series())
    assert out["case"].unique().tolist() == ["T01"]
    assert len(out) == 4 and (out["raw_file"] == "f.csv").all() and (out["campaign"] == "c").all()
