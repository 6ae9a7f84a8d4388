"""The peak-velocity method of sine records and the energy dissipated per cycle (Sec. 4 of the paper,
harmonic tests; the damper-test specifications' force-velocity curve).

For a sine displacement x = X0 + X sin(wt) the velocity peaks, +wX or -wX, where the displacement
crosses its centre X0 (rising: + peak, falling: - peak). Per crossing (:func:`peak_points`):

1. the crossing is found with hysteresis (a quarter of the amplitude) so noise does not split it,
   and refined on the record's own time stamps: a least-squares cubic x(t) through the samples within
   ``fit_fraction`` x T of it (at least ``min_side`` samples each side), its root nearest the sample
   crossing is the instant t_c of peak velocity and its slope there the peak velocity;
2. the force at t_c is a least-squares quadratic F(t) through the samples within the same span of
   t_c (the force is near an extreme in time there, and a lagging force has a slope: both fit).

Nothing assumes even sampling: a missing sample or a burst only thins a fit; a crossing whose fit
lacks ``min_side`` samples on either side is left out (counted in :func:`summarise`'s caller).
Bias on a pure sine with the default span (T/20 either side): below 3e-4 of the force at peak
velocity for F = c1 v + c2 v|v|.

:func:`settled` drops a direction's leading cycles still off the later cycles' median (start-up), and
:func:`summarise` averages the cycles of a step: mean velocity and force, the cycle-to-cycle standard
deviation of the force (ddof 1), the cycles n and the standard error std / sqrt(n).

Energy per cycle (:func:`cycle_energies`): the closed integral of F dx over each whole cycle between
consecutive rising crossings (trapezoids on the real time stamps, the ends interpolated at the
crossings), positive for a dissipating damper. For F = c v on x = X sin(wt): E = pi c w X^2; for
F = c2 v|v|: E = (8/3) c2 w^2 X^3.

:func:`steady_range` picks the steady whole periods of a record (first ones skipped while the
period-mean force still drifts), the same rule as :func:`isokinetic.measurement.loops.loop`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.measurement.crossings import hysteresis_crossings

#: Columns of :func:`peak_points`.
POINT_COLUMNS = ["direction", "time_s", "velocity_m_s", "force_N", "i_start", "i_stop"]
#: Columns of :func:`summarise`.
SUMMARY_COLUMNS = ["direction", "velocity_m_s", "force_N", "velocity_std_m_s", "force_std_N", "n_cycles",
                   "force_se_N"]
#: Columns of :func:`cycle_energies`.
ENERGY_COLUMNS = ["t_start_s", "t_end_s", "energy_J", "amplitude_m", "i_start", "i_stop"]


@dataclass(frozen=True)
class PeakSpec:
    """Settings of the peak-velocity method: fit span (fraction of the period either side of the crossing,
    widened to ``min_side`` + 1 sample intervals on coarse records), fewest samples each side, hysteresis
    (fraction of the amplitude), start-up periods skipped at least and the steady tolerance."""

    fit_fraction: float = 0.05
    min_side: int = 2
    hysteresis: float = 0.25
    skip_periods: int = 1
    steady_tolerance: float = 0.01

    def __post_init__(self):
        if not 0.0 < self.fit_fraction <= 0.125:
            raise ValueError(f"fit_fraction must lie in (0, 1/8], got {self.fit_fraction}")
        if self.min_side < 2:
            raise ValueError(f"min_side must be >= 2, got {self.min_side}")
        if not 0.0 < self.hysteresis < 1.0:
            raise ValueError(f"hysteresis must lie in (0, 1), got {self.hysteresis}")


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


def time_mean(t: np.ndarray, y: np.ndarray) -> float:
    """Time average of y (trapezoids on the real time stamps: gaps weigh by their length)."""
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)) / (t[-1] - t[0]))


def interval_integral(t: np.ndarray, y: np.ndarray, a: float, b: float) -> float:
    """Integral of y dt from a to b (trapezoids over the samples between, the ends linearly interpolated)."""
    i0 = int(np.searchsorted(t, a, side="right"))
    i1 = int(np.searchsorted(t, b, side="left"))
    tt = np.concatenate([[a], t[i0:i1], [b]])
    yy = np.concatenate([[np.interp(a, t, y)], y[i0:i1], [np.interp(b, t, y)]])
    return float(np.sum(0.5 * (yy[1:] + yy[:-1]) * np.diff(tt)))


def steady_range(time_s, force_N, period_s: float, spec: PeakSpec = PeakSpec()) -> tuple[float, float]:
    """[start, stop) of the record's steady whole periods on its time axis.

    Whole periods counted from the first sample; at least ``spec.skip_periods`` are skipped, more while
    a period's mean force differs from the last period's by more than ``spec.steady_tolerance`` x the
    last period's force amplitude (the start-up transient), always keeping one. Raises ValueError when
    the record holds no whole period.
    """
    t = np.asarray(time_s, dtype=float)
    f = np.asarray(force_N, dtype=float)
    if not (period_s > 0 and math.isfinite(period_s)):
        raise ValueError(f"period must be positive and finite, got {period_s}")
    dt = float(np.median(np.diff(t)))
    n_whole = int(math.floor((t[-1] - t[0] + dt) / period_s + 1e-6))
    if n_whole < 1:
        raise ValueError(f"record of {t[-1] - t[0] + dt:.4g} s holds no whole period of {period_s:.4g} s")
    k = np.floor((t - t[0]) / period_s + 1e-9).astype(np.int64)

    def period_mean(j: int) -> float | None:          # time mean: a burst of missing samples weighs its length
        if (k == j).sum() < 2:
            return None
        lo, hi = t[0] + j * period_s, min(t[0] + (j + 1) * period_s, t[-1])
        return interval_integral(t, f, lo, hi) / (hi - lo)

    last = f[k == n_whole - 1]
    start = n_whole - 1
    ref = period_mean(n_whole - 1)
    if ref is not None:
        tol = spec.steady_tolerance * 0.5 * float(last.max() - last.min())
        for j in range(n_whole - 2, -1, -1):
            mean_j = period_mean(j)
            if mean_j is not None and abs(mean_j - ref) > tol:
                break
            start = j
    skip = min(max(spec.skip_periods, start), n_whole - 1)
    return float(t[0] + skip * period_s), float(t[0] + n_whole * period_s)


def crossings(displacement_m, centre_m: float, hysteresis_m: float) -> list[tuple[int, float]]:
    """(i, sign) of each crossing of ``centre_m``: the sample crossing lies between samples i - 1 and i,
    sign +1 rising, -1 falling. The side changes only when x passes centre -/+ ``hysteresis_m``; the
    crossing is the last change of side of x - centre before that (:func:`hysteresis_crossings`)."""
    i, sign = hysteresis_crossings(np.asarray(displacement_m, dtype=float) - centre_m, hysteresis_m)
    return [(max(int(a), 1), float(b)) for a, b in zip(i, sign, strict=True)]


def _fit_span(t: np.ndarray, t0: float, half_s: float, min_side: int) -> tuple[int, int] | None:
    """Samples [lo, hi) within t0 -/+ half_s, None with fewer than ``min_side`` on either side."""
    lo = int(np.searchsorted(t, t0 - half_s, side="left"))
    mid = int(np.searchsorted(t, t0, side="left"))
    hi = int(np.searchsorted(t, t0 + half_s, side="right"))
    if mid - lo < min_side or hi - mid < min_side:
        return None
    return lo, hi


def _crossing_time(t: np.ndarray, x: np.ndarray, lo: int, hi: int, t0: float, half_s: float, centre: float
                   ) -> tuple[float, float] | None:
    """(t_c, dx/dt at t_c) of the least-squares cubic through samples [lo, hi): its root nearest t0."""
    u = (t[lo:hi] - t0) / half_s
    p = np.polynomial.Polynomial.fit(u, x[lo:hi] - centre, 3, domain=[-1, 1], window=[-1, 1])
    dp = p.deriv()
    r = 0.0
    for _ in range(20):                                  # Newton from the sample crossing
        d = float(dp(r))
        if d == 0.0:
            return None
        step = float(p(r)) / d
        r -= step
        if abs(step) < 1e-12:
            break
    if not (-1.0 <= r <= 1.0):
        return None
    return t0 + r * half_s, float(dp(r)) / half_s


def peak_points(time_s, displacement_m, force_N, period_s: float, *, t_start: float | None = None,
                t_stop: float | None = None, centre_m: float | None = None, spec: PeakSpec = PeakSpec()
                ) -> pd.DataFrame:
    """The force at each peak of velocity (module doc): one row per crossing of the centre whose instant
    lies in [t_start, t_stop) (default: the whole record).

    ``centre_m``: the displacement's centre, default its time mean over [t_start, t_stop). Columns
    :data:`POINT_COLUMNS`: direction '+'/'-', time_s (t_c), velocity_m_s (signed), force_N, and the
    samples [i_start, i_stop) the fits used.
    """
    t, x, f = _arrays(time_s, displacement_m, force_N)
    a = t[0] if t_start is None else float(t_start)
    b = t[-1] + 1.0 if t_stop is None else float(t_stop)
    inside = (t >= a) & (t < b)
    if inside.sum() < 4:
        return pd.DataFrame(columns=POINT_COLUMNS)
    amplitude = 0.5 * float(np.percentile(x[inside], 99.5) - np.percentile(x[inside], 0.5))
    if amplitude <= 0.0:
        return pd.DataFrame(columns=POINT_COLUMNS)
    if centre_m is not None:
        return _peak_points(t, x, f, period_s, a, b, centre_m, amplitude, spec)
    # the centre: the time mean over [a, b), then over the whole cycles between the first and last rising
    # crossings found with it (a range that is not whole periods, e.g. an off-nominal frequency, biases the first)
    first = _peak_points(t, x, f, period_s, a, b, time_mean(t[inside], x[inside]), amplitude, spec)
    up = first.loc[first["direction"] == "+", "time_s"].to_numpy(float)
    if up.size < 2:
        return first
    whole = interval_integral(t, x, float(up[0]), float(up[-1])) / float(up[-1] - up[0])
    return _peak_points(t, x, f, period_s, a, b, whole, amplitude, spec)


def _peak_points(t: np.ndarray, x: np.ndarray, f: np.ndarray, period_s: float, a: float, b: float, centre_m: float,
                 amplitude: float, spec: PeakSpec) -> pd.DataFrame:
    """:func:`peak_points` about a known centre."""
    dt = float(np.median(np.diff(t)))
    half_s = max(spec.fit_fraction * period_s, (spec.min_side + 0.5) * dt)
    rows = []
    for i, s in crossings(x, centre_m, spec.hysteresis * amplitude):
        xa, xb = x[i - 1] - centre_m, x[i] - centre_m
        t0 = t[i - 1] + (t[i] - t[i - 1]) * (xa / (xa - xb) if xa != xb else 0.5)
        if not (a <= t0 < b):
            continue
        span = _fit_span(t, t0, half_s, spec.min_side)
        if span is None:
            continue
        found = _crossing_time(t, x, *span, t0, half_s, centre_m)
        if found is None:
            continue
        tc, vc = found
        if not (a <= tc < b) or np.sign(vc) != s:
            continue
        span_f = _fit_span(t, tc, half_s, spec.min_side)
        if span_f is None:
            continue
        lo, hi = span_f
        q = np.polynomial.Polynomial.fit((t[lo:hi] - tc) / half_s, f[lo:hi], 2, domain=[-1, 1], window=[-1, 1])
        rows.append({"direction": "+" if s > 0 else "-", "time_s": tc, "velocity_m_s": vc, "force_N": float(q(0.0)),
                     "i_start": min(lo, span[0]), "i_stop": max(hi, span[1])})
    out = pd.DataFrame(rows, columns=POINT_COLUMNS)
    return out.astype({"i_start": "int64", "i_stop": "int64"})


def settled(points: pd.DataFrame, tolerance: float = 0.005, n_sigma: float = 4.0) -> pd.DataFrame:
    """:func:`peak_points` without the leading cycles of each direction still in the start-up transient.

    Per direction, in time order: the reference is the median force of the later half of the cycles and
    the scatter 1.4826 x their median absolute deviation; leading cycles are dropped while their force
    differs from the reference by more than max(``n_sigma`` x scatter, ``tolerance`` x |reference|). (A
    sine starting at its centre has a crossing on the first steady period's boundary, whose force the
    period means of :func:`steady_range` do not see settle.)"""
    keep = []
    for d in ("+", "-"):
        p = points[points["direction"] == d].sort_values("time_s", kind="stable")
        f = p["force_N"].to_numpy(float)
        if f.size >= 3:
            later = f[f.size // 2:]
            ref = float(np.median(later))
            limit = max(n_sigma * 1.4826 * float(np.median(np.abs(later - ref))), tolerance * abs(ref))
            first = 0
            while first < f.size // 2 and abs(f[first] - ref) > limit:
                first += 1
            p = p.iloc[first:]
        keep.append(p)
    out = pd.concat(keep) if keep else points
    return out.sort_values("time_s", kind="stable").reset_index(drop=True)


def summarise(points: pd.DataFrame) -> pd.DataFrame:
    """Per direction ('+' then '-'): the mean of the cycles' peak velocity and force, their cycle-to-cycle
    standard deviations (ddof 1; NaN for one cycle), n_cycles and force_se_N = force_std_N / sqrt(n)."""
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
                     "n_cycles": n, "force_se_N": sf / math.sqrt(n)})
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
    """The energy dissipated in each whole cycle, closed integral of F dx between consecutive rising
    crossings (module doc), for cycles within [t_start, t_stop). ``points``: :func:`peak_points` of the
    same record (computed when None). A pair of rising crossings more than 1.5 periods apart (a crossing
    left out) is no cycle. Columns :data:`ENERGY_COLUMNS` (amplitude_m: half the peak-to-peak displacement
    of the cycle; [i_start, i_stop) its samples)."""
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
