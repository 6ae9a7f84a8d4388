"""Noise-free responses of the virtual rig: Δp, piston velocity and force of a planned case.

Implements the damper model of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.); equation numbers are the paper's.
The force is Eq. (8) with a massless piston: F = A_p Δp + F_f(dy/dt) (Coulomb + Stribeck).

Triangle excitation
    Segment quadrature (:mod:`isokinetic.physics.hydraulics`, Eq. 13-14): segments of constant
    piston velocity from the play operator (:func:`excitation.piston_segments`), chained with Δp
    continuous; the tables of all segments of all cases are built in one vectorised pass
    (:func:`triangle_responses`).

Sine excitation
    Stiff integration with ``scipy.integrate.solve_ivp`` (LSODA, analytic Jacobian, rtol 1e-12:
    ~2e-10 relative to a Radau rtol 1e-13 solution, an order of magnitude faster than Radau at
    equal accuracy), split at every velocity discontinuity (turning points, gap contacts), t_eval
    at the samples (:func:`sine_response`).

A rigid servo (stiffness inf) uses these fast paths; a finite stiffness the coupled
actuator-gap-damper model of :mod:`isokinetic.physics.servo`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp

from isokinetic.physics.damper import NOMINAL, Damper, Effects, friction_force
from isokinetic.physics.excitation import (
    Segment,
    check_stroke,
    command_displacement,
    direction_between,
    piston_segments,
    record_end,
    sample_times,
    segment_index,
    turning_times,
)
from isokinetic.physics.hydraulics import (
    DEFAULT_STEP,
    Hydraulics,
    compressibility_time,
    relaxation,
    relaxations,
    steady_pressure,
)
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.servo import check_stiffness, servo_response


def triangle_response(case: CasePlan, hyd: Hydraulics, backlash_m: float = 0.0, step: float = DEFAULT_STEP):
    """Δp and piston velocity of a triangle case by segment quadrature, Eq. (13)-(14).

    Returns (t_s, dp_Pa, piston_velocity_m_s); Δp(0) = 0. See :func:`triangle_responses`.
    """
    return triangle_responses([case], hyd, backlash_m, step)[0]


@dataclass(frozen=True)
class Drive:
    """The piston motion a triangle case really had, measured from its displacement record.

    The model is then run "on equal terms" with the rig (paper Sec. 4.5): half-period j (1-based)
    moves at the measured speed ``speeds_m_s[j-1]`` (later half-periods repeat the last measured
    one of the same direction) between the plan's turning points (Eq. 26), the piston position
    chained from -Y; ``grid_offset_s`` in [0, 1/fs) is the plan time of the first sample, so that
    model samples fall at the measured samples' plan times (record time minus motion start).
    """

    speeds_m_s: tuple[float, ...]
    grid_offset_s: float = 0.0

    def __post_init__(self):
        if not self.speeds_m_s or any(not (math.isfinite(v) and v > 0) for v in self.speeds_m_s):
            raise ValueError(f"drive: speeds must be positive and finite, got {self.speeds_m_s}")
        if not (math.isfinite(self.grid_offset_s) and self.grid_offset_s >= 0):
            raise ValueError(f"drive: grid offset must be >= 0, got {self.grid_offset_s}")

    def speed(self, j: int) -> float:
        """Speed of half-period j (0-based); beyond the measured ones, the last of the same direction."""
        n = len(self.speeds_m_s)
        if j < n:
            return self.speeds_m_s[j]
        k = n - 1 if (j - (n - 1)) % 2 == 0 else n - 2
        return self.speeds_m_s[max(k, 0)]


def drive_times(case: CasePlan, drive: Drive | None = None) -> np.ndarray:
    """Model sample times: k / fs (plan grid), or grid_offset + k / fs up to the duration [s]."""
    if drive is None or drive.grid_offset_s == 0.0:
        return sample_times(case)
    n = int(math.floor((case.duration_s - drive.grid_offset_s) * case.sample_rate_Hz + 1e-9))
    return drive.grid_offset_s + np.arange(max(n, 0) + 1, dtype=float) / case.sample_rate_Hz


def driven_segments(case: CasePlan, drive: Drive) -> list[Segment]:
    """Contact segments between the plan's turning points at the drive's measured speeds.

    The piston starts at the command's start -Y (Eq. 26) and its position is chained through the
    segments, so amplitude follows from the measured speeds.
    """
    edges = [0.0, *turning_times(case), max(record_end(case), float(drive_times(case, drive)[-1]))]
    omega, phase = 2.0 * math.pi / case.period_s, case.phase_rad
    y = float(command_displacement(case, 0.0))
    segs = []
    for j, (ta, tb) in enumerate(zip(edges[:-1], edges[1:])):
        d = direction_between(omega, phase, ta, tb)
        segs.append(Segment(ta, tb, True, y, 0.0, d))
        y += d * drive.speed(j) * (tb - ta)
    return segs


def _check_positions(case: CasePlan, segs: Sequence[Segment], flows: Sequence[float], hyd: Hydraulics) -> None:
    """A driven piston must not empty a chamber anywhere on its path (Eq. 12)."""
    limit = min(hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3) / hyd.piston_area_m2
    for seg, qp in zip(segs, flows):
        end = seg.piston_start_m + qp / hyd.piston_area_m2 * (seg.t_end_s - seg.t_start_s)
        if max(abs(seg.piston_start_m), abs(end)) >= limit:
            raise ValueError(f"case {case.case}: the measured motion reaches the end of the cylinder "
                             f"(V0/A_p = {limit:g} m)")


def _triangle_plan(case: CasePlan, drive: Drive | None, hyd: Hydraulics, backlash_m: float):
    """(segments, piston flows A_p W of each) of a triangle case, from its plan or its drive."""
    if case.waveform != "triangle":
        raise ValueError(f"case {case.case}: not a triangle")
    a = hyd.piston_area_m2
    if drive is None:
        check_stroke(case, hyd)
        w = 4.0 * case.amplitude_m / case.period_s
        segs = piston_segments(case, backlash_m)
        return segs, [a * seg.direction * w if seg.contact else 0.0 for seg in segs]
    if backlash_m:
        raise ValueError(f"case {case.case}: a measured drive has no backlash model")
    segs = driven_segments(case, drive)
    flows = [a * seg.direction * drive.speed(j) for j, seg in enumerate(segs)]
    _check_positions(case, segs, flows, hyd)
    return segs, flows


def _chain(t: np.ndarray, segs: Sequence[Segment], flows: Sequence[float], hyd: Hydraulics, tables_: dict,
           step: float) -> tuple[np.ndarray, np.ndarray]:
    """Δp and piston velocity at ``t``, segment after segment from Δp(0) = 0 (tables reused by start)."""
    a = hyd.piston_area_m2
    dp = np.empty(t.size)
    vel = np.zeros(t.size)
    p = 0.0
    for seg, idx, qp in zip(segs, segment_index(t, segs), flows):
        key = (p, qp)
        if key not in tables_:
            tables_[key] = relaxation(p, qp, hyd, step)
        v = qp / a
        dt = np.append(t[idx], seg.t_end_s) - seg.t_start_s
        values = tables_[key].pressure(compressibility_time(dt, seg.piston_start_m, v, hyd))
        dp[idx] = values[:-1]
        vel[idx] = v
        p = float(values[-1])
    return dp, vel


def triangle_responses(cases: Sequence[CasePlan], hyd: Hydraulics, backlash_m: float = 0.0,
                       step: float = DEFAULT_STEP, drives: Sequence[Drive | None] | None = None
                       ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`triangle_response` of many cases, their segment tables built in one batch.

    Each segment is assumed to start from the previous one's steady Δp* (true once a segment has
    settled, when the chained Δp equals Δp* exactly); the tables for those starts are built in one
    vectorised :func:`relaxations` call and reused when the chain confirms them, otherwise (a
    segment cut short, e.g. a gap crossing) the table is built from the actual start.
    ``drives`` (one per case, None: the plan) runs a case with its measured half-period speeds on
    its measured sample grid (:class:`Drive`; no backlash).
    """
    drives = [None] * len(cases) if drives is None else list(drives)
    if len(drives) != len(cases):
        raise ValueError(f"{len(drives)} drives for {len(cases)} cases")
    plans = [(case, drive, *_triangle_plan(case, drive, hyd, backlash_m)) for case, drive in zip(cases, drives)]
    guesses = {}
    for *_, flows in plans:
        prev = 0.0
        for qp in flows:
            guesses.setdefault((prev, qp), None)
            prev = steady_pressure(qp, hyd)
    keys = list(guesses)
    tables_ = dict(zip(keys, relaxations([k[0] for k in keys], [k[1] for k in keys], hyd, step)))
    out = []
    for case, drive, segs, flows in plans:
        t = drive_times(case, drive)
        out.append((t, *_chain(t, segs, flows, hyd, tables_, step)))
    return out


def _sine_segment_system(seg: Segment, hyd: Hydraulics, amp: float, omega: float):
    """rhs and Jacobian of Eq. (1) on one piece of a sine case: pushed (y = Y sin ωt + offset) or at rest."""
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    q_n, dq_n = hyd.flow, hyd.flow_derivative
    if seg.contact:
        off = seg.offset_m

        def kin(tt):
            y = amp * math.sin(omega * tt) + off
            return a * amp * omega * math.cos(omega * tt), hyd.composite_volume(y)
    else:
        vol0 = hyd.composite_volume(seg.piston_start_m)

        def kin(tt):
            return 0.0, vol0

    def rhs(tt, z):
        qp, vol = kin(tt)
        return [(qp - q_n(z[0])) / (beta * vol)]

    def jac(tt, z):
        return [[-dq_n(z[0]) / (beta * kin(tt)[1])]]

    return rhs, jac


def sine_response(case: CasePlan, hyd: Hydraulics, backlash_m: float = 0.0, rtol: float = 1e-12,
                  method: str = "LSODA"):
    """Δp and piston velocity of a sine case by stiff integration of Eq. (1) (solve_ivp).

    Split at turning points and gap contacts; atol = rtol × the steady Δp at peak velocity.
    Returns (t_s, dp_Pa, piston_velocity_m_s); Δp(0) = 0.
    """
    if case.waveform != "sine":
        raise ValueError(f"case {case.case}: not a sine")
    check_stroke(case, hyd)
    t = sample_times(case)
    omega = 2.0 * math.pi * case.frequency_Hz
    amp = case.amplitude_m
    a = hyd.piston_area_m2
    atol = rtol * max(abs(steady_pressure(a * amp * omega, hyd)), abs(steady_pressure(-a * amp * omega, hyd)), 1.0)
    segs = piston_segments(case, backlash_m)
    dp = np.empty(t.size)
    vel = np.zeros(t.size)
    p = 0.0
    for seg, idx in zip(segs, segment_index(t, segs)):
        rhs, jac = _sine_segment_system(seg, hyd, amp, omega)
        t_eval = t[idx]
        t0, t1 = seg.t_start_s, seg.t_end_s
        sol = solve_ivp(rhs, (t0, t1), [p], method=method, jac=jac, rtol=rtol, atol=atol,
                        t_eval=np.append(t_eval, t1) if t_eval.size == 0 or t_eval[-1] < t1 else t_eval)
        if not sol.success:
            raise RuntimeError(f"case {case.case}: sine integration failed: {sol.message}")
        dp[idx] = sol.y[0, :t_eval.size]
        p = float(sol.y[0, -1])
        if seg.contact:
            vel[idx] = amp * omega * np.cos(omega * t_eval)
    return t, dp, vel


def true_response(case: CasePlan, damper: Damper, effects: Effects = NOMINAL,
                  hydraulics: Hydraulics | None = None, servo_stiffness_N_m: float = math.inf) -> pd.DataFrame:
    """Noise-free record: time_s, command_m, actuator_m, piston_velocity_m_s, dp_Pa, force_N (Eq. 8).

    ``hydraulics`` overrides the coefficients derived from damper and effects (e.g. c2 = 0);
    friction and backlash always come from ``effects``. ``actuator_m`` is what the LVDT sees: the
    command itself for a rigid servo (k = inf), command - F/k otherwise (:func:`servo.servo_response`).
    """
    return true_responses([case], damper, effects, hydraulics, servo_stiffness_N_m)[0]


def true_responses(cases: Sequence[CasePlan], damper: Damper, effects: Effects = NOMINAL,
                   hydraulics: Hydraulics | None = None,
                   servo_stiffness_N_m: float = math.inf) -> list[pd.DataFrame]:
    """:func:`true_response` of many cases (triangle tables built in one batch).

    A rigid servo (k = inf) uses the quadrature (triangle) and the LSODA play-operator model
    (sine); a finite k integrates the coupled actuator-gap-damper system (:func:`servo.servo_response`)
    for both waveforms.
    """
    hyd = Hydraulics.from_damper(damper, effects) if hydraulics is None else hydraulics
    servo = check_stiffness(servo_stiffness_N_m, "servo_stiffness_N_m")
    for c in cases:
        if c.waveform not in ("triangle", "sine"):
            raise ValueError(f"case {c.case}: the virtual rig cannot simulate waveform {c.waveform!r}")
    rigid = math.isinf(servo)
    tri = iter(triangle_responses([c for c in cases if c.waveform == "triangle"] if rigid else [], hyd,
                                  effects.backlash_m))
    out = []
    for case in cases:
        command = command_displacement(case, sample_times(case))
        if rigid:
            t, dp, vel = next(tri) if case.waveform == "triangle" else sine_response(case, hyd, effects.backlash_m)
            force = hyd.piston_area_m2 * dp + friction_force(vel, effects)
            actuator = command
        else:
            t, dp, vel, force, actuator, _ = servo_response(case, hyd, effects, servo)
        out.append(pd.DataFrame({"time_s": t, "command_m": command, "actuator_m": actuator,
                                 "piston_velocity_m_s": vel, "dp_Pa": dp, "force_N": force}))
    return out
