"""Hydraulics of the single-state damper model and its segment solution by quadrature.

Implements the model of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.); equation numbers are the paper's.

Model (noise free)
    Single state Δp = p1 - p2 (Eq. 1/2): β_eff 𝒱(y) dΔp/dt + Q_N(Δp) = A_p dy/dt, with the chamber
    volumes V1 = V0,1 - A_p y, V2 = V0,2 + A_p y following the *piston* position y (Eq. 2), β_eff
    from Eq. (3) with entrained air, and Q_N the orifice of Eq. (7) (laminar c1, turbulent c2 with the
    asymmetric C_D(1 ± a) chosen by the sign of Δp) in parallel with a laminar leakage Q_L = g Δp.
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
    last node (|q - q*| < 1e-17 of the scale) Δp = Δp* exactly. The tables of many segments are
    built in one vectorised pass (:func:`relaxations`). Max error ~4e-11 of the force scale against
    a DOP853 rtol 1e-13 solution (benchmark/virtual_rig_throughput.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isokinetic.physics.damper import (
    NOMINAL,
    Damper,
    Effects,
    effective_compressibility,
    laminar_coefficient,
    turbulent_coefficient,
)


@dataclass(frozen=True)
class Hydraulics:
    """Coefficients of the single-state model, Eq. (1)-(3), (7) plus leakage, SI.

    ``turbulent_coefficient_pos``/``_neg`` are c2 for Δp > 0 / Δp < 0 (asymmetric C_D). c1 = 0
    (pure turbulent) or c2 = 0 (pure laminar) are allowed, not both.
    """

    piston_area_m2: float
    chamber_volume_1_m3: float
    chamber_volume_2_m3: float
    compressibility_1_Pa: float
    laminar_coefficient: float
    turbulent_coefficient_pos: float
    turbulent_coefficient_neg: float
    leakage_conductance_m3_s_Pa: float = 0.0

    def __post_init__(self):
        if self.laminar_coefficient < 0 or self.turbulent_coefficient_pos < 0 or self.turbulent_coefficient_neg < 0:
            raise ValueError("hydraulics: c1 and c2 must be >= 0")
        if self.laminar_coefficient == 0 and min(self.turbulent_coefficient_pos, self.turbulent_coefficient_neg) == 0:
            raise ValueError("hydraulics: c1 = 0 needs c2 > 0 in both directions")
        if self.leakage_conductance_m3_s_Pa < 0:
            raise ValueError("hydraulics: leakage conductance must be >= 0")

    @classmethod
    def from_damper(cls, damper: Damper, effects: Effects = NOMINAL) -> Hydraulics:
        """Truth coefficients: Table 1 data with the effects (Eq. 3, 7, leakage, asymmetry)."""
        return cls(piston_area_m2=damper.piston_area_m2,
                   chamber_volume_1_m3=damper.chamber_volume_1_m3,
                   chamber_volume_2_m3=damper.chamber_volume_2_m3,
                   compressibility_1_Pa=float(effective_compressibility(damper, effects)),
                   laminar_coefficient=float(laminar_coefficient(damper, effects)),
                   turbulent_coefficient_pos=float(turbulent_coefficient(damper, effects, +1.0)),
                   turbulent_coefficient_neg=float(turbulent_coefficient(damper, effects, -1.0)),
                   leakage_conductance_m3_s_Pa=effects.leakage_conductance_m3_s_Pa)

    def c2(self, sign):
        """c2 of the flow direction ``sign`` (>= 0: positive side); a float for a scalar sign."""
        if isinstance(sign, (float, int)):
            return self.turbulent_coefficient_pos if sign >= 0 else self.turbulent_coefficient_neg
        return np.where(np.asarray(sign) >= 0, self.turbulent_coefficient_pos, self.turbulent_coefficient_neg)

    def flow(self, dp_Pa: float) -> float:
        """Scalar Q_N(Δp): orifice Eq. (7) plus leakage, for ODE right-hand sides [m³/s]."""
        a = abs(dp_Pa)
        if a == 0.0:
            return 0.0
        c1, c2 = self.laminar_coefficient, self.c2(float(dp_Pa))
        orifice = math.copysign(2.0 * a / (c1 + math.sqrt(c1 * c1 + 4.0 * c2 * a)), dp_Pa)
        return orifice + self.leakage_conductance_m3_s_Pa * dp_Pa

    def flow_derivative(self, dp_Pa: float) -> float:
        """Scalar dQ_N/dΔp = 1/sqrt(c1² + 4 c2|Δp|) + g, for ODE Jacobians [m³/(s Pa)]."""
        root = math.sqrt(self.laminar_coefficient**2 + 4.0 * self.c2(float(dp_Pa)) * abs(dp_Pa))
        return (1.0 / root if root > 0 else 1e300) + self.leakage_conductance_m3_s_Pa

    def composite_volume(self, y_m):
        """𝒱 = V1 V2 / (V1 + V2) at piston position y, Eq. (2) [m³]."""
        a, v01, v02 = self.piston_area_m2, self.chamber_volume_1_m3, self.chamber_volume_2_m3
        return (v01 - a * y_m) * (v02 + a * y_m) / (v01 + v02)


def orifice_pressure_of_flow(q_m3_s, hyd: Hydraulics):
    """Δp = c1 q + c2± q|q| for orifice flow q, Eq. (7) [Pa]."""
    q = np.asarray(q_m3_s, dtype=float)
    return hyd.laminar_coefficient * q + hyd.c2(q) * q * np.abs(q)


def orifice_flow_of_pressure(dp_Pa, hyd: Hydraulics):
    """Orifice flow q(Δp), Eq. (7) with the direction's c2, cancellation free [m³/s]."""
    dp = np.asarray(dp_Pa, dtype=float)
    a = np.abs(dp)
    c1, c2 = hyd.laminar_coefficient, hyd.c2(dp)
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
    g, c1, c2 = hyd.leakage_conductance_m3_s_Pa, hyd.laminar_coefficient, float(hyd.c2(qp))
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
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    v1 = hyd.chamber_volume_1_m3 - a * y_start_m
    v2 = hyd.chamber_volume_2_m3 + a * y_start_m
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
    """Quintic Hermite polynomial on each panel in s ∈ [0, 1] (ascending powers, shape (n, 6)).

    Values y, first derivatives d and second derivatives dd (in τ) at both ends, panel width h;
    cubic Hermite where a second derivative is not finite.
    """
    m0, m1 = h * d0, h * d1
    with np.errstate(invalid="ignore"):
        a0, a1 = h * h * dd0, h * h * dd1
    quintic = np.isfinite(a0) & np.isfinite(a1)
    a0, a1 = np.where(quintic, a0, 0.0), np.where(quintic, a1, 0.0)
    dy = y1 - y0
    coef = np.empty((h.size, 6))
    coef[:, 0], coef[:, 1], coef[:, 2] = y0, m0, 0.5 * a0
    coef[:, 3] = 10 * dy - 6 * m0 - 4 * m1 - 1.5 * a0 + 0.5 * a1
    coef[:, 4] = -15 * dy + 8 * m0 + 7 * m1 + 1.5 * a0 - a1
    coef[:, 5] = 6 * dy - 3 * m0 - 3 * m1 - 0.5 * a0 + 0.5 * a1
    cubic = ~quintic
    if cubic.any():
        coef[cubic, 2] = 3 * dy[cubic] - 2 * m0[cubic] - m1[cubic]
        coef[cubic, 3] = -2 * dy[cubic] + m0[cubic] + m1[cubic]
        coef[cubic, 4:] = 0.0
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
        """Panel polynomials from node values δ, dδ/dτ and d²δ/dτ² (inf: unknown)."""
        tau = np.asarray(tau, dtype=float)
        coef = _panel_coefficients(np.diff(tau), delta[:-1], delta[1:], slope[:-1], slope[1:],
                                   curvature[:-1], curvature[1:])
        return cls(tau, coef, float(steady_Pa))

    @classmethod
    def constant(cls, dp_Pa: float) -> Relaxation:
        """Δp stays at its start value (the start is already the steady state)."""
        return cls(np.zeros(1), np.zeros((0, 6)), float(dp_Pa))

    def pressure(self, tau) -> np.ndarray:
        """Δp at compressibility times ``tau`` (>= 0, **ascending**); Δp* beyond the table [Pa]."""
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


def _nodes(u0: float, u_end: float, u_ref: float, step: float, special: list[float], graded_min: float):
    """Descending nodes in u on [u_end, u0] (see :func:`relaxations`)."""
    parts = []
    if u0 > u_ref:                                   # beyond the scale (crossing piece): uniform step
        parts.append(np.linspace(u_ref, u0, math.ceil((u0 - u_ref) / step) + 1))
    top = min(u0, u_ref)
    # interpolation error ∝ h^6 |δ(u)| (quintic) with |δ| ∝ e^u: widths h = step·e^{(u_ref - u)/4}
    # (conservative), i.e. uniform in ζ = e^{(u - u_ref)/4}, up to a widest panel of 0.5 (reached
    # where |δ| < 2e-7 of the scale)
    zeta_top, zeta_cap = math.exp((top - u_ref) / 4.0), step / 0.5
    u_cap = max(u_end, u_ref + 4.0 * math.log(zeta_cap))
    if top > u_cap:
        zeta_lo = math.exp((u_cap - u_ref) / 4.0)
        zeta = np.linspace(zeta_lo, zeta_top, math.ceil((zeta_top - zeta_lo) / (step / 4.0)) + 1)
        parts.append(u_ref + 4.0 * np.log(zeta))
    lo_top = min(top, u_cap)
    parts.append(np.linspace(u_end, lo_top, max(2, math.ceil((lo_top - u_end) / 0.5) + 1)))
    if graded_min < 10.0 * step:
        off = 10.0 * step * 0.8 ** np.arange(0, math.ceil(math.log(graded_min / (10.0 * step)) / math.log(0.8)) + 1)
        for c in special:
            parts.append(np.concatenate([c - off, c + off, [c]]))
    u = np.concatenate(parts)
    u = np.unique(u[(u >= u_end) & (u <= u0)])
    return np.concatenate([[u0], u[u < u0]][::-1]) if u[-1] != u0 else u[::-1]


def relaxation(dp0_Pa: float, piston_flow_m3_s: float, hyd: Hydraulics, step: float = DEFAULT_STEP) -> Relaxation:
    """Tabulate the segment solution from Δp(0) = ``dp0_Pa`` under piston flow A_p W, Eq. (13)-(14).

    See :func:`relaxations` (this is the single-problem form).
    """
    return relaxations([dp0_Pa], [piston_flow_m3_s], hyd, step)[0]


def _segment_nodes(dp0: float, qp: float, hyd: Hydraulics, step: float):
    """Nodes in u and (q*, s, A_p W, Δp*, Δp0) of one problem; None if it starts at its steady state."""
    c1 = hyd.laminar_coefficient
    c2_max = max(hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)
    q_star = steady_orifice_flow(qp, hyd)
    p_star = float(orifice_pressure_of_flow(q_star, hyd))
    q0 = float(orifice_flow_of_pressure(dp0, hyd))
    dist = abs(q_star - q0)
    if dist == 0.0 or not math.isfinite(dist):
        return None
    s = math.copysign(1.0, q_star - q0)
    scale = max(abs(q_star), dist) if q_star * q0 >= 0 else abs(q_star)
    u0 = math.log(dist)
    special = []
    if q0 == 0.0:
        special.append(u0)
    elif q_star != 0.0 and q0 * q_star < 0.0:
        special.append(math.log(abs(q_star)))
    width = c1 / (2.0 * c2_max * abs(q_star)) if (c2_max > 0 and q_star != 0) else math.inf
    nodes = _nodes(u0, math.log(max(abs(q_star), dist) * 1e-17), math.log(scale), step, special,
                   max(1e-12, 1e-2 * width))
    return nodes, (q_star, s, qp, p_star, dp0)


def _integrand(uu: np.ndarray, params: np.ndarray, hyd: Hydraulics):
    """dτ/du, dΔp/dτ, δ = Δp - Δp* and dΔp/dq at points u of their problems (rows of ``params``).

    On the side of q*: A_pW - Q_N = (q* - q)(1 + g c1 + g c2 (|q*| + |q|)), exactly; across q = 0
    from the other side the direct form.
    """
    c1, g = hyd.laminar_coefficient, hyd.leakage_conductance_m3_s_Pa
    q_star, s, qp, p_star, _ = params.T
    e = np.exp(uu)
    q = q_star - s * e
    aq = np.abs(q)
    aqs = np.abs(q_star)
    c2 = np.where(q >= 0, hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)
    dpdq = c1 + 2.0 * c2 * aq                       # dΔp/dq, Eq. (7)
    same = (q * q_star > 0.0) | ((q_star == 0.0) & (q != 0.0))
    k_same = 1.0 + g * c1 + g * c2 * (aqs + aq)
    dtau = dpdq / k_same                            # dτ/du magnitude (τ grows as u falls)
    f = s * e * k_same                              # dΔp/dτ = A_p W - Q_N
    delta = -s * e * (c1 + c2 * (aq + aqs))         # Δp - Δp*
    if not same.all():
        o = ~same
        f[o] = qp[o] - q[o] - g * (c1 * q[o] + c2[o] * q[o] * aq[o])
        dtau[o] = dpdq[o] * e[o] / np.abs(f[o])
        delta[o] = c1 * q[o] + c2[o] * q[o] * aq[o] - p_star[o]
    return dtau, f, delta, dpdq


def _node_tau(panel_integrals: np.ndarray, hi: np.ndarray, sizes: np.ndarray, first: np.ndarray,
              prob: np.ndarray) -> np.ndarray:
    """τ at the nodes: cumulative panel integrals summed within each problem alone (one row each).

    A running sum over the whole batch, less its value at the problem's first node, would carry the
    rounding of the earlier problems' τ (often far larger) into this one's.
    """
    n = prob.size
    z = np.zeros(n)
    z[hi + 1] = panel_integrals
    col = np.arange(n) - np.repeat(first, sizes)
    rows = np.zeros((sizes.size, int(sizes.max())))
    rows[prob, col] = z
    return np.cumsum(rows, axis=1)[prob, col]


def _tables(node_sets: list[np.ndarray], params: list[tuple], hyd: Hydraulics) -> list[Relaxation]:
    """The Relaxation of every problem from its nodes (descending in u), in one vectorised pass."""
    g = hyd.leakage_conductance_m3_s_Pa
    sizes = np.array([u.size for u in node_sets])
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    u = np.concatenate(node_sets)
    prob = np.repeat(np.arange(sizes.size), sizes)
    is_last = np.zeros(u.size, dtype=bool)
    is_last[first + sizes - 1] = True
    hi = np.flatnonzero(~is_last)                   # panel [u[hi + 1], u[hi]]
    half = 0.5 * (u[hi] - u[hi + 1])
    pts = (0.5 * (u[hi] + u[hi + 1]))[:, None] + half[:, None] * _GL_X[None, :]
    n = u.size
    uu = np.concatenate([u, pts.ravel()])
    pp = np.concatenate([prob, np.repeat(prob[hi], _GL_X.size)])
    rows = np.array(params)[pp]
    dtau, f, delta, dpdq = _integrand(uu, rows, hyd)
    tau = _node_tau(half * (dtau[n:].reshape(pts.shape) @ _GL_W), hi, sizes, first, prob)
    with np.errstate(divide="ignore", invalid="ignore"):
        # d²Δp/dτ² = f'(q) dq/dτ = -(1 + g dΔp/dq) f / (dΔp/dq); infinite where dΔp/dq = 0
        curv = np.where(dpdq[:n] > 0, -(1.0 + g * dpdq[:n]) * f[:n] / dpdq[:n], np.inf)
    delta = delta[:n]
    delta[first] = rows[first, 4] - rows[first, 3]  # exact start: Δp continuous across segments
    coef = _panel_coefficients(tau[hi + 1] - tau[hi], delta[hi], delta[hi + 1], f[hi], f[hi + 1],
                               curv[hi], curv[hi + 1])
    taus = np.split(tau, first[1:])
    coefs = np.split(coef, (first - np.arange(sizes.size))[1:])
    return [Relaxation(t, c, float(p[3])) for t, c, p in zip(taus, coefs, params)]


def relaxations(dp0_Pa: Sequence[float], piston_flows_m3_s: Sequence[float], hyd: Hydraulics,
                step: float = DEFAULT_STEP) -> list[Relaxation]:
    """Tabulate many segment solutions at once (one vectorised pass), Eq. (13)-(14).

    Problem k starts at Δp(0) = ``dp0_Pa[k]`` under piston flow ``piston_flows_m3_s[k]`` = A_p W.
    τ(u) = ∫ (dΔp/dq) e^u / |A_p W - Q_N| du with u = ln|q* - q|, 3-point Gauss-Legendre per panel.
    Panel widths: ``step`` while |q - q*| exceeds the flow scale, then growing as e^{-u/4} (the
    Hermite error ~ width^6 × |Δp - Δp*| stays at the level of the pressure scale's), at most 0.5;
    graded (ratio 0.8) towards q = 0 (start from rest, or the sign change where c2 switches) down to
    1e-2 of the laminar-turbulent transition width c1/(2 c2 |q*|) (1e-12 for c1 = 0). A table ends
    where |q - q*| = 1e-17 of the scale; beyond it Δp = Δp*. The integrand is evaluated in factored,
    cancellation-free form on the side of q*: A_pW - Q_N = (q* - q)(1 + g c1 + g c2 (|q*| + |q|)).
    """
    out: list[Relaxation | None] = []
    params, node_sets = [], []
    for dp0, qp in zip(dp0_Pa, piston_flows_m3_s, strict=True):
        problem = _segment_nodes(float(dp0), float(qp), hyd, step)
        if problem is None:
            out.append(Relaxation.constant(float(dp0)))
            continue
        node_sets.append(problem[0])
        params.append(problem[1])
        out.append(None)
    if not node_sets:
        return out
    built = iter(_tables(node_sets, params, hyd))
    return [r if r is not None else next(built) for r in out]
