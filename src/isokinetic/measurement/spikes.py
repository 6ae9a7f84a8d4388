"""Spikes on the force channel: isolated samples far outside a stretch's spread (electrical spikes of a load cell).

Rule (a Hampel filter, :func:`spike_mask`)
    Over a stretch of samples (a window with ``CONTEXT`` samples of the record either side of it), the residual of
    each force sample from a robust local trend, the running median of ``2 HALF_WIDTH + 1`` = 11 samples, is
    compared with the noise's robust sigma: 1.4826 MAD (median absolute deviation) of the residuals from the
    median of each sample's 10 neighbours, the sample itself left out (with it, the residuals of ordinary samples
    shrink and the MAD would understate the noise by a third), the larger of the window's and of the
    ``SCALE_SAMPLES`` = 200 samples around it. A sample whose residual exceeds
    ``K_SIGMA`` = 6 sigma, and which stands out from the mean of its two neighbours by half that, is an outlier
    (a smooth curve's extremum sampled a few times stands out from a median of 11, never from its neighbours).
    Its extent is the run of consecutive samples beyond ``K_EDGE`` = 3 sigma around it (from the running median of
    the samples with the outliers bridged by straight lines, which a steep force's outlier does not shift by a
    sample's rise); a run of at most ``MAX_RUN`` = 3 samples is a spike: its samples are excluded from the
    window's statistics (mean, spread, noise model, diagnosis). A longer run is an event of the force, a
    transient or a step, and is kept: a spike is what no real force does, jump and come back within three samples.
    (The extent is measured at 3 sigma, not 6, so that a narrow real bump, whose flanks rise above the noise
    before its top passes 6 sigma, is seen whole and kept; a spike's noise neighbours pass 3 sigma with a
    probability of 0.3 %.) The median of 11 samples follows a step or a monotone transient exactly (the median of
    a monotone run is its middle sample), so neither ever gives a residual; only a narrow excursion does. The
    stretch's ends are continued by odd reflection, so the first samples of a sloped record are no extremum.

Why k = 6
    The residual of a sample from its neighbours' median is near-Gaussian with the spread above; beyond 6 sigma a
    Gaussian sample has a probability of 2e-9 (two-sided), so a campaign of 10^6 window samples flags one sample
    in about 500 campaigns, and a flag excludes one sample of hundreds, moving the mean by about 6 sigma / n, a
    fraction of its standard error. Measured on 1.9 million samples (white; white plus AR(1) noise of correlation
    0.9 a sample; quantised): none at k = 6, and 5e-7 to 3e-6 a sample at k = 5 (one false flag in every campaign
    of a million samples). A load-cell spike is hundreds of sigma: 10 kN on a 9 N noise is 1100 sigma.

Too many
    A window with more spike samples than max(``MIN_ALLOWED``, ``MAX_FRACTION`` of its samples) = max(1, 1 %) is
    set aside (:func:`too_many`): at that rate the channel is not a clean record with a rare spike but a faulty
    one (a loose connector, interference), whose other samples are no better than its spikes, and the Gaussian
    noise the standard errors assume does not hold. Below it, the samples lost cost under 0.5 % of the standard
    error.

Scale floor
    A window of constant or quantised samples has a MAD of 0; the scale is then at least the window's resolution
    (the smallest step between its distinct values) and 1e-9 of its largest |force|, so rounding is never a spike.

Limits
    The rule needs a window of at least ``MIN_SAMPLES`` samples (fewer: no spike is looked for); in a record of
    only a few dozen samples the scale rests on them alone and false flags are more likely (1e-3 to 1e-5 a sample
    on white noise for 11 to 40 samples). A spike of more
    than three samples (a long dropout to a rail value) is kept as an event and shows as the window's spread. The
    running median sees a sharp extremum of the force sampled more coarsely than a few samples a feature as a run
    of outliers, kept; where the trend is a smooth curve over many samples (the force around a peak of velocity),
    a least-squares quadratic is taken off first (``detrend``). Only the force channel is checked.
"""

from __future__ import annotations

import numpy as np

#: Half the running median's width: the trend of each sample is the median of 2 HALF_WIDTH + 1 samples.
HALF_WIDTH = 5
#: A sample beyond this many robust sigmas of the window's residuals is an outlier.
K_SIGMA = 6.0
#: A run of consecutive samples beyond K_EDGE sigmas (a spike's extent) that holds an outlier and lasts at most
#: MAX_RUN samples is a spike; a longer one is an event and is kept.
K_EDGE = 3.0
MAX_RUN = 3
#: Samples of the record either side of a window that the running median and the run rule see.
CONTEXT = HALF_WIDTH + MAX_RUN
#: Fewest samples a window needs for spikes to be looked for.
MIN_SAMPLES = 2 * HALF_WIDTH + 1
#: The noise's sigma is also measured over at least this many samples of the record around a window (the larger
#: of the two is the scale): the MAD of a few dozen samples is uncertain by tens of %, and a scale too small by a
#: third makes 6 sigma 4 (on white noise, 1e-3 false flags a sample for windows of 11 samples, 2e-5 for 40).
SCALE_SAMPLES = 200
#: A window with more spike samples than max(MIN_ALLOWED, MAX_FRACTION x its samples) is set aside.
MAX_FRACTION = 0.01
MIN_ALLOWED = 1
#: 1.4826 x the median absolute deviation is a normal distribution's sigma.
MAD_SIGMA = 1.4826


def running_median(x: np.ndarray, half: int = HALF_WIDTH, *, own: bool = True) -> np.ndarray:
    """The median of the 2 half + 1 samples around each sample (``own`` False: of the 2 half around it, the sample
    itself left out); the ends continued by odd reflection (``np.pad`` 'reflect', 'odd': a trend goes on as a
    trend, so the end of a sloped record is no extremum)."""
    return running_medians(x, half)[0 if own else 1]


def running_medians(x: np.ndarray, half: int = HALF_WIDTH) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`running_median` with the sample, without it) from one sort of each sample's 2 half + 1 window: with
    s its sorted window and m = s[half] the median, the 2 half others have the middle pair (s[half], s[half + 1])
    where the sample is below m, (s[half - 1], s[half]) above it, (s[half - 1], s[half + 1]) at it, and their median
    is the pair's mean, as ``np.median``'s (the same values, bit for bit; about twice as fast as two medians)."""
    if x.size <= half:
        m = np.full(x.shape, float(np.median(x)) if x.size else np.nan)
        return m, m
    padded = np.pad(x, half, mode="reflect", reflect_type="odd")
    s = np.sort(np.lib.stride_tricks.sliding_window_view(padded, 2 * half + 1), axis=1)
    m = s[:, half]
    below, above = s[:, half - 1], s[:, half + 1]
    lo = np.where(x < m, m, below)
    hi = np.where(x > m, m, above)
    return m, (lo + hi) / 2


def resolution(x: np.ndarray) -> float:
    """The smallest step between distinct values of x (a quantised channel's least significant bit), 0 for one value."""
    steps = np.diff(np.unique(x))
    return float(steps.min()) if steps.size else 0.0


def _quadratic_residual(y: np.ndarray) -> np.ndarray:
    """y less its least-squares quadratic against the sample index."""
    basis = np.vander(np.linspace(-1.0, 1.0, y.size), 3)
    return y - basis @ np.linalg.lstsq(basis, y, rcond=None)[0]


def short_runs(outside: np.ndarray, far: np.ndarray, max_run: int = MAX_RUN) -> np.ndarray:
    """The samples of the runs of consecutive True of ``outside`` that hold a True of ``far`` and last at most
    ``max_run`` samples (a spike, with its shoulders); a longer run is an event."""
    edges = np.diff(np.concatenate([[0], outside.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = np.zeros(outside.size, dtype=bool)
    for a, b in zip(starts, stops, strict=True):
        if b - a <= max_run and far[a:b].any():
            out[a:b] = True
    return out


def spike_mask(f: np.ndarray, i0: int, i1: int, *, detrend: bool = False, context: int = CONTEXT) -> np.ndarray:
    """Which samples of the window [i0, i1) of the record's force ``f`` are spikes (module doc), a boolean array of
    i1 - i0. The running median and the run rule see ``context`` samples of the record either side (more, up to
    ``SCALE_SAMPLES`` in all, for a short window); the scale is the larger of the window's and that stretch's.
    ``detrend``: a least-squares quadratic over the stretch is taken off first."""
    n = i1 - i0
    if n < MIN_SAMPLES:
        return np.zeros(max(n, 0), dtype=bool)
    reach = max(context, (SCALE_SAMPLES - n + 1) // 2)
    s0, s1 = max(0, i0 - reach), min(f.size, i1 + reach)
    y = np.asarray(f[s0:s1], dtype=float)
    if detrend:
        y = _quadratic_residual(y)
    with_own, without_own = running_medians(y)
    r = y - with_own
    apart = y - without_own
    scale = max(_mad_sigma(apart[i0 - s0:i1 - s0]), _mad_sigma(apart))
    window = np.asarray(f[i0:i1], dtype=float)
    scale = max(scale, resolution(window), 1e-9 * float(np.max(np.abs(window))), np.finfo(float).tiny)
    # an outlier stands out from its running median and from its two neighbours' mean too (half the threshold: a
    # spike of two or three samples stands out from one of its neighbours by half its height); a smooth curve's
    # extremum sampled a few times stands out from the median of 11 but never from its neighbours
    step = np.empty_like(y)
    step[1:-1] = y[1:-1] - 0.5 * (y[:-2] + y[2:])
    step[0], step[-1] = y[0] - y[1], y[-1] - y[-2]     # the ends: from their one neighbour
    far = (np.abs(r) > K_SIGMA * scale) & (np.abs(step) > 0.5 * K_SIGMA * scale)
    if not far.any():
        return np.zeros(n, dtype=bool)
    # the extent against the trend of the samples without the outliers (bridged by straight lines): on a steep
    # force an outlier inside the median's 11 samples shifts it by one sample's rise, which is no spike's extent
    at = np.arange(y.size)
    bridged = np.where(far, np.interp(at, at[~far], y[~far]), y) if (~far).any() else y
    return short_runs(np.abs(y - running_median(bridged)) > K_EDGE * scale, far)[i0 - s0:i1 - s0]


def _mad_sigma(x: np.ndarray) -> float:
    """1.4826 x the median absolute deviation of x from its median (a normal sigma)."""
    return MAD_SIGMA * float(np.median(np.abs(x - np.median(x))))


def too_many(n_spikes: int, n_samples: int) -> bool:
    """Whether a window of ``n_samples`` with ``n_spikes`` spike samples is set aside (module doc, 'Too many')."""
    return n_spikes > max(MIN_ALLOWED, MAX_FRACTION * n_samples)


def too_many_note(n_spikes: int, n_samples: int) -> str:
    """The reason a window with too many spikes is set aside."""
    return (f"{n_spikes} spike samples of {n_samples} (more than max({MIN_ALLOWED}, {100 * MAX_FRACTION:g} %)): "
            f"the force channel is faulty there, not a clean record with a rare spike; window set aside")
