"""Sampling of a record: its sample interval and its gaps (dropped samples) on the real time axis.

A busy logger drops samples, one at a time or in bursts; the time stamps of the samples it keeps
stay on its regular grid. Some loggers also round their time stamps (to 5 significant digits, say:
12.345 s, so that at 300 Hz the steps are 3 ms and 4 ms and the median step is 10 % short). The record's
sample interval (:func:`sample_interval_s`) is therefore the *mean of its steps below* ``GAP_FACTOR`` times
the median step: a dropout leaves a step of two or more intervals, above that bound, and is left out; rounded
stamps leave steps of two adjacent multiples of their resolution, k and k + 1, both below the bound when
k >= 2, and their mean is the interval. Where the stamps' resolution is as coarse as the interval itself
(k = 1: 900 Hz stamped to the millisecond, steps of 1 and 2 ms) the stamps cannot tell rounding from one
dropped sample in nine; the steps of 2 ms are then read as gaps, and the record's missing fraction says so.
An interval above ``GAP_FACTOR`` times the sample interval is a gap of round(interval / dt) - 1 missing
samples, at the grid times t_before + k·dt, k = 1 .. missing. Validate's rate check and ``init-campaign``
(its draft and ``--check``) use this one estimator and one tolerance, the settings' ``sample_rate_tolerance``
(:class:`isokinetic.contracts.settings.Settings`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: An interval above GAP_FACTOR sample intervals is a gap (timing jitter stays well below).
GAP_FACTOR = 1.5
#: Steps per span of the interval estimator: a span's mean step averages rounded time stamps out (to 1 % of a
#: step when they are rounded to a whole interval).
SPAN_STEPS = 100
#: A record is cut into at least this many spans (shorter spans for a short record, down to single steps).
MIN_SPANS = 8


def span_intervals_s(t_s) -> np.ndarray:
    """The mean step of each span of k consecutive steps (k = :data:`SPAN_STEPS`, fewer in a record of under
    :data:`MIN_SPANS` spans), spans holding a dropped sample (longer than k + 1/2 steps of the median span's)
    left out [s]; empty under 2 samples."""
    t = np.asarray(t_s, dtype=float)
    steps = t.size - 1
    if steps < 1:
        return np.empty(0)
    k = max(1, min(SPAN_STEPS, steps // MIN_SPANS))
    spans = np.diff(t[::k]) / k
    for _ in range(2):                   # the second pass from the median of the spans without a dropout
        kept = spans[spans * k < (k + 0.5) * float(np.median(spans))]
        spans = kept if kept.size else spans
    return spans


def sample_interval_s(t_s) -> float:
    """The record's sample interval: the mean of its steps below ``GAP_FACTOR`` times the median step (module
    doc: dropouts left out, rounded time stamps averaged) [s]; NaN under 2 samples."""
    steps = np.diff(np.asarray(t_s, dtype=float))
    if steps.size < 1:
        return math.nan
    kept = steps[steps < GAP_FACTOR * float(np.median(steps))]
    return float(kept.mean()) if kept.size else float(np.median(steps))


def sample_interval_error_s(t_s) -> float:
    """The standard error of :func:`sample_interval_s`: the spans' spread over the root of their number
    (times 1.25, a median's) [s]; NaN under 2 samples."""
    spans = span_intervals_s(t_s)
    if spans.size < 2:
        return 0.0 if spans.size else math.nan
    return 1.25 * float(np.std(spans, ddof=1)) / math.sqrt(spans.size)


def rate_offset(t_s, sample_rate_Hz: float) -> float:
    """How far the record's sample interval lies off 1/sample_rate_Hz, as a fraction (positive: longer)."""
    return sample_interval_s(t_s) * sample_rate_Hz - 1.0


@dataclass(frozen=True)
class Gaps:
    """The gaps of a record: for each, the index of the last sample before it (``before``), the
    samples missing in it (``missing``) and the interval between the samples either side [s]."""

    before: np.ndarray
    missing: np.ndarray
    interval_s: np.ndarray

    @property
    def total_missing(self) -> int:
        """The number of samples missing in all gaps."""
        return int(self.missing.sum())

    @property
    def longest_s(self) -> float:
        """The longest interval without a sample, 0 when there is no gap [s]."""
        return float(self.interval_s.max()) if self.interval_s.size else 0.0


def find_gaps(t_s, dt_s: float, factor: float = GAP_FACTOR) -> Gaps:
    """The intervals above ``factor``·dt_s, each missing round(interval/dt_s) - 1 samples (at least 1)."""
    t = np.asarray(t_s, dtype=float)
    intervals = np.diff(t)
    before = np.flatnonzero(intervals > factor * dt_s)
    # clipped before the cast: a gap of 1e308 s (a broken time stamp) counts 2**62 samples, not an overflow
    with np.errstate(over="ignore"):
        missing = np.maximum(np.minimum(np.rint(intervals[before] / dt_s), 2.0 ** 62).astype(np.int64) - 1, 1)
    return Gaps(before=before, missing=missing, interval_s=intervals[before])


@dataclass(frozen=True)
class SpanSampling:
    """Samples of a time span [start, end]: present, missing (grid times inside the span that fell in a
    gap), the longest gap missing samples of the span [s] (0: none) and the index of the first sample
    after the first such gap (None: none)."""

    present: int
    missing: int
    longest_gap_s: float
    first_after_gap: int | None

    @property
    def expected(self) -> int:
        """The number of samples the span holds on the record's grid, present or missing."""
        return self.present + self.missing

    @property
    def missing_fraction(self) -> float:
        """The fraction of the expected samples that are missing (0 for an empty span)."""
        return self.missing / self.expected if self.expected else 0.0


def span_sampling(t_s, start_s: float, end_s: float, dt_s: float, gaps: Gaps | None = None) -> SpanSampling:
    """The present and missing samples of [start_s, end_s] on the record's grid (:func:`find_gaps`).

    A gap's missing samples lie at t_before + k·dt_s (k = 1 .. missing); those within the span count,
    so a burst across a span edge counts only its part inside. Nothing is counted before the first
    or after the last sample of the record. Samples within 1e-6·dt_s of an edge are on it.
    """
    t = np.asarray(t_s, dtype=float)
    gaps = find_gaps(t, dt_s) if gaps is None else gaps
    eps = 1e-6 * dt_s
    present = int(np.searchsorted(t, end_s + eps, side="right") - np.searchsorted(t, start_s - eps, side="left"))
    ta, tb = t[gaps.before], t[gaps.before + 1]
    over = (ta < end_s + eps) & (tb > start_s - eps)
    k_lo = np.maximum(1, np.ceil((start_s - eps - ta[over]) / dt_s))
    k_hi = np.minimum(gaps.missing[over], np.floor((end_s + eps - ta[over]) / dt_s))
    counts = np.maximum(k_hi - k_lo + 1, 0).astype(np.int64)
    hit = counts > 0
    inside = gaps.before[over][hit]
    return SpanSampling(present=present, missing=int(counts.sum()),
                        longest_gap_s=float(gaps.interval_s[over][hit].max()) if hit.any() else 0.0,
                        first_after_gap=int(inside[0]) + 1 if inside.size else None)
