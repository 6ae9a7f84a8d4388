"""The damper model over a sine campaign's phase bins, at a cost set by the physics, not by the record.

Each sine case's model runs on its own grid of :data:`~isokinetic.physics.sine_grid.POINTS_PER_CYCLE` points a
cycle (:func:`isokinetic.physics.sine_grid.grid_response`: from rest, until its cycles repeat), whatever the
sampling rate or the number of cycles recorded. A phase bin's mean over the record's samples τ_k = τ_0 + k/fs,
k in [start, stop), is then taken from the grid without visiting the samples, by the midpoint rule read
backwards (Euler-Maclaurin):

    Σ_k Δp(τ_k) = [P(b) - P(a) - (h²/24) (Δp'(b) - Δp'(a))] / h + O(h⁴ Δp''''),
    a = τ_start - h/2, b = τ_stop-1 + h/2, h = 1/fs,

P the integral of Δp from τ = 0 (the model at rest before), Δp and P between grid points from the cubic Hermite
interpolant of Δp and its slope (and its exact integral). Samples a record dropped are taken off one by one.

The force channel. A pure delay L reads the bins shifted back by L (the sample-grid form interpolated the means
of whole-sample shifts linearly: the same to O(h²)). A Butterworth low-pass of order 1 or 2 is the analog
prototype of DC group delay L (corner c/L, c = 1, √2), applied exactly to the piecewise-cubic force (each of its
modes stepped over each grid interval with the cubic as input, in closed form), at rest at the motion's start.
A rig's anti-alias filter is analog; the digital filter at the sampling rate that the sample-by-sample model used
is its bilinear transform, which differs by the bilinear warp, under (f/fs)² at a force harmonic f.

A profiled Coulomb friction's column, sign(v) through the channel, needs no model run: it is exact on the drive's
reversals (:func:`reversals`, :func:`sweep`).
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from isokinetic.diagnosis.observations import Observations
from isokinetic.physics.damper import Damper, Effects
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.responses import scaled_viscosity
from isokinetic.physics.sine_drive import SineDrive
from isokinetic.physics.sine_grid import grid_response, mode_sweep

#: Model runs (effects -> the grids of every case) remembered, the least recent dropped first.
RUN_CACHE = 64


def hermite_values(p: np.ndarray, f: np.ndarray, h: np.ndarray, j: np.ndarray, s: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(value, slope) of the cubic Hermite interpolant of values ``p`` and slopes ``f`` at fraction ``s`` of grid
    interval ``j`` (indices into the concatenated grids; ``h`` the interval's length)."""
    p0, p1, f0, f1 = p[j], p[j + 1], f[j], f[j + 1]
    s2 = s * s
    s3 = s2 * s
    value = p0 * (2 * s3 - 3 * s2 + 1) + h * f0 * (s3 - 2 * s2 + s) + p1 * (3 * s2 - 2 * s3) + h * f1 * (s3 - s2)
    slope = (p0 - p1) * (6 * s2 - 6 * s) / h + f0 * (3 * s2 - 4 * s + 1) + f1 * (3 * s2 - 2 * s)
    return value, slope


def panel_integrals(p: np.ndarray, f: np.ndarray, h: float) -> np.ndarray:
    """∫ over each grid interval of the Hermite interpolant: h (p_j + p_j+1)/2 + h² (f_j - f_j+1)/12."""
    return 0.5 * h * (p[:-1] + p[1:]) + h * h / 12.0 * (f[:-1] - f[1:])


def hermite_integral(p, f, cum, h, j, s):
    """∫ from the grid's start to fraction ``s`` of interval ``j`` of the Hermite interpolant (``cum``: the
    integral up to each grid point)."""
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    return cum[j] + h * (p[j] * (0.5 * s4 - s3 + s) + h * f[j] * (0.25 * s4 - 2.0 / 3.0 * s3 + 0.5 * s2)
                         + p[j + 1] * (-0.5 * s4 + s3) + h * f[j + 1] * (0.25 * s4 - s3 / 3.0))


class Grids:
    """Signals of every case on its grid, concatenated: values, slopes and their running integral."""

    def __init__(self, parts: list[tuple[np.ndarray, np.ndarray]], steps_s: np.ndarray):
        sizes = np.array([p.size for p, _f in parts])
        self.offset = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        self.size = sizes
        self.step = steps_s
        self.p = np.concatenate([p for p, _f in parts])
        self.f = np.concatenate([f for _p, f in parts])
        self.cum = np.concatenate([np.concatenate([[0.0], np.cumsum(panel_integrals(p, f, h))])
                                   for (p, f), h in zip(parts, steps_s, strict=True)])

    def locate(self, case: np.ndarray, tau_s: np.ndarray):
        """(concatenated interval index, fraction, step, before the start) of times in their cases' grids."""
        h = self.step[case]
        x = tau_s / h
        before = x <= 0.0
        x = np.clip(x, 0.0, self.size[case] - 1 - 1e-9)
        j = np.floor(x).astype(np.int64)
        return self.offset[case] + j, x - j, h, before

    def integral(self, case, tau_s):
        j, s, h, before = self.locate(case, tau_s)
        return np.where(before, 0.0, hermite_integral(self.p, self.f, self.cum, h, j, s))

    def value(self, case, tau_s):
        j, s, h, before = self.locate(case, tau_s)
        v, d = hermite_values(self.p, self.f, h, j, s)
        return np.where(before, 0.0, v), np.where(before, 0.0, d)


def butterworth_modes(order: int, group_delay_s: float) -> tuple[tuple[complex, complex], ...]:
    """(pole λ, weight r) of each mode w' = λ w + u of the analog Butterworth low-pass of ``order`` (1, 2) and DC
    group delay L, corner Ω = c/L (c = 1, √2), its output Re Σ r w: 1/(1 + s/Ω) = Ω/(s + Ω); Ω²/(s² + √2 Ω s +
    Ω²), whose two modes are conjugate (one is kept, its residue doubled)."""
    if order == 1:
        w = 1.0 / group_delay_s
        return ((complex(-w, 0.0), complex(w, 0.0)),)
    w = math.sqrt(2.0) / group_delay_s
    pole = w * complex(-1.0, 1.0) / math.sqrt(2.0)
    return ((pole, 2.0 * complex(0.0, -w / math.sqrt(2.0))),)


def monomial_responses(pole: complex, h: float) -> np.ndarray:
    """J_k = ∫_0^h e^{λ(h-τ)} (τ/h)^k dτ, k = 0..3: the response of the mode w' = λ w + u over a step to the
    monomials of a cubic in s = τ/h. By the series h Σ_m (λh)^m k!/(m+k+1)! where |λh| < 1, else by the
    recurrence J_k = (k J_k-1/h - 1)·h/(λh) from J_0 = (e^{λh} - 1)/λ."""
    z = pole * h
    out = np.empty(4, dtype=complex)
    if abs(z) < 1.0:
        for k in range(4):
            term, total, m = 1.0 / math.factorial(k + 1), 0.0, 0
            while True:
                total += term
                m += 1
                term *= z / (m + k + 1)
                if abs(term) < 1e-17 * abs(total) or m > 60:
                    break
            out[k] = h * math.factorial(k) * total
        return out
    out[0] = (np.exp(z) - 1.0) / pole
    for k in range(1, 4):
        out[k] = (k * out[k - 1] / h - 1.0) / pole
    return out


def low_pass(p: np.ndarray, f: np.ndarray, h: float, order: int, group_delay_s: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(y, y') at the grid points of the Butterworth low-pass (:func:`butterworth_modes`) of the Hermite
    interpolant of (``p``, ``f``), at rest at the first point: each mode w' = λ w + u stepped exactly over each
    grid interval, w_j+1 = e^{λh} w_j + Σ_k c_k J_k with the cubic's coefficients c_k in s
    (:func:`monomial_responses`; the recurrence by scipy.signal.lfilter)."""
    from scipy.signal import lfilter

    c = np.stack([p[:-1], h * f[:-1], 3.0 * (p[1:] - p[:-1]) - h * (2.0 * f[:-1] + f[1:]),
                  2.0 * (p[:-1] - p[1:]) + h * (f[:-1] + f[1:])])
    y = np.zeros(p.size)
    slope = np.zeros(p.size)
    for pole, residue in butterworth_modes(order, group_delay_s):
        g = monomial_responses(pole, h) @ c
        w = np.concatenate([[0.0], lfilter([1.0], [1.0, -np.exp(pole * h)], g)])
        y += np.real(residue * w)
        slope += np.real(residue * (pole * w + p))
    return y, slope


def reversals(drive: SineDrive, end_s: float, points: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """(times, signs) of the drive's velocity: the motion starts at τ = 0 with the sign of v(0+), and each time
    its velocity changes sign (a sine's quarter and three-quarter periods; with harmonics, the roots of dy/du,
    found on ``points`` phases a cycle and refined by the secant rule), up to ``end_s``; sign i holds from time i."""
    u = 2.0 * math.pi * np.arange(points + 1) / points
    v = drive.phase_velocity(u)
    change = np.flatnonzero(np.sign(v[:-1]) != np.sign(v[1:]))
    roots = []
    for i in change:   # the secant rule on the bracket, a few steps (dy/du is smooth)
        lo, hi, vlo, vhi = u[i], u[i + 1], v[i], v[i + 1]
        for _ in range(40):
            mid = lo - vlo * (hi - lo) / (vhi - vlo)
            vm = float(drive.phase_velocity(np.array([mid]))[0])
            if vm == 0.0 or hi - lo < 1e-14:
                break
            if np.sign(vm) == np.sign(vlo):
                lo, vlo = mid, vm
            else:
                hi, vhi = mid, vm
        roots.append(mid)
    period = 1.0 / drive.frequency_Hz
    per_cycle = np.array(roots) / (2.0 * math.pi) * period
    cycles = int(math.ceil(end_s / period)) + 1
    times = (np.arange(cycles)[:, None] * period + per_cycle[None, :]).ravel()
    times = np.concatenate([[0.0], times[(times > 0.0) & (times <= end_s + period)]])
    first = 1.0 if v[0] > 0.0 or (v[0] == 0.0 and v[1] > 0.0) else -1.0
    return times, first * (-1.0) ** np.arange(times.size)


def sweep(jumps: np.ndarray, signs: np.ndarray, lam: complex, queries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`isokinetic.physics.sine_grid.mode_sweep` at any ``queries`` (sorted here, returned in their order;
    times <= 0: 0)."""
    order = np.argsort(queries, kind="stable")
    w, big = np.empty(queries.size, dtype=complex), np.empty(queries.size, dtype=complex)
    mode_sweep(jumps, signs.astype(float), complex(lam), np.maximum(queries[order], 0.0), w, big)
    out_w, out_big = np.empty_like(w), np.empty_like(big)
    out_w[order], out_big[order] = w, big
    return out_w, out_big


class GridEvaluator:
    """Noise-free model means over a sine-only campaign's phase bins, run on the physics' grids (module
    docstring): the interface of :class:`isokinetic.diagnosis.model.Evaluator` for runs without friction."""

    def __init__(self, obs: Observations, damper: Damper):
        self.obs = obs
        self.damper = damper
        self.calls = 0
        self.drives: tuple[SineDrive, ...] = tuple(obs.drives)
        fs = np.array([p.sample_rate_Hz for p in obs.plans])
        start = np.array([d.grid_start_s for d in self.drives])
        ci = obs.case_index
        self._h = 1.0 / fs[ci]
        self._a = start[ci] + (obs.start - 0.5) * self._h
        self._b = start[ci] + (obs.stop - 0.5) * self._h
        self._hole_row = obs.holes[:, 0]
        self._hole_tau = start[ci[self._hole_row]] + obs.holes[:, 1] / fs[ci[self._hole_row]]
        self._n = (obs.stop - obs.start - np.bincount(self._hole_row, minlength=len(obs))).astype(float)
        ends = np.zeros(len(obs.plans))
        np.maximum.at(ends, ci, self._b)
        self._end = ends
        self._runs: OrderedDict = OrderedDict()
        self._reversal_cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def share_runs(self, other: GridEvaluator) -> None:
        """Remember runs together with ``other`` (the same damper and drives: a sine-only campaign's period-1
        evaluator beside the full one), each run made to the later of the two's last samples."""
        self._end = other._end = np.maximum(self._end, other._end)
        self._runs = other._runs

    def _grids(self, effects: Effects) -> tuple[float, list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
        """(A_p, (Δp, slope) of every case on its grid, the grid steps) of a run (remembered)."""
        hit = self._runs.get(effects)
        if hit is not None:
            self._runs.move_to_end(effects)
            return hit
        self.calls += 1
        hyd = Hydraulics.from_damper(self.damper, effects)
        scales = self.obs.viscosity_scale or (1.0,) * len(self.drives)
        parts, steps = [], []
        for d, scale, end in zip(self.drives, scales, self._end, strict=True):
            run = grid_response(d.amplitude_m, d.frequency_Hz, d.harmonics, scaled_viscosity(hyd, scale), end)
            parts.append(run.unfolded(end))
            steps.append(run.step_s)
        out = self._runs[effects] = (hyd.piston_area_m2, parts, np.array(steps))
        if len(self._runs) > RUN_CACHE:
            self._runs.popitem(last=False)
        return out

    def _bin_means(self, grids: Grids, shift_s: float, area: float) -> np.ndarray:
        """A_p × each bin's mean of the signal over its samples, read ``shift_s`` late (module docstring)."""
        ci, h = self.obs.case_index, self._h
        a, b = self._a - shift_s, self._b - shift_s
        _va, da = grids.value(ci, a)
        _vb, db = grids.value(ci, b)
        sums = (grids.integral(ci, b) - grids.integral(ci, a) - h * h / 24.0 * (db - da)) / h
        if self._hole_row.size:
            holes, _d = grids.value(ci[self._hole_row], self._hole_tau - shift_s)
            sums = sums - np.bincount(self._hole_row, holes, minlength=len(self.obs))
        return area * sums / self._n

    def lagged(self, effects: Effects, lags_s) -> np.ndarray:
        area, parts, steps = self._grids(effects)
        grids = Grids(parts, steps)
        return np.array([self._bin_means(grids, float(lag), area) for lag in np.atleast_1d(lags_s)])

    def filtered(self, effects: Effects, group_delays_s, order: int) -> np.ndarray:
        area, parts, steps = self._grids(effects)
        rows = []
        for lag in np.atleast_1d(np.asarray(group_delays_s, dtype=float)):
            out = [low_pass(p, f, h, order, float(lag)) for (p, f), h in zip(parts, steps, strict=True)]
            rows.append(self._bin_means(Grids(out, steps), 0.0, area))
        return np.array(rows)

    def friction_read(self, form: int, lag_s: float) -> np.ndarray:
        """Each bin's mean of the unit Coulomb friction sign(v) (Eq. 8 per newton of F_C) as a force channel of
        ``form`` (0: a delay, 1 or 2: the Butterworth low-pass of :func:`butterworth_modes`) and group delay
        ``lag_s`` reads it: exact on the drive's reversals (:func:`reversals`, :func:`sweep`), the sample sums
        by the rule of the module docstring."""
        ci, h, n = self.obs.case_index, self._h, len(self.obs)
        shift = lag_s if form == 0 else 0.0
        modes = ((0j, 1.0 + 0j),) if form == 0 else butterworth_modes(form, lag_s)
        sums = np.zeros(n)
        hole_case = ci[self._hole_row]
        for i in range(len(self.drives)):
            rows, holes = np.flatnonzero(ci == i), np.flatnonzero(hole_case == i)
            if not rows.size:
                continue
            jumps, signs = self._reversal_table(i)
            q = np.concatenate([self._a[rows], self._b[rows], self._hole_tau[holes]]) - shift
            for lam, residue in modes:
                w, big = sweep(jumps, signs, lam, q)
                sigma = signs[np.maximum(np.searchsorted(jumps, np.maximum(q, 0.0), side="right") - 1, 0)] * (q > 0)
                if form == 0:   # the delayed sign itself: its integral w, no slope between reversals
                    y, slope, value = np.real(w), np.zeros(q.size), sigma
                else:           # the mode's output r w, its integral r W and slope r (λ w + σ)
                    y = np.real(residue * big)
                    slope = np.real(residue * (lam * w + sigma))
                    value = np.real(residue * w)
                m = rows.size
                ya, yb, da, db = y[:m], y[m:2 * m], slope[:m], slope[m:2 * m]
                sums[rows] += (yb - ya - h[rows] ** 2 / 24.0 * (db - da)) / h[rows]
                if holes.size:
                    np.subtract.at(sums, self._hole_row[holes], value[2 * m:])
        return sums / self._n

    def _reversal_table(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """The reversals of case ``i``'s drive up to its last sample (remembered)."""
        hit = self._reversal_cache.get(i)
        if hit is None:
            hit = self._reversal_cache[i] = reversals(self.drives[i], float(self._end[i]))
        return hit

    def moments(self, effects: Effects) -> tuple[np.ndarray, np.ndarray]:
        """(mean, mean square) of the model force over each bin's samples."""
        area, parts, steps = self._grids(effects)
        squares = [(p * p, 2.0 * p * f) for p, f in parts]
        return (self._bin_means(Grids(parts, steps), 0.0, area),
                self._bin_means(Grids(squares, steps), 0.0, area * area))
