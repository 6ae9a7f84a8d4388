"""The reference rig's kinematics: the delayed command, a first-order servo and the play operator of
backlash, as closed-form pieces of smooth motion (a sibling of :mod:`isokinetic.reference.rig`,
sharing its independence: it imports only the standard library, numpy and scipy)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from isokinetic.reference.rig import RigCase, RigImperfections, TriangleCase, TrueEffects


# ---------------------------------------------------------------------------------------------
# Kinematics: delayed command, first-order servo, play operator
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ActuatorPiece:
    """x(t) on [t_start, t_end): x = c_s + v s - v tau + K exp(-s/tau), s = t - t_start.

    The delayed command on the piece is c_s + v s; with tau = 0, x = c_s + v s exactly.
    """

    t_start_s: float
    t_end_s: float
    command_start_m: float
    velocity_m_s: float
    lag_s: float
    transient_m: float

    def position(self, t):
        s = np.asarray(t, dtype=float) - self.t_start_s
        x = self.command_start_m + self.velocity_m_s * (s - self.lag_s)
        if self.lag_s > 0.0:
            x = x + self.transient_m * np.exp(-s / self.lag_s)
        return x

    def velocity(self, t):
        s = np.asarray(t, dtype=float) - self.t_start_s
        if self.lag_s > 0.0:
            return self.velocity_m_s - self.transient_m / self.lag_s * np.exp(-s / self.lag_s)
        return np.full_like(s, self.velocity_m_s)


def actuator_pieces(case: TriangleCase, rig: RigImperfections, t_end_s: float) -> list[ActuatorPiece]:
    """Closed-form servo response to the delayed command, one piece per command segment.

    The command holds -Y before t = 0; delayed by d its corners lie at d + k T/2 (k = 0..3).
    x(0) = -Y at rest; x and (for tau_s > 0) dx/dt are continuous across pieces.
    """
    y_amp, w, half, d, tau = case.amplitude_m, case.velocity_m_s, case.period_s / 2.0, rig.delay_s, rig.servo_lag_s
    starts = [(0.0, -y_amp, 0.0)] if d > 0.0 else []
    for k in range(4):
        t_k = d + k * half
        if t_k < t_end_s:
            starts.append((t_k, -y_amp if k % 2 == 0 else y_amp, w if k % 2 == 0 else -w))
    pieces = []
    x0 = -y_amp
    for i, (ts, cs, v) in enumerate(starts):
        te = starts[i + 1][0] if i + 1 < len(starts) else t_end_s
        piece = ActuatorPiece(ts, te, cs, v, tau, (x0 - cs + v * tau) if tau > 0.0 else 0.0)
        pieces.append(piece)
        x0 = float(piece.position(te)) if tau > 0.0 else cs + v * (te - ts)
    return pieces


@dataclass(frozen=True)
class SineActuatorPiece:
    """x(t) on [t_start, t_end) for the delayed sine command c = Y sin(w s), s = t - d >= 0, through the
    first-order servo dx/dt = (c - x)/tau from rest at x = 0: with r = w tau,
    x = Y (sin ws - r cos ws) / (1 + r^2) + K exp(-s/tau), K = Y r / (1 + r^2); tau = 0: x = c.

    ``harmonics`` (k, h, phi) add the command terms Y h (sin(k w s + phi) - sin phi) (:class:`SineCase`), each
    through the same servo by superposition: with R = k w tau and A = Y h, the steady part
    A (sin(k w s + phi) - R cos(k w s + phi)) / (1 + R^2) - A sin phi, plus the exp(-s/tau) term that starts
    it at rest."""

    t_start_s: float
    t_end_s: float
    delay_s: float
    amplitude_m: float
    omega_rad_s: float
    lag_s: float
    harmonics: tuple[tuple[int, float, float], ...] = ()

    def state(self, t: float) -> tuple[float, float]:
        """(x, dx/dt) at a float time t (the ODE's fast path)."""
        s, w, tau = t - self.delay_s, self.omega_rad_s, self.lag_s
        r = w * tau
        g = self.amplitude_m / (1.0 + r * r)
        sn, cs = math.sin(w * s), math.cos(w * s)
        if tau > 0.0:
            e = g * r * math.exp(-s / tau)
            x, v = g * (sn - r * cs) + e, g * w * (cs + r * sn) - e / tau
        else:
            x, v = g * sn, g * w * cs
        for k, h, phi in self.harmonics:
            big_w, a_k = k * w, self.amplitude_m * h
            big_r = big_w * tau
            gk = a_k / (1.0 + big_r * big_r)
            snk, csk = math.sin(big_w * s + phi), math.cos(big_w * s + phi)
            if tau > 0.0:
                ek = (a_k * math.sin(phi) - gk * (math.sin(phi) - big_r * math.cos(phi))) * math.exp(-s / tau)
                x += gk * (snk - big_r * csk) - a_k * math.sin(phi) + ek
                v += gk * big_w * (csk + big_r * snk) - ek / tau
            else:
                x += a_k * (snk - math.sin(phi))
                v += a_k * big_w * csk
        return x, v

    def position(self, t):
        return np.vectorize(lambda x: self.state(x)[0], otypes=[float])(np.asarray(t, dtype=float))

    def velocity(self, t):
        return np.vectorize(lambda x: self.state(x)[1], otypes=[float])(np.asarray(t, dtype=float))

    def turning_times(self) -> list[float]:
        """Where dx/dt changes sign in (t_start, t_end): bracketed on 64 points a period, then brentq."""
        from scipy.optimize import brentq

        n = int(math.ceil((self.t_end_s - self.t_start_s) * self.omega_rad_s / (2.0 * math.pi) * 64)) + 2
        grid = np.linspace(self.t_start_s, self.t_end_s, n)
        v = self.velocity(grid)
        out = []
        for i in np.flatnonzero(v[:-1] * v[1:] < 0.0):
            out.append(brentq(lambda t: self.state(t)[1], grid[i], grid[i + 1], xtol=1e-13, rtol=1e-15))
        return out


def sine_actuator_pieces(case, rig: RigImperfections, t_end_s: float) -> list:
    """At rest at x = 0 until the delayed command starts at d, then one sine piece to ``t_end_s``."""
    d = rig.delay_s
    rest = [ActuatorPiece(0.0, d, 0.0, 0.0, rig.servo_lag_s, 0.0)] if d > 0.0 else []
    return rest + [SineActuatorPiece(min(d, t_end_s), t_end_s, d, case.amplitude_m,
                                     2.0 * math.pi * case.frequency_Hz, rig.servo_lag_s,
                                     case.harmonics)]


def _actuator_turning_times(pieces: Sequence) -> list[float]:
    """Times where the actuator starts to move or reverses (dx/dt changes sign), sorted."""
    out, moving = [], 0.0
    for p in pieces:
        if isinstance(p, SineActuatorPiece):   # the last piece: starts moving upwards, then its reversals
            out += [p.t_start_s, *p.turning_times()]
            break
        v = p.velocity_m_s
        if v == 0.0:
            continue
        v0 = float(p.velocity(p.t_start_s))
        t_turn = p.t_start_s
        if v0 * v < 0.0:   # still coasting the old way (tau_s > 0): dx/dt = v - (K/tau) e^(-s/tau) = 0 at s*
            t_turn = p.t_start_s + p.lag_s * math.log(p.transient_m / (p.lag_s * v))
        if t_turn < p.t_end_s and math.copysign(1.0, v) != moving:
            out.append(t_turn)
            moving = math.copysign(1.0, v)
    return out


@dataclass(frozen=True)
class PistonPiece:
    """One interval of smooth piston motion.

    contact: y = x + offset (the actuator pushes, offset = -/+ b/2); else y = rest_m.
    """

    t_start_s: float
    t_end_s: float
    actuator: ActuatorPiece
    contact: bool
    offset_m: float
    rest_m: float

    def position(self, t):
        if self.contact:
            return self.actuator.position(t) + self.offset_m
        return np.full_like(np.asarray(t, dtype=float), self.rest_m)

    def velocity(self, t):
        if self.contact:
            return self.actuator.velocity(t)
        return np.zeros_like(np.asarray(t, dtype=float))


def _actuator_at(pieces: Sequence[ActuatorPiece], t: float) -> ActuatorPiece:
    for p in pieces:
        if p.t_start_s <= t < p.t_end_s:
            return p
    return pieces[-1]


def _crossing_time(pieces: Sequence[ActuatorPiece], ta: float, tb: float, target: float) -> float | None:
    """First t in [ta, tb] with x(t) = target, x monotone there; None if not reached."""
    for p in pieces:
        a, b = max(ta, p.t_start_s), min(tb, p.t_end_s)
        if b <= a:
            continue
        fa, fb = float(p.position(a)) - target, float(p.position(b)) - target
        if fa == 0.0:
            return a
        if fa * fb <= 0.0:
            if isinstance(p, ActuatorPiece) and p.lag_s == 0.0:
                return min(max(a - fa / p.velocity_m_s, a), b)
            from scipy.optimize import brentq

            return brentq(lambda t, p=p: float(p.position(t)) - target, a, b, xtol=1e-13 * max(1.0, b), rtol=1e-15)
    return None


def piston_pieces(case: RigCase, effects: TrueEffects, rig: RigImperfections) -> list[PistonPiece]:
    """Play operator of total gap b between actuator x and piston y, as smooth pieces.

    Pushing upwards y = x - b/2, downwards y = x + b/2; at every actuator reversal the contact
    is lost and the piston stands still until x has travelled b. The record starts at rest with
    the piston at y = -Y + b/2 (as left by the downward stroke that brought it to -Y), so the
    first upward motion crosses the whole gap too (a sine case likewise from y = b/2, its command starting at 0
    upwards). Pieces break at the delayed command corners,
    actuator reversals and contacts: the piston velocity is smooth inside each piece.
    """
    t_end = float(case.sample_times_s()[-1])
    sine = hasattr(case, "frequency_Hz")
    acts = sine_actuator_pieces(case, rig, t_end) if sine else actuator_pieces(case, rig, t_end)
    b = effects.backlash_m
    turns = [t for t in _actuator_turning_times(acts) if 0.0 <= t < t_end]
    stretch_edges = sorted({0.0, *turns, t_end})
    spans = []                                      # (ta, tb, contact, offset, rest)
    y = case.start_position_m + b / 2.0
    for ta, tb in zip(stretch_edges[:-1], stretch_edges[1:]):
        mid = 0.5 * (ta + tb)
        v_mid = float(_actuator_at(acts, mid).velocity(mid))
        direction = 0.0 if v_mid == 0.0 else math.copysign(1.0, v_mid)
        if direction == 0.0:
            spans.append((ta, tb, b == 0.0, 0.0, y))
            continue
        tc = ta if b == 0.0 else _crossing_time(acts, ta, tb, y + direction * b / 2.0)
        if tc is None:
            tc = tb
        if tc > ta:
            spans.append((ta, tc, False, 0.0, y))
        if tc < tb:
            spans.append((tc, tb, True, -direction * b / 2.0, y))
            y = float(_actuator_at(acts, tb).position(tb)) - direction * b / 2.0
    out = []
    for ta, tb, contact, offset, rest in spans:
        for p in acts:
            a, e = max(ta, p.t_start_s), min(tb, p.t_end_s)
            if e > a:
                out.append(PistonPiece(a, e, p, contact, offset, rest))
    return out
