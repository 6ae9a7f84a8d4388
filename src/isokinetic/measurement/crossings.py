"""Crossings of zero with hysteresis: a signal changes side only when it passes the opposite threshold, so
noise near zero makes no extra crossing. One mechanism for the sine cycles of the peak-velocity method, the
half-cycles of harmonic records and the steps of a stepped record."""

from __future__ import annotations

import numpy as np


def hysteresis_crossings(x, hysteresis: float) -> tuple[np.ndarray, np.ndarray]:
    """(i, sign) of each change of side of ``x`` (sign +1 rising, -1 falling), vectorised.

    The side is decided only where |x| > ``hysteresis`` and held in between; a change of the held side is a
    crossing, placed at the actual change of sign before it: i is the first sample on the new side (the
    crossing lies between samples i - 1 and i). The first decided side is no crossing."""
    x = np.asarray(x, dtype=float)
    state = np.where(x > hysteresis, 1, np.where(x < -hysteresis, -1, 0))
    idx = np.arange(x.size)
    last = np.maximum.accumulate(np.where(state != 0, idx, -1))
    held = np.where(last >= 0, state[np.maximum(last, 0)], 0)
    flips = np.flatnonzero((held[1:] != held[:-1]) & (held[:-1] != 0)) + 1
    sign = held[flips]
    last_not_above = np.maximum.accumulate(np.where(x <= 0, idx, -1))   # sign(x) != +1
    last_not_below = np.maximum.accumulate(np.where(x >= 0, idx, -1))   # sign(x) != -1
    before = np.where(sign > 0, last_not_above[flips - 1], last_not_below[flips - 1])
    return before + 1, sign.astype(float)
