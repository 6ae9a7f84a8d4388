"""Hydraulics of the single-state damper model and its segment solution by quadrature.

Implements the model of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.); equation numbers are the paper's.

Model (noise free)
    Single state Δp = p1 - p2 (Eq. 1/2): β_eff 𝒱(y) dΔp/dt + Q_N(Δp) = A_p dy/dt, with the chamber
    volumes V1 = V0,1 - A_p y, V2 = V0,2 + A_p y following the *piston* position y (Eq. 2), β_eff
    from Eq. (3) with entrained air, and Q_N the orifice of Eq. (7) (laminar c1, turbulent c2 with the
    asymmetric C_D(1 ± a) chosen by the sign of Δp, and both scaled by 1 + b for Δp < 0 with a one-sided
    flow-path resistance b) in parallel with a laminar leakage Q_L = g Δp.
    y = 0 is the position where the chamber volumes are V0,1 and V0,2 (the centre of the stroke).

Segment solution: quadrature, not a time stepper
    Within a segment of constant piston velocity W (W = 0 while a backlash gap is crossed) Eq. (13)
    separates: dΔp/dτ = A_p W - Q_N(Δp) with τ(t) = ∫ dt / (β_eff 𝒱(y(t))) in closed form
    (Eq. 14, written with log1p; Δt / (β_eff 𝒱) when W = 0: :func:`compressibility_time`). The
    autonomous problem is integrated once per segment in the *orifice flow* q (Δp = c1 q + c2 q|q| is
    polynomial in q, whereas q(Δp) has a square-root branch point at Δp = -c1²/4c2 right next to 0)
    with the log variable u = ln|q* - q| (q* the steady root), which turns the logarithmic
    singularity of τ at q* into a smooth, asymptotically linear integrand. Gauss-Legendre panels give
    τ at nodes in u (nodes graded towards q = 0, where c2 switches and the flow regime changes within
    |q| ~ c1/2c2), and Δp(τ) is evaluated for all samples at once by quintic Hermite interpolation
    with the exact derivatives dΔp/dτ = A_p W - Q_N and d²Δp/dτ² (:class:`Relaxation`). Beyond the
    last node (|q - q*| < 1e-17 of the scale) Δp = Δp* exactly. Max error ~4e-11 of the force scale
    against a DOP853 rtol 1e-13 solution (benchmark/virtual_rig_throughput.py).

Batches
    The tables of many segments are built in one vectorised pass, node generation included
    (:func:`relaxation_batch`, :func:`relaxations`), and a :class:`RelaxationBatch` evaluates samples
    of many tables at once. Each table is, bit for bit, the one its problem has alone: the per-problem
    scalars use the same (``math``) functions and ``np.linspace``'s arithmetic, the τ of a table is
    summed within that table only, and every other step is elementwise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from isokinetic.physics.damper import (
    AIR_COMPRESSIBILITY_1_PA,
    NOMINAL,
    Damper,
    Effects,
    effective_compressibility,
    laminar_coefficient,
    turbulent_coefficient,
)
from isokinetic.physics.gas_law import compressibility_ratio, hermite


@dataclass(frozen=True)
class Hydraulics:
    """Coefficients of the single-state model, Eq. (1)-(3), (7) plus leakage, SI.

    ``turbulent_coefficient_pos``/``_neg`` are c2 for Δp > 0 / Δp < 0 (asymmetric C_D);
    ``laminar_coefficient_neg`` is c1 for Δp < 0 (None: ``laminar_coefficient``, the same both ways;
    a one-sided flow path). c1 = 0 (pure turbulent) or c2 = 0 (pure laminar) are allowed, not both.
    ``charge_pressure_Pa`` set: the part ``air_compressibility_1_Pa`` of ``compressibility_1_Pa`` (the gas
    term of Eq. 3 at rest) follows the gas law around it (:meth:`compressibility_ratio`, :mod:`.gas_law`).
    """

    piston_area_m2: float
    chamber_volume_1_m3: float
    chamber_volume_2_m3: float
    compressibility_1_Pa: float
    laminar_coefficient: float
    turbulent_coefficient_pos: float
    turbulent_coefficient_neg: float
    leakage_conductance_m3_s_Pa: float = 0.0
    laminar_coefficient_neg: float | None = None
    air_compressibility_1_Pa: float = 0.0
    charge_pressure_Pa: float | None = None

    def __post_init__(self):
        if self.laminar_coefficient_neg == self.laminar_coefficient:
            object.__setattr__(self, "laminar_coefficient_neg", None)   # one form of the symmetric path
        c1_neg = self.c1(-1.0)
        if min(self.laminar_coefficient, c1_neg, self.turbulent_coefficient_pos, self.turbulent_coefficient_neg) < 0:
            raise ValueError("hydraulics: c1 and c2 must be >= 0")
        if ((self.laminar_coefficient == 0 and self.turbulent_coefficient_pos == 0)
                or (c1_neg == 0 and self.turbulent_coefficient_neg == 0)):
            raise ValueError("hydraulics: c1 = 0 needs c2 > 0 in that direction")
        if self.leakage_conductance_m3_s_Pa < 0:
            raise ValueError("hydraulics: leakage conductance must be >= 0")
        if not 0.0 <= self.air_compressibility_1_Pa < self.compressibility_1_Pa:
            raise ValueError("hydraulics: the air's compressibility must lie in [0, compressibility_1_Pa)")
        if self.charge_pressure_Pa is not None and not self.charge_pressure_Pa > 0:
            raise ValueError("hydraulics: the charge pressure must be > 0")

    @classmethod
    def from_damper(cls, damper: Damper, effects: Effects = NOMINAL) -> Hydraulics:
        """The truth coefficients: Table 1 data with the effects (Eq. 3, 7, leakage, asymmetry); air follows the
        gas law where the damper declares its charge pressure."""
        gas_law = damper.charge_pressure_Pa is not None and effects.air_volume_fraction > 0
        return cls(piston_area_m2=damper.piston_area_m2,
                   chamber_volume_1_m3=damper.chamber_volume_1_m3,
                   chamber_volume_2_m3=damper.chamber_volume_2_m3,
                   compressibility_1_Pa=float(effective_compressibility(damper, effects)),
                   laminar_coefficient=float(laminar_coefficient(damper, effects)),
                   turbulent_coefficient_pos=float(turbulent_coefficient(damper, effects, +1.0)),
                   turbulent_coefficient_neg=float(turbulent_coefficient(damper, effects, -1.0)),
                   leakage_conductance_m3_s_Pa=effects.leakage_conductance_m3_s_Pa,
                   laminar_coefficient_neg=float(laminar_coefficient(damper, effects, -1.0)),
                   air_compressibility_1_Pa=effects.air_volume_fraction * AIR_COMPRESSIBILITY_1_PA if gas_law else 0.0,
                   charge_pressure_Pa=damper.charge_pressure_Pa if gas_law else None)

    @property
    def gas_law(self) -> bool:
        """Whether the compressibility depends on Δp (air under the gas law)."""
        return self.charge_pressure_Pa is not None and self.air_compressibility_1_Pa > 0.0

    @property
    def tau_compressibility_1_Pa(self) -> float:
        """The β of Eq. (14)'s τ: β_eff, or the oil's β with the gas law (and :attr:`gas_volumes_m3`)."""
        return self.compressibility_1_Pa - self.air_compressibility_1_Pa if self.gas_law else self.compressibility_1_Pa

    @property
    def gas_volumes_m3(self) -> tuple[float, float]:
        """With the gas law, V0,i φ0 (1/(β_oil p0) - 1), φ0 = γ p0: chamber i at rest has the compliance
        β_oil (V_i(y) + this), its gas fixed as the piston moves (:mod:`.gas_law`). (0, 0) without."""
        if not self.gas_law:
            return 0.0, 0.0
        oil, phi0 = self.tau_compressibility_1_Pa, self.air_compressibility_1_Pa * self.charge_pressure_Pa
        k = phi0 * (1.0 / (oil * self.charge_pressure_Pa) - 1.0)
        return self.chamber_volume_1_m3 * k, self.chamber_volume_2_m3 * k

    def rest_compliance(self, y_m):
        """𝒞(Δp = 0) at piston position y [m³/Pa]: β_eff 𝒱(y), Eq. (2)-(3), with the gas law's gas volumes."""
        v1, v2 = tau_volumes(*start_volumes(y_m, self), self)
        return self.tau_compressibility_1_Pa * v1 * v2 / (v1 + v2)

    def compressibility_ratio(self, dp_Pa, y_m=0.0, stored_m3=0.0) -> tuple[np.ndarray, np.ndarray]:
        """(r, dr/dΔp): 𝒞(Δp, y, K) = :meth:`rest_compliance` (y) r(Δp, y, K) with the gas law, K the stored
        volume (:func:`isokinetic.physics.gas_law.compressibility_ratio`); r = 1 without."""
        if not self.gas_law:
            shape = np.broadcast(np.asarray(dp_Pa), np.asarray(y_m), np.asarray(stored_m3)).shape
            return np.ones(shape), np.zeros(shape)
        return compressibility_ratio(dp_Pa, self.tau_compressibility_1_Pa, self.air_compressibility_1_Pa,
                                     self.charge_pressure_Pa, self.chamber_volume_1_m3, self.chamber_volume_2_m3,
                                     y_m, self.piston_area_m2, stored_m3)

    def c1(self, sign):
        """c1 [Pa s/m³] of the flow direction ``sign`` (>= 0: positive side); a float for a scalar sign."""
        neg = self.laminar_coefficient if self.laminar_coefficient_neg is None else self.laminar_coefficient_neg
        if isinstance(sign, (float, int)):
            return self.laminar_coefficient if sign >= 0 else neg
        return np.where(np.asarray(sign) >= 0, self.laminar_coefficient, neg)

    def c2(self, sign):
        """c2 [Pa s²/m⁶] of the flow direction ``sign`` (>= 0: positive side); a float for a scalar sign."""
        if isinstance(sign, (float, int)):
            return self.turbulent_coefficient_pos if sign >= 0 else self.turbulent_coefficient_neg
        return np.where(np.asarray(sign) >= 0, self.turbulent_coefficient_pos, self.turbulent_coefficient_neg)

    def flow(self, dp_Pa: float) -> float:
        """Scalar Q_N(Δp): orifice Eq. (7) plus leakage, for ODE right-hand sides [m³/s]."""
        a = abs(dp_Pa)
        if a == 0.0:
            return 0.0
        pos = dp_Pa >= 0
        c1 = self.laminar_coefficient if pos or self.laminar_coefficient_neg is None else self.laminar_coefficient_neg
        c2 = self.turbulent_coefficient_pos if pos else self.turbulent_coefficient_neg
        orifice = math.copysign(2.0 * a / (c1 + math.sqrt(c1 * c1 + 4.0 * c2 * a)), dp_Pa)
        return orifice + self.leakage_conductance_m3_s_Pa * dp_Pa

    def flow_derivative(self, dp_Pa: float) -> float:
        """Scalar dQ_N/dΔp = 1/sqrt(c1² + 4 c2|Δp|) + g, for ODE Jacobians [m³/(s Pa)]."""
        pos = dp_Pa >= 0
        c1 = self.laminar_coefficient if pos or self.laminar_coefficient_neg is None else self.laminar_coefficient_neg
        root = math.sqrt(c1**2 + 4.0 * (self.turbulent_coefficient_pos if pos else self.turbulent_coefficient_neg)
                         * abs(dp_Pa))
        return (1.0 / root if root > 0 else 1e300) + self.leakage_conductance_m3_s_Pa

    def composite_volume(self, y_m):
        """𝒱 = V1 V2 / (V1 + V2) at piston position y, Eq. (2) [m³]."""
        a, v01, v02 = self.piston_area_m2, self.chamber_volume_1_m3, self.chamber_volume_2_m3
        return (v01 - a * y_m) * (v02 + a * y_m) / (v01 + v02)


def orifice_pressure_of_flow(q_m3_s, hyd: Hydraulics):
    """Δp = c1± q + c2± q|q| for orifice flow q, Eq. (7) [Pa]."""
    q = np.asarray(q_m3_s, dtype=float)
    c1 = hyd.laminar_coefficient if hyd.laminar_coefficient_neg is None else hyd.c1(q)
    return c1 * q + hyd.c2(q) * q * np.abs(q)


def orifice_flow_of_pressure(dp_Pa, hyd: Hydraulics):
    """Orifice flow q(Δp), Eq. (7) with the direction's c2, cancellation free [m³/s]."""
    dp = np.asarray(dp_Pa, dtype=float)
    a = np.abs(dp)
    c1 = hyd.laminar_coefficient if hyd.laminar_coefficient_neg is None else hyd.c1(dp)
    c2 = hyd.c2(dp)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(a > 0, 2.0 * a / (c1 + np.sqrt(c1 * c1 + 4.0 * c2 * a)), 0.0)
    return np.sign(dp) * q


def total_flow(dp_Pa, hyd: Hydraulics):
    """Q_N(Δp) = orifice (Eq. 7) + leakage g Δp [m³/s]."""
    dp = np.asarray(dp_Pa, dtype=float)
    return orifice_flow_of_pressure(dp, hyd) + hyd.leakage_conductance_m3_s_Pa * dp


def steady_orifice_flow(piston_flow_m3_s: float, hyd: Hydraulics) -> float:
    """Orifice flow q* of the incompressible steady state, q + g Δp(q) = A_p W (Eq. 2, 24) [m³/s]."""
    qp = float(piston_flow_m3_s)
    if qp == 0.0:
        return 0.0
    g, c1, c2 = hyd.leakage_conductance_m3_s_Pa, hyd.c1(qp), float(hyd.c2(qp))
    b = 1.0 + g * c1
    return math.copysign(2.0 * abs(qp) / (b + math.sqrt(b * b + 4.0 * g * c2 * abs(qp))), qp)


def steady_pressure(piston_flow_m3_s: float, hyd: Hydraulics) -> float:
    """Incompressible steady Δp for piston flow A_p W: Eq. (24) with leakage and asymmetry [Pa]."""
    return float(orifice_pressure_of_flow(steady_orifice_flow(piston_flow_m3_s, hyd), hyd))


def compressibility_time(dt_s, y_start_m: float, velocity_m_s: float, hyd: Hydraulics):
    """τ = ∫ dt / (β_eff 𝒱(y)) over a constant-velocity segment, Eq. (14) [Pa/(m³/s)].

    ln(V2/V2,s) - ln(V1/V1,s) divided by β A_p W, written with log1p (exact as W -> 0);
    Δt / (β 𝒱(y_s)) when W = 0.
    """
    dt = np.asarray(dt_s, dtype=float)
    a, beta = hyd.piston_area_m2, hyd.tau_compressibility_1_Pa
    v1, v2 = tau_volumes(*start_volumes(y_start_m, hyd), hyd)
    if velocity_m_s == 0.0:
        return dt * (1.0 / v1 + 1.0 / v2) / beta
    qp = a * velocity_m_s
    return (np.log1p(qp * dt / v2) - np.log1p(-qp * dt / v1)) / (beta * qp)


# --------------------------------------------------------------------------------------------
# Segment tables Δp(τ), Eq. (13)-(14)
# --------------------------------------------------------------------------------------------

#: Default panel width in u (see :func:`relaxations`): max error ~4e-11 of the pressure scale.
DEFAULT_STEP = 0.03

#: Gauss-Legendre rule used on every panel in u.
_GL_X, _GL_W = np.polynomial.legendre.leggauss(3)


def _panel_coefficients(h, y0, y1, d0, d1, dd0, dd1) -> np.ndarray:
    """Quintic Hermite polynomial on each panel in s ∈ [0, 1] (ascending powers: row j is the
    coefficient of s^j of every panel, shape (6, n)).

    Values y, first derivatives d and second derivatives dd (in τ) at both ends, panel width h;
    cubic Hermite where a second derivative is not finite.
    """
    m0, m1 = h * d0, h * d1
    hh = h * h
    if np.isfinite(hh).all() and np.isfinite(dd0).all() and np.isfinite(dd1).all():
        a0, a1 = hh * dd0, hh * dd1                 # finite times finite: never invalid
    else:
        with np.errstate(invalid="ignore"):
            a0, a1 = hh * dd0, hh * dd1
    quintic = np.isfinite(a0) & np.isfinite(a1)
    cubic = ~quintic
    if cubic.any():
        a0, a1 = np.where(quintic, a0, 0.0), np.where(quintic, a1, 0.0)
    dy = y1 - y0
    coef = np.empty((6, h.size))
    coef[0], coef[1], coef[2] = y0, m0, 0.5 * a0
    coef[3] = 10 * dy - 6 * m0 - 4 * m1 - 1.5 * a0 + 0.5 * a1
    coef[4] = -15 * dy + 8 * m0 + 7 * m1 + 1.5 * a0 - a1
    coef[5] = 6 * dy - 3 * m0 - 3 * m1 - 0.5 * a0 + 0.5 * a1
    if cubic.any():
        coef[2, cubic] = 3 * dy[cubic] - 2 * m0[cubic] - m1[cubic]
        coef[3, cubic] = -2 * dy[cubic] + m0[cubic] + m1[cubic]
        coef[4:, cubic] = 0.0
    return coef


@dataclass(frozen=True)
class Relaxation:
    """Δp(τ) of one constant-velocity segment: dΔp/dτ = A_p W - Q_N(Δp), Eq. (13).

    Tabulated at nodes τ_i (from nodes in u = ln|q* - q|, q the orifice flow); between nodes
    δ = Δp - Δp* is the quintic Hermite interpolant of the exact values, first and second
    derivatives in τ (cubic on a panel touching a node where the second derivative is infinite:
    q = 0 with c1 = 0), stored as polynomial coefficients in s = (τ - τ_i)/(τ_{i+1} - τ_i).
    Build with :func:`relaxation`.
    """

    tau: np.ndarray           # node τ, ascending, tau[0] = 0 [Pa s/m³]
    coef: np.ndarray          # (nodes - 1, 6): δ on each panel, ascending powers of s [Pa]
    steady_Pa: float          # Δp*

    @classmethod
    def from_nodes(cls, tau, delta, slope, curvature, steady_Pa: float) -> Relaxation:
        """The table of panel polynomials from node values δ, dδ/dτ and d²δ/dτ² (inf: unknown)."""
        tau = np.asarray(tau, dtype=float)
        coef = _panel_coefficients(np.diff(tau), delta[:-1], delta[1:], slope[:-1], slope[1:],
                                   curvature[:-1], curvature[1:]).T
        return cls(tau, coef, float(steady_Pa))

    @classmethod
    def constant(cls, dp_Pa: float) -> Relaxation:
        """A table whose Δp stays at its start value [Pa] (the start is already the steady state)."""
        return cls(np.zeros(1), np.zeros((0, 6)), float(dp_Pa))

    def pressure(self, tau) -> np.ndarray:
        """Δp [Pa] at compressibility times ``tau`` [Pa s/m³] (>= 0, **ascending**, Eq. 14); Δp* beyond the table."""
        tau = np.asarray(tau, dtype=float)
        out = np.full(tau.shape, self.steady_Pa)
        x = self.tau
        if x.size < 2:
            return out
        n_live = int(np.searchsorted(tau, x[-1], side="left"))
        t = tau[:n_live]
        i = np.searchsorted(x, t, side="right") - 1
        np.clip(i, 0, x.size - 2, out=i)
        s = (t - x[i]) / (x[i + 1] - x[i])
        c = self.coef[i]
        out[:n_live] += ((((c[:, 5] * s + c[:, 4]) * s + c[:, 3]) * s + c[:, 2]) * s + c[:, 1]) * s + c[:, 0]
        return out


def _linspaces(start: np.ndarray, stop: np.ndarray, num: np.ndarray) -> np.ndarray:
    """``np.linspace(start[k], stop[k], num[k])`` of every k, concatenated, with its arithmetic exactly.

    y_i = i·step + start with step = (stop - start)/(num - 1) (i·(stop - start)/(num - 1) where that
    step underflows to 0; a single point is 0·(stop - start) + start), the last point set to stop.
    """
    ends = num.cumsum()
    per = np.arange(num.size).repeat(num)
    i = (np.arange(per.size) - (ends - num).take(per)).astype(float)
    div = num - 1
    delta = stop - start
    step = np.divide(delta, div, out=delta.copy(), where=div > 0)   # one point: 0·delta + start
    y = i * step.take(per)
    tiny = (div > 0) & (step == 0.0)
    if tiny.any():                                         # linspace's denormal branch, gh-5437
        t = tiny[per]
        y[t] = i[t] / div[per[t]] * delta[per[t]]
    y += start.take(per)
    last = num > 1
    y[ends[last] - 1] = stop[last]
    return y


def _math(fun, x: np.ndarray) -> np.ndarray:
    """``fun`` (a scalar ``math`` function) of every element: the old scalar code's exact values."""
    return np.array(list(map(fun, x.tolist())), dtype=float)


def _problems(dp0: np.ndarray, qp: np.ndarray, hyd: Hydraulics):
    """The scalars of every segment problem, vectorised: (q*, s, Δp*, q0, dist), q0 the start's orifice flow.

    dist = |q* - q0|; a problem with dist 0 (or not finite) starts at its steady state.
    """
    g = hyd.leakage_conductance_m3_s_Pa
    one_c1 = hyd.laminar_coefficient_neg is None    # the same c1 both ways: the scalar (the old arithmetic)

    def c1(x):                                      # c1 and c2 of the flow direction of x, Eq. (7)
        return hyd.laminar_coefficient if one_c1 else np.where(x >= 0, hyd.laminar_coefficient,
                                                                hyd.laminar_coefficient_neg)

    def c2(x):
        return np.where(x >= 0, hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)

    aqp = np.abs(qp)
    c1_q = c1(qp)
    b = 1.0 + g * c1_q                              # steady_orifice_flow, element by element
    q_star = np.copysign(2.0 * aqp / (b + np.sqrt(b * b + 4.0 * g * c2(qp) * aqp)), qp)
    q_star[qp == 0.0] = 0.0
    c1_q = c1(q_star)
    p_star = c1_q * q_star + c2(q_star) * q_star * np.abs(q_star)   # Eq. (7)
    a = np.abs(dp0)                                 # orifice_flow_of_pressure, element by element
    c1_q = c1(dp0)
    q0 = np.divide(2.0 * a, c1_q + np.sqrt(c1_q * c1_q + 4.0 * c2(dp0) * a), out=np.zeros(a.size), where=a > 0)
    q0 *= np.sign(dp0)
    dist = np.abs(q_star - q0)
    return q_star, np.copysign(1.0, q_star - q0), p_star, q0, dist


def _node_sets(q_star: np.ndarray, q0: np.ndarray, dist: np.ndarray, hyd: Hydraulics, step: float):
    """Descending nodes in u of every problem, concatenated, and their counts (see :func:`relaxations`).

    u0 = ln|q* - q0| down to u_end = ln(1e-17 max(|q*|, |q* - q0|)), around u_ref = ln(scale): a
    uniform crossing piece of width ``step`` above u_ref, widths growing as e^{(u_ref - u)/4} below it
    up to a widest panel of 0.5, and a graded cluster (ratio 0.8) around q = 0 (start from rest, or
    the sign change where c2 switches). All problems at once; per-problem transcendental scalars with
    ``math`` and the ``np.linspace`` arithmetic (:func:`_linspaces`), so that each problem's nodes
    are those it has alone.
    """
    c1 = min(hyd.laminar_coefficient, hyd.c1(-1.0))     # the narrower transition of the two directions
    c2_max = max(hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)
    n = q_star.size
    aqs = np.abs(q_star)
    big = np.maximum(aqs, dist)
    cross = q0 * q_star < 0.0                              # q = 0 is crossed (else: start from rest)
    # the laminar-turbulent transition width c1/(2 c2 |q*|) (infinite for q* = 0 or c2 = 0)
    width = np.divide(c1, 2.0 * c2_max * aqs, out=np.full(n, math.inf), where=(aqs != 0) & (c2_max > 0))
    graded_min = np.maximum(1e-12, 1e-2 * width)
    graded = ((q0 == 0.0) | cross) & (graded_min < 10.0 * step)
    n_cross, n_graded = int(np.count_nonzero(cross)), int(np.count_nonzero(graded))
    logs = _math(math.log, np.concatenate([dist, big * 1e-17, np.where(q_star * q0 >= 0, big, aqs), aqs[cross],
                                           graded_min[graded] / (10.0 * step)]))
    u0, u_end, u_ref = logs[:n], logs[n:2 * n], logs[2 * n:3 * n]
    centre = u0.copy()                                     # q = 0: the start (from rest) or the crossing
    centre[cross] = logs[3 * n:3 * n + n_cross]
    # A: uniform crossing piece above the scale
    n_a = np.ceil((u0 - u_ref) / step) + 1
    n_a[u0 <= u_ref] = 0
    # B: interpolation error ∝ h^6 |δ(u)| (quintic) with |δ| ∝ e^u: widths h = step·e^{(u_ref - u)/4}
    # (conservative), i.e. uniform in ζ = e^{(u - u_ref)/4}, up to a widest panel of 0.5 (reached
    # where |δ| < 2e-7 of the scale); C: panels of 0.5 below that
    top = np.minimum(u0, u_ref)
    u_cap = np.maximum(u_end, u_ref + 4.0 * math.log(step / 0.5))
    zeta = _math(math.exp, np.concatenate([(top - u_ref) / 4.0, (u_cap - u_ref) / 4.0]))
    zeta_top, zeta_lo = zeta[:n], zeta[n:]
    n_b = np.ceil((zeta_top - zeta_lo) / (step / 4.0)) + 1
    n_b[top <= u_cap] = 0
    lo_top = np.minimum(top, u_cap)
    n_c = np.maximum(2, np.ceil((lo_top - u_end) / 0.5) + 1)
    num = np.concatenate([n_a, n_b, n_c]).astype(np.int64)
    lin = _linspaces(np.concatenate([u_ref, zeta_lo, u_end]), np.concatenate([u0, zeta_top, lo_top]), num)
    a, b = int(_sum(num[:n])), int(_sum(num[:2 * n]))
    lin[a:b] = u_ref.repeat(num[n:2 * n]) + 4.0 * np.log(lin[a:b])
    # the graded cluster c ∓ 10·step·0.8^k, c, around q = 0
    n_off = np.zeros(n, dtype=np.int64)
    n_off[graded] = np.ceil(logs[3 * n + n_cross:] / math.log(0.8)).astype(np.int64) + 1
    k = _ranks(n_off)
    off = (10.0 * step * 0.8 ** np.arange(0, int(n_off.max())))[k] if n_graded else np.zeros(0)
    c = centre.repeat(n_off)
    # every candidate in one row per problem (pieces A | B | C | c - off | c + off | c | u0), sorted
    counts = np.concatenate([num.reshape(3, n), [n_off, n_off, graded, np.ones(n, dtype=np.int64)]])
    cols = _sum(counts, axis=0)
    width = int(cols.max())
    start = counts.cumsum(axis=0) - counts + np.arange(n) * width
    counts = counts.reshape(-1)
    at = (start.reshape(-1) - counts.cumsum() + counts).repeat(counts) + np.arange(int(_sum(cols)))
    grid = np.full((n, width), -np.inf)
    grid.reshape(-1)[at] = np.concatenate([lin, c - off, c + off, centre[graded], u0])
    grid[(grid < u_end[:, None]) | (grid > u0[:, None])] = -np.inf
    grid.sort(axis=1)
    grid = grid[:, ::-1]                                   # descending; u0 (the largest) first
    keep = grid > -np.inf
    keep[:, 1:] &= grid[:, 1:] != grid[:, :-1]             # distinct values, as np.unique
    return grid[keep], _sum(keep, axis=1)


def _ranks(counts: np.ndarray) -> np.ndarray:
    """0..counts[k]-1 for every k, concatenated."""
    return np.arange(int(_sum(counts))) - (counts.cumsum() - counts).repeat(counts)


def _sum(x: np.ndarray, axis: int | None = None):
    """Sum of an array, booleans counted (the ufunc reduction, without ndarray.sum's Python wrapper)."""
    return np.add.reduce(x, axis=axis, dtype=np.int64 if x.dtype == bool else None)


def _integrand(uu: np.ndarray, n: int, pp: np.ndarray, q_star: np.ndarray, s: np.ndarray, qp: np.ndarray,
               p_star: np.ndarray, hyd: Hydraulics, y0: np.ndarray | None = None, k0: np.ndarray | None = None,
               panel_nodes: np.ndarray | None = None):
    """dτ/du at points u of their problems (``pp``: the problem of each point; q*, s, A_p W, Δp* per problem), and
    at the first ``n`` points (the nodes) also dΔp/dτ, δ = Δp - Δp* and dΔp/dq; with the gas law also r and
    dr/dΔp at the nodes (else None), r at the problem's start position ``y0`` and stored volume ``k0``
    (``panel_nodes``: the first node of each Gauss point's panel).

    On the side of q*: A_pW - Q_N = (q* - q)(1 + g c1 + g c2 (|q*| + |q|)), exactly; across q = 0
    from the other side the direct form.
    """
    g = hyd.leakage_conductance_m3_s_Pa
    q_star, s = q_star.take(pp), s.take(pp)
    e = np.exp(uu)
    q = s * e
    np.subtract(q_star, q, out=q)                   # q = q* - s e^u
    aq = np.abs(q)
    side = q >= 0
    c2 = np.where(side, hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)
    # c1 of q's side; on the side of q* (the factored forms below) it is also q*'s
    c1 = hyd.laminar_coefficient if hyd.laminar_coefficient_neg is None else \
        np.where(side, hyd.laminar_coefficient, hyd.laminar_coefficient_neg)
    dpdq = 2.0 * c2
    dpdq *= aq
    dpdq += c1                                      # dΔp/dq = c1 + 2 c2 |q|, Eq. (7)
    same = q * q_star > 0.0
    at_rest = q_star == 0.0
    if at_rest.any():
        same |= at_rest & (q != 0.0)
    both = np.abs(q_star)
    both += aq
    k_same = g * c2
    k_same *= both
    k_same += 1.0 + g * c1                          # 1 + g c1 + g c2 (|q*| + |q|)
    dtau = dpdq / k_same                            # dτ/du magnitude (τ grows as u falls)
    f = s[:n] * e[:n]
    f *= k_same[:n]                                 # dΔp/dτ = A_p W - Q_N
    delta = -s[:n]
    delta *= e[:n]
    both = both[:n] * c2[:n]
    both += c1 if np.isscalar(c1) else c1[:n]
    delta *= both                                   # Δp - Δp* = -s e^u (c1 + c2 (|q| + |q*|))
    if not same.all():
        o = (~same).nonzero()[0]
        qo = q[o]
        c1o = c1 if np.isscalar(c1) else c1[o]
        po = c1o * qo + c2[o] * qo * aq[o]          # Δp(q), Eq. (7)
        fo = qp.take(pp.take(o)) - qo - g * po
        dtau[o] = dpdq[o] * e[o] / np.abs(fo)
        o_nodes = o[:int(o.searchsorted(n))]
        f[o_nodes] = fo[:o_nodes.size]
        delta[o_nodes] = po[:o_nodes.size] - p_star.take(pp.take(o_nodes))
    if not hyd.gas_law:
        return dtau, f, delta, dpdq[:n], None
    # the gas law: 𝒞(0, y) r(Δp) dΔp/dt = A_p W - Q_N, so dτ/du and dΔp/dτ carry r; r at the nodes, at the
    # Gauss points the cubic Hermite interpolant in Δp between their panel's nodes (``panel_nodes``)
    dp = c1 * q + c2 * q * aq
    nodes = pp[:n]
    ratio, slope = hyd.compressibility_ratio(dp[:n], 0.0 if y0 is None else y0.take(nodes),
                                             0.0 if k0 is None else k0.take(nodes))
    f /= ratio
    dtau[:n] *= ratio
    dtau[n:] *= hermite(dp[n:], dp.take(panel_nodes), dp.take(panel_nodes + 1), ratio.take(panel_nodes),
                         ratio.take(panel_nodes + 1), slope.take(panel_nodes), slope.take(panel_nodes + 1))
    return dtau, f, delta, dpdq[:n], (ratio, slope)


def _node_tau(panel_integrals: np.ndarray, hi: np.ndarray, sizes: np.ndarray, first: np.ndarray,
              prob: np.ndarray) -> np.ndarray:
    """τ at the nodes: cumulative panel integrals summed within each problem alone (one row each).

    A running sum over the whole batch, less its value at the problem's first node, would carry the
    rounding of the earlier problems' τ (often far larger) into this one's.
    """
    width = int(sizes.max())
    at = np.arange(prob.size) + (np.arange(sizes.size) * width - first).repeat(sizes)   # (problem, node) cell
    rows = np.zeros(sizes.size * width)
    rows[at.take(hi + 1)] = panel_integrals
    return rows.reshape(sizes.size, width).cumsum(axis=1).reshape(-1).take(at)


@dataclass(frozen=True)
class RelaxationBatch:
    """The segment tables Δp(τ) of a batch of problems, concatenated (see :class:`Relaxation`).

    Table k has nodes ``tau[first[k]:first[k] + sizes[k]]`` (ascending from 0) and panels
    ``coef[:, first[k] - k:first[k] - k + sizes[k] - 1]``; a table of one node is a constant Δp =
    ``steady_Pa[k]`` (the problem started at its steady state). Build with :func:`relaxation_batch`.
    """

    tau: np.ndarray           # nodes of all tables [Pa s/m³]
    coef: np.ndarray          # (6, nodes - tables): row j the s^j coefficient of every panel [Pa]
    first: np.ndarray         # index in ``tau`` of each table's first node
    sizes: np.ndarray         # nodes of each table
    steady_Pa: np.ndarray     # Δp* of each table
    end_tau: np.ndarray = field(init=False)   # τ of each table's last node; -inf for a constant

    def __post_init__(self):
        end = self.tau[self.first + self.sizes - 1] if self.sizes.size else np.zeros(0)
        object.__setattr__(self, "end_tau", np.where(self.sizes > 1, end, -np.inf))

    def __len__(self) -> int:
        return self.sizes.size

    def relaxation(self, k: int) -> Relaxation:
        """The table k alone."""
        a, n = int(self.first[k]), int(self.sizes[k])
        if n < 2:
            return Relaxation.constant(float(self.steady_Pa[k]))
        return Relaxation(self.tau[a:a + n], self.coef[:, a - k:a - k + n - 1].T, float(self.steady_Pa[k]))

    @classmethod
    def concatenate(cls, parts: Sequence[RelaxationBatch]) -> RelaxationBatch:
        """The tables of all ``parts``, in order (table k of part p is number sum(len(parts[:p])) + k)."""
        nodes = np.cumsum([0] + [p.tau.size for p in parts[:-1]])
        return cls(np.concatenate([p.tau for p in parts]), np.concatenate([p.coef for p in parts], axis=1),
                   np.concatenate([p.first + n for p, n in zip(parts, nodes.tolist())]),
                   np.concatenate([p.sizes for p in parts]), np.concatenate([p.steady_Pa for p in parts]))

    def pressure(self, table: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Δp [Pa] of table ``table[i]`` at τ ``tau[i]`` for every i, each exactly as :meth:`Relaxation.pressure`.

        For samples of one table in ascending τ (as there), the ones before the table's end are
        interpolated, the others are Δp* (the per-sample test τ < τ_end is the same split).
        """
        table = np.asarray(table, dtype=np.int64)
        tau = np.asarray(tau, dtype=float)
        out = self.steady_Pa.take(table)
        live = (tau < self.end_tau.take(table)).nonzero()[0]
        if live.size:
            k, t = table.take(live), tau.take(live)
            # last node <= t within the sample's own table: a search in (table, τ) order
            keys = _pairs(np.arange(len(self)).repeat(self.sizes), self.tau)
            node = keys.searchsorted(_pairs(k, t), side="right") - 1
            out[live] += self._interpolate(self._clipped_panel(k, node), t)
        return out

    def pressure_runs(self, table: np.ndarray, counts: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """:meth:`pressure` of runs of samples: ``counts[r]`` ascending τ of table ``table[r]``, one run
        after the other, all before their table's end (one sorted search per run)."""
        local = np.empty(tau.size, dtype=np.int64)      # nodes <= τ within the run's table
        first = self.first.take(table)
        nodes, at = self.tau, 0
        for a, b, n in zip(first.tolist(), (first + self.sizes.take(table)).tolist(), counts.tolist()):
            if n:
                local[at:at + n] = nodes[a:b].searchsorted(tau[at:at + n], side="right")
                at += n
        if tau.size and tau.min() < 0.0:
            k = table.repeat(counts)
            panel = self._clipped_panel(k, local + (first - 1).repeat(counts))
        else:   # τ >= 0 = the first node and τ < the table's end: within the panels
            panel = local
            panel += (first - 1 - table).repeat(counts)   # global node - table = panel
        return self.steady_Pa.take(table).repeat(counts) + self._interpolate(panel, tau)

    def _clipped_panel(self, k: np.ndarray, node: np.ndarray) -> np.ndarray:
        """The panel of global node ``node`` of table ``k``, the node kept within the table's panels."""
        first = self.first.take(k)
        return node.clip(first, first + self.sizes.take(k) - 2) - k

    @cached_property
    def _panels(self) -> tuple[np.ndarray, np.ndarray]:
        """(τ at the start, width in τ) of every panel, in the order of ``coef``'s columns."""
        node = np.arange(self.coef.shape[1]) + np.arange(len(self)).repeat(np.maximum(self.sizes - 1, 0))
        x0 = self.tau.take(node)
        return x0, self.tau.take(node + 1) - x0

    def _interpolate(self, panel: np.ndarray, t: np.ndarray) -> np.ndarray:
        """δ = Δp - Δp* at τ ``t`` on panel ``panel`` (its quintic in s = (τ - τ_i)/(τ_{i+1} - τ_i))."""
        x0, width = self._panels
        s = t - x0.take(panel)
        s /= width.take(panel)
        c = self.coef
        out = c[5].take(panel)
        for j in (4, 3, 2, 1):
            out *= s
            out += c[j].take(panel)
        out *= s
        out += c[0].take(panel)
        return out


def _pairs(k: np.ndarray, x: np.ndarray) -> np.ndarray:
    """k + i·x, exactly (complex; sorted by k, then x)."""
    out = np.empty(x.size, dtype=complex)
    out.real = k
    out.imag = x
    return out


def _tables(u: np.ndarray, sizes: np.ndarray, q_star: np.ndarray, s: np.ndarray, qp: np.ndarray,
            p_star: np.ndarray, dp0: np.ndarray, hyd: Hydraulics, y0: np.ndarray | None = None,
            k0: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(τ at the nodes, panel polynomials) of every problem from its nodes u (descending, concatenated)."""
    g = hyd.leakage_conductance_m3_s_Pa
    first = sizes.cumsum() - sizes
    prob = np.arange(sizes.size).repeat(sizes)
    hi = np.arange(u.size - sizes.size) + np.arange(sizes.size).repeat(sizes - 1)   # panel [u[hi + 1], u[hi]]
    u_hi, u_lo = u.take(hi), u.take(hi + 1)
    half = 0.5 * (u_hi - u_lo)
    mid = 0.5 * (u_hi + u_lo)
    n = u.size
    uu = np.empty(n + _GL_X.size * hi.size)
    uu[:n] = u
    pts = uu[n:].reshape(hi.size, _GL_X.size)       # Gauss points of every panel: mid + half x_k
    for k, x in enumerate(_GL_X.tolist()):
        np.multiply(half, x, out=pts[:, k])
        pts[:, k] += mid
    pp = np.concatenate([prob, prob.take(hi).repeat(_GL_X.size)])
    dtau, f, delta, dpdq, gas = _integrand(uu, n, pp, q_star, s, qp, p_star, hyd, y0, k0,
                                           hi.repeat(_GL_X.size) if hyd.gas_law else None)
    tau = _node_tau(half * (dtau[n:].reshape(pts.shape) @ _GL_W), hi, sizes, first, prob)
    # d²Δp/dτ² = f'(q) dq/dτ = -(1 + g dΔp/dq) f / (dΔp/dq); infinite where dΔp/dq = 0
    curv = np.divide(-(1.0 + g * dpdq) * f, dpdq, out=np.full(n, np.inf), where=dpdq > 0)
    if gas is not None:     # f = (A_p W - Q_N)/r: d²Δp/dτ² = (f F' - f² r')/r, F' = -(1 + g dΔp/dq)/(dΔp/dq)
        ratio, slope = gas
        curv -= f * f * slope
        curv /= ratio
    if hyd.laminar_coefficient_neg is not None:     # c1 jumps at q = 0: d²Δp/dτ² is one-sided there (cubic)
        qs = q_star.take(prob)
        q_nodes = qs - s.take(prob) * np.exp(u)
        curv[np.abs(q_nodes) <= 1e-9 * np.abs(qs)] = np.inf
    delta[first] = dp0 - p_star                      # exact start: Δp continuous across segments
    coef = _panel_coefficients(tau.take(hi + 1) - tau.take(hi), delta.take(hi), delta.take(hi + 1), f.take(hi),
                               f.take(hi + 1), curv.take(hi), curv.take(hi + 1))
    return tau, coef


def relaxation_batch(dp0_Pa, piston_flows_m3_s, hyd: Hydraulics, step: float = DEFAULT_STEP,
                     y_start_m=None, stored_m3=None) -> RelaxationBatch:
    """:func:`relaxations` as one :class:`RelaxationBatch` (no per-problem objects): the batched form.
    ``y_start_m``, ``stored_m3``: each problem's piston position and stored volume at its start, where the gas
    law's r(Δp, y, K) is taken (:meth:`Hydraulics.compressibility_ratio`; 0 when None)."""
    dp0 = np.asarray(dp0_Pa, dtype=float).reshape(-1)
    qp = np.asarray(piston_flows_m3_s, dtype=float).reshape(-1)
    if dp0.size != qp.size:
        raise ValueError(f"{dp0.size} start pressures for {qp.size} piston flows")
    y0, k0 = ((None if x is None or not hyd.gas_law else np.broadcast_to(np.asarray(x, dtype=float), dp0.shape))
              for x in (y_start_m, stored_m3))
    q_star, s, p_star, q0, dist = _problems(dp0, qp, hyd)
    moving = (dist != 0.0) & np.isfinite(dist)
    if moving.all():
        u, sizes = _node_sets(q_star, q0, dist, hyd, step)
        tau, coef = _tables(u, sizes, q_star, s, qp, p_star, dp0, hyd, y0, k0)
        return RelaxationBatch(tau, coef, sizes.cumsum() - sizes, sizes, p_star)
    sizes = np.ones(dp0.size, dtype=np.int64)
    steady = np.where(moving, p_star, dp0)
    if not moving.any():
        return RelaxationBatch(np.zeros(dp0.size), np.zeros((6, 0)), np.arange(dp0.size), sizes, steady)
    m = np.flatnonzero(moving)
    u, node_sizes = _node_sets(q_star[m], q0[m], dist[m], hyd, step)
    tau_m, coef = _tables(u, node_sizes, q_star[m], s[m], qp[m], p_star[m], dp0[m], hyd,
                          None if y0 is None else y0[m], None if k0 is None else k0[m])
    sizes[m] = node_sizes
    first = np.cumsum(sizes) - sizes
    tau = np.zeros(int(sizes.sum()))                 # a constant's single node is τ = 0
    tau[np.repeat(first[m], node_sizes) + _ranks(node_sizes)] = tau_m
    return RelaxationBatch(tau, coef, first, sizes, steady)


def relaxations(dp0_Pa: Sequence[float], piston_flows_m3_s: Sequence[float], hyd: Hydraulics,
                step: float = DEFAULT_STEP) -> list[Relaxation]:
    """The tables of many segment solutions, built at once (one vectorised pass), Eq. (13)-(14).

    Problem k starts at Δp(0) = ``dp0_Pa[k]`` under piston flow ``piston_flows_m3_s[k]`` = A_p W.
    τ(u) = ∫ (dΔp/dq) e^u / |A_p W - Q_N| du with u = ln|q* - q|, 3-point Gauss-Legendre per panel.
    Panel widths: ``step`` while |q - q*| exceeds the flow scale, then growing as e^{-u/4} (the
    Hermite error ~ width^6 × |Δp - Δp*| stays at the level of the pressure scale's), at most 0.5;
    graded (ratio 0.8) towards q = 0 (start from rest, or the sign change where c2 switches) down to
    1e-2 of the laminar-turbulent transition width c1/(2 c2 |q*|) (1e-12 for c1 = 0). A table ends
    where |q - q*| = 1e-17 of the scale; beyond it Δp = Δp*. The integrand is evaluated in factored,
    cancellation-free form on the side of q*: A_pW - Q_N = (q* - q)(1 + g c1 + g c2 (|q*| + |q|)).
    Every problem's table is the one it has alone (:func:`relaxation_batch` is the concatenated form).
    """
    dp0, qp = list(dp0_Pa), list(piston_flows_m3_s)
    if len(dp0) != len(qp):
        raise ValueError(f"{len(dp0)} start pressures for {len(qp)} piston flows")
    if not dp0:
        return []
    batch = relaxation_batch(dp0, qp, hyd, step)
    return [batch.relaxation(k) for k in range(len(batch))]


def relaxation(dp0_Pa: float, piston_flow_m3_s: float, hyd: Hydraulics, step: float = DEFAULT_STEP) -> Relaxation:
    """Tabulate the segment solution from Δp(0) = ``dp0_Pa`` under piston flow A_p W, Eq. (13)-(14).

    See :func:`relaxations` (this is the single-problem form).
    """
    return relaxations([dp0_Pa], [piston_flow_m3_s], hyd, step)[0]


def start_volumes(y_start_m, hyd: Hydraulics):
    """Chamber volumes (V1, V2) at piston positions y, Eq. (2) [m³]."""
    a = hyd.piston_area_m2
    return hyd.chamber_volume_1_m3 - a * y_start_m, hyd.chamber_volume_2_m3 + a * y_start_m


def tau_volumes(volume_1_m3, volume_2_m3, hyd: Hydraulics):
    """The volumes of Eq. (14)'s τ: the chamber volumes, plus the gas law's gas volumes
    (:attr:`Hydraulics.gas_volumes_m3`) [m³]."""
    if not hyd.gas_law:
        return volume_1_m3, volume_2_m3
    g1, g2 = hyd.gas_volumes_m3
    return volume_1_m3 + g1, volume_2_m3 + g2


def compressibility_times(dt_s: np.ndarray, volume_1_m3: np.ndarray, volume_2_m3: np.ndarray,
                          piston_flow_m3_s: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """:func:`compressibility_time` element by element: each with its segment's start volumes
    (:func:`start_volumes`) and piston flow A_p W (A_p times the velocity), the same arithmetic."""
    out = compressibility_logs(dt_s, volume_1_m3, volume_2_m3, piston_flow_m3_s)
    out /= compressibility_divisors(piston_flow_m3_s, hyd)
    return out


def compressibility_logs(dt_s: np.ndarray, volume_1_m3: np.ndarray, volume_2_m3: np.ndarray,
                         piston_flow_m3_s: np.ndarray) -> np.ndarray:
    """The part of Eq. (14) without β_eff: ln(V2/V2,s) - ln(V1/V1,s) (log1p), Δt (1/V1,s + 1/V2,s) when
    A_p W = 0; :func:`compressibility_times` is this over :func:`compressibility_divisors`, bit for bit."""
    dt, v1, v2, qp = dt_s, volume_1_m3, volume_2_m3, piston_flow_m3_s
    out = np.log1p(qp * dt / v2)
    out -= np.log1p(-qp * dt / v1)
    rest = qp == 0.0
    if rest.any():
        out[rest] = dt[rest] * (1.0 / v1[rest] + 1.0 / v2[rest])
    return out


def compressibility_divisors(piston_flow_m3_s: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """β_eff A_p W of Eq. (14) (β_eff where A_p W = 0), element by element [Pa m³/s]; the oil's β with the
    gas law (:attr:`Hydraulics.tau_compressibility_1_Pa`)."""
    beta = hyd.tau_compressibility_1_Pa
    out = beta * piston_flow_m3_s
    out[piston_flow_m3_s == 0.0] = beta
    return out
