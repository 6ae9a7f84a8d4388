"""The force at each extremum of the measured velocity of a periodic record, and the energy dissipated per
cycle (Sec. 4 of the paper, harmonic tests; the damper-test specifications' force-velocity curve).

Any periodic record (a sine, a servo-distorted sine, a crank or slider-crank, a sine with harmonics) is
reduced the same way: distortion changes the peak speed, never the method. Per half-cycle of one velocity
sign (:func:`peak_points`):

1. the half-cycles are the runs of one sign of a coarse velocity (:func:`isokinetic.measurement.loops.smooth_velocity`
   with its window at most T/20, :func:`isokinetic.measurement.loops.half_cycles`), and the largest |v| of
   the run is a first guess of the peak;
2. the peak is refined on the record's own time stamps: a least-squares model of the displacement over one
   period around the guess (a line, the fundamental and each harmonic up to ``MAX_HARMONIC`` whose amplitude
   exceeds ``HARMONIC_SIGMA`` standard errors); its velocity's extremum (the acceleration's root) is the instant
   t_v and the peak velocity; a peak not inside its half-cycle, or whose period leaves the record, is left out;
3. the force while the speed is at its peak (:func:`window_force`): the samples of the speed window, the run
   around t_v where the model's |v| >= ``peak_fraction`` (0.99) of its peak (+-arccos(0.99)/w, 2.25 % of the
   period, on a sine; at least ``min_side`` samples a side). A quadratic F(t) through them; when its residual
   spread is what the force's noise gives (third differences over +-T/8 around t_v, chi-square at ``alpha``)
   or within ``steady_fraction`` (1 %) of the force, the force is steady and the point is the quadratic at t_v
   (the window mean corrected for a smooth force's curvature). Otherwise (a backlash, a stick-slip: the force
   swings far beyond its noise while the speed is at its peak) the point is the window's mean force, not
   steady, with its spread (the window's standard deviation): the force at peak velocity is then known no
   better than that spread, and the stage flags the point and widens its standard error by it. A narrow local
   fit at one instant would follow the swing instead and be silently wrong.
   Spikes (:mod:`isokinetic.measurement.spikes`, the same rule as a triangle window's, on the force over +-T/8
   around t_v less its least-squares quadratic) are left out of the fit, of the window's mean and spread and of
   the noise the steadiness test uses, and counted (``spikes_excluded``); a cycle whose speed window holds more
   than max(1, 1 %) spike samples is marked ``spike_set_aside`` and gives no point (the stage leaves it out).

Why the velocity's extremum: there dv/dt = 0, so the force of a memoryless damper is F(v) at the highest
speed of the half-cycle, and a damper whose force lags (a Maxwell element: the oil's compressibility in
series with the orifice, paper Sec. 4) is met where its lag error, first order in dv/dt, vanishes. The force
at peak velocity still lies below the steady characteristic by the second-order part of the compressibility
lag (:mod:`isokinetic.measurement.loops`). For a pure sine t_v is the crossing of the displacement's centre; for
a distorted one it is not, and the speed there is not the peak speed.

Nothing assumes even sampling: a missing sample only thins a window, a burst over a peak leaves that cycle out.

Settling (:func:`settled`) is measured on the record, not by a fixed skip: per direction, the reference is
the median of the later half of the cycles (the last cycle when there are two); leading and trailing cycles
(start-up, ramp-in, ramp-out) are dropped while their peak speed differs from the reference by more than
max(2 %, 4 x the later cycles' scatter) (real rigs' steady cycles scatter by 0.2-1 % in peak speed; a ramp's
by tens of %) or their force by more than max(0.5 %, four noise standard errors). One cycle left is kept: it
is a point, flagged by its count. :func:`summarise` averages the cycles of a step: mean velocity and force,
their cycle-to-cycle standard deviation (ddof 1), the cycles n, the standard error std / sqrt(n) (none for one
cycle), and the cycles whose force is not steady with their rms spread.

:func:`periodicity` says whether a record is periodic: its cycles (consecutive peaks of one sign) last the
same within 10 %.

Energy per cycle (:func:`cycle_energies`): the closed integral of F dx over each whole cycle between
consecutive velocity peaks of one sign (trapezoids on the real time stamps, the ends interpolated), positive
for a dissipating damper. For F = c v on x = X sin(wt): E = pi c w X^2; for F = c2 v|v|: E = (8/3) c2 w^2 X^3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.measurement.crossings import hysteresis_crossings
from isokinetic.measurement.loops import half_cycles, noise_sigma, smooth_velocity
from isokinetic.measurement.spikes import spike_mask, too_many
from isokinetic.stats import ALPHA, chi2_isf

#: Columns of :func:`peak_points`.
POINT_COLUMNS = ["direction", "time_s", "velocity_m_s", "force_N", "force_noise_N", "force_spread_N", "steady",
                 "window_s", "i_start", "i_stop", "spikes_excluded", "spike_set_aside"]
#: Columns of :func:`summarise`.
SUMMARY_COLUMNS = ["direction", "velocity_m_s", "force_N", "velocity_std_m_s", "force_std_N", "n_cycles",
                   "force_se_N", "force_noise_N", "force_spread_N", "n_unsteady", "spikes_excluded"]
#: Columns of :func:`cycle_energies`.
ENERGY_COLUMNS = ["t_start_s", "t_end_s", "energy_J", "amplitude_m", "i_start", "i_stop"]
#: The coarse velocity's smoothing window is at most this fraction of the period (the harmonics survive it).
COARSE_PERIOD_FRACTION = 0.25
#: Harmonics of the cycle model of the displacement (:func:`_cycle_model`): at most this many ...
MAX_HARMONIC = 6
#: ... those above the fundamental kept only when their amplitude exceeds this many standard errors.
HARMONIC_SIGMA = 4.0
#: Polynomial degree of the force fit over the speed window (a smooth force's curvature).
FORCE_DEGREE = 2
#: The force's local noise is measured over this fraction of the period either side of the peak.
NOISE_PERIOD_FRACTION = 0.125


@dataclass(frozen=True)
class PeakSpec:
    """Settings of the peak-velocity method (module doc): the speed window (the part of a half-cycle whose speed
    is at least ``peak_fraction`` of its peak), the fewest samples each side of the peak (coarse records widen
    the window to them), the force steadiness test (a spread beyond the noise at ``alpha`` and beyond
    ``steady_fraction`` of the force), and the settling tolerances (:func:`settled`): peak speed (relative,
    or ``n_sigma`` times the measured cycle-to-cycle scatter when larger) and force (relative, or ``n_sigma``
    times the noise)."""

    peak_fraction: float = 0.99
    min_side: int = 3
    steady_fraction: float = 0.01
    alpha: float = ALPHA
    speed_tolerance: float = 0.02
    force_tolerance: float = 0.005
    n_sigma: float = 4.0

    def __post_init__(self):
        if not 0.9 <= self.peak_fraction < 1.0:
            raise ValueError(f"peak_fraction must lie in [0.9, 1), got {self.peak_fraction}")
        if self.min_side < 2:
            raise ValueError(f"min_side must be >= 2 (a quadratic through the peak), got {self.min_side}")
        if not (self.speed_tolerance > 0 and self.force_tolerance > 0 and self.n_sigma > 0
                and self.steady_fraction > 0 and 0 < self.alpha < 1):
            raise ValueError("settling and steadiness tolerances must be positive")


def _arrays(time_s, displacement_m, force_N) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(displacement_m, dtype=float)
    f = np.asarray(force_N, dtype=float)
    if not (t.ndim == 1 and t.shape == x.shape == f.shape):
        raise ValueError("time_s, displacement_m and force_N must be 1-D arrays of equal length")
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("time must be strictly increasing with at least two samples")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x)) and np.all(np.isfinite(f))):
        raise ValueError("time, displacement and force must be finite")
    return t, x, f


def _harmonic_basis(tau: np.ndarray, omega: float, harmonics) -> np.ndarray:
    """Columns 1, tau, cos(k w tau), sin(k w tau) for k in ``harmonics``."""
    cols = [np.ones_like(tau), tau]
    for k in harmonics:
        cols += [np.cos(k * omega * tau), np.sin(k * omega * tau)]
    return np.column_stack(cols)


def _cycle_model(tau: np.ndarray, x: np.ndarray, omega: float) -> tuple[np.ndarray, list[int]]:
    """Least-squares coefficients of x(tau) = c0 + c1 tau + sum_k a_k cos(k w tau) + b_k sin(k w tau) over one
    period, and the harmonics kept: the fundamental and each of 2..``MAX_HARMONIC`` whose amplitude exceeds
    ``HARMONIC_SIGMA`` standard errors (noise is not made into distortion)."""
    every = list(range(1, MAX_HARMONIC + 1))
    basis = _harmonic_basis(tau, omega, every)
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    resid = x - basis @ coef
    dof = max(1, tau.size - basis.shape[1])
    var = float(resid @ resid) / dof
    cov = var * np.linalg.pinv(basis.T @ basis)
    kept = [1] + [k for k in every[1:] if math.hypot(coef[2 * k], coef[2 * k + 1])
                  > HARMONIC_SIGMA * math.sqrt(max(cov[2 * k, 2 * k] + cov[2 * k + 1, 2 * k + 1], 0.0) / 2.0)]
    if len(kept) < MAX_HARMONIC:
        coef, *_ = np.linalg.lstsq(_harmonic_basis(tau, omega, kept), x, rcond=None)
    return coef, kept


def _model_velocity(coef: np.ndarray, kept: list[int], omega: float, tau, order: int = 1) -> np.ndarray:
    """The ``order``-th derivative of the cycle model (:func:`_cycle_model`) at tau."""
    tau = np.asarray(tau, dtype=float)
    out = np.full(tau.shape, coef[1] if order == 1 else 0.0)
    for j, k in enumerate(kept):
        a, b, w = coef[2 + 2 * j], coef[3 + 2 * j], k * omega
        # d^n/dtau^n of a cos(w tau) + b sin(w tau) = w^n (a cos(w tau + n pi/2) + b sin(w tau + n pi/2))
        out = out + w ** order * (a * np.cos(w * tau + order * math.pi / 2) + b * np.sin(w * tau + order * math.pi / 2))
    return out


def _velocity_peak(t: np.ndarray, x: np.ndarray, i: int, period_s: float, sign: float, fraction: float
                   ) -> tuple[float, float, float, float] | None:
    """(t_v, v(t_v), t_a, t_b) of the velocity's extremum of sign ``sign`` near sample i (module doc, step 2): the
    cycle model of the period around it (shifted to lie inside the record), its s v maximised within a quarter
    period of t[i]; [t_a, t_b] the run around t_v where s v >= ``fraction`` s v(t_v) (the speed window). None when
    the record is shorter than a period or the maximum, or the window, reaches that range's edge."""
    if t[-1] - t[0] < period_s:
        return None
    start = min(max(t[i] - 0.5 * period_s, t[0]), t[-1] - period_s)
    lo = int(np.searchsorted(t, start, side="left"))
    hi = int(np.searchsorted(t, start + period_s, side="right"))
    if hi - lo < 2 * MAX_HARMONIC + 4:
        return None
    omega = 2.0 * math.pi / period_s
    tau0 = float(t[i])
    coef, kept = _cycle_model(t[lo:hi] - tau0, x[lo:hi], omega)
    grid = np.linspace(-0.25 * period_s, 0.25 * period_s, 2001)
    speed = sign * _model_velocity(coef, kept, omega, grid)
    j = int(np.argmax(speed))
    if j in (0, grid.size - 1) or speed[j] <= 0.0:
        return None
    tau = _refine(coef, kept, omega, float(grid[j]), float(grid[1] - grid[0]), period_s)
    v = float(_model_velocity(coef, kept, omega, tau))
    below = np.flatnonzero(speed < fraction * sign * v)
    before, after = below[below < j], below[below > j]
    if before.size == 0 or after.size == 0:
        return None
    return tau0 + tau, v, tau0 + float(grid[before[-1] + 1]), tau0 + float(grid[after[0] - 1])


def _refine(coef: np.ndarray, kept: list[int], omega: float, tau: float, step_max: float, period_s: float) -> float:
    """Newton on the cycle model's acceleration from ``tau``; ``tau`` itself when Newton leaves its grid cell."""
    start = tau
    for _ in range(8):
        acc = float(_model_velocity(coef, kept, omega, tau, 2))
        jerk = float(_model_velocity(coef, kept, omega, tau, 3))
        if jerk == 0.0:
            break
        step = acc / jerk
        tau -= step
        if abs(step) < 1e-9 * period_s:
            break
    return tau if abs(tau - start) <= step_max else start


def measured_period(t: np.ndarray, x: np.ndarray, period_s: float) -> float:
    """The record's own period [s] (time t [s], displacement x [m]): the median interval between rising crossings
    of the displacement's mean (with hysteresis a quarter of the amplitude, the instants interpolated between
    samples) when that lies within 20 % of ``period_s`` (the manifest's or the dominant one), else ``period_s``."""
    centre = float(np.mean(x))
    amplitude = 0.5 * float(np.percentile(x, 99.5) - np.percentile(x, 0.5))
    if amplitude <= 0.0:
        return period_s
    i, sign = hysteresis_crossings(x - centre, 0.25 * amplitude)
    i = i[(sign > 0) & (i > 0)]
    if i.size < 2:
        return period_s
    xa, xb = x[i - 1] - centre, x[i] - centre
    frac = np.where(xa != xb, xa / np.where(xa != xb, xa - xb, 1.0), 0.5)
    up = t[i - 1] + (t[i] - t[i - 1]) * frac
    found = float(np.median(np.diff(up)))
    return found if abs(found - period_s) <= 0.2 * period_s else period_s


def _window(t: np.ndarray, t_a: float, t_b: float, tv: float, min_side: int) -> tuple[int, int] | None:
    """Samples [lo, hi) of the speed window [t_a, t_b], each side widened to (``min_side`` + 1/2) median sample
    intervals on a coarse record; None when it leaves the record or either side holds fewer than ``min_side``
    samples (a burst of missing ones)."""
    dt = float(np.median(np.diff(t)))
    a, b = min(t_a, tv - (min_side + 0.5) * dt), max(t_b, tv + (min_side + 0.5) * dt)
    if a < t[0] or b > t[-1]:
        return None
    lo = int(np.searchsorted(t, a, side="left"))
    mid = int(np.searchsorted(t, tv, side="left"))
    hi = int(np.searchsorted(t, b, side="right"))
    return (lo, hi) if mid - lo >= min_side and hi - mid >= min_side else None


def window_force(t: np.ndarray, f: np.ndarray, lo: int, hi: int, tv: float, noise_N: float,
                 spec: PeakSpec = PeakSpec(), spikes: np.ndarray | None = None) -> dict:
    """The force over the speed window [lo, hi) of a record (time t [s], force f [N]) around t_v = ``tv`` [s] (module
    doc, step 3), a dict of force_N, force_noise_N, force_spread_N, steady: a least-squares quadratic F(t)
    through the window; when its residual spread is what the noise gives (chi-square at ``spec.alpha``) or within
    ``spec.steady_fraction`` of the force, the force is steady and the point is the quadratic at t_v (the window
    mean corrected for a smooth force's curvature); otherwise it is the window's mean force, not steady, and
    force_spread_N is the window's standard deviation. force_noise_N: the quadratic's residual spread. ``spikes``
    (a boolean of hi - lo, :func:`isokinetic.measurement.spikes.spike_mask`): samples left out of all of it."""
    u = t[lo:hi] - tv
    y = f[lo:hi]
    if spikes is not None and spikes.any():
        u, y = u[~spikes], y[~spikes]
    half = max(float(np.max(np.abs(u))), 1e-300)
    q = np.polynomial.Polynomial.fit(u / half, y, FORCE_DEGREE, domain=[-1, 1], window=[-1, 1])
    dof = max(1, y.size - FORCE_DEGREE - 1)
    resid = y - q(u / half)
    spread = math.sqrt(float(resid @ resid) / dof)
    bound = noise_N * math.sqrt(chi2_isf(spec.alpha, dof) / dof)
    at_peak = float(q(0.0))
    steady = spread <= max(bound, spec.steady_fraction * abs(at_peak))
    if steady:
        return {"force_N": at_peak, "force_noise_N": spread, "force_spread_N": 0.0, "steady": True}
    return {"force_N": float(np.mean(y)), "force_noise_N": spread, "force_spread_N": float(np.std(y, ddof=1)),
            "steady": False}


def _near_spikes(f: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Spikes of the record's force (a boolean of the record) within the stretch ``near`` (+-T/8 around a peak),
    its least-squares quadratic taken off (:func:`isokinetic.measurement.spikes.spike_mask`)."""
    out = np.zeros(f.size, dtype=bool)
    at = np.flatnonzero(near)
    if at.size:
        out[at[0]:at[-1] + 1] = spike_mask(f, int(at[0]), int(at[-1]) + 1, detrend=True)
    return out


def peak_points(time_s, displacement_m, force_N, period_s: float, *, t_start: float | None = None,
                t_stop: float | None = None, spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """The force at each extremum of the measured velocity (module doc): one row per half-cycle whose peak
    instant lies in [t_start, t_stop) [s] (default: the whole record).

    ``period_s`` sets the coarse velocity's smoothing (the manifest's period, or the record's dominant one).
    Columns :data:`POINT_COLUMNS`: direction '+'/'-', time_s (t_v), velocity_m_s (signed), force_N, force_noise_N
    and force_spread_N (:func:`window_force`), steady, window_s (the speed window's duration) and the samples
    [i_start, i_stop) of the speed window.
    """
    t, x, f = _arrays(time_s, displacement_m, force_N)
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period must be positive and finite, got {period_s}")
    a = -math.inf if t_start is None else float(t_start)
    b = math.inf if t_stop is None else float(t_stop)
    v = smooth_velocity(t, x, period_s=COARSE_PERIOD_FRACTION * period_s)
    own = measured_period(t, x, period_s)
    record_noise = noise_sigma(f)
    rows = []
    for lo_run, hi_run, s in half_cycles(v):
        i = lo_run + int(np.argmax(s * v[lo_run:hi_run]))
        found = _velocity_peak(t, x, i, own, s, spec.peak_fraction)
        if found is None:
            continue
        tv, vv, t_a, t_b = found
        span = _window(t, t_a, t_b, tv, spec.min_side)
        if span is None or not (a <= tv < b) or not (t[lo_run] <= tv <= t[hi_run - 1]):
            continue
        lo, hi = span
        near = (t >= tv - NOISE_PERIOD_FRACTION * own) & (t <= tv + NOISE_PERIOD_FRACTION * own)
        spikes = _near_spikes(f, near)
        noise = noise_sigma(f[near & ~spikes]) if near.sum() >= 16 else record_noise
        n_spikes = int(spikes[lo:hi].sum())
        rows.append({"direction": "+" if s > 0 else "-", "time_s": tv, "velocity_m_s": vv,
                     **window_force(t, f, lo, hi, tv, noise, spec, spikes[lo:hi]), "window_s": float(t_b - t_a),
                     "i_start": lo, "i_stop": hi, "spikes_excluded": n_spikes,
                     "spike_set_aside": too_many(n_spikes, hi - lo)})
    out = pd.DataFrame(rows, columns=POINT_COLUMNS)
    return out.astype({"i_start": "int64", "i_stop": "int64", "steady": bool, "spikes_excluded": "int64",
                       "spike_set_aside": bool})


def periodicity(points: pd.DataFrame, tolerance: float = 0.1) -> float | None:
    """The period [s] of a record whose peaks (:func:`peak_points`) repeat: the median time between consecutive
    peaks of one sign, when at least two such cycles exist and nine in ten of them last that median within
    ``tolerance``; None when the record is not periodic by that test (a random or swept record)."""
    durations = np.concatenate([np.diff(np.sort(points.loc[points["direction"] == d, "time_s"].to_numpy(float)))
                                for d in ("+", "-")]) if len(points) else np.array([])
    if durations.size < 2:
        return None
    period = float(np.median(durations))
    regular = np.abs(durations - period) <= tolerance * period
    return period if regular.sum() >= 2 and regular.mean() >= 0.9 else None


def _agrees(p: pd.DataFrame, v_ref: float, v_limit: float, f_ref: float, f_limit: float) -> np.ndarray:
    """Which cycles' peak speed and force agree with the reference (:func:`settled`)."""
    dv = np.abs(p["velocity_m_s"].abs().to_numpy(float) - v_ref)
    df = np.abs(p["force_N"].to_numpy(float) - f_ref)
    return (dv <= v_limit) & (df <= f_limit)


def _robust_scatter(y: np.ndarray, centre: float) -> float:
    """1.4826 x the median absolute deviation from ``centre`` (a normal scatter's sigma)."""
    return 1.4826 * float(np.median(np.abs(y - centre))) if y.size else 0.0


def settled(points: pd.DataFrame, spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """:func:`peak_points` without the cycles of each direction that have not settled (module doc).

    Per direction, in time order: reference speed and force = the medians of the later half of the cycles (the
    last cycle when there are two); speed limit = max(``speed_tolerance`` x reference, ``n_sigma`` x the later
    cycles' speed scatter); force limit = max(``force_tolerance`` x |reference|, ``n_sigma`` x the larger of the
    later cycles' scatter and a point's fit error, noise x sqrt(3 / samples)). Scatters: 1.4826 x median absolute
    deviation. Leading cycles, then trailing ones, are dropped while they disagree."""
    keep = []
    for d in ("+", "-"):
        p = points[points["direction"] == d].sort_values("time_s", kind="stable")
        n = len(p)
        if n >= 2:
            later = p.iloc[n // 2:] if n >= 3 else p.iloc[-1:]
            lf, lv = later["force_N"].to_numpy(float), later["velocity_m_s"].abs().to_numpy(float)
            f_ref, v_ref = float(np.median(lf)), float(np.median(lv))
            fit_se = later["force_noise_N"].to_numpy(float) * np.sqrt(
                (FORCE_DEGREE + 1) / np.maximum(1, (later["i_stop"] - later["i_start"]).to_numpy(float)))
            f_scatter = max(_robust_scatter(lf, f_ref), float(np.median(fit_se)))
            v_limit = max(spec.speed_tolerance * v_ref, spec.n_sigma * _robust_scatter(lv, v_ref))
            f_limit = max(spec.force_tolerance * abs(f_ref), spec.n_sigma * f_scatter)
            ok = _agrees(p, v_ref, v_limit, f_ref, f_limit)
            first, last = 0, n
            while first < n - 1 and not ok[first]:
                first += 1
            while last - 1 > first and not ok[last - 1]:
                last -= 1
            p = p.iloc[first:last]
        keep.append(p)
    out = pd.concat(keep) if keep else points
    return out.sort_values("time_s", kind="stable").reset_index(drop=True)


def summarise(points: pd.DataFrame) -> pd.DataFrame:
    """One row per direction ('+' then '-'): the mean of the cycles' peak velocity and force, their cycle-to-cycle
    standard deviations (ddof 1; NaN for one cycle), n_cycles, force_se_N = force_std_N / sqrt(n) (NaN for one
    cycle: nothing says how the cycle repeats), the mean force noise of the fits, force_spread_N the root mean
    square of the cycles' in-window spread (0 when every cycle's force is steady) and n_unsteady the cycles
    whose force is not steady across the speed window (:func:`window_force`), spikes_excluded their spike samples
    left out."""
    rows = []
    for d in ("+", "-"):
        p = points[points["direction"] == d] if len(points) else points
        n = len(p)
        if n == 0:
            continue
        v, f = p["velocity_m_s"].to_numpy(float), p["force_N"].to_numpy(float)
        sf = float(f.std(ddof=1)) if n > 1 else math.nan
        spread = p["force_spread_N"].to_numpy(float) if "force_spread_N" in p else np.zeros(n)
        rows.append({"direction": d, "velocity_m_s": float(v.mean()), "force_N": float(f.mean()),
                     "velocity_std_m_s": float(v.std(ddof=1)) if n > 1 else math.nan, "force_std_N": sf,
                     "n_cycles": n, "force_se_N": sf / math.sqrt(n),
                     "force_noise_N": float(p["force_noise_N"].mean()) if "force_noise_N" in p else math.nan,
                     "force_spread_N": float(np.sqrt(np.mean(spread * spread))),
                     "n_unsteady": int((~p["steady"].astype(bool)).sum()) if "steady" in p else 0,
                     "spikes_excluded": int(p["spikes_excluded"].sum()) if "spikes_excluded" in p else 0})
    out = pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
    return out.astype({"n_cycles": "int64", "n_unsteady": "int64", "spikes_excluded": "int64"})


def loop_energy(t: np.ndarray, x: np.ndarray, f: np.ndarray, t_a: float, t_b: float) -> float:
    """The integral of F dx from t_a to t_b [J] (time t, t_a, t_b [s], displacement x [m], force f [N]): trapezoids
    over the samples between, the ends linearly interpolated on the time axis."""
    i0 = int(np.searchsorted(t, t_a, side="right"))
    i1 = int(np.searchsorted(t, t_b, side="left"))
    xx = np.concatenate([[np.interp(t_a, t, x)], x[i0:i1], [np.interp(t_b, t, x)]])
    ff = np.concatenate([[np.interp(t_a, t, f)], f[i0:i1], [np.interp(t_b, t, f)]])
    return float(np.sum(0.5 * (ff[1:] + ff[:-1]) * np.diff(xx)))


def _whole_cycles(points: pd.DataFrame, period_s: float) -> list[tuple[float, float]]:
    """(start, end) of the whole cycles between consecutive peaks of one sign, 0.5 to 1.5 periods apart: those
    of the positive peaks, or of the negative ones when they give more (a record cut so that one positive peak
    is left still has a cycle between its negative ones)."""
    best: list[tuple[float, float]] = []
    for d in ("+", "-"):
        at = np.sort(points.loc[points["direction"] == d, "time_s"].to_numpy(float)) if len(points) else np.array([])
        cycles = [(float(a), float(b)) for a, b in zip(at[:-1], at[1:], strict=True)
                  if 0.5 * period_s <= b - a <= 1.5 * period_s]
        if len(cycles) > len(best):
            best = cycles
    return best


def cycle_energies(time_s, displacement_m, force_N, period_s: float, *, t_start: float | None = None,
                   t_stop: float | None = None, points: pd.DataFrame | None = None,
                   spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """The energy dissipated in each whole cycle, closed integral of F dx between consecutive peaks of one velocity
    sign (module doc, :func:`_whole_cycles`), for cycles within [t_start, t_stop). ``points``:
    :func:`peak_points` of the same record (computed when None). Two peaks more than 1.5 or less than 0.5
    periods apart (a peak left out) make no cycle. Columns :data:`ENERGY_COLUMNS` (amplitude_m: half the
    peak-to-peak displacement of the cycle; [i_start, i_stop) its samples)."""
    t, x, f = _arrays(time_s, displacement_m, force_N)
    if points is None:
        points = peak_points(t, x, f, period_s, t_start=t_start, t_stop=t_stop, spec=spec)
    rows = []
    for t_a, t_b in _whole_cycles(points, period_s):
        i0 = int(np.searchsorted(t, t_a, side="left"))
        i1 = int(np.searchsorted(t, t_b, side="right"))
        seg = x[i0:i1]
        rows.append({"t_start_s": float(t_a), "t_end_s": float(t_b), "energy_J": loop_energy(t, x, f, t_a, t_b),
                     "amplitude_m": 0.5 * float(seg.max() - seg.min()) if seg.size else math.nan,
                     "i_start": i0, "i_stop": i1})
    return pd.DataFrame(rows, columns=ENERGY_COLUMNS).astype({"i_start": "int64", "i_stop": "int64"})
