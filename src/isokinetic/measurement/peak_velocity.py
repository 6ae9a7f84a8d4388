"""The force at each extremum of the measured velocity of a periodic record, and the energy dissipated per
cycle (Sec. 4 of the paper, harmonic tests; the damper-test specifications' force-velocity curve).

Any periodic record (a sine, a servo-distorted sine, a crank or slider-crank, a sine with harmonics) is
reduced the same way: distortion changes the peak speed, never the method. Per half-cycle of one velocity
sign (:func:`peak_points`):

1. the half-cycles are the runs of one sign of a coarse velocity (:func:`isokinetic.measurement.loops.smooth_velocity`
   with its window at most T/20, :func:`isokinetic.measurement.loops.half_cycles`), and the largest |v| of
   the run is a first guess of the peak;
2. the peak is refined on the record's own time stamps: a least-squares quintic x(t) through the samples
   within ``fit_fraction`` x T of the guess (at least ``min_side`` samples each side); the root of x'' = 0
   inside the span where x' is largest (for its sign) is the instant t_v of peak velocity and x'(t_v) the
   peak velocity. The fit is recentred on t_v until it moves less than a tenth of the span (3 rounds at most);
   a peak that is not inside its span (the record cut mid-stroke, a burst of missing samples) is left out;
3. the force at t_v is a least-squares quartic F(t) through the samples within the same span of t_v; the
   residual scatter of that fit is the point's ``force_noise_N``.

Why the velocity's extremum: there dv/dt = 0, so the force of a memoryless damper is F(v) at the highest
speed of the half-cycle, and a damper whose force lags (a Maxwell element: the oil's compressibility in
series with the orifice, paper Sec. 4) is met where its lag error, first order in dv/dt, vanishes. The force
at peak velocity still lies below the steady characteristic by the second-order part of the compressibility
lag (:mod:`isokinetic.measurement.loops`). For a pure sine t_v is the crossing of the displacement's centre; for
a distorted one it is not, and the speed there is not the peak speed.

Nothing assumes even sampling: a missing sample or a burst only thins a fit. Bias on the noise-free
F = c1 v + c2 v|v| driven by a sine with 3 % third and 4 % fourth harmonics, span T/20 either side: below
2e-4 of the force and 2e-5 of the velocity (tests/measurement/test_peak_velocity.py).

Settling (:func:`settled`) is measured on the record, not by a fixed skip: per direction, the reference is
the median of the later half of the cycles (the last cycle when there are two); leading and trailing cycles
(start-up, ramp-in, ramp-out) are dropped while their peak speed or their force differs from the reference
by more than the tolerances (speed 1 %, force 0.5 % or four times the noise, whichever is larger). One cycle
left is kept: it is a point, flagged by its count. :func:`summarise` averages the cycles of a step: mean
velocity and force, their cycle-to-cycle standard deviation (ddof 1), the cycles n and the standard error
std / sqrt(n) (none for one cycle).

:func:`periodicity` says whether a record is periodic: its cycles (consecutive peaks of one sign) last the
same within 10 %.

Energy per cycle (:func:`cycle_energies`): the closed integral of F dx over each whole cycle between
consecutive peaks of positive velocity (trapezoids on the real time stamps, the ends interpolated), positive
for a dissipating damper. For F = c v on x = X sin(wt): E = pi c w X^2; for F = c2 v|v|: E = (8/3) c2 w^2 X^3.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.measurement.crossings import hysteresis_crossings
from isokinetic.measurement.loops import half_cycles, smooth_velocity

#: Columns of :func:`peak_points`.
POINT_COLUMNS = ["direction", "time_s", "velocity_m_s", "force_N", "force_noise_N", "i_start", "i_stop"]
#: Columns of :func:`summarise`.
SUMMARY_COLUMNS = ["direction", "velocity_m_s", "force_N", "velocity_std_m_s", "force_std_N", "n_cycles",
                   "force_se_N", "force_noise_N"]
#: Columns of :func:`cycle_energies`.
ENERGY_COLUMNS = ["t_start_s", "t_end_s", "energy_J", "amplitude_m", "i_start", "i_stop"]
#: The coarse velocity's smoothing window is at most this fraction of the period (the harmonics survive it).
COARSE_PERIOD_FRACTION = 0.25
#: Harmonics of the cycle model of the displacement (:func:`_cycle_model`): at most this many ...
MAX_HARMONIC = 6
#: ... those above the fundamental kept only when their amplitude exceeds this many standard errors.
HARMONIC_SIGMA = 4.0
#: Polynomial degree of the force fit at the peak.
FORCE_DEGREE = 4


@dataclass(frozen=True)
class PeakSpec:
    """Settings of the peak-velocity method: fit span (fraction of the period either side of the peak,
    widened to ``min_side`` + 1/2 sample intervals on coarse records), fewest samples each side, and the
    settling tolerances (:func:`settled`): peak speed and force, relative, and the force in noise units."""

    fit_fraction: float = 0.05
    min_side: int = 3
    speed_tolerance: float = 0.01
    force_tolerance: float = 0.005
    n_sigma: float = 4.0

    def __post_init__(self):
        if not 0.0 < self.fit_fraction <= 0.125:
            raise ValueError(f"fit_fraction must lie in (0, 1/8], got {self.fit_fraction}")
        if self.min_side < 3:
            raise ValueError(f"min_side must be >= 3 (a quintic through the peak), got {self.min_side}")
        if not (self.speed_tolerance > 0 and self.force_tolerance > 0 and self.n_sigma > 0):
            raise ValueError("settling tolerances must be positive")


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


def _fit_span(t: np.ndarray, t0: float, half_s: float, min_side: int) -> tuple[int, int] | None:
    """Samples [lo, hi) within t0 -/+ half_s; None when the span leaves the record or either side holds fewer
    than ``min_side`` samples (a burst of missing ones)."""
    if t0 - half_s < t[0] or t0 + half_s > t[-1]:
        return None
    lo = int(np.searchsorted(t, t0 - half_s, side="left"))
    mid = int(np.searchsorted(t, t0, side="left"))
    hi = int(np.searchsorted(t, t0 + half_s, side="right"))
    if mid - lo < min_side or hi - mid < min_side:
        return None
    return lo, hi


def _poly(t: np.ndarray, y: np.ndarray, lo: int, hi: int, t0: float, half_s: float, degree: int):
    """The least-squares polynomial of ``degree`` through samples [lo, hi) in u = (t - t0) / half_s."""
    return np.polynomial.Polynomial.fit((t[lo:hi] - t0) / half_s, y[lo:hi], degree, domain=[-1, 1], window=[-1, 1])


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


def _velocity_peak(t: np.ndarray, x: np.ndarray, i: int, period_s: float, sign: float
                   ) -> tuple[float, float, int, int] | None:
    """(t_v, v(t_v), lo, hi) of the velocity's extremum of sign ``sign`` near sample i (module doc, step 2): the
    cycle model of the period around it (shifted to lie inside the record), its s v maximised within a quarter
    period of t[i]; None when the record is shorter than a period or the maximum lies on that range's edge."""
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
    grid = np.linspace(-0.25 * period_s, 0.25 * period_s, 401)
    j = int(np.argmax(sign * _model_velocity(coef, kept, omega, grid)))
    if j in (0, grid.size - 1):
        return None
    tau = float(grid[j])
    for _ in range(8):                                   # Newton on the acceleration's root
        acc = float(_model_velocity(coef, kept, omega, tau, 2))
        jerk = float(_model_velocity(coef, kept, omega, tau, 3))
        if jerk == 0.0:
            break
        step = acc / jerk
        tau -= step
        if abs(step) < 1e-9 * period_s:
            break
    if abs(tau - grid[j]) > grid[1] - grid[0]:
        tau = float(grid[j])
    v = float(_model_velocity(coef, kept, omega, tau))
    return (tau0 + tau, v, lo, hi) if sign * v > 0.0 else None


def measured_period(t: np.ndarray, x: np.ndarray, period_s: float) -> float:
    """The record's own period: the median interval between rising crossings of the displacement's mean (with
    hysteresis a quarter of the amplitude, the instants interpolated between samples) when that lies within
    20 % of ``period_s`` (the manifest's or the dominant one), else ``period_s``."""
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


def peak_points(time_s, displacement_m, force_N, period_s: float, *, t_start: float | None = None,
                t_stop: float | None = None, spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """The force at each extremum of the measured velocity (module doc): one row per half-cycle whose peak
    instant lies in [t_start, t_stop) (default: the whole record).

    ``period_s`` sets the fit span and the coarse velocity's smoothing (the manifest's period, or the record's
    dominant one). Columns :data:`POINT_COLUMNS`: direction '+'/'-', time_s (t_v), velocity_m_s (signed),
    force_N, force_noise_N (residual scatter of the force fit) and the samples [i_start, i_stop) the fits used.
    """
    t, x, f = _arrays(time_s, displacement_m, force_N)
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period must be positive and finite, got {period_s}")
    a = -math.inf if t_start is None else float(t_start)
    b = math.inf if t_stop is None else float(t_stop)
    dt = float(np.median(np.diff(t)))
    half_s = max(spec.fit_fraction * period_s, (spec.min_side + 0.5) * dt)
    v = smooth_velocity(t, x, period_s=COARSE_PERIOD_FRACTION * period_s)
    own = measured_period(t, x, period_s)
    rows = []
    for lo_run, hi_run, s in half_cycles(v):
        i = lo_run + int(np.argmax(s * v[lo_run:hi_run]))
        found = _velocity_peak(t, x, i, own, s)
        if found is None:
            continue
        tv, vv, lo_x, hi_x = found
        span = _fit_span(t, tv, half_s, spec.min_side)
        if span is None or not (a <= tv < b) or not (t[lo_run] - half_s <= tv <= t[hi_run - 1] + half_s):
            continue
        lo, hi = span
        q = _poly(t, f, lo, hi, tv, half_s, FORCE_DEGREE)
        resid = f[lo:hi] - q((t[lo:hi] - tv) / half_s)
        noise = float(np.sqrt(np.sum(resid * resid) / max(1, hi - lo - FORCE_DEGREE - 1)))
        rows.append({"direction": "+" if s > 0 else "-", "time_s": tv, "velocity_m_s": vv, "force_N": float(q(0.0)),
                     "force_noise_N": noise, "i_start": min(lo, lo_x), "i_stop": max(hi, hi_x)})
    out = pd.DataFrame(rows, columns=POINT_COLUMNS)
    return out.astype({"i_start": "int64", "i_stop": "int64"})


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


def _agrees(p: pd.DataFrame, v_ref: float, f_ref: float, f_limit: float, spec: PeakSpec) -> np.ndarray:
    """Which cycles' peak speed and force agree with the reference (:func:`settled`)."""
    dv = np.abs(p["velocity_m_s"].abs().to_numpy(float) - v_ref)
    df = np.abs(p["force_N"].to_numpy(float) - f_ref)
    return (dv <= spec.speed_tolerance * v_ref) & (df <= f_limit)


def settled(points: pd.DataFrame, spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """:func:`peak_points` without the cycles of each direction that have not settled (module doc).

    Per direction, in time order: reference speed and force = the medians of the later half of the cycles (the
    last cycle when there are two); force limit = max(``force_tolerance`` x |reference|, ``n_sigma`` x the larger
    of the later cycles' scatter (1.4826 x median absolute deviation) and a point's fit error, noise x
    sqrt(5 / samples)). Leading cycles, then trailing ones, are dropped while they disagree."""
    keep = []
    for d in ("+", "-"):
        p = points[points["direction"] == d].sort_values("time_s", kind="stable")
        n = len(p)
        if n >= 2:
            later = p.iloc[n // 2:] if n >= 3 else p.iloc[-1:]
            lf = later["force_N"].to_numpy(float)
            f_ref = float(np.median(lf))
            v_ref = float(np.median(later["velocity_m_s"].abs().to_numpy(float)))
            fit_se = later["force_noise_N"].to_numpy(float) * np.sqrt(
                (FORCE_DEGREE + 1) / np.maximum(1, (later["i_stop"] - later["i_start"]).to_numpy(float)))
            scatter = max(1.4826 * float(np.median(np.abs(lf - f_ref))), float(np.median(fit_se)))
            ok = _agrees(p, v_ref, f_ref, max(spec.force_tolerance * abs(f_ref), spec.n_sigma * scatter), spec)
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
    """Per direction ('+' then '-'): the mean of the cycles' peak velocity and force, their cycle-to-cycle
    standard deviations (ddof 1; NaN for one cycle), n_cycles, force_se_N = force_std_N / sqrt(n) (NaN for one
    cycle: nothing says how the cycle repeats) and the mean force noise of the fits."""
    rows = []
    for d in ("+", "-"):
        p = points[points["direction"] == d] if len(points) else points
        n = len(p)
        if n == 0:
            continue
        v, f = p["velocity_m_s"].to_numpy(float), p["force_N"].to_numpy(float)
        sf = float(f.std(ddof=1)) if n > 1 else math.nan
        rows.append({"direction": d, "velocity_m_s": float(v.mean()), "force_N": float(f.mean()),
                     "velocity_std_m_s": float(v.std(ddof=1)) if n > 1 else math.nan, "force_std_N": sf,
                     "n_cycles": n, "force_se_N": sf / math.sqrt(n),
                     "force_noise_N": float(p["force_noise_N"].mean()) if "force_noise_N" in p else math.nan})
    out = pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
    return out.astype({"n_cycles": "int64"})


def loop_energy(t: np.ndarray, x: np.ndarray, f: np.ndarray, t_a: float, t_b: float) -> float:
    """Integral of F dx from t_a to t_b: trapezoids over the samples between, the ends linearly
    interpolated on the time axis."""
    i0 = int(np.searchsorted(t, t_a, side="right"))
    i1 = int(np.searchsorted(t, t_b, side="left"))
    xx = np.concatenate([[np.interp(t_a, t, x)], x[i0:i1], [np.interp(t_b, t, x)]])
    ff = np.concatenate([[np.interp(t_a, t, f)], f[i0:i1], [np.interp(t_b, t, f)]])
    return float(np.sum(0.5 * (ff[1:] + ff[:-1]) * np.diff(xx)))


def cycle_energies(time_s, displacement_m, force_N, period_s: float, *, t_start: float | None = None,
                   t_stop: float | None = None, points: pd.DataFrame | None = None,
                   spec: PeakSpec = PeakSpec()) -> pd.DataFrame:
    """The energy dissipated in each whole cycle, closed integral of F dx between consecutive peaks of positive
    velocity (module doc), for cycles within [t_start, t_stop). ``points``: :func:`peak_points` of the same
    record (computed when None). Two peaks more than 1.5 or less than 0.5 periods apart (a peak left out) make
    no cycle. Columns :data:`ENERGY_COLUMNS` (amplitude_m: half the peak-to-peak displacement of the cycle;
    [i_start, i_stop) its samples)."""
    t, x, f = _arrays(time_s, displacement_m, force_N)
    if points is None:
        points = peak_points(t, x, f, period_s, t_start=t_start, t_stop=t_stop, spec=spec)
    up = np.sort(points.loc[points["direction"] == "+", "time_s"].to_numpy(float)) if len(points) else np.array([])
    rows = []
    for t_a, t_b in zip(up[:-1], up[1:], strict=True):
        if t_b - t_a > 1.5 * period_s or t_b - t_a < 0.5 * period_s:
            continue
        i0 = int(np.searchsorted(t, t_a, side="left"))
        i1 = int(np.searchsorted(t, t_b, side="right"))
        seg = x[i0:i1]
        rows.append({"t_start_s": float(t_a), "t_end_s": float(t_b), "energy_J": loop_energy(t, x, f, t_a, t_b),
                     "amplitude_m": 0.5 * float(seg.max() - seg.min()) if seg.size else math.nan,
                     "i_start": i0, "i_stop": i1})
    return pd.DataFrame(rows, columns=ENERGY_COLUMNS).astype({"i_start": "int64", "i_stop": "int64"})
