"""The spike rule (isokinetic.measurement.spikes): isolated samples far outside a window's spread are found, and
noise, steps, transients and smooth curves are not; checked on records built here with known spikes."""

import math

import numpy as np
from scipy.signal import lfilter

from isokinetic.measurement.spikes import MAX_RUN, running_medians, spike_mask, too_many, too_many_note


def noise(n: int, seed: int, sigma: float = 9.0) -> np.ndarray:
    return sigma * np.random.default_rng(seed).standard_normal(n)


def test_one_spike_in_a_noisy_window_is_found_and_nothing_else():
    f = 759.0 + noise(600, 1)
    f[300] += 10_000.0
    mask = spike_mask(f, 50, 550)
    assert np.flatnonzero(mask).tolist() == [250]


def test_gaussian_white_and_coloured_noise_give_no_spike():
    rng = np.random.default_rng(2)
    flagged = 0
    for _ in range(100):
        white = rng.standard_normal(3000)
        ar1 = lfilter([math.sqrt(1 - 0.81)], [1, -0.9], rng.standard_normal(3000))
        coloured = 0.3 * rng.standard_normal(3000) + ar1
        flagged += int(spike_mask(white, 100, 2900).sum()) + int(spike_mask(coloured, 100, 2900).sum())
    assert flagged == 0


def test_a_force_step_inside_or_at_the_end_of_a_window_is_no_spike():
    f = noise(400, 3)
    f[200:] += 500.0                     # a step of 55 sigma in the window
    assert not spike_mask(f, 50, 350).any()
    g = noise(400, 4)
    g[298:] += 500.0                     # the step two samples before the window ends, the record continuing
    assert not spike_mask(g, 50, 300).any()


def test_a_transient_longer_than_a_few_samples_is_kept():
    t = np.arange(400, dtype=float)
    bump = 400.0 * np.exp(-0.5 * ((t - 200.0) / 4.0) ** 2)          # a smooth event, ~10 samples wide
    decay = np.where(t >= 100, 300.0 * np.exp(-(t - 100.0) / 6.0), 0.0)   # a relaxation from a jump
    assert not spike_mask(bump + noise(400, 5), 20, 380).any()
    assert not spike_mask(decay + noise(400, 6), 20, 380).any()


def test_a_run_of_three_outliers_is_a_spike_and_a_run_of_four_an_event():
    f = noise(300, 7)
    f[100:100 + MAX_RUN] += 5000.0
    f[200:200 + MAX_RUN + 1] += 5000.0
    mask = spike_mask(f, 0, 300)
    assert np.flatnonzero(mask).tolist() == list(range(100, 100 + MAX_RUN))


def test_a_constant_or_quantised_window_has_no_spike_but_a_jump_of_it_is_one():
    const = np.full(100, 1234.5)
    const[::7] += 1e-12                  # float rounding
    assert not spike_mask(const, 0, 100).any()
    quantised = np.round(0.3 * np.random.default_rng(8).standard_normal(200)) * 0.5   # mostly one level
    assert not spike_mask(quantised, 0, 200).any()
    quantised[120] = 40.0
    assert np.flatnonzero(spike_mask(quantised, 0, 200)).tolist() == [120]


def test_a_coarse_smooth_peak_taken_off_its_quadratic_is_no_spike_and_a_spike_on_it_is_found():
    # the force around a velocity peak of a sine sampled 64 times a cycle, +-T/8: 17 samples
    phase = 2.0 * math.pi * np.arange(-8, 9) / 64.0
    f = 1000.0 * np.cos(phase) + noise(phase.size, 9, sigma=2.0)
    assert not spike_mask(f, 0, f.size, detrend=True).any()
    f[9] += 3000.0
    assert np.flatnonzero(spike_mask(f, 0, f.size, detrend=True)).tolist() == [9]


def test_a_window_too_short_to_judge_has_no_spike():
    f = np.array([1.0, 2.0, 1e6, 2.0, 1.0])
    assert not spike_mask(f, 0, 5).any()


def test_more_than_one_spike_or_one_percent_of_a_window_sets_it_aside():
    assert not too_many(1, 50) and too_many(2, 50)
    assert not too_many(5, 500) and too_many(6, 500)
    assert "set aside" in too_many_note(6, 500) and "6 spike samples of 500" in too_many_note(6, 500)


def test_short_windows_in_a_noisy_record_give_no_spike():
    # a window's own MAD of a dozen samples is uncertain by a third: the scale of the 200 samples around it holds
    rng = np.random.default_rng(10)
    flagged = 0
    for n in (11, 16, 25, 40):
        for _ in range(2000):
            f = rng.standard_normal(n + 400)
            flagged += int(spike_mask(f, 200, 200 + n).sum())
    assert flagged == 0


def test_the_running_medians_are_each_samples_window_median_with_and_without_it():
    rng = np.random.default_rng(5)
    for n in (3, 7, 11, 40):
        x = np.round(np.cumsum(rng.standard_normal(n)) * 2.0) / 2.0   # quantised: ties in most windows
        x[rng.integers(n)] += 50.0
        padded = np.concatenate([2 * x[0] - x[5:0:-1], x, 2 * x[-1] - x[-2:-7:-1]]) if n > 5 else None
        own, apart = running_medians(x)
        for i in range(n):
            window = padded[i:i + 11] if padded is not None else x
            assert own[i] == np.median(window)
            assert apart[i] == (np.median(np.delete(window, 5)) if padded is not None else np.median(x))
