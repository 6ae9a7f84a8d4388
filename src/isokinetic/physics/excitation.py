"""Excitation of the virtual rig: sample grid, actuator command, turning points and the play operator.

Implements the test inputs of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.): the triangle of Eq. (26) and the
sine Y sin(2πft); equation numbers are the paper's.

Backlash (rigid servo)
    ``Effects.backlash_m`` = b is a play operator between the actuator x (which follows the command
    exactly for a rigid servo; the LVDT measures x) and the piston y: y stays in [x - b/2, x + b/2]
    and only moves when the actuator pushes it at one edge of the gap. While the gap is crossed the
    piston stands still (W = 0) and Δp relaxes through the flow paths; the load cell is assumed to
    keep reading A_p Δp (friction is sign(0) = 0 there), i.e. the piston is held by its seals, not
    floating. At the start of a record the piston sits at the far side of the gap (as after a
    reversal), so the first motion also crosses the whole gap. Records start from rest with Δp(0) = 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.plan import CasePlan, sine_displacement, triangle_displacement


def sample_times(case: CasePlan) -> np.ndarray:
    """t = k / fs for k = 0..round(duration fs), the endpoint included [s]."""
    n = int(round(case.duration_s * case.sample_rate_Hz))
    return np.arange(n + 1, dtype=float) / case.sample_rate_Hz


def record_end(case: CasePlan) -> float:
    """The end of the simulated interval [s]: the duration, or the last sample if rounding puts it later."""
    return max(case.duration_s, round(case.duration_s * case.sample_rate_Hz) / case.sample_rate_Hz)


def command_displacement(case: CasePlan, t_s) -> np.ndarray:
    """Ideal actuator command of the case: Eq. (26) triangle or Y sin(2πft) [m]."""
    if case.waveform == "triangle":
        return triangle_displacement(t_s, case.amplitude_m, case.period_s, case.phase_rad)
    if case.waveform == "sine":
        return sine_displacement(t_s, case.amplitude_m, case.frequency_Hz)
    raise ValueError(f"case {case.case}: the virtual rig cannot simulate waveform {case.waveform!r}")


def angular_motion(case: CasePlan) -> tuple[float, float]:
    """(ω [rad/s], phase [rad]) of the command's argument ω t + phase: 2π/T and the plan phase, or 2πf and 0."""
    if case.waveform == "triangle":
        return 2.0 * math.pi / case.period_s, case.phase_rad
    return 2.0 * math.pi * case.frequency_Hz, 0.0


def _snap(t: float, case: CasePlan) -> float:
    """A breakpoint within 1e-9 of the record length of a sample time is put on it."""
    k = round(t * case.sample_rate_Hz)
    ts = k / case.sample_rate_Hz
    return ts if abs(ts - t) <= 1e-9 * record_end(case) else t


def turning_times(case: CasePlan) -> list[float]:
    """The actuator's turning points in (0, record end) [s]: argument π/2 + kπ (triangle or sine)."""
    omega, phase = angular_motion(case)
    k = math.floor((phase - math.pi / 2) / math.pi)
    end = record_end(case)
    out = []
    while True:
        t = (math.pi / 2 + k * math.pi - phase) / omega
        if t >= end * (1 - 1e-12):
            break
        if t > end * 1e-12:
            out.append(_snap(t, case))
        k += 1
    return out


def direction_between(omega: float, phase: float, ta: float, tb: float) -> float:
    """The command direction (+1 / -1) between turning points ta, tb [s]: the sign of cos at the middle."""
    return 1.0 if math.cos(omega * 0.5 * (ta + tb) + phase) > 0 else -1.0


@dataclass(frozen=True)
class Segment:
    """A time interval of the piston: at rest (contact=False) or pushed by the actuator."""

    t_start_s: float
    t_end_s: float
    contact: bool
    piston_start_m: float
    offset_m: float      # in contact: y = x + offset (∓ b/2)
    direction: float     # actuator direction of motion on the interval (+1 / -1)


def piston_segments(case: CasePlan, backlash_m: float = 0.0) -> list[Segment]:
    """Play operator of total gap b between actuator x (the command) and piston y.

    y ∈ [x - b/2, x + b/2]; pushed upwards y = x - b/2, downwards y = x + b/2. The piston starts
    at the far side of the gap, y(0) = x(0) + sign(v0) b/2. Returns rest and contact intervals.
    """
    b = float(backlash_m)
    if b < 0:
        raise ValueError("backlash_m must be >= 0")
    edges = [0.0, *turning_times(case), record_end(case)]
    omega = 2.0 * math.pi * (case.frequency_Hz if case.waveform == "sine" else 1.0 / case.period_s)
    phase = 0.0 if case.waveform == "sine" else case.phase_rad
    x = lambda t: float(command_displacement(case, t))  # noqa: E731
    segs: list[Segment] = []
    y = None
    for ta, tb in zip(edges[:-1], edges[1:]):
        d = direction_between(omega, phase, ta, tb)
        xa = x(ta)
        if y is None:
            y = xa + d * b / 2.0
        x_contact = y + d * b / 2.0                   # actuator position that touches the piston
        if b == 0.0 or d * (x_contact - xa) <= 0.0:
            tc = ta
        elif d * (x(tb) - x_contact) <= 0.0:
            tc = tb
        else:
            tc = _contact_time(case, ta, tb, x_contact, d, omega)
        if tc > ta:
            segs.append(Segment(ta, tc, False, y, 0.0, d))
        if tc < tb:
            segs.append(Segment(tc, tb, True, x(tc) - d * b / 2.0, -d * b / 2.0, d))
            y = x(tb) - d * b / 2.0
    return segs


def _contact_time(case: CasePlan, ta: float, tb: float, x_c: float, d: float, omega: float) -> float:
    """Time in (ta, tb) at which the monotone actuator reaches x_c."""
    if case.waveform == "triangle":
        w = 4.0 * case.amplitude_m / case.period_s
        return min(max(ta + d * (x_c - float(command_displacement(case, ta))) / w, ta), tb)
    # x = Y sin(ω t): increasing piece ωt ∈ [-π/2, π/2] + 2πm, decreasing ∈ [π/2, 3π/2] + 2πm
    r = math.asin(max(-1.0, min(1.0, x_c / case.amplitude_m)))
    mid = omega * 0.5 * (ta + tb)
    if d > 0:
        m = round(mid / (2 * math.pi))
        t = (2 * math.pi * m + r) / omega
    else:
        m = round((mid - math.pi) / (2 * math.pi))
        t = (2 * math.pi * m + math.pi - r) / omega
    return min(max(t, ta), tb)


def check_stroke(case: CasePlan, hyd: Hydraulics) -> None:
    """The piston (|y| <= Y) must not empty a chamber (Eq. 12: T_max < T_lim)."""
    limit = min(hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3) / hyd.piston_area_m2
    if not case.amplitude_m < limit:
        raise ValueError(f"case {case.case}: amplitude {case.amplitude_m:g} m reaches the end of the "
                         f"cylinder (V0/A_p = {limit:g} m)")


def segment_index(t: np.ndarray, segs: Sequence[Segment]) -> list[slice]:
    """The sample indices of each segment: [t_start, t_end), the last one closed."""
    starts = np.array([s.t_start_s for s in segs])
    i0 = np.searchsorted(t, starts, side="left")
    i1 = np.append(i0[1:], t.size)
    return [slice(int(a), int(b)) for a, b in zip(i0, i1)]
