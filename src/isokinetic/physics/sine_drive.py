"""The damper model driven by a measured sine: Δp and piston velocity on any uniform sample grid.

A sine case's displacement record is fitted by y = c + Y sin(2πf t + φ) (the diagnosis' sine
observations); the model is then driven by that motion, from rest, starting where the fitted sine
starts its first cycle (plan time τ = 0), and sampled at the record's own sample times, which need
not fall on τ = k/fs. Equation numbers are those of the paper "A method for the identification of
hydraulic damper characteristics from steady velocity inputs" (Titurus et al.): Eq. (1) with the
composite volume of Eq. (2), the flow of Eq. (7) plus leakage, integrated with LSODA and an analytic
Jacobian (``scipy.integrate.odeint``: its output times in Fortran, about ten times faster than
``solve_ivp``'s dense output at a record's thousands of samples), split at the turning points and gap
contacts of the play operator (:func:`isokinetic.physics.excitation.piston_segments`), as
:func:`isokinetic.physics.responses.sine_response` does on the plan grid (the tests check the two agree there),
except that pushed pieces with no gap crossed between them are integrated as one (:func:`merged_contacts`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from isokinetic.physics.excitation import check_stroke, piston_segments, segment_index
from isokinetic.physics.hydraulics import Hydraulics, steady_pressure
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import sine_segment_system

#: Relative tolerance of the model's integration: ~1e-7 of the force scale (measured against rtol 1e-12),
#: far below any bin's noise, and smooth enough in the parameters for finite-difference Jacobians.
SINE_RTOL = 1e-10


@dataclass(frozen=True)
class SineDrive:
    """The measured motion of a sine case: y = Y sin(2π f τ) for plan time τ >= 0, at rest at y = 0 before;
    the model is sampled at τ_k = ``grid_start_s`` + k/fs, k = 0 .. ``n_samples`` - 1 (``grid_start_s`` < 0:
    the record starts before the motion)."""

    amplitude_m: float
    frequency_Hz: float
    grid_start_s: float
    n_samples: int

    def __post_init__(self):
        for name in ("amplitude_m", "frequency_Hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"sine drive: {name} must be positive and finite, got {v!r}")
        if not math.isfinite(self.grid_start_s) or self.n_samples < 1:
            raise ValueError(f"sine drive: bad grid ({self.grid_start_s!r}, {self.n_samples!r} samples)")

    def times(self, sample_rate_Hz: float) -> np.ndarray:
        """The model's sample times in plan time τ [s]."""
        return self.grid_start_s + np.arange(self.n_samples, dtype=float) / sample_rate_Hz

    def scaled(self, factor: float) -> SineDrive:
        """The same drive with the amplitude times ``factor`` (an LVDT scale, a sensitivity step)."""
        return SineDrive(self.amplitude_m * factor, self.frequency_Hz, self.grid_start_s, self.n_samples)


def merged_contacts(segs: list) -> list:
    """Consecutive pushed pieces with the same offset (no gap crossed between them: always without backlash)
    joined into one: the piston's sine motion is smooth across the actuator's turning points, and each restart
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


def sine_drive_response(drive: SineDrive, sample_rate_Hz: float, hyd: Hydraulics, backlash_m: float = 0.0,
                        rtol: float = SINE_RTOL) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(τ, Δp, piston velocity) of the model driven by ``drive`` at its sample times (Eq. 1, 2, 7; Δp = 0 and
    at rest for τ <= 0); atol = rtol × the steady Δp at peak velocity (Eq. 24)."""
    from scipy.integrate import odeint  # ~0.4 s of imports: only where sine cases are modelled

    tau = drive.times(sample_rate_Hz)
    dp, vel = np.zeros(tau.size), np.zeros(tau.size)
    live = tau > 0.0
    if not live.any():
        return tau, dp, vel
    amp, omega = drive.amplitude_m, 2.0 * math.pi * drive.frequency_Hz
    plan = CasePlan("sine", "sine", sample_rate_Hz, amplitude_m=amp, frequency_Hz=drive.frequency_Hz, phase_rad=0.0,
                    duration_s=float(tau[-1]))
    check_stroke(plan, hyd)
    atol = rtol * max(abs(steady_pressure(hyd.piston_area_m2 * amp * omega, hyd)),
                      abs(steady_pressure(-hyd.piston_area_m2 * amp * omega, hyd)), 1.0)
    t = tau[live]
    out_dp, out_vel = np.zeros(t.size), np.zeros(t.size)
    segs = merged_contacts(piston_segments(plan, backlash_m))
    p = 0.0
    for seg, idx in zip(segs, segment_index(t, segs), strict=True):
        t_eval, t0, t1 = t[idx], seg.t_start_s, seg.t_end_s
        if t1 <= t0:
            continue
        rhs, jac = sine_segment_system(seg, hyd, amp, omega)
        times = np.concatenate([[t0], t_eval, [t1]])
        sol, info = odeint(rhs, [p], times, Dfun=jac, rtol=rtol, atol=atol, tfirst=True, full_output=True,
                           mxstep=100_000)
        if info["message"] != "Integration successful.":
            raise RuntimeError(f"sine drive ({drive.frequency_Hz:g} Hz): integration failed: {info['message']}")
        out_dp[idx] = sol[1:-1, 0]
        p = float(sol[-1, 0])
        if seg.contact:
            out_vel[idx] = amp * omega * np.cos(omega * t_eval)
    dp[live], vel[live] = out_dp, out_vel
    return tau, dp, vel
