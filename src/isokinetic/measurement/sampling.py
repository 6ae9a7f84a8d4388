"""Sampling of a record: its sample interval and its gaps (dropped samples) on the real time axis.

A busy logger drops samples, one at a time or in bursts; the time stamps of the samples it keeps
stay on its regular grid. The record's sample interval is therefore the *median* interval (a few
percent of dropouts leave it unchanged), and an interval above ``GAP_FACTOR`` times it is a gap of
round(interval / dt) - 1 missing samples, at the grid times t_before + k·dt, k = 1 .. missing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: An interval above GAP_FACTOR sample intervals is a gap (timing jitter stays well below).
GAP_FACTOR = 1.5


def sample_interval_s(t_s) -> float:
    """The record's sample interval: the median of its time-stamp intervals [s] (NaN under 2 samples)."""
    t = np.asarray(t_s, dtype=float)
    return float(np.median(np.diff(t))) if t.size > 1 else math.nan


@dataclass(frozen=True)
class Gaps:
    """The gaps of a record: for each, the index of the last sample before it (``before``), the
    samples missing in it (``missing``) and the interval between the samples either side [s]."""

    before: np.ndarray
    missing: np.ndarray
    interval_s: np.ndarray

    @property
    def total_missing(self) -> int:
        return int(self.missing.sum())

    @property
    def longest_s(self) -> float:
        """The longest interval without a sample, 0 when there is no gap [s]."""
        return float(self.interval_s.max()) if self.interval_s.size else 0.0


def find_gaps(t_s, dt_s: float, factor: float = GAP_FACTOR) -> Gaps:
    """Intervals above ``factor``·dt_s, each missing round(interval/dt_s) - 1 samples (at least 1)."""
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
        return self.present + self.missing

    @property
    def missing_fraction(self) -> float:
        return self.missing / self.expected if self.expected else 0.0


def span_sampling(t_s, start_s: float, end_s: float, dt_s: float, gaps: Gaps | None = None) -> SpanSampling:
    """Present and missing samples of [start_s, end_s] on the record's grid (:func:`find_gaps`).

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
