"""The steps of a stepped record: where one record holds several tests (a sine sweep in steps of frequency or
amplitude, a series of triangle ramps at different speeds) and standstill stretches between them.

Standstill: the displacement stays within :data:`FLAT_FRACTION` of the record's range (or a few noise levels) over
a sliding :data:`FLAT_WINDOW_S` window, for at least :data:`MIN_STANDSTILL_S`. Motion: the cycles between
successive upward crossings of the mid-stroke (with a hysteresis of a few noise levels), each with its period and
amplitude; consecutive cycles whose period and amplitude stay within :data:`STEP_TOLERANCE` of their group's
median are one step. A step is a run of cycles of one frequency and amplitude between rests or frequency changes:
a group inside continuous motion needs :data:`MIN_GROUP_CYCLES` cycles (a lone cycle there is a transition between
two steps and is left out), a group that is all the motion between two rests (:func:`between_rests`: a short step
of an MTS-style sweep, whose 2 cycles from a reversal hold only one whole cycle between mid-stroke crossings) is a
step whatever its count. A step's first :func:`settling_cycles` are left out (less the cycles of motion since the
last standstill, dwell or step, to the nearest whole one: those settled it), but never so many that fewer than
:data:`MIN_KEPT_CYCLES` remain: the characteristic stage measures settling on the record itself and gives a point
from one cycle. A step's slice runs over whole kept cycles, from an upward mid-stroke crossing (a sine's phase 0)
to the crossing that ends its last cycle; when the step then runs into a rest through less than a cycle (a sweep's
step ending at a reversal), that tail is the step's too (``tail_s``): a sine's slice runs on to the rest, so that
the velocity peak at the last crossing lies inside it. A triangle's slice is moved back a quarter period to start
at the reversal (the spec's phase -π/2). The bounds are rounded inwards to :func:`resolution` (at most 1 % of the
period).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.measurement.crossings import hysteresis_crossings
from isokinetic.measurement.motion import noise_level

#: Sliding window over which a standstill's displacement stays flat [s].
FLAT_WINDOW_S = 1.0
#: Flat: the window's range below this fraction of the record's range (and above the noise floor below).
FLAT_FRACTION = 0.02
#: ... or below this many noise levels (1σ) of the displacement.
FLAT_SIGMAS = 8.0
#: Shortest standstill drafted as a case [s] (its slice leaves out half a window at each end).
MIN_STANDSTILL_S = 2.0
#: A dwell: over this centred window [s] the range stays below this fraction of the record's range (or
#: :data:`FLAT_SIGMAS` noise levels). A sine's turning point is flatter than that only below about 0.07 Hz.
DWELL_WINDOW_S, DWELL_FRACTION = 0.25, 0.001
#: Hysteresis of the mid-stroke crossings: this many noise levels, or this fraction of the half range.
CROSSING_SIGMAS, CROSSING_FRACTION = 5.0, 0.01
#: Cycles whose period and amplitude stay within this fraction of their group's median are one step.
STEP_TOLERANCE = 0.05
#: Fewest similar cycles of a step; fewer are a transition.
MIN_GROUP_CYCLES = 2
#: Fewest steady cycles a drafted step keeps (the characteristic stage gives a point from one, flagged).
MIN_KEPT_CYCLES = 1


@dataclass(frozen=True)
class Step:
    """One stretch of a record: ``standstill`` or ``cycles`` (a steady step of a sine or triangle), its slice
    [start_s, end_s) on the file's own time axis, and for cycles the median period and amplitude of the kept
    cycles, how many were kept, how many settling or transition cycles were left out before them, the start
    of the first of those (``onset_s``), and the end of the motion after the last kept cycle when the step runs
    into a rest through less than a cycle (``tail_s``, NaN otherwise)."""

    kind: str
    start_s: float
    end_s: float
    period_s: float = math.nan
    amplitude_m: float = math.nan
    cycles: int = 0
    settling: int = 0
    onset_s: float = math.nan
    tail_s: float = math.nan


def resolution(period_s: float) -> float:
    """The rounding step of a slice's bounds: the power of ten at most 1 % of the period, in [1e-4, 0.1] s."""
    if not (math.isfinite(period_s) and period_s > 0):
        return 0.1
    return min(0.1, max(1e-4, 10.0 ** math.floor(math.log10(period_s / 100.0) + 0.01)))


def rounded_inwards(start_s: float, end_s: float, step_s: float) -> tuple[float, float]:
    """[start, end) with the start rounded up and the end rounded down to a multiple of ``step_s``."""
    digits = max(0, -math.floor(math.log10(step_s)))
    a = round(math.ceil(start_s / step_s - 1e-9) * step_s, digits)
    b = round(math.floor(end_s / step_s + 1e-9) * step_s, digits)
    return a, b


def flat_mask(t_s: np.ndarray, y: np.ndarray, threshold: float) -> np.ndarray:
    """True where the centred :data:`FLAT_WINDOW_S` window around a sample has a range below ``threshold``."""
    step = float(np.median(np.diff(t_s)))
    window = max(3, int(round(FLAT_WINDOW_S / step)) | 1)
    series = pd.Series(y)
    rolling = series.rolling(window, center=True, min_periods=window)
    span = (rolling.max() - rolling.min()).to_numpy()
    return np.nan_to_num(span, nan=np.inf) < threshold


def still_runs(mask: np.ndarray, y: np.ndarray, threshold: float) -> np.ndarray:
    """``mask`` keeping only the runs over which ``y`` as a whole stays within ``threshold``: a slow ramp is flat
    in every short window, but not over the run."""
    out = np.zeros_like(mask)
    for a, b in runs(mask):
        if np.ptp(y[a:b]) < threshold:
            out[a:b] = True
    return out


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the True runs of ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), np.flatnonzero(edges == -1).tolist()))


def dwell_mask(t_s: np.ndarray, y: np.ndarray, threshold: float) -> np.ndarray:
    """True where the motion pauses (a dwell between two steps, shorter than a standstill): the centred
    :data:`DWELL_WINDOW_S` window's range below ``threshold``. A dwell ends the cycle before it (its start is
    a cycle boundary) and spoils the one it falls in."""
    step = float(np.median(np.diff(t_s)))
    window = max(5, int(round(DWELL_WINDOW_S / step)) | 1)
    rolling = pd.Series(y).rolling(window, center=True, min_periods=window)
    span = np.nan_to_num((rolling.max() - rolling.min()).to_numpy(), nan=np.inf)
    return span < threshold


def upward_crossings(t_s: np.ndarray, y: np.ndarray, mid: float, hysteresis: float) -> np.ndarray:
    """Times at which ``y`` rises through ``mid`` (interpolated between samples), counted only when it has been
    below mid - hysteresis before and goes above mid + hysteresis after (noise makes no extra crossing)."""
    d = y - mid
    i, sign = hysteresis_crossings(d, hysteresis)
    j = i[sign > 0] - 1                     # the last sample at or below mid before each rise
    frac = -d[j] / (d[j + 1] - d[j])
    return t_s[j] + frac * (t_s[j + 1] - t_s[j])


def settling_cycles(cycles: int) -> int:
    """Cycles left out at the start of a step of ``cycles`` cycles: one, two when it has six or more."""
    return 1 if cycles < 6 else 2


def group_cycles(periods: np.ndarray, amplitudes: np.ndarray, valid: np.ndarray) -> list[tuple[int, int]]:
    """[first, stop) cycle index ranges of consecutive valid cycles whose period and amplitude stay within
    :data:`STEP_TOLERANCE` of their group's median."""
    groups, start = [], None
    for k in range(periods.size):
        if start is not None and valid[k]:
            p, a = np.median(periods[start:k]), np.median(amplitudes[start:k])
            if abs(periods[k] / p - 1.0) <= STEP_TOLERANCE and abs(amplitudes[k] / a - 1.0) <= STEP_TOLERANCE:
                continue
        if start is not None:
            groups.append((start, k))
        start = k if valid[k] else None
    if start is not None:
        groups.append((start, periods.size))
    return groups


def find_steps(t_s: np.ndarray, y_m: np.ndarray) -> list[Step]:
    """The standstills and steady steps of a record (time [s], motion channel [m]), in time order."""
    ok = np.isfinite(t_s) & np.isfinite(y_m)
    t, y = t_s[ok], y_m[ok]
    if t.size < 20:
        return []
    lo, hi = np.percentile(y, [0.5, 99.5])
    sigma = noise_level(y)
    if hi - lo <= 2.0 * FLAT_SIGMAS * sigma:
        return []
    flat = still_runs(flat_mask(t, y, max(FLAT_FRACTION * (hi - lo), FLAT_SIGMAS * sigma)), y,
                      max(FLAT_FRACTION * (hi - lo), FLAT_SIGMAS * sigma))
    steps = []
    for a, b in runs(flat):       # a run of flat windows: the flat stretch less half a window at each end
        if t[b - 1] - t[a] >= MIN_STANDSTILL_S - FLAT_WINDOW_S:
            start, end = rounded_inwards(t[a], t[b - 1], 0.1)
            if end > start:
                steps.append(Step("standstill", start, end))
    moving = ~flat
    if moving.sum() < 20:
        return steps
    m_lo, m_hi = np.percentile(y[moving], [0.5, 99.5])
    mid = 0.5 * (m_lo + m_hi)
    hysteresis = max(CROSSING_SIGMAS * sigma, CROSSING_FRACTION * 0.5 * (m_hi - m_lo))
    dwell = still_runs(dwell_mask(t, y, max(FLAT_SIGMAS * sigma, DWELL_FRACTION * (hi - lo))), y,
                       max(FLAT_SIGMAS * sigma, DWELL_FRACTION * (hi - lo)))
    stops = np.array([t[a] - 0.5 * DWELL_WINDOW_S for a, _ in runs(dwell)])
    crossings = np.unique(np.concatenate([upward_crossings(t, y, mid, hysteresis), stops]))
    still = flat | dwell
    if crossings.size and still[np.searchsorted(t, crossings[-1]):].any():
        crossings = np.append(crossings, t[-1])           # a record that ends at rest: the rest closes its last cycle
    if crossings.size < MIN_GROUP_CYCLES + 1:
        return sorted(steps, key=lambda s: s.start_s)
    bounds = np.searchsorted(t, crossings)
    periods = np.diff(crossings)
    amplitudes = np.array([0.5 * np.ptp(y[a:b]) if b > a else 0.0 for a, b in zip(bounds[:-1], bounds[1:])])
    rested = np.array([still[a:b].any() for a, b in zip(bounds[:-1], bounds[1:])], dtype=bool)
    valid = np.array([b > a + 4 for a, b in zip(bounds[:-1], bounds[1:])]) & ~rested & (amplitudes > 0)
    rest_end = rest_ends(t, still, dwell)
    previous_end = -math.inf
    for first, stop in group_cycles(periods, amplitudes, valid):
        period = float(np.median(periods[first:stop]))
        short = periods < (1.0 - STEP_TOLERANCE) * period
        if stop - first < MIN_GROUP_CYCLES and not between_rests(first, stop, rested, short):
            continue
        since = max(previous_end, rest_end[min(bounds[first], t.size - 1)])   # the motion since: it settled the step
        before = max(0, int(math.floor((crossings[first] - since) / period + 0.5)))   # to the nearest whole cycle
        skip = min(max(0, settling_cycles(stop - first) - before), stop - first - MIN_KEPT_CYCLES)
        previous_end = float(crossings[stop])
        kept = slice(first + skip, stop)
        tail = float(crossings[stop + 1]) if runs_into_rest(stop, rested, short) else math.nan
        steps.append(Step("cycles", float(crossings[first + skip]), float(crossings[stop]),
                          float(np.median(periods[kept])), float(np.median(amplitudes[kept])), stop - first - skip,
                          skip + before, float(crossings[first]) - before * period, tail))
    return sorted(steps, key=lambda s: s.start_s)


def rest_ends(t: np.ndarray, still: np.ndarray, dwell: np.ndarray) -> np.ndarray:
    """At each sample, when the last rest before it ended: half a :data:`DWELL_WINDOW_S` after the last dwell
    sample (the centred window's edge reaches the motion there), or the last still sample if later; the record's
    start before any rest."""
    idx = np.arange(t.size)
    last_dwell = np.maximum.accumulate(np.where(dwell, idx, -1))
    last_still = np.maximum.accumulate(np.where(still, idx, -1))
    by_dwell = np.where(last_dwell >= 0, t[np.maximum(last_dwell, 0)] + 0.5 * DWELL_WINDOW_S, t[0])
    return np.maximum(by_dwell, np.where(last_still >= 0, t[np.maximum(last_still, 0)], t[0]))


def runs_into_rest(stop: int, rested: np.ndarray, short: np.ndarray) -> bool:
    """Whether the motion after cycles [.., stop) is a rest, or less than a cycle (``short``) ending in one."""
    n = rested.size
    return stop < n - 1 and bool(short[stop]) and bool(rested[stop + 1])


def between_rests(first: int, stop: int, rested: np.ndarray, short: np.ndarray) -> bool:
    """Whether cycles [first, stop) are all the motion between two rests (``rested``: the cycle holds a rest;
    ``short``: a partial cycle, shorter than the step's period): a rest before them, or a partial cycle from one,
    and a rest after them, or a partial cycle into one."""
    before = first >= 1 and (rested[first - 1] or (first >= 2 and short[first - 1] and rested[first - 2]))
    after = stop < rested.size and (rested[stop] or runs_into_rest(stop, rested, short))
    return bool(before and after)


def is_stepped(steps: list[Step], t_s: np.ndarray) -> bool:
    """Whether a record is several tests: more than one stretch found, and its steps cover at least a third of it
    (a free record's chance groups of similar cycles do not make it stepped)."""
    if len(steps) < 2 or not any(s.kind == "cycles" for s in steps):
        return False
    covered = sum(s.end_s - (s.start_s if s.kind == "standstill" else s.onset_s) for s in steps)
    return covered >= (t_s[-1] - t_s[0]) / 3.0


#: A single record's steady cycles (between a ramp-in and a ramp-out) must cover this fraction of it.
MIN_STEADY_FRACTION = 0.3


def steady_part(steps: list[Step], t_s: np.ndarray) -> Step | None:
    """The steady cycles of a single record with a ramp-in and ramp-out (one step of cycles, no standstill, covering
    at least :data:`MIN_STEADY_FRACTION` of it), None otherwise."""
    cycles = [s for s in steps if s.kind == "cycles"]
    if len(cycles) != 1 or len(steps) != 1:
        return None
    step = cycles[0]
    return step if step.end_s - step.start_s >= MIN_STEADY_FRACTION * (t_s[-1] - t_s[0]) else None
