"""Measured kinematics of a triangle case (motion.estimate_motion), on small numpy records."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lfilter, lfilter_zi

from isokinetic.measurement.motion import ends_early, estimate_motion, triangle_shape
from isokinetic.physics.plan import CasePlan, triangle_displacement, triangle_wave
from rigfiles import dropout_rows


def servo_lag(t, x, tau_s: float):
    """First-order lag (time constant tau_s) of x, exact for x linear between samples."""
    dt = t[1] - t[0]
    a = math.exp(-dt / tau_s)
    b0 = (dt - tau_s * (1 - a)) / dt
    b, den = [b0, (1 - a) - b0], [1.0, -a]
    return lfilter(b, den, x, zi=lfilter_zi(b, den) * x[0])[0]


def triangle_record(period_s=20.0, amplitude_m=1e-3, rate_Hz=100.0, delay_s=0.0, lag_s=0.0, noise_m=3e-6,
                    time_offset_s=0.0, gain=1.0, seed=1, oversample=10):
    """(t, y): a two-period triangle (Eq. 26, phase -π/2) held at -Y until ``delay_s``, through a servo
    lag, with LVDT noise, on a time axis starting at ``time_offset_s``."""
    n = int(round(2 * period_s * rate_Hz))
    fine = np.arange(n * oversample) / (rate_Hz * oversample)
    x = gain * triangle_displacement(np.maximum(fine - delay_s, 0.0), amplitude_m, period_s)
    y = servo_lag(fine, x, lag_s) if lag_s > 0 else x
    rng = np.random.default_rng(seed)
    return fine[::oversample] + time_offset_s, y[::oversample] + rng.normal(0.0, noise_m, n)


def plan(period_s=20.0, amplitude_m=1e-3, rate_Hz=100.0, phase_rad=-math.pi / 2):
    return CasePlan(case="T01", waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=amplitude_m,
                    period_s=period_s, phase_rad=phase_rad, duration_s=2 * period_s)


def test_triangle_shape_is_the_plans_triangle_held_before_the_start():
    tau = np.linspace(-3.0, 50.0, 1001)
    expected = np.where(tau < 0, -1.0, triangle_wave(2 * np.pi * tau / 20.0 - np.pi / 2))
    np.testing.assert_allclose(triangle_shape(tau, 20.0, -np.pi / 2), expected, atol=1e-12)


def test_record_that_starts_with_its_motion_has_no_delay():
    t, y = triangle_record()
    m = estimate_motion(t, y, plan())
    assert (m.motion_start_s, m.delay_s) == (0.0, 0.0)
    assert m.velocity_ratio == pytest.approx(1.0, abs=1e-3)


def test_delay_and_servo_lag_are_measured_within_2_ms():
    t, y = triangle_record(delay_s=0.015, lag_s=0.010)       # steady ramp lag: 15 + 10 ms
    m = estimate_motion(t, y, plan())
    assert m.delay_s == pytest.approx(0.025, abs=0.002)
    assert m.motion_start_s == pytest.approx(0.025, abs=0.002)


@pytest.mark.parametrize("period_s, amplitude_m", [(80.0, 0.5e-3), (240.0, 0.3e-3)])
def test_delay_of_slow_cases_is_measured_within_its_standard_error(period_s, amplitude_m):
    t, y = triangle_record(period_s, amplitude_m, delay_s=0.015, lag_s=0.010, noise_m=1e-6)
    m = estimate_motion(t, y, plan(period_s, amplitude_m))
    assert m.delay_s == pytest.approx(0.025, abs=max(4 * m.delay_std_s, 0.002))


def test_time_axis_offset_is_the_motion_start():
    t, y = triangle_record(time_offset_s=7.3)
    m = estimate_motion(t, y, plan())
    assert m.motion_start_s == 7.3 and m.delay_s == 0.0


def test_time_axis_offset_and_delay_together():
    t, y = triangle_record(time_offset_s=7.3, delay_s=0.015, lag_s=0.010)
    m = estimate_motion(t, y, plan())
    assert m.motion_start_s == pytest.approx(7.325, abs=0.002)
    assert m.delay_s == pytest.approx(0.025, abs=0.002)


def test_motion_that_started_before_the_record_has_a_negative_delay():
    t, y = triangle_record(delay_s=0.5)
    m = estimate_motion(t[60:] - t[60], y[60:], plan())       # record starts 0.1 s after the motion
    assert m.delay_s == pytest.approx(-0.1, abs=0.002)


@pytest.mark.parametrize("phase_rad", [-1.5707963, -1.5708])
def test_rounded_phase_gives_the_same_motion_as_minus_pi_over_2(phase_rad):
    t, y = triangle_record(delay_s=0.015, lag_s=0.010)
    assert estimate_motion(t, y, plan(phase_rad=phase_rad)) == estimate_motion(t, y, plan())


def test_velocity_of_each_half_period_is_measured():
    t, y = triangle_record(gain=1.2)
    m = estimate_motion(t, y, plan())
    np.testing.assert_allclose(m.velocity_ratios, 1.2, rtol=2e-3)
    w = 4 * 1e-3 / 20.0
    assert m.planned_velocities_m_s == pytest.approx((w, -w, w, -w))
    assert m.velocities_m_s == pytest.approx((1.2 * w, -1.2 * w, 1.2 * w, -1.2 * w), rel=2e-3)
    assert m.amplitude_m == pytest.approx(1.2e-3, rel=2e-3)


def test_amplitude_rounded_to_4_digits_in_the_manifest_still_matches():
    t, y = triangle_record(amplitude_m=0.123456e-3, noise_m=0.5e-6)
    m = estimate_motion(t, y, plan(amplitude_m=0.1235e-3))
    assert m.velocity_ratio == pytest.approx(1.0, abs=1e-3)
    assert m.excess_rms_m < 0.01 * 0.1235e-3


def test_inverted_displacement_moves_against_the_plan():
    t, y = triangle_record(gain=-1.0)
    m = estimate_motion(t, y, plan())
    assert (m.velocity_ratios < 0).all()
    assert m.velocity_ratio == pytest.approx(1.0, abs=1e-3)


def test_rms_departure_of_a_clean_triangle_is_the_lvdt_noise():
    t, y = triangle_record(noise_m=3e-6)
    m = estimate_motion(t, y, plan())
    assert m.rms_m == pytest.approx(3e-6, rel=0.05)
    assert m.noise_m == pytest.approx(3e-6, rel=0.1)
    assert m.excess_rms_m < 0.005 * 1e-3


def test_rms_departure_of_a_wrong_period_is_large():
    t, y = triangle_record(period_s=25.0, amplitude_m=1.25e-3)    # same speed, longer period
    m = estimate_motion(t, y, plan())
    assert m.excess_rms_m > 0.1 * 1e-3


def test_noise_free_record_is_exact():
    t, y = triangle_record(noise_m=0.0)
    m = estimate_motion(t, y, plan())
    assert (m.motion_start_s, m.delay_s) == (0.0, 0.0) and m.noise_m < 1e-15
    assert m.rms_m < 1e-15 and m.velocity_ratio == pytest.approx(1.0, abs=1e-12)


def test_a_48000_sample_record_gives_its_delay():
    # (its speed is a benchmark figure, not a test: timed assertions fail on a loaded machine)
    t, y = triangle_record(period_s=240.0, amplitude_m=0.3e-3, oversample=1, delay_s=0.02)
    m = estimate_motion(t, y, plan(240.0, 0.3e-3))
    assert t.size == 48000 and m.delay_s == pytest.approx(0.02, abs=0.005)


def test_only_triangle_cases_have_a_motion_to_estimate():
    sine = CasePlan(case="H01", waveform="sine", sample_rate_Hz=100.0, amplitude_m=1e-3, frequency_Hz=1.0)
    with pytest.raises(ValueError, match="case H01: motion is estimated for triangle cases, not sine"):
        estimate_motion(np.arange(100) / 100.0, np.zeros(100), sine)


def test_dropped_samples_leave_the_motion_unchanged():
    t, y = triangle_record(delay_s=0.015, lag_s=0.010)
    keep = np.ones(t.size, dtype=bool)
    keep[dropout_rows(t.size, seed=7)] = False
    full, thinned = estimate_motion(t, y, plan()), estimate_motion(t[keep], y[keep], plan())
    assert thinned.motion_start_s == pytest.approx(full.motion_start_s, abs=3 * full.delay_std_s)
    np.testing.assert_allclose(thinned.velocities_m_s, full.velocities_m_s, rtol=1e-3)
    assert thinned.noise_m == pytest.approx(full.noise_m, rel=0.1)
    assert thinned.rms_m == pytest.approx(full.rms_m, rel=0.05)


@pytest.mark.parametrize("end_s", [32.0, 25.0, 15.5])
def test_record_cut_short_measures_its_delay_from_the_half_periods_it_holds(end_s):
    t, y = triangle_record(delay_s=0.015, lag_s=0.010)
    keep = t < end_s
    m = estimate_motion(t[keep], y[keep], plan())
    assert ends_early(t[keep], plan())
    assert m.delay_s == pytest.approx(0.025, abs=0.002)
    held = int((end_s - 0.025) // 10.0) + (1 if (end_s - 0.025) % 10.0 >= 5.0 else 0)   # up to their middle
    assert np.isfinite(m.velocities_m_s).tolist() == [k < held for k in range(4)]


def test_complete_record_does_not_end_early():
    t, y = triangle_record()
    assert not ends_early(t, plan())
