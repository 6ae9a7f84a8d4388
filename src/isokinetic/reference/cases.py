"""The reference rig's test cases: a triangle (Eq. 26) or a sine command, what the rig records of it (a sibling
of :mod:`isokinetic.reference.rig`, sharing its independence: it imports only the standard library and numpy)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TriangleCase:
    """One triangle test: command c(t) = Y tri(2 pi t / T - pi/2), Y = W T / 4, 2T recorded."""

    case_id: str
    velocity_m_s: float
    period_s: float
    sample_rate_Hz: float = 50.0

    def __post_init__(self):
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_-]*", self.case_id):
            raise ValueError(f"case id {self.case_id!r}: letters, digits, '_' and '-' only")
        for name in ("velocity_m_s", "period_s", "sample_rate_Hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"case {self.case_id}: {name} must be > 0, got {v!r}")

    @property
    def amplitude_m(self) -> float:
        """Y = W T / 4 (Eq. 26)."""
        return self.velocity_m_s * self.period_s / 4.0

    @property
    def stroke_amplitude_m(self) -> float:
        """The largest |c(t)|: Y."""
        return self.amplitude_m

    @property
    def duration_s(self) -> float:
        return 2.0 * self.period_s

    @property
    def peak_speed_m_s(self) -> float:
        """The largest commanded speed |dc/dt|: W."""
        return self.velocity_m_s

    @property
    def start_position_m(self) -> float:
        """c(0) = -Y, where the record starts at rest."""
        return -self.amplitude_m

    def command_m(self, t_s) -> np.ndarray:
        """The ideal (undelayed) command c(t) [m]."""
        return triangle_command(t_s, self.amplitude_m, self.period_s)

    def sample_times_s(self) -> np.ndarray:
        """t = k / fs, k = 0 .. round(2 T fs)."""
        n = int(round(self.duration_s * self.sample_rate_Hz))
        return np.arange(n + 1, dtype=float) / self.sample_rate_Hz


@dataclass(frozen=True)
class SineCase:
    """One sine test: command c(t) = Y sin(2 pi f t) for t >= 0, 0 before; ``n_cycles`` periods recorded.

    ``harmonics``: (k, h, phi) terms that distort the actuator's motion, as a servo's distortion or a crank's
    kinematics do: the actuator moves as if commanded Y [sin(2 pi f t) + sum_k h (sin(2 pi k f t + phi) - sin phi)]
    (each term starts at 0; k >= 2), while the command channel (:meth:`command_m`) and the manifest declare
    the sine (f, Y)."""

    case_id: str
    frequency_Hz: float
    amplitude_m: float
    n_cycles: float = 4.0
    sample_rate_Hz: float = 500.0
    harmonics: tuple[tuple[int, float, float], ...] = ()

    def __post_init__(self):
        if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_-]*", self.case_id):
            raise ValueError(f"case id {self.case_id!r}: letters, digits, '_' and '-' only")
        for name in ("frequency_Hz", "amplitude_m", "n_cycles", "sample_rate_Hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"case {self.case_id}: {name} must be > 0, got {v!r}")
        for k, h, phi in self.harmonics:
            if not (int(k) == k and k >= 2 and math.isfinite(h) and math.isfinite(phi)):
                raise ValueError(f"case {self.case_id}: a harmonic needs an integer k >= 2 and finite h, phi, "
                                 f"got {(k, h, phi)!r}")

    @property
    def stroke_amplitude_m(self) -> float:
        """A bound on |c(t)|: Y (1 + sum 2|h|)."""
        return self.amplitude_m * (1.0 + sum(2.0 * abs(h) for _k, h, _phi in self.harmonics))

    @property
    def duration_s(self) -> float:
        return self.n_cycles / self.frequency_Hz

    @property
    def peak_speed_m_s(self) -> float:
        """The largest commanded speed: 2 pi f Y."""
        return 2.0 * math.pi * self.frequency_Hz * self.amplitude_m

    @property
    def start_position_m(self) -> float:
        """c(0) = 0, where the record starts at rest."""
        return 0.0

    def command_m(self, t_s) -> np.ndarray:
        """The ideal (undelayed) command c(t) [m]."""
        return sine_command(t_s, self.amplitude_m, self.frequency_Hz)

    def sample_times_s(self) -> np.ndarray:
        """t = k / fs, k = 0 .. round(n_cycles fs / f)."""
        n = int(round(self.duration_s * self.sample_rate_Hz))
        return np.arange(n + 1, dtype=float) / self.sample_rate_Hz



def triangle_command(t_s, amplitude_m: float, period_s: float) -> np.ndarray:
    """c(t) = Y tri(2 pi t / T - pi/2) for t >= 0 and -Y before (Eq. 26 with phi = -pi/2) [m].

    Written with the fractional phase, not arcsin(sin(.)), so that corners are exact.
    """
    t = np.asarray(t_s, dtype=float)
    s = np.mod(t / period_s, 1.0)                        # phase in periods, 0 at -Y
    c = amplitude_m * np.where(s < 0.5, 4.0 * s - 1.0, 3.0 - 4.0 * s)
    return np.where(t < 0.0, -amplitude_m, c)


#: A case the rig can run.
RigCase = TriangleCase | SineCase


def sine_command(t_s, amplitude_m: float, frequency_Hz: float) -> np.ndarray:
    """c(t) = Y sin(2 pi f t) for t >= 0 and 0 before [m]."""
    t = np.asarray(t_s, dtype=float)
    return np.where(t < 0.0, 0.0, amplitude_m * np.sin(2.0 * math.pi * frequency_Hz * t))
