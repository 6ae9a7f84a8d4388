"""Velocity bins of a free record (measurement.loops.binned_characteristic) near a friction reversal: the
reference is the analytic steady law at each bin's mean velocity, not the method."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from isokinetic.measurement.loops import RESOLVE_SIGMA, binned_characteristic, free_loop, velocity_noise_m_s

C1, F_C, V_C = 1500.0, 25.0, 2.0e-4      # N s/m, N, m/s: a damper with a sharp friction reversal


def law(v):
    return C1 * v + F_C * np.tanh(v / V_C)


def random_series(disp_noise_m=2.0e-6, seed=3) -> pd.DataFrame:
    """A smooth random displacement (sum of sines 0.2-3 Hz) at 300 Hz, 60 s, its steady force."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 60.0, 1.0 / 300.0)
    freqs = np.linspace(0.2, 3.0, 15)
    amps = 2.0e-3 / freqs
    phases = rng.uniform(0, 2 * math.pi, freqs.size)
    x = sum(a * np.sin(2 * math.pi * fr * t + ph) for a, fr, ph in zip(amps, freqs, phases, strict=True))
    v = sum(a * 2 * math.pi * fr * np.cos(2 * math.pi * fr * t + ph) for a, fr, ph in zip(amps, freqs, phases,
                                                                                        strict=True))
    return pd.DataFrame({"time_s": t, "displacement_m": x + disp_noise_m * rng.standard_normal(t.size),
                         "force_N": law(v)})


def test_velocity_noise_is_the_displacement_noise_times_the_derivatives_gain():
    # white displacement noise only (x = 0): the estimate's own scatter is the reference
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 20.0, 1e-3)
    x = 1e-5 * rng.standard_normal(t.size)
    from isokinetic.measurement.loops import smooth_velocity
    measured = float(np.std(smooth_velocity(t, x, 0.02)))
    assert velocity_noise_m_s(t, x, 0.02) == pytest.approx(measured, rel=0.1)


def test_no_bin_averages_the_friction_reversal_it_cannot_resolve():
    lp = free_loop(random_series())
    noise = lp.attrs["velocity_noise_m_s"]
    bins = binned_characteristic(lp)
    assert bins["bin_low_m_s"].abs().min() == pytest.approx(RESOLVE_SIGMA * noise)
    np.testing.assert_allclose(bins["force_N"], law(bins["velocity_m_s"].to_numpy()), rtol=0.01)


def test_bins_from_zero_speed_average_the_reversal_and_miss_the_law():
    # the same record binned from v = 0: the lowest bins hold samples whose velocity sign the noise flipped
    lp = free_loop(random_series())
    bins = binned_characteristic(lp, min_speed_m_s=0.0)
    lowest = bins.loc[bins["velocity_m_s"].abs().idxmin()]
    assert abs(lowest["force_N"] / law(lowest["velocity_m_s"]) - 1.0) > 0.02
