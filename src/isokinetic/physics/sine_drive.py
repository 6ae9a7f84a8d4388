"""The damper model driven by a measured sine: Δp and piston velocity on any uniform sample grid.

A sine case's displacement record is fitted by y = c + Y sin(2πf t + φ), plus its significant harmonics
where the motion is not a pure sine (the diagnosis' sine observations); the model is then driven by that
motion, from rest, starting where the fitted sine starts its first cycle (plan time τ = 0), and sampled at
the record's own sample times, which need not fall on τ = k/fs. Equation numbers are those of the paper
"A method for the identification of hydraulic damper characteristics from steady velocity inputs"
(Titurus et al.): Eq. (1) with the composite volume of Eq. (2), the flow of Eq. (7) plus leakage,
integrated with LSODA and an analytic Jacobian (``scipy.integrate.odeint``: its output times in Fortran,
about ten times faster than
``solve_ivp``'s dense output at a record's thousands of samples), split at the turning points and gap
contacts of the play operator (:func:`isokinetic.physics.excitation.piston_segments`), as
:func:`isokinetic.physics.responses.sine_response` does on the plan grid (the tests check the two agree there),
except that pushed pieces with no gap crossed between them are integrated as one (:func:`merged_contacts`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from isokinetic.physics.excitation import Segment, check_stroke, piston_segments, segment_index
from isokinetic.physics.gas_law import PRESSURE_FLOOR, chamber_compliance, chamber_compliance_slope, gas_amounts
from isokinetic.physics.hydraulics import Hydraulics, steady_pressure
from isokinetic.physics.plan import CasePlan

#: Relative tolerance of the model's integration: ~1e-7 of the force scale up to 13 mm/s of peak speed, ~1e-5 at
#: 0.13-0.16 m/s (measured against rtol 1e-12), far below any bin's noise, and smooth enough in the parameters for
#: finite-difference Jacobians.
SINE_RTOL = 1e-10


@dataclass(frozen=True)
class SineDrive:
    """The measured motion of a sine case: y = Y sin(2π f τ) for plan time τ >= 0, at rest at y = 0 before;
    the model is sampled at τ_k = ``grid_start_s`` + k/fs, k = 0 .. ``n_samples`` - 1 (``grid_start_s`` < 0:
    the record starts before the motion).

    ``harmonics``: (k, A_k, θ_k) terms of a periodic motion that is not a pure sine (a servo's distortion, a
    crank's kinematics), y = Y sin ωτ + Σ A_k (sin(kωτ + θ_k) - sin θ_k) for τ >= 0 (each term starts at 0, so
    the motion starts at rest at y = 0; k >= 2, A_k [m])."""

    amplitude_m: float
    frequency_Hz: float
    grid_start_s: float
    n_samples: int
    harmonics: tuple[tuple[int, float, float], ...] = ()
    harmonic_se_m: tuple[float, ...] = ()   # the measured motion's standard error of each harmonic's
    #                                          sine and cosine components, k = 2, 3, ... [m] (not simulated)

    def __post_init__(self):
        for name in ("amplitude_m", "frequency_Hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"sine drive: {name} must be positive and finite, got {v!r}")
        if not math.isfinite(self.grid_start_s) or self.n_samples < 1:
            raise ValueError(f"sine drive: bad grid ({self.grid_start_s!r}, {self.n_samples!r} samples)")
        for k, a_k, theta in self.harmonics:
            if not (int(k) == k and k >= 2 and math.isfinite(a_k) and math.isfinite(theta)):
                raise ValueError(f"sine drive: a harmonic needs an integer k >= 2 and finite A_k, θ_k, got "
                                 f"{(k, a_k, theta)!r}")

    def times(self, sample_rate_Hz: float) -> np.ndarray:
        """The model's sample times in plan time τ [s]."""
        return self.grid_start_s + np.arange(self.n_samples, dtype=float) / sample_rate_Hz

    def scaled(self, factor: float) -> SineDrive:
        """The same drive with every amplitude times ``factor`` (an LVDT scale, a sensitivity step)."""
        return replace(self, amplitude_m=self.amplitude_m * factor,
                       harmonics=tuple((k, a_k * factor, theta) for k, a_k, theta in self.harmonics),
                       harmonic_se_m=tuple(se * factor for se in self.harmonic_se_m))

    def with_harmonic_step(self, k: int, cosine: bool, step_m: float) -> SineDrive:
        """The drive with ``step_m`` added to the sine (``cosine``: cosine) component of harmonic ``k`` of the
        fundamental's phase u: A_k sin(k u + θ_k) = A_k cos θ_k sin ku + A_k sin θ_k cos ku."""
        terms = {kk: (a_k * math.cos(theta), a_k * math.sin(theta)) for kk, a_k, theta in self.harmonics}
        s_k, c_k = terms.get(k, (0.0, 0.0))
        terms[k] = (s_k, c_k + step_m) if cosine else (s_k + step_m, c_k)
        return replace(self, harmonics=tuple((kk, math.hypot(*sc), math.atan2(sc[1], sc[0]))
                                             for kk, sc in sorted(terms.items())))

    @property
    def stroke_amplitude_m(self) -> float:
        """A bound on |y - the mean position|: Y + Σ 2|A_k|."""
        return self.amplitude_m + sum(2.0 * abs(a_k) for _k, a_k, _theta in self.harmonics)

    def velocity(self, tau_s) -> np.ndarray:
        """dy/dτ for τ > 0 [m/s]."""
        omega = 2.0 * math.pi * self.frequency_Hz
        return omega * self.phase_velocity(omega * np.asarray(tau_s, dtype=float))

    def phase_velocity(self, u) -> np.ndarray:
        """dy/du [m/rad] at the fundamental's phases u = ωτ [rad]: Y cos u + Σ k A_k cos(k u + θ_k)."""
        u = np.asarray(u, dtype=float)
        v = self.amplitude_m * np.cos(u)
        for k, a_k, theta in self.harmonics:
            v = v + k * a_k * np.cos(k * u + theta)
        return v


def merged_contacts(segs: list) -> list:
    """The segments with consecutive pushed pieces of the same offset (no gap crossed between them: always without
    backlash) joined into one: the piston's sine motion is smooth across the actuator's turning points, and each restart
    of the integrator costs its step-size ramp-up again."""
    out = []
    for seg in segs:
        prev = out[-1] if out else None
        if prev is not None and prev.contact and seg.contact and prev.offset_m == seg.offset_m \
                and prev.t_end_s == seg.t_start_s:
            out[-1] = replace(prev, t_end_s=seg.t_end_s)
        else:
            out.append(seg)
    return out


def fused_segment_system(seg: Segment, hyd: Hydraulics, amp: float, omega: float,
                         harmonics: tuple[tuple[int, float, float], ...] = ()):
    """(rhs, Jacobian) of Eq. (1) on one piece of a sine case (``seg``: a piece of
    :func:`isokinetic.physics.excitation.piston_segments`), pushed (y = Y sin ωt + offset, plus the
    ``harmonics`` of :class:`SineDrive` where given) or at rest: the
    arithmetic of :meth:`Hydraulics.composite_volume` (Eq. 2), :meth:`Hydraulics.flow` (Eq. 7 plus leakage) and
    :meth:`Hydraulics.flow_derivative`, operation for operation (tests/physics/test_sine_drive.py checks it bit
    for bit against those methods), in closures of local Python floats (the state read with ``item()``: numpy
    scalars cost more): the integrator calls the rhs thousands of times per case, and this makes a sine run
    about 30 % cheaper than calling the methods. The virtual rig (:func:`isokinetic.physics.responses.sine_response`)
    and the diagnosis' sine drive both integrate it. With the gas law: the two chambers (:func:`initial_state`)."""
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    v01, v02 = hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3
    c1p = hyd.laminar_coefficient
    c1n = c1p if hyd.laminar_coefficient_neg is None else hyd.laminar_coefficient_neg
    c2p, c2n, leak = hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg, hyd.leakage_conductance_m3_s_Pa
    sqrt, copysign, sin, cos = math.sqrt, math.copysign, math.sin, math.cos
    contact, off, qamp = seg.contact, seg.offset_m, a * amp * omega
    y0 = seg.piston_start_m
    vol0 = (v01 - a * y0) * (v02 + a * y0) / (v01 + v02)
    terms = tuple((k * omega, a_k, theta, a_k * math.sin(theta), a * a_k * k * omega) for k, a_k, theta in harmonics)

    def volume(tt):   # Hydraulics.composite_volume of the piston's position (the sine plus its harmonics)
        if not contact:
            return vol0
        y = amp * sin(omega * tt) + off + sum(a_k * sin(w_k * tt + th) - start for w_k, a_k, th, start, _ in terms)
        return (v01 - a * y) * (v02 + a * y) / (v01 + v02)

    c1p2, c1n2, c2p4, c2n4, vsum = c1p * c1p, c1n * c1n, 4.0 * c2p, 4.0 * c2n, v01 + v02

    def flow(p):   # Hydraulics.flow, operation for operation (its constant factors computed once)
        m = abs(p)
        if m == 0.0:
            return 0.0
        if p >= 0:
            return copysign(2.0 * m / (c1p + sqrt(c1p2 + c2p4 * m)), p) + leak * p
        return copysign(2.0 * m / (c1n + sqrt(c1n2 + c2n4 * m)), p) + leak * p

    def dflow(p):   # Hydraulics.flow_derivative
        c1, c2 = (c1p, c2p) if p >= 0 else (c1n, c2n)
        root = sqrt(c1**2 + 4.0 * c2 * abs(p))
        return (1.0 / root if root > 0 else 1e300) + leak

    motion = _piston_motion(seg, a, amp, omega, terms)

    if hyd.gas_law:   # the two chambers: none of the one-state closures below
        return _gas_law_system(hyd, motion, flow, dflow)

    def pushed(tt, z):   # Eq. 1 driven by the sine; z.item(): a Python float (numpy scalars cost more)
        p = z.item()
        m = abs(p)
        if m == 0.0:
            q = 0.0
        elif p >= 0:
            q = copysign(2.0 * m / (c1p + sqrt(c1p2 + c2p4 * m)), p) + leak * p
        else:
            q = copysign(2.0 * m / (c1n + sqrt(c1n2 + c2n4 * m)), p) + leak * p
        ph = omega * tt
        ay = a * (amp * sin(ph) + off)
        return [(qamp * cos(ph) - q) / (beta * ((v01 - ay) * (v02 + ay) / vsum))]

    def pushed_periodic(tt, z):   # Eq. 1 driven by the sine and its harmonics
        q = flow(z.item())
        y, qin = motion(tt)
        ay = a * y
        return [(qin - q) / (beta * ((v01 - ay) * (v02 + ay) / vsum))]

    def resting(tt, z):   # Eq. 1 with the piston at rest
        return [(0.0 - flow(z.item())) / (beta * vol0)]

    rhs = (pushed_periodic if terms else pushed) if contact else resting

    def jac(tt, z):
        return [[-dflow(z.item()) / (beta * volume(tt))]]

    return rhs, jac


def _piston_motion(seg: Segment, a: float, amp: float, omega: float, terms: tuple):
    """(y, A_p ẏ) of the piston on ``seg`` as a function of time: the sine plus its harmonics (``terms`` of
    :func:`fused_segment_system`) in contact, standing at its start position at rest."""
    sin, cos, y0, off, qamp = math.sin, math.cos, seg.piston_start_m, seg.offset_m, a * amp * omega

    def motion(tt):
        if not seg.contact:
            return y0, 0.0
        ph = omega * tt
        y, qin = amp * sin(ph) + off, qamp * cos(ph)
        for w_k, a_k, theta, start, qa_k in terms:
            arg = w_k * tt + theta
            y += a_k * sin(arg) - start
            qin += qa_k * cos(arg)
        return y, qin

    return motion


def _gas_law_system(hyd: Hydraulics, motion, flow, dflow):
    """rhs and Jacobian of the two chambers with the gas law, z = (p1, p2): 𝒞_1 ṗ1 = A_p ẏ - Q_N(Δp) = -𝒞_2 ṗ2,
    𝒞_i = β_oil (V_i(y) - G_i/p_i) + G_i/p_i² (Eq. 1-3 per chamber, :mod:`isokinetic.physics.gas_law`), from the
    piston's ``motion`` (y, A_p ẏ) and the flow and its derivative; Δp = p1 - p2 (:func:`state_pressure`). The
    same model as the triangle tables' (Δp, K), written without K's Newton iteration."""
    b, a, p0 = hyd.tau_compressibility_1_Pa, hyd.piston_area_m2, hyd.charge_pressure_Pa
    g1, g2 = gas_amounts(hyd.air_compressibility_1_Pa, p0, hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3)
    bv1, bv2, low = b * hyd.chamber_volume_1_m3, b * hyd.chamber_volume_2_m3, PRESSURE_FLOOR * p0

    def chambers(tt, z):   # (Δp, A_p ẏ, 𝒞_1, 𝒞_2, u1, u2)
        p1, p2 = z.item(0), z.item(1)
        y, qin = motion(tt)
        u1, u2 = 1.0 / max(p1, low), 1.0 / max(p2, low)
        return (p1 - p2, qin, chamber_compliance(u1, bv1 - b * a * y, g1, b),
                chamber_compliance(u2, bv2 + b * a * y, g2, b), u1, u2)

    def rhs(tt, z):
        dp, qin, c1, c2, _, _ = chambers(tt, z)
        net = qin - flow(dp)
        return [net / c1, -net / c2]

    def jac(tt, z):
        dp, qin, c1, c2, u1, u2 = chambers(tt, z)
        net, d = qin - flow(dp), dflow(dp)
        s1, s2 = chamber_compliance_slope(u1, g1, b), chamber_compliance_slope(u2, g2, b)
        return [[(-d - net / c1 * s1) / c1, d / c1], [d / c2, (-d + net / c2 * s2) / c2]]

    return rhs, jac


def initial_state(hyd: Hydraulics) -> list[float]:
    """The state of :func:`fused_segment_system` at rest: [Δp = 0], or the chambers at the charge pressure."""
    return [hyd.charge_pressure_Pa] * 2 if hyd.gas_law else [0.0]


def state_pressure(rows: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """Δp of states ``rows`` (one a row, :func:`fused_segment_system`'s order) [Pa]."""
    return rows[:, 0] - rows[:, 1] if hyd.gas_law else rows[:, 0]


def sine_drive_response(drive: SineDrive, sample_rate_Hz: float, hyd: Hydraulics, backlash_m: float = 0.0,
                        rtol: float = SINE_RTOL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(τ [s], Δp [Pa], piston velocity [m/s]) of the model driven by ``drive`` at its sample times (Eq. 1, 2, 7;
    Δp = 0 and at rest for τ <= 0); atol = rtol × the steady Δp at peak velocity (Eq. 24)."""
    from scipy.integrate import odeint  # ~0.4 s of imports: only where sine cases are modelled

    tau = drive.times(sample_rate_Hz)
    dp, vel = np.zeros(tau.size), np.zeros(tau.size)
    live = tau > 0.0
    if not live.any():
        return tau, dp, vel
    amp, omega = drive.amplitude_m, 2.0 * math.pi * drive.frequency_Hz
    if drive.harmonics and backlash_m > 0.0:
        raise ValueError("sine drive: a motion with harmonics is modelled without backlash only (its turning "
                         "points are not the sine's)")
    plan = CasePlan("sine", "sine", sample_rate_Hz, amplitude_m=amp, frequency_Hz=drive.frequency_Hz, phase_rad=0.0,
                    duration_s=float(tau[-1]))
    check_stroke(replace(plan, amplitude_m=drive.stroke_amplitude_m) if drive.harmonics else plan, hyd)
    atol = rtol * max(abs(steady_pressure(hyd.piston_area_m2 * amp * omega, hyd)),
                      abs(steady_pressure(-hyd.piston_area_m2 * amp * omega, hyd)), 1.0)
    t = tau[live]
    out_dp, out_vel = np.zeros(t.size), np.zeros(t.size)
    segs = merged_contacts(piston_segments(plan, backlash_m))
    state = initial_state(hyd)
    for seg, idx in zip(segs, segment_index(t, segs), strict=True):
        t_eval, t0, t1 = t[idx], seg.t_start_s, seg.t_end_s
        if t1 <= t0:
            continue
        rhs, jac = fused_segment_system(seg, hyd, amp, omega, drive.harmonics)
        times = np.concatenate([[t0], t_eval, [t1]])
        sol, info = odeint(rhs, state, times, Dfun=jac, rtol=rtol, atol=atol, tfirst=True, full_output=True,
                           mxstep=100_000)
        if info["message"] != "Integration successful.":
            raise RuntimeError(f"sine drive ({drive.frequency_Hz:g} Hz): integration failed: {info['message']}")
        out_dp[idx] = state_pressure(sol[1:-1], hyd)
        state = [float(x) for x in sol[-1]]
        if seg.contact:
            out_vel[idx] = drive.velocity(t_eval) if drive.harmonics else amp * omega * np.cos(omega * t_eval)
    dp[live], vel[live] = out_dp, out_vel
    return tau, dp, vel
