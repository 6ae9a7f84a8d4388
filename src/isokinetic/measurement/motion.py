"""Measured kinematics of a triangle case: where and how the piston really moved (Eq. 26).

The plan gives y(t) = Y tri(2πt/T + φ) from t = 0 (Eq. 26); a rig records the piston some time
after its command (actuator delay plus the servo's steady ramp lag) on a time axis that need not
start at 0. :func:`estimate_motion` finds, from the displacement channel alone:

* ``motion_start_s``: the time on the record's own axis at which the plan's t = 0 lies. Windows
  are cut at motion_start_s + the plan's window times (:func:`windows.window_ranges`).
* ``delay_s`` = motion_start_s - the first time stamp (the command-to-piston delay).
* the speed of each of the four half-periods (least-squares line over their central part
  [0.1, 0.9] T/2, away from the reversals), the amplitude, and the rms departure of the measured
  displacement from the planned triangle shifted by motion_start_s.

Method: a coarse least-squares search of the shift in [-T/4, +T/4] around the first time stamp
(the planned triangle held at its start value before the motion starts, offset and gain free,
on a block-averaged record), then a refinement from the four half-period lines: each line crosses
the mid-stroke at the middle of its half-period, so rising and falling lines fix the shift and the
mid-stroke together. A shift within ``ZERO_DELAY_SIGMAS`` standard errors of the first time stamp
is not distinguishable from it and is taken as the first time stamp exactly (a record that starts
with its motion is windowed exactly as planned, whatever its noise).

A record that ends before the plan's two periods (:func:`ends_early`: a rig that crashed while writing) fits
only the half-periods it holds up to their middle, where their line crosses the mid-stroke (the crossing is then
measured, not extrapolated from the first samples of a half-period). The motion start needs a rising and a
falling line (a ramp alone does not fix the mid-stroke: a record that ends before the middle of its second
half-period places its windows up to T/4 off); validate sets such a record aside. A record that lasts the plan's
duration is measured exactly as before.

Every step works on the real time stamps (lines and spans by time, blocks averaged in time and
displacement alike), so a record that dropped samples gives the same motion; the noise estimate
(median second difference) is robust to the few differences a gap disturbs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isokinetic.physics.plan import CasePlan, half_periods, snapped_phase_rad

#: Central part of a half-period used for its line fit, as fractions of T/2 (away from reversals).
LINE_FRACTIONS = (0.1, 0.9)
#: The coarse search covers shifts of [-T/4, +T/4] around the first time stamp.
SEARCH_FRACTION = 0.25
#: Points of the block-averaged record the coarse search runs on.
COARSE_POINTS = 2000
#: A shift within this many standard errors of the first time stamp counts as no delay.
ZERO_DELAY_SIGMAS = 4.0
#: Fewest samples of a half-period's central part for its line fit.
MIN_LINE_SAMPLES = 5


@dataclass(frozen=True)
class Motion:
    """Measured kinematics of one triangle case (SI; times on the record's own axis).

    ``velocities_m_s`` are the signed slopes of the first four half-periods (NaN where the record
    holds too little of one), ``planned_velocities_m_s`` the plan's ±4Y/T (Eq. 26).
    ``delay_std_s`` is the standard error of the motion start from the line fits (inf when none
    fitted); ``amplitude_m`` the least-squares amplitude of the planned triangle shape at the motion
    start; ``mid_stroke_m`` the measured mid-stroke (LVDT zero offset); ``rms_m`` the rms of
    y - mid_stroke - Y tri(...) over the record (noise included); ``noise_m`` the LVDT noise (1σ).
    """

    motion_start_s: float
    delay_s: float
    delay_std_s: float
    velocities_m_s: tuple[float, ...]
    planned_velocities_m_s: tuple[float, ...]
    amplitude_m: float
    mid_stroke_m: float
    rms_m: float
    noise_m: float

    @property
    def velocity_ratios(self) -> np.ndarray:
        """The signed measured / planned velocity of each half-period [-] (negative: against the plan)."""
        return np.asarray(self.velocities_m_s) / np.asarray(self.planned_velocities_m_s)

    @property
    def velocity_ratio(self) -> float:
        """The mean measured |v| of the half-periods over the planned W = 4Y/T (Eq. 26) [-]."""
        ratios = np.abs(self.velocity_ratios)
        ratios = ratios[np.isfinite(ratios)]
        return float(ratios.mean()) if ratios.size else math.nan

    @property
    def excess_rms_m(self) -> float:
        """The rms departure from the plan beyond the LVDT noise: sqrt(rms² - noise²) [m]."""
        return math.sqrt(max(self.rms_m ** 2 - self.noise_m ** 2, 0.0))


def triangle_shape(tau_s, period_s: float, phase_rad: float):
    """tri(2πτ/T + φ) [-] for τ >= 0 [s], held at tri(φ) before (Eq. 26, amplitude 1)."""
    tau = np.maximum(np.asarray(tau_s, dtype=float), 0.0)
    u = np.mod(tau / period_s + phase_rad / (2.0 * np.pi) + 0.75, 1.0)
    return 4.0 * np.abs(u - 0.5) - 1.0


def block_means(t, y, points: int = COARSE_POINTS):
    """(t, y) (time [s], displacement [m]) averaged over consecutive blocks, about ``points`` of them."""
    k = max(1, t.size // points)
    n = (t.size // k) * k
    return t[:n].reshape(-1, k).mean(axis=1), y[:n].reshape(-1, k).mean(axis=1)


def shift_misfit(t, y, shifts_s, period_s: float, phase_rad: float) -> np.ndarray:
    """The residual sum of squares [y²] of y ≈ c + g·tri(t - shift) (c, g free) for each candidate shift."""
    u = triangle_shape(t[None, :] - np.asarray(shifts_s)[:, None], period_s, phase_rad)
    uc = u - u.mean(axis=1, keepdims=True)
    yc = y - y.mean()
    cov = uc @ yc
    var = np.einsum("ij,ij->i", uc, uc)
    with np.errstate(divide="ignore", invalid="ignore"):
        explained = np.where(var > 0, cov * cov / var, 0.0)
    return float(yc @ yc) - explained


def coarse_shift(t, y, period_s: float, phase_rad: float, n: int = 101) -> float:
    """Shift of the planned triangle [s] that fits the record best, searched in [-T/4, T/4]
    around the first time stamp, then on a grid ten times finer around the best."""
    tb, yb = block_means(t, y)
    reach = SEARCH_FRACTION * period_s
    shifts = t[0] + np.linspace(-reach, reach, n)
    best = shifts[int(np.argmin(shift_misfit(tb, yb, shifts, period_s, phase_rad)))]
    step = 2.0 * reach / (n - 1)
    fine = best + np.linspace(-step, step, 41)
    return float(fine[int(np.argmin(shift_misfit(tb, yb, fine, period_s, phase_rad)))])


def line_fit(t, y) -> tuple[float, float, float, float, float]:
    """The least-squares line through (t, y): (slope, value at the mean time, mean time, standard error of that
    value, standard error of the slope), the residual scatter taken as the noise."""
    tm, ym = t.mean(), y.mean()
    tc = t - tm
    sxx = float(tc @ tc)
    slope = float(tc @ (y - ym) / sxx)
    resid = y - ym - slope * tc
    sigma = math.sqrt(float(resid @ resid) / max(t.size - 2, 1))
    return slope, float(ym), float(tm), sigma / math.sqrt(t.size), sigma / math.sqrt(sxx)


def line_fits(t, y, starts_s, half_s: float, cut: bool = False):
    """The least-squares lines over [0.1, 0.9]·T/2 after each start: (slope, value at mean time,
    mean time, crossing-time standard error per unit slope, samples), NaN for too few samples, and with
    ``cut`` (a record that ends early) for a half-period whose middle lies after the record's last sample."""
    lo, hi = LINE_FRACTIONS
    starts = np.asarray(starts_s)
    i0 = np.searchsorted(t, starts + lo * half_s, side="left")
    i1 = np.searchsorted(t, starts + hi * half_s, side="right")
    out = np.full((len(i0), 5), np.nan)
    for k, (a, b) in enumerate(zip(i0, i1)):
        if b - a < MIN_LINE_SAMPLES or (cut and starts[k] + 0.5 * half_s > t[-1]):
            continue
        slope, ym, tm, se_mean, _ = line_fit(t[a:b], y[a:b])
        out[k] = (slope, ym, tm, se_mean, b - a)
    return out


def solve_shift(fits, mids_s, fallback_mid_m: float):
    """The shift s [s] and mid-stroke c [m] from lines that each cross c at s + their half-period's middle.

    Each line y = a + b (t - tm) gives b·s - c = -a - b (mid - tm); rising and falling lines
    separate s from c. Lines of one direction only keep c = ``fallback_mid_m``. Returns
    (s, c, standard error of s) or None when no line has a slope.
    """
    ok = np.isfinite(fits[:, 0]) & (np.abs(fits[:, 0]) > 0)
    if not ok.any():
        return None
    b, a, tm, se = fits[ok, 0], fits[ok, 1], fits[ok, 2], fits[ok, 3]
    rhs = -a - b * (np.asarray(mids_s)[ok] - tm)
    crossing_se = se / np.abs(b)
    if (b > 0).any() and (b < 0).any():
        (s, c), *_ = np.linalg.lstsq(np.column_stack([b, -np.ones_like(b)]), rhs, rcond=None)
    else:
        c = fallback_mid_m
        s = float(np.mean((rhs + c) / b))
    return float(s), float(c), float(math.sqrt(np.sum(crossing_se ** 2)) / b.size)


def noise_level(y) -> float:
    """The LVDT noise of displacement y [m], 1σ, from the median absolute second difference (zero on a ramp) [m]."""
    if y.size < 5:
        return 0.0
    d2 = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def planned_half_periods(plan: CasePlan) -> np.ndarray:
    """The first four half-periods of a triangle plan (rows t_start, t_end, sign; plan time, Eq. 26),
    the turning point within one sample interval of t = 0 counted, as the motion estimate uses them."""
    dt = 1.0 / plan.sample_rate_Hz
    phase = snapped_phase_rad(plan.period_s, plan.phase_rad, dt)
    return half_periods(plan.period_s, phase, 3.0 * plan.period_s, tolerance_s=dt, max_count=4)


def line_spans_s(plan: CasePlan, motion_start_s: float) -> np.ndarray:
    """[start, end] on the record's axis of the line fit of each of the four half-periods (rows): the
    motion start + the half-period's start + LINE_FRACTIONS·T/2. The measured speeds and the motion
    start rest on the samples of these spans (a record's gaps there are judged by validate)."""
    starts = planned_half_periods(plan)[:, :1]
    return motion_start_s + starts + np.asarray(LINE_FRACTIONS) * (plan.period_s / 2.0)


def ends_early(t_s, plan: CasePlan) -> bool:
    """Whether a record ends before its plan's duration (Sec. 4.3: two periods of a triangle), less one sample
    interval of slack: a record cut short, as a rig that crashed while writing leaves it."""
    dt_s = 1.0 / plan.sample_rate_Hz
    return float(t_s[-1] - t_s[0]) < (plan.required_duration_s - dt_s) * (1.0 - 1e-9)


def estimate_motion(t_s, y_m, plan: CasePlan, iterations: int = 3) -> Motion:
    """The measured kinematics of a triangle case from its time stamps and displacement (Eq. 26).

    A record that ends early (:func:`ends_early`) fits only the half-periods it holds up to their middle
    (module doc). Raises ValueError for a case that is not a triangle or a record of fewer than 10 samples.
    """
    if plan.waveform != "triangle":
        raise ValueError(f"case {plan.case}: motion is estimated for triangle cases, not {plan.waveform}")
    t = np.asarray(t_s, dtype=float)
    y = np.asarray(y_m, dtype=float)
    if t.size < 10:
        raise ValueError(f"case {plan.case}: {t.size} samples are too few to estimate the motion")
    period, amp = plan.period_s, plan.amplitude_m
    dt = 1.0 / plan.sample_rate_Hz
    phase = snapped_phase_rad(period, plan.phase_rad, dt)
    half = period / 2.0
    segments = planned_half_periods(plan)
    starts, signs = segments[:, 0], segments[:, 2]
    mids = starts + 0.5 * half
    s = coarse_shift(t, y, period, phase)
    u = triangle_shape(t - s, period, phase)
    fallback_c = float(y.mean() - np.polyfit(u, y, 1)[0] * u.mean()) if np.ptp(u) > 0 else float(y.mean())
    c, s_se = fallback_c, math.inf
    cut = ends_early(t, plan)
    for _ in range(iterations):
        solved = solve_shift(line_fits(t, y, s + starts, half, cut), mids, fallback_c)
        if solved is None:
            break
        s, c, s_se = solved
    if abs(s - t[0]) <= max(ZERO_DELAY_SIGMAS * s_se, 1e-3 * dt):
        s = float(t[0])
    fits = line_fits(t, y, s + starts, half, cut)
    u = triangle_shape(t - s, period, phase)
    uc = u - u.mean()
    gain = float(uc @ (y - y.mean()) / (uc @ uc)) if uc @ uc > 0 else 0.0
    departure = y - c - amp * u
    w = 4.0 * amp / period
    return Motion(motion_start_s=float(s), delay_s=float(s - t[0]), delay_std_s=float(s_se),
                  velocities_m_s=tuple(float(v) for v in fits[:, 0]),
                  planned_velocities_m_s=tuple(float(sign * w) for sign in signs),
                  amplitude_m=abs(gain), mid_stroke_m=float(c),
                  rms_m=float(np.sqrt(np.mean(departure ** 2))), noise_m=noise_level(y))
