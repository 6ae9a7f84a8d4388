"""The damper driven by a measured periodic motion, on a grid set by the physics, not by the sampling rate.

Eq. (1) with the composite volume of Eq. (2), the flow of Eq. (7) plus leakage (and, with entrained air under the
gas law, the two chambers of :mod:`isokinetic.physics.gas_law`) is integrated from rest by the 3-stage Radau IIA
method (order 5, L-stable: Hairer & Wanner, "Solving Ordinary Differential Equations II", IV.5) with a fixed step
of one ``points_per_cycle``-th of the drive's period, so that the result is a smooth function of the damper's
parameters (finite-difference Jacobians need that) and costs the same at any sampling rate. The first step is
cut into geometrically growing sub-steps: the pressure starts at 0 while the piston moves at its peak speed, a
transient as short as the relaxation time of Eq. (14).

The periodic steady state is reached after a number of cycles set by the physics (the relaxation against the
period); a cycle whose change from the one before repeats the change before it to within ``CONVERGED`` of the
pressure scale ends the integration, and every later cycle is that one plus as many of that change (none, or the
constant drift of the chambers' mean pressure the gas law's oil term makes: some 1e-7 of the pressure a cycle)
(:attr:`GridResponse.periodic_from`). A record of a hundred cycles costs as little as its first few. The kernel
is compiled once by numba (cached beside this module).

The piston motion is that of :class:`isokinetic.physics.sine_drive.SineDrive`: y = Y sin ωτ + Σ A_k (sin(kωτ +
θ_k) - sin θ_k) for τ >= 0, at rest at y = 0 before (the diagnosis' sine drive has no backlash).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numba  # ~0.15 s of import: this module is imported only where a periodic drive is modelled
import numpy as np

from isokinetic.physics.gas_law import PRESSURE_FLOOR, gas_amounts
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.sine_drive import SineDrive

#: Grid points per cycle of the drive: Radau IIA's error on the pressure of a smooth periodic drive is about
#: (2π/points)^5 of its amplitude: within 1e-5 of the pressure scale at 128 (against LSODA at rtol 1e-10).
POINTS_PER_CYCLE = 128
#: Sub-steps of the first step, growing geometrically from FIRST_SUBSTEP of the period.
SUBSTEPS = 48
FIRST_SUBSTEP = 1e-9
#: A cycle whose pressure repeats the cycle before's to within this share of the largest |Δp| ends the integration.
CONVERGED = 1e-8
#: Newton iterations per step at most; the Newton iteration stops at this relative step.
NEWTON_ITERATIONS = 12
NEWTON_TOL = 1e-11

_S6 = math.sqrt(6.0)
#: Radau IIA, 3 stages: nodes and coefficients (the last row is the step's weights: stiffly accurate).
RADAU_C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])
RADAU_A = np.array([[(88.0 - 7.0 * _S6) / 360.0, (296.0 - 169.0 * _S6) / 1800.0, (-2.0 + 3.0 * _S6) / 225.0],
                    [(296.0 + 169.0 * _S6) / 1800.0, (88.0 + 7.0 * _S6) / 360.0, (-2.0 - 3.0 * _S6) / 225.0],
                    [(16.0 - _S6) / 36.0, (16.0 + _S6) / 36.0, 1.0 / 9.0]])


@dataclass(frozen=True)
class GridResponse:
    """Δp and dΔp/dτ of one drive at τ_j = j·``step_s``, j = 0 .. (from τ = 0, the motion's start, at rest before);
    ``periodic_from``: the index of the first grid point of the cycle from which on the response repeats, or
    changes from cycle to cycle by a constant drift (the arrays end with that cycle; :meth:`unfolded`), or -1 where
    the record ended before the response settled."""

    step_s: float
    points_per_cycle: int
    dp_Pa: np.ndarray
    slope_Pa_s: np.ndarray
    periodic_from: int

    def unfolded(self, end_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(Δp [Pa], dΔp/dτ [Pa/s]) on the grid from τ = 0 to at least ``end_s``: after the integrated cycles, the
        last one plus m times its change from the one before, m = 1, 2, ... (the change is none, or the drift of the
        chambers' mean pressure that the gas law's oil term makes each cycle: constant)."""
        need = int(math.ceil(end_s / self.step_s)) + 2
        p, f = self.dp_Pa, self.slope_Pa_s
        if self.periodic_from < 0 or need <= p.size:
            return p, f
        last = slice(self.periodic_from + 1, self.periodic_from + 1 + self.points_per_cycle)
        before = slice(self.periodic_from + 1 - self.points_per_cycle, self.periodic_from + 1)
        copies = np.arange(1, int(math.ceil((need - p.size) / self.points_per_cycle)) + 1)[:, None]

        def extend(x):   # the last cycle plus m times its change from the one before (the gas law's slow drift)
            return np.concatenate([x, (x[last] + copies * (x[last] - x[before])).ravel()])
        return extend(p), extend(f)


def _drive_terms(harmonics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, A_k, θ_k) of the drive's harmonics as three arrays (the kernel's form)."""
    ks = np.array([float(k) for k, _a, _t in harmonics])
    aks = np.array([float(a) for _k, a, _t in harmonics])
    ths = np.array([float(t) for _k, _a, t in harmonics])
    return ks, aks, ths


# The kernel below is compiled by numba (cached beside this module). ``par``: amp, omega, h, area, beta, v01, v02,
# c1p, c1n, c2p, c2n, leak, gas, b_oil, g1, g2, p0, low, scale (:func:`grid_parameters`), a tuple. Its functions pass
# scalars, not array views (each view costs a reference count), and are inlined into :func:`_integrate`.

@numba.njit(cache=True, inline="always", error_model="numpy")
def _motion(t, par, ks, aks, ths, start):   # pragma: no cover - compiled
    """(y, dy/dτ) of the drive at τ (:class:`isokinetic.physics.sine_drive.SineDrive`)."""
    ph = par[1] * t
    y = par[0] * math.sin(ph)
    v = par[0] * math.cos(ph)
    for i in range(ks.size):
        arg = ks[i] * ph + ths[i]
        y += aks[i] * math.sin(arg)
        v += ks[i] * aks[i] * math.cos(arg)
    return y - start, par[1] * v


@numba.njit(cache=True, inline="always", error_model="numpy")
def _flow(p, par):   # pragma: no cover - compiled
    """(Q_N, dQ_N/dΔp): Eq. (7) with the direction's c1, c2, plus leakage."""
    c1p, c1n, c2p, c2n, leak = par[7], par[8], par[9], par[10], par[11]
    m = abs(p)
    if m == 0.0:
        return 0.0, 1.0 / max(c1p, 1e-300) + leak
    if p >= 0.0:
        root = math.sqrt(c1p * c1p + 4.0 * c2p * m)
        return 2.0 * m / (c1p + root) + leak * p, 1.0 / root + leak
    root = math.sqrt(c1n * c1n + 4.0 * c2n * m)
    return -2.0 * m / (c1n + root) + leak * p, 1.0 / root + leak


@numba.njit(cache=True, inline="always", error_model="numpy")
def _rhs(y, v, p1, p2, par):   # pragma: no cover - compiled
    """Eq. (1) at piston position y and speed v: (f1, f2, J11, J12, J21, J22), the rates of the state and their
    Jacobian: one state Δp = p1 with the composite volume of Eq. (2) (f2, J12, J21, J22 zero); with the gas law
    the two chamber pressures p1, p2 (:mod:`isokinetic.physics.gas_law`). Scalars only: no array is passed."""
    area, beta, v01, v02 = par[3], par[4], par[5], par[6]
    qin = area * v
    if par[12] < 0.5:
        q, dq = _flow(p1, par)
        cap = beta * ((v01 - area * y) * (v02 + area * y) / (v01 + v02))
        return (qin - q) / cap, 0.0, -dq / cap, 0.0, 0.0, 0.0
    b_oil, g1, g2, low = par[13], par[14], par[15], par[17]
    u1 = 1.0 / max(p1, low)
    u2 = 1.0 / max(p2, low)
    cap1 = b_oil * (v01 - area * y) + g1 * u1 * (u1 - b_oil)
    cap2 = b_oil * (v02 + area * y) + g2 * u2 * (u2 - b_oil)
    q, dq = _flow(p1 - p2, par)
    net = qin - q
    s1 = g1 * u1 * u1 * (b_oil - 2.0 * u1)
    s2 = g2 * u2 * u2 * (b_oil - 2.0 * u2)
    return (net / cap1, -net / cap2, (-dq - net / cap1 * s1) / cap1, dq / cap1, dq / cap2,
            (-dq + net / cap2 * s2) / cap2)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _factor(big, piv):   # pragma: no cover - compiled
    """LU factors of ``big`` with partial pivoting, in place (pivots in ``piv``)."""
    n = big.shape[0]
    for col in range(n):
        p = col
        for r in range(col + 1, n):
            if abs(big[r, col]) > abs(big[p, col]):
                p = r
        piv[col] = p
        if p != col:
            for c in range(n):
                big[col, c], big[p, c] = big[p, c], big[col, c]
        for r in range(col + 1, n):
            big[r, col] /= big[col, col]
            m = big[r, col]
            if m != 0.0:
                for c in range(col + 1, n):
                    big[r, c] -= m * big[col, c]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _back(big, piv, res):   # pragma: no cover - compiled
    """res <- big⁻¹ res from the factors of :func:`_factor`."""
    n = big.shape[0]
    for col in range(n):
        p = piv[col]
        if p != col:
            res[col], res[p] = res[p], res[col]
        for r in range(col + 1, n):
            res[r] -= big[r, col] * res[col]
    for r in range(n - 1, -1, -1):
        acc = res[r]
        for c in range(r + 1, n):
            acc -= big[r, c] * res[c]
        res[r] = acc / big[r, r]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _newton(z, hh, my, mv, stage, par, radau_a, newton_iterations, newton_tol, work):   # pragma: no cover
    """Simplified Newton on the stage increments Z_i = hh Σ_j A_ij f(t + c_j hh, z + Z_j) from ``stage`` (the
    iteration matrix built and factorised once, from the Jacobian at the predicted stages); then z += Z_3.
    ``work``: the scratch arrays of :func:`_work`."""
    dim = z.size
    fst, jst, big, piv, res = work
    for it in range(newton_iterations):
        for i in range(3):
            q2 = z[1] + stage[i, 1] if dim == 2 else 0.0
            f1, f2, j11, j12, j21, j22 = _rhs(my[i], mv[i], z[0] + stage[i, 0], q2, par)
            fst[i, 0], fst[i, 1] = f1, f2
            jst[i, 0, 0], jst[i, 0, 1], jst[i, 1, 0], jst[i, 1, 1] = j11, j12, j21, j22
        if it == 0:
            for i in range(3):
                for d in range(dim):
                    for j in range(3):
                        for e in range(dim):
                            big[i * dim + d, j * dim + e] = -hh * radau_a[i, j] * jst[j, d, e] + (
                                1.0 if (i == j and d == e) else 0.0)
            _factor(big, piv)
        for i in range(3):
            for d in range(dim):
                acc = stage[i, d]
                for j in range(3):
                    acc -= hh * radau_a[i, j] * fst[j, d]
                res[i * dim + d] = acc
        _back(big, piv, res)
        size = 0.0
        for i in range(3):
            for d in range(dim):
                stage[i, d] -= res[i * dim + d]
                size = max(size, abs(res[i * dim + d]))
        if size <= newton_tol * par[18]:
            break
    for d in range(dim):
        z[d] += stage[2, d]


@numba.njit(cache=True, inline="always", error_model="numpy")
def _work(dim):   # pragma: no cover - compiled
    """Scratch arrays of :func:`_newton`: stage rates and Jacobians (room for two states), the iteration matrix,
    pivots, residual."""
    n = 3 * dim
    return np.zeros((3, 2)), np.zeros((3, 2, 2)), np.empty((n, n)), np.empty(n, dtype=np.int64), np.empty(n)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _store(j, y, v, z, par, out_p, out_f):   # pragma: no cover - compiled
    """Δp and dΔp/dτ of state ``z`` at grid point ``j``."""
    if z.size == 2:
        f1, f2, _a, _b, _c, _d = _rhs(y, v, z[0], z[1], par)
        out_p[j], out_f[j] = z[0] - z[1], f1 - f2
    else:
        f1, _f2, _a, _b, _c, _d = _rhs(y, v, z[0], 0.0, par)
        out_p[j], out_f[j] = z[0], f1


@numba.njit(cache=True, error_model="numpy")
def _integrate(par, ks, aks, ths, radau_a, radau_c, n_steps, per_cycle, substeps, first_sub, converged,
               newton_iterations, newton_tol, stage_y, stage_v, out_p, out_f):   # pragma: no cover - compiled
    """Radau IIA over ``n_steps`` grid steps from rest (module docstring); fills out_p, out_f (Δp, dΔp/dτ at the
    grid points) and returns the index of the first point of the cycle that repeats the one before (-1: none).
    ``stage_y``, ``stage_v``: the piston's position and velocity at τ = (j + c_i) h of grid step j of a cycle
    (columns i = 0..2, the stages; column 3: the grid point j h), :func:`stage_motion`."""
    dim = 2 if par[12] > 0.5 else 1
    start = 0.0
    for i in range(ks.size):
        start += aks[i] * math.sin(ths[i])
    z = np.full(dim, par[16]) if dim == 2 else np.zeros(1)
    stage = np.zeros((3, dim))
    my, mv = np.empty(3), np.empty(3)
    work = _work(dim)
    _store(0, stage_y[0, 3], stage_v[0, 3], z, par, out_p, out_f)
    ratio = (1.0 / first_sub) ** (1.0 / (substeps - 1))   # the first step: geometric sub-steps summing to h
    hh = par[2] * (ratio - 1.0) / (ratio ** substeps - 1.0)
    t = 0.0
    for j in range(-substeps, n_steps):
        if j < 0:
            for i in range(3):
                my[i], mv[i] = _motion(t + radau_c[i] * hh, par, ks, aks, ths, start)
        else:
            if j == 0:
                continue
            hh, t, k = par[2], j * par[2], j % per_cycle
            for i in range(3):
                my[i], mv[i] = stage_y[k, i], stage_v[k, i]
        if j < 0 or j == 1:   # Euler's predictor after a change of step, else the last step's increments
            y0, v0 = _motion(t, par, ks, aks, ths, start)
            f1, f2, _a, _b, _c, _d = _rhs(y0, v0, z[0], z[1] if dim == 2 else 0.0, par)
            for i in range(3):
                stage[i, 0] = radau_c[i] * hh * f1
                if dim == 2:
                    stage[i, 1] = radau_c[i] * hh * f2
        _newton(z, hh, my, mv, stage, par, radau_a, newton_iterations, newton_tol, work)
        if j < 0:
            t += hh
            hh *= ratio
            if j == -1:
                _store(1, stage_y[1 % per_cycle, 3], stage_v[1 % per_cycle, 3], z, par, out_p, out_f)
            continue
        k1 = (j + 1) % per_cycle
        _store(j + 1, stage_y[k1, 3], stage_v[k1, 3], z, par, out_p, out_f)
        if (j + 1) % per_cycle == 0 and j + 1 >= 3 * per_cycle:
            worst = 0.0   # the change from cycle to cycle, changing no more (a drift) or none
            for k in range(j + 1 - per_cycle, j + 1):
                worst = max(worst, abs(out_p[k + 1] - 2.0 * out_p[k + 1 - per_cycle] + out_p[k + 1 - 2 * per_cycle]))
            if worst <= converged * par[18]:
                return j + 1 - per_cycle
    return -1


@numba.njit(cache=True, error_model="numpy")
def mode_sweep(jumps, signs, lam, queries, w_out, big_w_out):   # pragma: no cover - compiled
    """w and W = ∫_0 w of the mode w' = λ w + σ(t) (σ piecewise constant: ``signs`` from each of ``jumps``, 0
    before the first) at the sorted ``queries``: exactly, segment by segment (w = -σ/λ + (w0 + σ/λ) e^{λΔ});
    λ = 0: the integral of σ and its integral."""
    w, big, t, sigma, k = 0j, 0j, 0.0, 0.0, 0
    for q in range(queries.size):
        target = queries[q]
        while True:
            nxt = jumps[k] if k < jumps.size else np.inf
            stop = min(nxt, target)
            d = stop - t
            if d > 0.0:
                if lam == 0:
                    big += w * d + 0.5 * sigma * d * d
                    w += sigma * d
                else:
                    e = np.exp(lam * d)
                    a = w + sigma / lam
                    big += -sigma / lam * d + a * (e - 1.0) / lam
                    w = -sigma / lam + a * e
                t = stop
            if nxt <= target:
                sigma = signs[k]
                k += 1
            else:
                break
        w_out[q] = w
        big_w_out[q] = big


@lru_cache(maxsize=256)
def stage_motion(amplitude_m: float, frequency_Hz: float, harmonics: tuple, points_per_cycle: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(y [m], dy/dτ [m/s]) of the drive at τ = (j + c_i) h, j = 0 .. points - 1, i the Radau stages, and (column 3) at
    τ = j h (h = 1/(f points)): the same every cycle, computed once per drive."""
    drive = SineDrive(amplitude_m, frequency_Hz, 0.0, 1, harmonics)
    u = 2.0 * math.pi * (np.arange(points_per_cycle)[:, None] + np.append(RADAU_C, 0.0)[None, :]) / points_per_cycle
    y = amplitude_m * np.sin(u)
    for k, a_k, theta in harmonics:
        y = y + a_k * (np.sin(k * u + theta) - math.sin(theta))
    return y, 2.0 * math.pi * frequency_Hz * drive.phase_velocity(u)


def grid_parameters(amplitude_m: float, frequency_Hz: float, hyd: Hydraulics, points_per_cycle: int) -> np.ndarray:
    """The kernel's parameter vector of a drive and its hydraulics (:func:`_integrate`)."""
    gas = hyd.gas_law
    g1, g2 = gas_amounts(hyd.air_compressibility_1_Pa, hyd.charge_pressure_Pa, hyd.chamber_volume_1_m3,
                         hyd.chamber_volume_2_m3) if gas else (0.0, 0.0)
    p0 = hyd.charge_pressure_Pa if gas else 0.0
    omega = 2.0 * math.pi * frequency_Hz
    c1n = hyd.c1(-1.0)
    scale = max(abs(hyd.c2(1.0)), abs(hyd.c2(-1.0))) * (hyd.piston_area_m2 * amplitude_m * omega) ** 2 \
        + max(hyd.laminar_coefficient, c1n) * hyd.piston_area_m2 * amplitude_m * omega
    return np.array([amplitude_m, omega, 1.0 / (frequency_Hz * points_per_cycle), hyd.piston_area_m2,
                     hyd.compressibility_1_Pa, hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3,
                     hyd.laminar_coefficient, c1n, hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg,
                     hyd.leakage_conductance_m3_s_Pa, 1.0 if gas else 0.0, hyd.tau_compressibility_1_Pa, g1, g2, p0,
                     PRESSURE_FLOOR * p0, max(scale, 1.0)])


def grid_response(amplitude_m: float, frequency_Hz: float, harmonics, hyd: Hydraulics, end_s: float,
                  points_per_cycle: int = POINTS_PER_CYCLE) -> GridResponse:
    """The Δp of the damper driven from rest by the periodic motion (module docstring) on the grid of
    ``points_per_cycle`` points a cycle, up to ``end_s`` (or the cycle that repeats the one before)."""
    par = grid_parameters(amplitude_m, frequency_Hz, hyd, points_per_cycle)
    n_steps = max(int(math.ceil(end_s / par[2])) + 1, 2)
    out_p, out_f = np.empty(n_steps + 1), np.empty(n_steps + 1)
    ks, aks, ths = _drive_terms(harmonics)
    stage_y, stage_v = stage_motion(amplitude_m, frequency_Hz, tuple(harmonics), points_per_cycle)
    # the parameters as a tuple: the kernel keeps them in registers
    periodic = _integrate(tuple(float(x) for x in par), ks, aks, ths, RADAU_A, RADAU_C, n_steps, points_per_cycle,
                          SUBSTEPS, FIRST_SUBSTEP, CONVERGED, NEWTON_ITERATIONS, NEWTON_TOL, stage_y, stage_v, out_p,
                          out_f)
    last = n_steps + 1 if periodic < 0 else periodic + points_per_cycle + 1
    return GridResponse(float(par[2]), points_per_cycle, out_p[:last], out_f[:last], int(periodic))
