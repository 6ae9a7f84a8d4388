"""Physics a damper's record obeys whatever its design: the checks that need no damper block.

- **Causality** (:func:`force_lags`): a damper's force lags its motion (oil compressibility, seals, a load
  cell's anti-alias filter); at each reversal of the measured velocity the force crosses from one branch to
  the other a little *after* the velocity changes sign. A record played backwards (rows reversed, the time
  column left ascending) turns every lag into a lead of the same size, whatever the load cell's sign.
- **Dissipation** (:func:`cycle_energies`): over each complete cycle the damper absorbs energy, the closed
  integral of F dx is positive; a load-cell offset cancels over a cycle. A record that gives energy back has
  the opposite sign convention, or runs backwards in time (then the negated force leads the motion).
- **Magnitudes without design data** (:func:`force_magnitude_problem`, :func:`implied_damping_N_s_m`).
  A unit mix-up scales a channel by a power of 1000. Noise, resolution and signal scale together, so their
  ratios (steps against noise, signal against noise) are the same in any unit and decide nothing; only an
  absolute magnitude against physics can: the force against the channel's declared full scale, or, without
  one, against the forces hydraulic dampers make (the same rule and numbers as init-campaign's unit scores,
  :mod:`isokinetic.init_campaign.channels`), and force over velocity against the damping any damper has.
- **A temperature that follows the motion** (:func:`follows`): an oil temperature drifts slowly; a channel
  that repeats the command or the displacement is that channel, not a temperature.

All pure functions of SI arrays; the stage that applies them is :mod:`isokinetic.stages.validate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isokinetic.measurement.crossings import hysteresis_crossings

#: A velocity or force has changed side when past this fraction of its typical level (|v| of the moving
#: samples; half the gap between the force's two branches): noise near zero makes no reversal.
SIDE_FRACTION = 0.25
#: The force leads the motion (time reversed, or channels shifted) only beyond the larger of these at every
#: reversal. Real rigs delay the *displacement* against the force by at most: one sample interval of channel
#: skew in a multiplexed logger, plus an LVDT conditioner's low-pass (1st order at >= 100 Hz: 1.6 ms; 2nd
#: order at >= 100 Hz: 2.3 ms). A low-pass on the force only adds lag.
LEAD_BOUND_SAMPLES, LEAD_BOUND_S = 2.0, 0.005
#: The cycles give energy back, beyond what a passive damper seen through a lagging force channel can show, when
#: their net work is below minus this fraction of their absolute work |F v| dt. A dissipative damper recorded
#: with its force inverted, or played backwards, gives back most of it (a viscous one all of it); a passive
#: damper whose force is mostly elastic (a tiny stroke on the oil's compressibility) can cross 90 degrees of
#: phase through a force low-pass and give back a part: the reference rig's 0.08 mm, 2 Hz sine through a 4 Hz
#: first-order filter gives back 20 %. Below this fraction the record is kept and its quality says so.
ENERGY_FRACTION = 0.5
#: ... and a kept record that gives back more than this fraction is flagged in its quality.
ENERGY_NOTE_FRACTION = 0.1
#: The longest group delay of a rig's force channel (an anti-alias low-pass of 1.3 Hz, first order; the blind
#: suite's go to 113 ms) [s], and the share of a cycle it may span for the energy to decide: a lag of a twelfth of
#: a period turns a force by 30 degrees, so that a sign error (most of the work given back) stays apart from a lag.
#: Faster records give back energy through such a channel whatever their sign: they are flagged, not set aside.
FORCE_LAG_MAX_S = 0.12
ENERGY_PERIODS_PER_LAG = 12.0
#: Typical largest force of a damper test [N], the physical bounds of a force reading [N] and the margin
#: (decades) a unit must win by to be sure: one source for the build and for init-campaign, which reads them
#: (:data:`isokinetic.init_campaign.channels.TYPICAL`, ``BOUNDS``).
TYPICAL_FORCE_N, FORCE_BOUNDS_N, SURE_MARGIN = 300.0, (0.5, 2e6), 1.5
#: One case alone: a 99th percentile |F| below this [N] reads SURE_MARGIN decades better as kN than as N
#: (log10(300/p) - |log10(1000 p/300)| >= 1.5 for p <= 300 x 10^-2.25 = 1.69 N). A campaign's cases together
#: are judged by :func:`kn_reading_sure`, init-campaign's own rule.
MIN_PEAK_FORCE_N = TYPICAL_FORCE_N * 10.0 ** (-(3.0 + SURE_MARGIN) / 2.0)
#: With a declared full scale: a 99th percentile |value| below this fraction of it uses under 0.01 % of the
#: sensor's range (6 counts of a 16-bit converter): a unit 1000x too large, not a test.
MIN_FULL_SCALE_FRACTION = 1e-4
#: A declared full scale vouches for forces below MIN_PEAK_FORCE_N when they reach this fraction of it.
VOUCH_FRACTION = 1e-3
#: Plausible damping of a damper, force over velocity [N s/m]: a bicycle's shock at speed to a friction-dominated
#: helicopter lag damper creeping at 0.05 mm/s (1e7 and more); outside, the force or the velocity is off by orders
#: of magnitude (a wrong column, or units). init-campaign reads it too.
DAMPING_RANGE_N_S_M = (1.0, 1.0e9)
#: A temperature whose correlation with the command or the displacement reaches this is that channel.
FOLLOW_CORRELATION = 0.9


def smoothing_samples(n: int) -> int:
    """The half-width [samples] of the velocity's central difference: about 1/2000 of the record (noise averaged,
    symmetric in time, so no crossing moves)."""
    return max(1, n // 2000)


def central_velocity(t: np.ndarray, y: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(time [s], dy/dt [y's unit per s]) by central differences over ±k samples, at samples k .. n-k-1."""
    return t[k:-k], (y[2 * k:] - y[:-2 * k]) / (t[2 * k:] - t[:-2 * k])


def line_zero(t: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """(time, standard error) [s] where a straight line fitted to (t [s], x) crosses zero (NaN when it cannot)."""
    n = t.size
    if n < 2 or np.ptp(t) == 0:
        return math.nan, math.inf
    tc = t - t.mean()
    sxx = float(tc @ tc)
    slope = float(tc @ (x - x.mean())) / sxx
    if slope == 0:
        return math.nan, math.inf
    t0 = float(t.mean() - x.mean() / slope)
    sigma2 = float(np.sum((x - x.mean() - slope * tc) ** 2)) / (n - 2) if n > 2 else 0.0
    return t0, math.sqrt(sigma2 / n + (t0 - t.mean()) ** 2 * sigma2 / sxx) / abs(slope)


def crossing_times(t: np.ndarray, x: np.ndarray, hysteresis: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(time [s], sign, standard error [s]) of each change of side of ``x`` (:func:`hysteresis_crossings`): where a
    straight line fitted to the transition (from the last sample beyond the old side's threshold to the first
    beyond the new side's, :func:`line_zero`) crosses zero; symmetric, so noise moves it neither way."""
    idx, signs = hysteresis_crossings(x, hysteresis)
    times, errors = np.empty(idx.size), np.empty(idx.size)
    for j, (i, s) in enumerate(zip(idx, signs)):
        before = np.flatnonzero(s * x[:i] < -hysteresis)
        after = np.flatnonzero(s * x[i:] > hysteresis)
        a = int(before[-1]) if before.size else max(i - 1, 0)
        b = i + (int(after[0]) if after.size else 0)
        t0, se = line_zero(t[a:b + 1], x[a:b + 1])
        inside = math.isfinite(t0) and t[a] <= t0 <= t[b]
        times[j], errors[j] = (t0, se) if inside else (0.5 * (t[i - 1] + t[i]), 0.5 * (t[i] - t[i - 1]))
    return times, signs, errors


def branch_level(force_N: np.ndarray, v: np.ndarray, hysteresis: float) -> tuple[float, float]:
    """(mid-level, half gap) [N] of a force's two branches: the medians of the force while v > h and v < -h [m/s]."""
    up, down = force_N[v > hysteresis], force_N[v < -hysteresis]
    if up.size == 0 or down.size == 0:
        return math.nan, math.nan
    hi, lo = float(np.median(up)), float(np.median(down))
    return 0.5 * (hi + lo), 0.5 * (hi - lo)


@dataclass(frozen=True)
class Reversals:
    """The measured velocity's reversals: times [s], signs (+1: to positive velocity), standard errors [s] (the
    central difference's correlated samples counted once per 2k), the velocity at each sample (NaN at the k
    samples of each end) and the side threshold [m/s]."""

    times_s: np.ndarray
    signs: np.ndarray
    errors_s: np.ndarray
    velocity_m_s: np.ndarray
    hysteresis_m_s: float


def velocity_reversals(t: np.ndarray, displacement_m: np.ndarray) -> Reversals:
    """The reversals of the displacement's central-difference velocity (:func:`crossing_times`)."""
    k = smoothing_samples(t.size)
    full = np.full(t.size, np.nan)
    if t.size < 2 * k + 3:
        return Reversals(np.array([]), np.array([]), np.array([]), full, math.nan)
    tv, v = central_velocity(t, displacement_m, k)
    full[k:-k] = v
    h = SIDE_FRACTION * float(np.percentile(np.abs(v), 90.0))
    if not h > 0:
        return Reversals(np.array([]), np.array([]), np.array([]), full, h)
    times, signs, errors = crossing_times(tv, v, h)
    return Reversals(times, signs, errors * math.sqrt(2 * k), full, h)


def force_lags(t: np.ndarray, displacement_m: np.ndarray, force_N: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lag [s], its standard error [s], the reversal's sign) of the force behind the velocity at each reversal
    of the velocity: the time the force crosses the middle between its two branches (:func:`branch_level`) in
    the same direction, less the time the velocity crosses zero; a force crossing is paired only when nearer
    than half the reversals' spacing (a quarter period of a sine: beyond it the force would not dissipate).
    Positive: the force lags (a damper); negative: it leads. A damper stronger one way crosses the middle at a
    velocity off zero, later one way and earlier the other: :attr:`Causality.pair_lags_s` averages that out."""
    rev = velocity_reversals(t, displacement_m)
    v = rev.velocity_m_s
    ok = np.isfinite(v)
    mid, half_gap = branch_level(force_N[ok], v[ok], rev.hysteresis_m_s) if rev.times_s.size else (0.0, 0.0)
    if not half_gap > 0:
        return np.array([]), np.array([]), np.array([])
    tf, sf, ef = crossing_times(t, force_N - mid, SIDE_FRACTION * half_gap)
    spacing = float(np.median(np.diff(rev.times_s))) if rev.times_s.size > 1 else float(t[-1] - t[0])
    lags, errors, signs = [], [], []
    for time, sign, error in zip(rev.times_s, rev.signs, rev.errors_s):
        same = np.flatnonzero(sf == sign)
        if same.size:
            j = same[np.argmin(np.abs(tf[same] - time))]
            if abs(tf[j] - time) < 0.5 * spacing:
                lags.append(tf[j] - time)
                errors.append(math.hypot(ef[j], error))
                signs.append(sign)
    return np.array(lags), np.array(errors), np.array(signs)


def lead_bound_s(sample_interval_s: float) -> float:
    """The largest lead of the force that real rigs' channel skew and displacement filters make
    (:data:`LEAD_BOUND_SAMPLES` sample intervals, at least :data:`LEAD_BOUND_S`)."""
    return max(LEAD_BOUND_SAMPLES * sample_interval_s, LEAD_BOUND_S)


#: A lead counts only this many standard errors beyond the bound.
LEAD_SIGMAS = 3.0


@dataclass(frozen=True)
class Causality:
    """The force's lag at each reversal [s], their standard errors [s], the reversals' signs and the bound a
    lead must pass [s]."""

    lags_s: np.ndarray
    errors_s: np.ndarray
    signs: np.ndarray
    bound_s: float

    @property
    def pair_lags_s(self) -> tuple[np.ndarray, np.ndarray]:
        """(mean lag, its standard error) of each two consecutive reversals of opposite directions: a damper's
        asymmetry moves the two the opposite ways and cancels."""
        pair = np.flatnonzero(self.signs[1:] != self.signs[:-1])
        means = 0.5 * (self.lags_s[pair] + self.lags_s[pair + 1])
        return means, 0.5 * np.hypot(self.errors_s[pair], self.errors_s[pair + 1])

    @property
    def leads_everywhere(self) -> bool:
        """Whether there is at least one pair of reversals and in every pair the force leads by more than the bound
        plus LEAD_SIGMAS standard errors."""
        means, errors = self.pair_lags_s
        return means.size >= 1 and bool(np.all(means < -(self.bound_s + LEAD_SIGMAS * errors)))

    def said(self) -> str:
        """The sentence a refusal gives: the force leads the motion, by how much and beyond what bound."""
        lead = -self.pair_lags_s[0] * 1e3
        return (f"the force leads the motion at all {self.lags_s.size} reversals of the velocity, by "
                f"{np.median(lead):.3g} ms (median over {lead.size} up-and-down pair(s); {lead.min():.3g} to "
                f"{lead.max():.3g} ms), beyond the {self.bound_s * 1e3:.3g} ms a rig's channel skew and "
                "displacement filter can make; a damper's force lags its motion")


def causality(t: np.ndarray, displacement_m: np.ndarray, force_N: np.ndarray, sample_interval_s: float) -> Causality:
    """:func:`force_lags` with the bound of :func:`lead_bound_s`."""
    return Causality(*force_lags(t, displacement_m, force_N), lead_bound_s(sample_interval_s))


def cycle_energies(t: np.ndarray, displacement_m: np.ndarray, force_N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(net work, absolute work) [J] the damper absorbs over each complete cycle, between every second reversal
    of the velocity (:func:`velocity_reversals`): the trapezoidal closed integral of F dx, and the integral of
    |F v| dt with the smoothed velocity (so that displacement noise does not inflate it)."""
    rev = velocity_reversals(t, displacement_m)
    at = np.searchsorted(t, rev.times_s)
    f_mid = 0.5 * (force_N[1:] + force_N[:-1])
    work = f_mid * np.diff(displacement_m)
    v = np.nan_to_num(rev.velocity_m_s)
    power = np.abs(f_mid * 0.5 * (v[1:] + v[:-1])) * np.diff(t)
    net = [float(work[a:b].sum()) for a, b in zip(at[:-2], at[2:])]
    absolute = [float(power[a:b].sum()) for a, b in zip(at[:-2], at[2:])]
    return np.array(net), np.array(absolute)


def gives_energy_back(net_J: np.ndarray, absolute_J: np.ndarray) -> bool:
    """Whether there is at least one complete cycle, and over all of them more than ENERGY_FRACTION of the absolute work
    returned (summed: one cycle cut by a spurious reversal does not decide)."""
    return net_J.size >= 1 and float(net_J.sum()) < -ENERGY_FRACTION * float(absolute_J.sum())


def energy_decides(t: np.ndarray, displacement_m: np.ndarray) -> bool:
    """Whether the record's cycles are slow enough for their energy to tell a sign error from a force channel's
    lag: the median cycle (every second reversal, :func:`velocity_reversals`) lasts at least
    ENERGY_PERIODS_PER_LAG × FORCE_LAG_MAX_S (no complete cycle: False)."""
    times = velocity_reversals(t, displacement_m).times_s
    if times.size < 3:
        return False
    return float(np.median(times[2:] - times[:-2])) >= ENERGY_PERIODS_PER_LAG * FORCE_LAG_MAX_S


def energy_given_back(net_J: np.ndarray, absolute_J: np.ndarray) -> float:
    """The fraction of the absolute work the complete cycles give back (0 when they absorb, or none is complete)."""
    total = float(absolute_J.sum()) if absolute_J.size else 0.0
    return max(0.0, -float(net_J.sum()) / total) if total > 0.0 else 0.0


#: A triangle case's displacement column is a velocity when this fraction of its samples lies within
#: LEVEL_BAND of the two levels +-median|y - median y| (a square wave: nearly all; a triangle: 15 %).
TWO_LEVEL_FRACTION, LEVEL_BAND = 0.6, 0.15


def two_level_fraction(y: np.ndarray) -> float:
    """The fraction of samples within LEVEL_BAND of the two levels +-a, a = median|y - median y|: the piecewise
    constant velocity of a triangle test (Eq. 26's derivative) puts nearly all there, its displacement, spread
    evenly over [-Y, Y], LEVEL_BAND of them (|y| between 0.425 and 0.575 Y)."""
    centred = np.abs(y - np.median(y))
    a = float(np.median(centred))
    return float(np.mean(np.abs(centred - a) < LEVEL_BAND * a)) if a > 0.0 else 0.0


def peak_magnitude(x: np.ndarray) -> float:
    """The 99th percentile of |x| (one wild sample does not move it)."""
    return float(np.percentile(np.abs(x), 99.0))


def force_score(peak_N: float) -> float:
    """The init-campaign score of a force reading: decades between its 99th percentile |F| and TYPICAL_FORCE_N,
    infinite outside FORCE_BOUNDS_N (:func:`isokinetic.init_campaign.channels.force_scores`)."""
    if not FORCE_BOUNDS_N[0] <= peak_N <= FORCE_BOUNDS_N[1]:
        return math.inf
    return abs(math.log10(peak_N / TYPICAL_FORCE_N))


def kn_reading_sure(peaks_N) -> bool:
    """Whether the forces of a campaign's cases sharing one column (their 99th percentile |F| as declared, in
    N) are surely kN declared as N, by init-campaign's rule for a unit (:func:`channels.choose_unit`, scores
    summed over the files): the kN reading plausible and the N reading implausible in some case, or better by
    SURE_MARGIN decades per case on average, or by SURE_MARGIN in one case while no case prefers N."""
    as_n = np.array([force_score(p) for p in peaks_N])
    as_kn = np.array([force_score(1e3 * p) for p in peaks_N])
    if as_n.size == 0 or not np.isfinite(as_kn.sum()) or as_kn.sum() >= as_n.sum():
        return False
    if not np.isfinite(as_n.sum()):
        return True
    margins = as_n - as_kn
    return bool(margins.mean() >= SURE_MARGIN or (margins.max() >= SURE_MARGIN and margins.min() >= 0))


def force_magnitude_problem(force_N: np.ndarray, full_scale_N: float | None = None, campaign_peaks_N=None) -> str:
    """'' when the force's size is plausible, else why not: its 99th percentile |F| below
    MIN_FULL_SCALE_FRACTION of a declared full scale; or, unless a declared full scale vouches for such small
    forces (the peak at least VOUCH_FRACTION of it: a load cell chosen for them), the peaks of the cases that
    share its column (``campaign_peaks_N``, this case's included; None: this case alone) surely kN declared
    as N (:func:`kn_reading_sure`)."""
    peak = peak_magnitude(force_N)
    declared = full_scale_N is not None and full_scale_N > 0
    if declared and peak < MIN_FULL_SCALE_FRACTION * full_scale_N:
        return (f"99th percentile |force| {peak:.4g} N is {peak / full_scale_N:.2g} of the declared full scale "
                f"{full_scale_N:.4g} N, under the {MIN_FULL_SCALE_FRACTION:g} no test uses: a unit mix-up "
                "(e.g. values in kN declared as N)?")
    peaks = [peak] if campaign_peaks_N is None else list(campaign_peaks_N)
    if (declared and peak >= VOUCH_FRACTION * full_scale_N) or not kn_reading_sure(peaks):
        return ""
    cases = f" (the {len(peaks)} cases sharing its column: {min(peaks):.4g} to {max(peaks):.4g} N)" \
        if len(peaks) > 1 else ""
    return (f"99th percentile |force| {peak:.4g} N{cases}: read as kN these forces fit a damper's (typically "
            f"{TYPICAL_FORCE_N:g} N, {FORCE_BOUNDS_N[0]:g} N at least) surely better than as N, by init-campaign's "
            "rule: values in kN declared as N? (forces truly this small: declare the load cell's full_scale)")


def implied_damping_N_s_m(t: np.ndarray, displacement_m: np.ndarray, force_N: np.ndarray) -> float:
    """Force over velocity, the least-squares slope cov(v, F) / var(v) [N s/m] (NaN without motion)."""
    k = smoothing_samples(t.size)
    if t.size < 2 * k + 3:
        return math.nan
    _, v = central_velocity(t, displacement_m, k)
    f = force_N[k:-k]
    var = float(np.var(v))
    return float(np.cov(v, f, bias=True)[0, 1] / var) if var > 0 else math.nan


def plausible_damping(damping_N_s_m: float) -> bool:
    """Whether |force over velocity| lies inside DAMPING_RANGE_N_S_M (NaN: nothing to judge, plausible)."""
    return not math.isfinite(damping_N_s_m) or \
        DAMPING_RANGE_N_S_M[0] <= abs(damping_N_s_m) <= DAMPING_RANGE_N_S_M[1]


def follows(signal: np.ndarray, reference: np.ndarray) -> float:
    """The |correlation| [-] of a channel with another (0 when either is constant)."""
    if signal.size < 3 or np.std(signal) == 0 or np.std(reference) == 0:
        return 0.0
    return abs(float(np.corrcoef(signal, reference)[0, 1]))
