"""Finite servo stiffness: the coupled actuator - gap - damper system of the virtual rig.

Extends the damper model of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.) with the rig's servo; equation
numbers are the paper's.

The rig is in displacement control with a servo of finite stiffness k: x = command - F/k, F the
force transmitted by the attachment (read by the load cell), the LVDT on x. The coupled
actuator-gap-damper system is integrated as a hybrid ODE (LSODA, rtol 1e-10, event-located mode
switches): in contact the massless piston follows the actuator (sliding) or is held by Coulomb seal
friction (sticking); while the gap is crossed F = 0, so x = command. In sliding contact
dΔp/dt = (A_p dc/dt - Q_N) / (β_eff 𝒱 + A_p²/k): the servo compliance adds to the effective
compressibility like the fixture term of Eq. (3). Under load the actuator lags; when the load
vanishes at a force zero crossing it crosses the gap at the command velocity, which the LVDT shows
as a velocity spike (paper Sec. 4.5, Fig. 13). Both waveforms; Coulomb friction only (Stribeck
refused). With k = inf the fast paths of :mod:`isokinetic.physics.responses` are used instead
(byte-identical exports); note that the rigid play model keeps the piston still from the reversal
on and lets the load cell read A_p Δp during the gap, whereas the servo model keeps contact while
the load is positive and reads F = 0 in the gap, so k -> inf with b > 0 does not reproduce it exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isokinetic.physics.damper import NOMINAL, Effects
from isokinetic.physics.excitation import (
    angular_motion,
    check_stroke,
    command_displacement,
    direction_between,
    record_end,
    sample_times,
    turning_times,
)
from isokinetic.physics.hydraulics import Hydraulics, steady_pressure, total_flow
from isokinetic.physics.plan import CasePlan

GAP, STICK, SLIDE = "gap", "stick", "slide"

#: Series of a servo record, in the order :func:`servo_response` returns them after the time.
_SERIES = ("dp", "velocity", "force", "actuator", "piston")


def check_stiffness(value, key: str) -> float:
    """A servo stiffness: a number > 0, inf allowed (a rigid servo); else ValueError naming ``key``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value) or value <= 0:
        raise ValueError(f"{key}: must be a number > 0 (inf: rigid servo), got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Mode:
    """State of the attachment in :class:`ServoRig`.

    ``side`` s is the contact side: +1 the actuator pushes the piston up (y = x - b/2, F >= 0),
    -1 down (y = x + b/2, F <= 0), 0 bilateral (no gap, b = 0). ``sense`` σ is the sliding
    direction of the piston (SLIDE), ``piston_m`` its position while it stands (GAP, STICK).
    """

    kind: str
    side: float = 0.0
    sense: float = 1.0
    piston_m: float = 0.0


def _event(fun, direction: float, target):
    """A terminal, directional solve_ivp event on fun(t, Δp); ``target`` gives the next (mode, Δp)."""
    def g(tt, z):
        return fun(tt, z[0])
    g.terminal, g.direction, g.target = True, direction, target
    return g


@dataclass(frozen=True)
class ServoRig:
    """One case on a servo of finite stiffness k with backlash b and Coulomb friction F_C.

    The actuator x lags its command c under load, x = c - F/k (massless, quasi-static servo), and
    the LVDT measures x. F is the force transmitted by the attachment (what the load cell reads).
    The piston y is massless; static = kinetic friction = F_C. Per mode:

    SLIDE (contact, piston moving, direction σ)
        y = x ∓ b/2 follows the actuator; F = A_p Δp + σ F_C; eliminating x and ẏ gives
        dΔp/dt = (A_p ċ - Q_N(Δp)) / (β_eff 𝒱(y) + A_p²/k): the servo compliance adds the volume
        compliance A_p²/k to β_eff 𝒱, as the fixture term of Eq. (3) does. ẏ = ẋ = ċ - Ḟ/k.
    STICK (contact, piston held by the seals)
        ẏ = ẋ = 0, F = k (c - x) with x fixed, dΔp/dt = -Q_N(Δp) / (β_eff 𝒱(y)); the friction
        force F - A_p Δp must stay in [-F_C, F_C], else the piston slides in that direction.
    GAP (b > 0: the actuator crosses the play)
        F = 0, so x = c; the massless piston stands, held by the seals (|A_p Δp| <= F_C; on entry
        Δp is set to the nearest admissible value, Δp = 0 without friction) while Δp relaxes
        through the flow paths. Contact resumes when x reaches y ± b/2.

    Build with :meth:`of` (it checks the inputs); :meth:`run` integrates the record.
    """

    case: CasePlan
    hyd: Hydraulics
    stiffness_N_m: float
    backlash_m: float
    coulomb_force_N: float
    rtol: float = 1e-10
    method: str = "LSODA"
    triangle: bool = field(init=False)
    omega: float = field(init=False)        # argument ω t + phase of the command [rad/s]
    phase: float = field(init=False)
    speed: float = field(init=False)        # triangle speed 4Y/T, or sine peak speed 2πfY [m/s]
    compliance_m3_Pa: float = field(init=False)   # A_p²/k: the servo as a volume compliance
    atol: float = field(init=False)         # absolute Δp tolerance [Pa]
    tol_f: float = field(init=False)        # force threshold of a mode switch [N]
    tol_x: float = field(init=False)        # position threshold of a contact [m]
    probe_s: float = field(init=False)      # trends at a transition are judged this much later

    def __post_init__(self):
        a, k, fc, amp = self.hyd.piston_area_m2, self.stiffness_N_m, self.coulomb_force_N, self.case.amplitude_m
        tri = self.case.waveform == "triangle"
        omega, phase = angular_motion(self.case)
        speed = 4.0 * amp / self.case.period_s if tri else amp * 2.0 * math.pi * self.case.frequency_Hz
        pscale = max(abs(steady_pressure(a * speed, self.hyd)), abs(steady_pressure(-a * speed, self.hyd)), fc / a, 1.0)
        derived = {"triangle": tri, "omega": omega, "phase": phase, "speed": speed, "compliance_m3_Pa": a * a / k,
                   "atol": self.rtol * pscale, "tol_f": 1e-9 * (a * pscale + fc),
                   "tol_x": 1e-12 * max(amp, self.backlash_m, 1e-9),
                   "probe_s": 1e-7 / omega}   # events are exact to ~1e-15
        for name, value in derived.items():
            object.__setattr__(self, name, value)

    @classmethod
    def of(cls, case: CasePlan, hyd: Hydraulics, effects: Effects, servo_stiffness_N_m: float,
           rtol: float = 1e-10, method: str = "LSODA") -> ServoRig:
        """The servo model of a case; ValueError for k not finite > 0, Stribeck friction, a too long stroke."""
        k = float(servo_stiffness_N_m)
        if not (k > 0 and math.isfinite(k)):
            raise ValueError(f"servo_stiffness_N_m must be finite and > 0 here, got {servo_stiffness_N_m!r}")
        if case.waveform not in ("triangle", "sine"):
            raise ValueError(f"case {case.case}: the virtual rig cannot simulate waveform {case.waveform!r}")
        if effects.stribeck_force_N:
            raise ValueError(f"case {case.case}: a finite servo stiffness supports Coulomb friction only "
                             "(stribeck_force_N must be 0)")
        check_stroke(case, hyd)
        b, fc = float(effects.backlash_m), float(effects.coulomb_force_N)
        if b < 0:
            raise ValueError("backlash_m must be >= 0")
        return cls(case, hyd, k, b, fc, rtol, method)

    # ---------------------------------------------------------------- kinematics

    def command(self, tt: float) -> float:
        """Command c(t) as a float (triangle of Eq. 26 or Y sin(ωt)) [m]."""
        amp = self.case.amplitude_m
        if self.triangle:
            return amp * (2.0 / math.pi) * math.asin(max(-1.0, min(1.0, math.sin(self.omega * tt + self.phase))))
        return amp * math.sin(self.omega * tt)

    def rate(self, tt: float, d: float) -> float:
        """Command velocity ċ(t) on an interval of direction d [m/s]."""
        return d * self.speed if self.triangle else self.speed * math.cos(self.omega * tt)

    def rates(self, ts: np.ndarray, d: float) -> np.ndarray:
        """:meth:`rate` at many times."""
        return np.full(ts.shape, d * self.speed) if self.triangle else self.speed * np.cos(self.omega * ts)

    def slide_state(self, tt: float, p: float, m: Mode, r: float):
        """(F [N], y [m], dΔp/dt [Pa/s], ẏ [m/s]) of a sliding contact at Δp = p [Pa], command rate r [m/s]."""
        a, k = self.hyd.piston_area_m2, self.stiffness_N_m
        f = a * p + m.sense * self.coulomb_force_N
        y = self.command(tt) - f / k - m.side * self.backlash_m / 2.0
        dp = (a * r - self.hyd.flow(p)) / (self.hyd.compressibility_1_Pa * self.hyd.composite_volume(y)
                                           + self.compliance_m3_Pa)
        return f, y, dp, r - a * dp / k

    # ---------------------------------------------------------------- modes

    def contact(self, side: float, y: float) -> Mode:
        """The mode on closing the gap at piston position y: sticking with friction, else sliding."""
        if self.coulomb_force_N > 0:
            return Mode(STICK, side, 1.0, y)
        return Mode(SLIDE, side, side or 1.0)

    def gap(self, y: float, p: float) -> tuple[Mode, float]:
        """(mode, Δp [Pa]) on entering the gap at piston position y [m]: Δp clipped to what the seals hold,
        |A_p Δp| <= F_C."""
        limit = self.coulomb_force_N / self.hyd.piston_area_m2
        return Mode(GAP, 0.0, 1.0, y), min(max(p, -limit), limit)

    def settle(self, m: Mode, tt: float, p: float, d: float) -> tuple[Mode, float]:
        """The mode consistent with the state at tt (complementarity of contact and friction).

        Values are judged at tt, the sign of a quantity that sits at its threshold (a force at 0 or
        ±F_C, a piston velocity at 0) a short ``probe_s`` later, so that an event located a rounding
        error before the true crossing does not flip the mode back.
        """
        for _ in range(8):
            if m.kind == GAP:
                new = self._leave_gap(m, tt, p, d)
            elif m.kind == STICK:
                new = self._leave_stick(m, tt, p, d)
            else:
                new = self._leave_slide(m, tt, p, d)
            if new is None:
                return m, p
            m, p = new
        return m, p

    def _leave_gap(self, m: Mode, tt: float, p: float, d: float) -> tuple[Mode, float] | None:
        """Contact when the actuator has reached an edge of the gap moving towards it."""
        r, c, half = self.rate(tt, d), self.command(tt), self.backlash_m / 2.0
        if c - (m.piston_m + half) >= -self.tol_x and r > 0:
            return self.contact(1.0, m.piston_m), p
        if c - (m.piston_m - half) <= self.tol_x and r < 0:
            return self.contact(-1.0, m.piston_m), p
        return None

    def _leave_stick(self, m: Mode, tt: float, p: float, d: float) -> tuple[Mode, float] | None:
        """Gap when the transmitted force vanishes; sliding when the friction demand reaches ±F_C."""
        a, k, b = self.hyd.piston_area_m2, self.stiffness_N_m, self.backlash_m
        fc, tol_f = self.coulomb_force_N, self.tol_f
        r = self.rate(tt, d)
        f = k * (self.command(tt) - (m.piston_m + m.side * b / 2.0))
        if b > 0 and (m.side * f < -tol_f or (abs(f) <= tol_f and m.side * r < 0)):
            return self.gap(m.piston_m, p)
        demand = f - a * p
        rate_demand = (k * self.rate(tt + self.probe_s, d)
                       + a * self.hyd.flow(p) / (self.hyd.compressibility_1_Pa * self.hyd.composite_volume(m.piston_m)))
        if demand > fc + tol_f or (demand >= fc - tol_f and rate_demand > 0):
            return Mode(SLIDE, m.side, 1.0), p
        if demand < -fc - tol_f or (demand <= -fc + tol_f and rate_demand < 0):
            return Mode(SLIDE, m.side, -1.0), p
        return None

    def _leave_slide(self, m: Mode, tt: float, p: float, d: float) -> tuple[Mode, float] | None:
        """Gap when the transmitted force vanishes; sticking when the piston velocity turns."""
        f, y, dp, _ = self.slide_state(tt, p, m, self.rate(tt, d))
        yd = self.slide_state(tt + self.probe_s, p + self.probe_s * dp, m, self.rate(tt + self.probe_s, d))[3]
        if self.backlash_m > 0 and (m.side * f < -self.tol_f or (abs(f) <= self.tol_f and m.side * dp < 0)):
            return self.gap(y, p)
        if self.coulomb_force_N > 0 and m.sense * yd < 0:
            return Mode(STICK, m.side, 1.0, y), p
        return None

    # ---------------------------------------------------------------- ODE of each mode

    def system(self, m: Mode, d: float):
        """(rhs, jac, events) of mode m on an interval of command direction d."""
        return self._slide_system(m, d) if m.kind == SLIDE else self._rest_system(m)

    def _slide_system(self, m: Mode, d: float):
        a, fc = self.hyd.piston_area_m2, self.coulomb_force_N
        beta, cs = self.hyd.compressibility_1_Pa, self.compliance_m3_Pa

        def rhs(tt, z):
            return [self.slide_state(tt, z[0], m, self.rate(tt, d))[2]]

        def jac(tt, z):
            y = self.slide_state(tt, z[0], m, 0.0)[1]
            return [[-self.hyd.flow_derivative(z[0]) / (beta * self.hyd.composite_volume(y) + cs)]]

        events = []
        if fc > 0:
            events.append(_event(lambda tt, p: self.slide_state(tt, p, m, self.rate(tt, d))[3], -m.sense,
                                 lambda tt, p: (Mode(STICK, m.side, 1.0, self.slide_state(tt, p, m, 0.0)[1]), p)))
        if self.backlash_m > 0:
            events.append(_event(lambda tt, p: m.side * (a * p + m.sense * fc), -1.0,
                                 lambda tt, p: self.gap(self.slide_state(tt, p, m, 0.0)[1], p)))
        return rhs, jac, events

    def _rest_system(self, m: Mode):
        """GAP and STICK: the piston stands at m.piston_m, Δp relaxes through the flow paths."""
        k, b, fc, a = self.stiffness_N_m, self.backlash_m, self.coulomb_force_N, self.hyd.piston_area_m2
        y = m.piston_m
        compliance = self.hyd.compressibility_1_Pa * self.hyd.composite_volume(y)

        def rhs(tt, z):
            return [-self.hyd.flow(z[0]) / compliance]

        def jac(tt, z):
            return [[-self.hyd.flow_derivative(z[0]) / compliance]]

        if m.kind == GAP:
            events = [_event(lambda tt, p: self.command(tt) - (y + b / 2.0), 1.0,
                             lambda tt, p: (self.contact(1.0, y), p)),
                      _event(lambda tt, p: self.command(tt) - (y - b / 2.0), -1.0,
                             lambda tt, p: (self.contact(-1.0, y), p))]
            return rhs, jac, events
        x = y + m.side * b / 2.0
        events = [_event(lambda tt, p: k * (self.command(tt) - x) - a * p - fc, 1.0,
                         lambda tt, p: (Mode(SLIDE, m.side, 1.0), p)),
                  _event(lambda tt, p: k * (self.command(tt) - x) - a * p + fc, -1.0,
                         lambda tt, p: (Mode(SLIDE, m.side, -1.0), p))]
        if b > 0:
            events.append(_event(lambda tt, p: m.side * k * (self.command(tt) - x), -1.0, lambda tt, p: self.gap(y, p)))
        return rhs, jac, events

    def outputs(self, ts: np.ndarray, ps: np.ndarray, m: Mode, d: float):
        """(F [N], x [m], y [m], ẏ [m/s]) at times ts [s] with Δp = ps [Pa] in mode m."""
        a, k, b = self.hyd.piston_area_m2, self.stiffness_N_m, self.backlash_m
        c = command_displacement(self.case, ts)
        if m.kind == SLIDE:
            f = a * ps + m.sense * self.coulomb_force_N
            x = c - f / k
            y = x - m.side * b / 2.0
            dp = (a * self.rates(ts, d) - total_flow(ps, self.hyd)) / (
                self.hyd.compressibility_1_Pa * self.hyd.composite_volume(y) + self.compliance_m3_Pa)
            return f, x, y, self.rates(ts, d) - a * dp / k
        y = np.full(ts.shape, m.piston_m)
        if m.kind == STICK:
            x = np.full(ts.shape, m.piston_m + m.side * b / 2.0)
            return k * (c - x), x, y, np.zeros(ts.shape)
        return np.zeros(ts.shape), c + 0.0, y, np.zeros(ts.shape)

    # ---------------------------------------------------------------- the record

    def initial_mode(self, d0: float) -> Mode:
        """The mode at rest, the piston at the far side of the gap, as in :func:`excitation.piston_segments`."""
        if self.backlash_m > 0:
            return Mode(GAP, 0.0, 1.0, self.command(0.0) + d0 * self.backlash_m / 2.0)
        return self.contact(0.0, self.command(0.0))

    def _solve(self, m: Mode, d: float, tt: float, tb: float, p: float, ts: np.ndarray):
        """solve_ivp of mode m from (tt, p) to tb or its first event, evaluated at ts (and tb)."""
        t_eval = ts if ts.size and ts[-1] == tb else np.append(ts, tb)
        from scipy.integrate import solve_ivp  # scipy.integrate (~0.4 s): only where a servo is integrated

        rhs, jac, events = self.system(m, d)
        sol = solve_ivp(rhs, (tt, tb), [p], method=self.method, jac=jac, rtol=self.rtol, atol=self.atol,
                        t_eval=t_eval, events=events or None)
        if sol.status == -1:
            raise RuntimeError(f"case {self.case.case}: servo integration failed: {sol.message}")
        return sol, events

    def _store(self, sol, n_wanted: int, i: int, m: Mode, d: float, out: dict[str, np.ndarray]) -> int:
        """Write the solved samples (at most ``n_wanted``) from index i; returns how many."""
        t_sol = np.asarray(sol.t, dtype=float)
        n_done = min(t_sol.size, n_wanted)
        if n_done:
            p_sol = np.asarray(sol.y, dtype=float)[0, :n_done]
            f, x, y, yd = self.outputs(t_sol[:n_done], p_sol, m, d)
            sl = slice(i, i + n_done)
            out["dp"][sl], out["force"][sl], out["actuator"][sl] = p_sol, f, x
            out["piston"][sl], out["velocity"][sl] = y, yd
        return n_done

    def run(self):
        """The integrated record: (t_s, dp_Pa, piston_velocity_m_s, force_N, actuator_m, piston_m)."""
        t = sample_times(self.case)
        end = record_end(self.case)
        edges = [0.0, *turning_times(self.case), end]
        out = {name: np.empty(t.size) for name in _SERIES}
        m = self.initial_mode(direction_between(self.omega, self.phase, edges[0], edges[1]))
        tt, p, i, stalls = 0.0, 0.0, 0, 0
        for ta, tb in zip(edges[:-1], edges[1:]):
            d = direction_between(self.omega, self.phase, ta, tb)
            m, p = self.settle(m, tt, p, d)
            while tt < tb:
                ts = t[i:int(np.searchsorted(t, tb, side="right"))]
                sol, events = self._solve(m, d, tt, tb, p, ts)
                i += self._store(sol, ts.size, i, m, d, out)
                if sol.status != 1:
                    tt, p = tb, float(np.asarray(sol.y, dtype=float)[0, -1])
                    continue
                t_e, n = min((float(te[0]), n) for n, te in enumerate(sol.t_events) if te.size)
                stalls = stalls + 1 if t_e - tt <= 1e-12 * end else 0
                if stalls > 20:
                    raise RuntimeError(f"case {self.case.case}: servo model chatters at t = {t_e:.9g} s ({m.kind})")
                m, p = events[n].target(t_e, float(sol.y_events[n][0][0]))
                tt = t_e
                m, p = self.settle(m, tt, p, d)
        if i != t.size:
            raise RuntimeError(f"case {self.case.case}: servo integration covered {i} of {t.size} samples")
        return (t, *(out[name] for name in _SERIES))


def servo_response(case: CasePlan, hyd: Hydraulics, effects: Effects = NOMINAL,
                   servo_stiffness_N_m: float = math.inf, rtol: float = 1e-10, method: str = "LSODA"):
    """Triangle or sine case with a servo of finite stiffness k, backlash b and Coulomb friction.

    See :class:`ServoRig` for the modes. Transitions are located as events (solve_ivp, terminal,
    directional): SLIDE -> STICK when ẏ reaches 0; STICK -> SLIDE when the friction demand reaches
    ±F_C; contact -> GAP when the transmitted force falls to zero (s·F = 0); GAP -> contact (STICK,
    or SLIDE without friction) when the actuator closes the gap. At every event and turning point
    the mode is made consistent with the state (contact and friction complementarity, judged on the
    trend). The piston starts at the far side of the gap with Δp = 0, as in
    :func:`excitation.piston_segments`.

    Backlash spikes: in contact near F = 0, ẋ = (1 - κ) ċ + κ Q_N/A_p with κ = k_h/(k + k_h) and
    k_h = A_p²/(β_eff 𝒱) the hydraulic stiffness (and ẋ = 0 while the piston sticks); once the
    load vanishes the actuator catches up with its command and crosses the gap at ċ. The LVDT
    velocity therefore jumps up for b/|ċ| at each force zero crossing. With k = inf there is no
    lag and no spike (use :func:`responses.sine_response` / :func:`responses.triangle_responses` then).

    Returns (t_s, dp_Pa, piston_velocity_m_s, force_N, actuator_m, piston_m). Air under the gas law
    (a damper with a charge pressure) is refused: this model carries Δp alone, not the chambers' mean pressure.
    """
    if hyd.gas_law:
        raise ValueError(f"case {case.case}: a servo of finite stiffness is modelled without the gas law's air "
                         "(declare no charge pressure, or an infinitely stiff servo)")
    return ServoRig.of(case, hyd, effects, servo_stiffness_N_m, rtol, method).run()

