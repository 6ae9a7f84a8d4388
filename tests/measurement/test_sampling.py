"""Sampling of a record (measurement.sampling): the sample interval and the gaps of a logger that drops samples."""

from __future__ import annotations

import numpy as np
import pytest

from isokinetic.contracts.settings import DEFAULTS
from isokinetic.measurement.sampling import (
    find_gaps,
    rate_offset,
    sample_interval_error_s,
    sample_interval_s,
    span_sampling,
)

DT = 0.01


def grid(n=1000, dt=DT, jitter=0.0, seed=3):
    """A regular time axis of ``n`` samples, optionally with time-stamp jitter (uniform, ± jitter·dt)."""
    rng = np.random.default_rng(seed)
    return np.arange(n) * dt + rng.uniform(-jitter, jitter, n) * dt


def drop(t, indices):
    return np.delete(t, list(indices))


def test_sample_interval_is_the_median_so_dropouts_do_not_change_it():
    t = drop(grid(), range(1, 400, 3))          # a third of the first 400 samples lost in singles
    assert np.mean(np.diff(t)) > 1.1 * DT
    assert sample_interval_s(t) == pytest.approx(DT, rel=1e-9)


def test_gaps_count_singles_and_bursts_at_their_place():
    t = drop(grid(), [100, *range(500, 537), 900])
    gaps = find_gaps(t, DT)
    assert gaps.missing.tolist() == [1, 37, 1]
    assert gaps.total_missing == 39
    assert t[gaps.before].tolist() == pytest.approx([0.99, 4.99, 8.99])      # the sample before each gap
    assert gaps.longest_s == pytest.approx(38 * DT)


def test_time_stamp_jitter_is_not_a_gap():
    t = grid(jitter=0.2)
    assert find_gaps(t, sample_interval_s(t)).total_missing == 0
    assert find_gaps(drop(t, [300, 301]), sample_interval_s(t)).missing.tolist() == [2]


def test_a_complete_record_has_no_gap():
    gaps = find_gaps(grid(), DT)
    assert (gaps.total_missing, gaps.longest_s) == (0, 0.0)


def test_span_counts_the_missing_samples_of_the_grid_inside_it():
    full = grid()
    dropped = [*range(195, 210), 250, *range(296, 305)]        # a burst across 2.0 s, a single, a burst across 3.0 s
    t = drop(full, dropped)
    span = span_sampling(t, 2.0, 3.0, DT)
    inside = [i for i in dropped if 2.0 - 1e-9 <= full[i] <= 3.0 + 1e-9]   # the grid's own count
    assert (span.missing, span.present) == (len(inside), 101 - len(inside))
    assert span.expected == 101
    assert span.missing_fraction == pytest.approx(len(inside) / 101)
    assert span.longest_gap_s == pytest.approx(16 * DT)
    assert t[span.first_after_gap] == pytest.approx(full[210])


def test_span_without_missing_samples():
    t = drop(grid(), range(100, 120))
    span = span_sampling(t, 5.0, 6.0, DT)
    assert (span.missing, span.longest_gap_s, span.first_after_gap, span.present) == (0, 0.0, None, 101)


def test_span_inside_one_gap_misses_all_its_samples():
    t = drop(grid(), range(100, 200))
    span = span_sampling(t, 1.2, 1.5, DT)
    assert (span.present, span.missing, span.missing_fraction) == (0, 31, 1.0)


def test_a_gap_of_1e308_seconds_counts_without_overflow():
    """Issue 20: a broken time stamp gives a huge but finite count, no int64 overflow (or warning)."""
    t = np.append(np.arange(10) * 0.01, 1e308)
    gaps = find_gaps(t, 0.01)
    assert gaps.before.tolist() == [9] and gaps.missing[0] == 2 ** 62 - 1 and gaps.total_missing > 0


def rounded(rate_Hz: float, n: int = 20000, start_s: float = 10.0) -> np.ndarray:
    """A logger's time stamps rounded to 5 significant digits (12.345 s: 1 ms resolution from 10 s on)."""
    return np.array([float(f"{x:.5g}") for x in start_s + np.arange(n) / rate_Hz])


def test_rounded_time_stamps_give_the_interval_as_the_mean_step_not_the_median():
    """At 300 Hz stamped to the millisecond the steps are 3 and 4 ms: the median step is 10 % short."""
    t = rounded(300.0)
    assert np.median(np.diff(t)) == pytest.approx(3e-3)
    assert sample_interval_s(t) == pytest.approx(1.0 / 300.0, rel=1e-3)
    assert abs(rate_offset(t, 300.0)) < 1e-3 and abs(rate_offset(t, 330.0)) > DEFAULTS.sample_rate_tolerance
    assert find_gaps(t, sample_interval_s(t)).total_missing == 0


def test_rounded_time_stamps_with_dropouts_keep_their_interval_and_count_the_gaps():
    t = drop(rounded(300.0), [*range(3000, 3030), *range(5000, 15000, 997)])
    assert sample_interval_s(t) == pytest.approx(1.0 / 300.0, rel=2e-3)
    assert find_gaps(t, sample_interval_s(t)).total_missing == 30 + len(range(5000, 15000, 997))
    assert sample_interval_error_s(t) < 1e-3 / 300.0


def test_stamps_as_coarse_as_the_interval_read_as_dropouts():
    """900 Hz stamped to the millisecond (steps of 1 and 2 ms) cannot be told from 1 kHz losing one sample in
    nine: the stamps are read as the latter, and the missing fraction (10 %) says so."""
    t = rounded(900.0)
    assert sample_interval_s(t) == pytest.approx(1e-3)
    assert find_gaps(t, sample_interval_s(t)).total_missing == pytest.approx(len(t) / 9, rel=0.02)
