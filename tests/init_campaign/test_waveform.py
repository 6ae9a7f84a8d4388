"""Waveform detection: a triangle's period, amplitude and phase, a sine's frequency and amplitude, else free."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.init_campaign.waveform import detect_waveform, round_to_uncertainty
from isokinetic.physics.plan import sine_displacement, triangle_displacement

T = np.arange(4000) / 100.0          # two periods of 20 s at 100 Hz
TS = np.arange(5714) / 1000.0        # ten periods of 1.75 Hz at 1 kHz


@pytest.fixture
def rng():
    return np.random.default_rng(20240601)


@pytest.mark.parametrize("value, se, rounded", [(20.0000131, 1e-5, 20.0), (19.98816, 0.0089, 20.0),
                                                (1.2200506, 3.9e-5, 1.22), (12.4999289, 9e-5, 12.5),
                                                (20.0031, 1e-5, 20.0031), (240.0, 0.0, 240.0)])
def test_round_to_uncertainty_keeps_the_fewest_digits_within_four_standard_errors(value, se, rounded):
    assert round_to_uncertainty(value, se) == rounded


def test_clean_triangle_gives_its_plan_exactly():
    w = detect_waveform(T, triangle_displacement(T, 1.22e-3, 20.0))
    assert (w.kind, w.period_s.rounded, w.amplitude_m.rounded_amplitude, w.phase_rad) == \
        ("triangle", 20.0, 1.22e-3, -math.pi / 2)


def test_noisy_triangle_still_gives_its_period(rng):
    y = triangle_displacement(T, 1e-3, 20.0) + rng.normal(0.0, 0.05e-3, T.size)     # noise 5 % of the amplitude
    w = detect_waveform(T, y)
    assert w.kind == "triangle" and w.period_s.rounded == 20.0
    assert abs(w.amplitude_m.value / 1e-3 - 1.0) < 0.01
    assert w.phase_rad == -math.pi / 2


@pytest.mark.parametrize("phase_rad", [math.pi / 2, 0.7, -2.5])
def test_triangle_phase(phase_rad):
    w = detect_waveform(T, triangle_displacement(T, 1e-3, 20.0, phase_rad))
    assert w.kind == "triangle" and w.phase_rad == pytest.approx(phase_rad, abs=1e-9)


def test_a_delayed_start_keeps_the_default_phase(rng):
    y = triangle_displacement(np.maximum(T - 0.2, 0.0), 1e-3, 20.0) + rng.normal(0.0, 1e-6, T.size)
    w = detect_waveform(T + 5.0, y)                     # a time axis from 5 s, the motion 0.2 s late
    assert w.phase_rad == -math.pi / 2 and "+0.2 s from the first sample" in w.phase_note


def test_triangle_period_off_the_record_length(rng):
    t = np.arange(4125) / 100.0
    w = detect_waveform(t, triangle_displacement(t, 1e-3, 12.5) + rng.normal(0.0, 1e-6, t.size))
    assert w.period_s.rounded == 12.5


def test_sine_gives_frequency_and_amplitude(rng):
    w = detect_waveform(TS, sine_displacement(TS, 0.23e-3, 1.75))
    assert (w.kind, w.frequency_Hz.rounded, w.amplitude_m.rounded_amplitude) == ("sine", 1.75, 0.23e-3)
    noisy = detect_waveform(TS, sine_displacement(TS, 0.23e-3, 1.75) + rng.normal(0.0, 0.023e-3, TS.size))
    assert (noisy.kind, noisy.frequency_Hz.rounded) == ("sine", 1.75)
    assert abs(noisy.amplitude_m.value / 0.23e-3 - 1.0) < 0.01


@pytest.mark.parametrize("name, y", [
    ("two frequencies", 2e-4 * np.sin(2 * np.pi * 0.7 * TS) + 1e-4 * np.sin(2 * np.pi * 1.9 * TS + 0.3)),
    ("crank with a second harmonic", 1e-3 * (np.sin(2 * np.pi * 2 * TS) + 0.15 * np.cos(4 * np.pi * 2 * TS))),
    ("square", 1e-3 * np.sign(np.sin(2 * np.pi * 2 * TS + 0.1))),
    ("random walk", np.cumsum(np.random.default_rng(3).normal(0.0, 1e-6, TS.size))),
    ("half a period", 1e-3 * np.sin(2 * np.pi * 0.05 * TS)),
    ("no motion", np.zeros(TS.size)),
])
def test_anything_else_is_free(name, y):
    w = detect_waveform(TS, y)
    assert w.kind == "free", w.how
    assert w.period_s is None and w.frequency_Hz is None


def test_line_fits_are_bounded_by_the_samples_whatever_the_last_time_stamp():
    """A loop over half-periods up to the last stamp would not end for 1e308 (it ran until the record's end)."""
    from isokinetic.init_campaign.waveform import line_fits

    period, amplitude = 4.0, 1e-3
    tau = np.arange(0.0, 8.0, 0.01)
    phase = -np.pi / 2
    y = amplitude * (2.0 / np.pi) * np.arcsin(np.sin(2.0 * np.pi * tau / period + phase))
    good = line_fits(tau, y, period, phase)
    for last in (1e308, 3.0e9):                  # a broken stamp; a year typo in seconds
        broken = tau.copy()
        broken[-1] = last
        fits = line_fits(broken, y, period, phase)
        np.testing.assert_array_equal(fits[:-1], good[:-1])


def test_a_fast_sine_with_servo_harmonics_is_a_sine():
    """An MTS sweep's 10 Hz step: the servo adds 3 % of a second and 2 % of a third harmonic."""
    t = np.arange(2048) / 1024.0
    w = 2 * np.pi * 10.0
    y = 0.0127 * (np.sin(w * t) + 0.03 * np.sin(2 * w * t + 0.4) + 0.02 * np.sin(3 * w * t - 1.0))
    found = detect_waveform(t, y)
    assert found.kind == "sine" and found.frequency_Hz.value == pytest.approx(10.0, rel=1e-4)
