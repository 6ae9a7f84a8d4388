"""Virtual test rig: simulated triangle and sine campaigns of a compressible two-chamber damper.

Equation numbers refer to the reference paper (shared/reference/000_003c8e4a5d3ba538.txt).

Physics (noise free)
    Single state Δp = p1 - p2 (Eq. 1/2): β_eff 𝒱(y) dΔp/dt + Q_N(Δp) = A_p dy/dt, with the chamber
    volumes V1 = V0,1 - A_p y, V2 = V0,2 + A_p y following the *piston* position y (Eq. 2), β_eff
    from Eq. (3) with entrained air, and Q_N the orifice of Eq. (7) (laminar c1, turbulent c2 with the
    asymmetric C_D(1 ± a) chosen by the sign of Δp) in parallel with a laminar leakage Q_L = g Δp.
    The force is Eq. (8) with a massless piston: F = A_p Δp + F_f(dy/dt) (Coulomb + Stribeck).
    y = 0 is the position where the chamber volumes are V0,1 and V0,2 (the centre of the stroke).

Backlash (rigid servo)
    ``Effects.backlash_m`` = b is a play operator between the actuator x (which follows the command
    exactly when ``Measurement.servo_stiffness_N_m`` is inf, the default; the LVDT measures x) and
    the piston y: y stays in [x - b/2, x + b/2] and only moves when the actuator pushes it at one
    edge of the gap. While the gap is crossed the piston stands still (W = 0) and Δp relaxes
    through the flow paths; the load cell is assumed to keep reading A_p Δp (friction is
    sign(0) = 0 there), i.e. the piston is held by its seals, not floating.
    At the start of a record the piston sits at the far side of the gap (as after a reversal), so
    the first motion also crosses the whole gap. Records start from rest with Δp(0) = 0.

Triangle excitation: quadrature, not a time stepper
    Within a segment of constant piston velocity W (W = 0 while crossing the gap) Eq. (13)
    separates: dΔp/dτ = A_p W - Q_N(Δp) with τ(t) = ∫ dt / (β_eff 𝒱(y(t))) in closed form
    (Eq. 14, written with log1p; Δt / (β_eff 𝒱) when W = 0). The autonomous problem is integrated
    once per segment in the *orifice flow* q (Δp = c1 q + c2 q|q| is polynomial in q, whereas q(Δp)
    has a square-root branch point at Δp = -c1²/4c2 right next to 0) with the log variable
    u = ln|q* - q| (q* the steady root), which turns the logarithmic singularity of τ at q* into a
    smooth, asymptotically linear integrand. Gauss-Legendre panels give τ at nodes in u (nodes
    graded towards q = 0, where c2 switches and the flow regime changes within |q| ~ c1/2c2), and
    Δp(τ) is evaluated for all samples at once by quintic Hermite interpolation with the exact
    derivatives dΔp/dτ = A_p W - Q_N and d²Δp/dτ². Beyond the last node (|q - q*| < 1e-17 of the
    scale) Δp = Δp* exactly. Segments are chained with Δp continuous; the tables of all segments
    of all cases are built in one vectorised pass (:func:`triangle_responses`). Max error ~4e-11 of
    the force scale against a DOP853 rtol 1e-13 solution (benchmark/virtual_rig_throughput.py).

Sine excitation
    Stiff integration with ``scipy.integrate.solve_ivp`` (LSODA, analytic Jacobian, rtol 1e-12:
    ~2e-10 relative to a Radau rtol 1e-13 solution, an order of magnitude faster than Radau at
    equal accuracy), split at every velocity discontinuity (turning points, gap contacts), t_eval
    at the samples.

Finite servo stiffness (``Measurement.servo_stiffness_N_m`` = k < inf): :func:`servo_response`
    The rig is in displacement control with a servo of finite stiffness: x = command - F/k, F the
    force transmitted by the attachment (read by the load cell), the LVDT on x. The coupled
    actuator-gap-damper system is integrated as a hybrid ODE (LSODA, rtol 1e-10, event-located
    mode switches): in contact the massless piston follows the actuator (sliding) or is held by
    Coulomb seal friction (sticking); while the gap is crossed F = 0, so x = command. In sliding
    contact dΔp/dt = (A_p dc/dt - Q_N) / (β_eff 𝒱 + A_p²/k): the servo compliance adds to the
    effective compressibility like the fixture term of Eq. (3). Under load the actuator lags; when
    the load vanishes at a force zero crossing it crosses the gap at the command velocity, which
    the LVDT shows as a velocity spike (paper Sec. 4.5, Fig. 13). Both waveforms; Coulomb friction
    only (Stribeck refused). With k = inf the fast paths above are used unchanged (byte-identical
    exports); note that the rigid play model keeps the piston still from the reversal on and lets
    the load cell read A_p Δp during the gap, whereas the servo model keeps contact while the load
    is positive and reads F = 0 in the gap, so k -> inf with b > 0 does not reproduce it exactly.

Measurement
    Seeded Gaussian noise, independent per case (``SeedSequence([seed, crc32(case)])``): LVDT noise
    on the actuator position (the command for a rigid servo), additive plus |F|-proportional noise
    on the force (Fig. 12). Every channel is then quantised to a stated resolution (ADC step), so
    the exported CSV prints exact decimals and reading it back reproduces the simulated series to
    float rounding.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import re
import shutil
import tempfile
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from scipy.integrate import solve_ivp

from . import tables
from .campaign import CAMPAIGN_KEYS, timeseries_relpath, write_ingested
from .damper import (NOMINAL, Damper, Effects, effective_compressibility, friction_force,
                     laminar_coefficient, turbulent_coefficient)
from .plan import CasePlan, paper_plan, sine_displacement, triangle_displacement

#: Campaign names allowed by the raw-campaign spec.
CAMPAIGN_NAME = re.compile(r"[a-z0-9][a-z0-9_-]*\Z")

#: CSV columns of an exported case: (column name, unit, SI per unit).
RAW_COLUMNS = {
    "time": ("time_s", "s", 1.0),
    "displacement": ("disp_mm", "mm", 1.0e-3),
    "force": ("force_kN", "kN", 1.0e3),
    "command": ("cmd_mm", "mm", 1.0e-3),
}


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

def _number(value, key: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    """A finite float from config, else ValueError naming ``key``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{key}: must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{key}: must be > 0, got {value!r}")
    if nonnegative and value < 0:
        raise ValueError(f"{key}: must be >= 0, got {value!r}")
    return float(value)


def _mapping(value, key: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(value).__name__}")
    return value


def _check_keys(values: Mapping, allowed: Iterable[str], required: Iterable[str], where: str) -> None:
    allowed = set(allowed)
    for key in values:
        if key not in allowed:
            raise KeyError(f"{where}: unknown key {key!r}; allowed: {sorted(allowed)}")
    for key in required:
        if key not in values:
            raise KeyError(f"{where}: missing key {key!r}")


def _stiffness(value, key: str) -> float:
    """A servo stiffness from config: a number > 0, inf allowed (a rigid servo)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value) or value <= 0:
        raise ValueError(f"{key}: must be a number > 0 (inf: rigid servo), got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Measurement:
    """Sensor and servo model of the rig (1σ noise levels, ADC resolutions, servo stiffness, SI).

    Resolutions quantise the *measured* channels (and the command) to integer multiples of the
    step; 0 disables quantisation. A resolution must be a short decimal in the export unit
    (e.g. 0.1 N = 1e-4 kN) so that the CSV prints it exactly.

    ``servo_stiffness_N_m`` k: the displacement-controlled actuator lags its command under load,
    x = command - F/k, and the LVDT measures x (:func:`servo_response`). inf (the default) is a
    rigid servo: x = command exactly, the fast paths of :func:`true_responses`.
    """

    force_noise_N: float = 0.0
    force_noise_rel: float = 0.0
    displacement_noise_m: float = 0.0
    force_resolution_N: float = 0.1
    displacement_resolution_m: float = 1.0e-7
    command_resolution_m: float = 1.0e-9
    servo_stiffness_N_m: float = math.inf

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if f.name == "servo_stiffness_N_m":
                _stiffness(self.servo_stiffness_N_m, f"measurement.{f.name}")
            else:
                _number(getattr(self, f.name), f"measurement.{f.name}", nonnegative=True)

    @classmethod
    def ideal(cls) -> "Measurement":
        """Noise free and unquantised (for physics checks)."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_config(cls, values: Mapping | None, where: str = "measurement") -> "Measurement":
        """Build from the config block; unknown keys raise KeyError naming the key."""
        values = _mapping(values or {}, where)
        names = [f.name for f in dataclasses.fields(cls)]
        _check_keys(values, names, (), where)
        return cls(**{k: (_stiffness(v, f"{where}.{k}") if k == "servo_stiffness_N_m"
                          else _number(v, f"{where}.{k}", nonnegative=True)) for k, v in values.items()})


@dataclass(frozen=True)
class VirtualCampaign:
    """One simulated campaign: nominal damper, hidden truth effects, sensors and test plan."""

    name: str
    description: str
    seed: int
    temperature_C: float
    damper: Damper
    effects: Effects
    measurement: Measurement
    cases: tuple[CasePlan, ...]

    def case(self, case_id: str) -> CasePlan:
        for c in self.cases:
            if c.case == case_id:
                return c
        raise KeyError(f"campaign {self.name}: unknown case {case_id!r}; known: {[c.case for c in self.cases]}")

    @classmethod
    def from_config(cls, name: str, mapping: Mapping) -> "VirtualCampaign":
        """Parse one entry of ``virtual_campaigns`` (config/config.yaml); mm -> m here.

        Errors (KeyError / ValueError) name the offending key as ``virtual_campaigns.<name>.<key>``.
        """
        where = f"virtual_campaigns.{name}"
        if not isinstance(name, str) or not CAMPAIGN_NAME.match(name):
            raise ValueError(f"{where}: campaign name must match [a-z0-9][a-z0-9_-]*")
        mapping = _mapping(mapping, where)
        _check_keys(mapping, ("description", "seed", "temperature_C", "damper", "effects", "measurement", "plan"),
                    ("seed", "temperature_C", "damper", "plan"), where)
        seed = mapping["seed"]
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"{where}.seed: must be a non-negative integer, got {seed!r}")
        description = mapping.get("description", "") or ""
        if not isinstance(description, str):
            raise ValueError(f"{where}.description: must be a string")
        try:
            damper = Damper.from_mapping(_mapping(mapping["damper"], f"{where}.damper"))
        except (KeyError, ValueError) as exc:
            raise type(exc)(f"{where}.{exc.args[0]}") from exc
        extra = set(_mapping(mapping["damper"], f"{where}.damper")) - {f.name for f in dataclasses.fields(Damper)}
        if extra:
            raise KeyError(f"{where}.damper: unknown key {sorted(extra)[0]!r}")
        groups = _mapping(mapping.get("effects") or {}, f"{where}.effects")
        for group, values in groups.items():
            for key, value in _mapping(values or {}, f"{where}.effects.{group}").items():
                _number(value, f"{where}.effects.{group}.{key}")
        try:
            effects = Effects.from_config(groups)
        except KeyError as exc:
            raise KeyError(f"{where}.{exc.args[0]}") from exc
        measurement = Measurement.from_config(mapping.get("measurement"), f"{where}.measurement")
        cases = _plan_from_config(_mapping(mapping["plan"], f"{where}.plan"), f"{where}.plan")
        return cls(name=name, description=description.strip(), seed=seed,
                   temperature_C=_number(mapping["temperature_C"], f"{where}.temperature_C"),
                   damper=damper, effects=effects, measurement=measurement, cases=tuple(cases))


def _number_list(values, key: str) -> list[float]:
    if not isinstance(values, (list, tuple)) or not values:
        raise ValueError(f"{key}: must be a non-empty list")
    return [_number(v, f"{key}[{i}]", positive=True) for i, v in enumerate(values)]


def _plan_from_config(plan: Mapping, where: str) -> list[CasePlan]:
    """Cases of a ``plan`` block via :func:`plan.paper_plan` (mm -> m)."""
    _check_keys(plan, ("triangle", "sine"), (), where)
    if not plan:
        raise KeyError(f"{where}: needs a 'triangle' and/or a 'sine' block")
    velocities, periods, tri_rate, phase, acq = [], [], 1.0, -math.pi / 2, 2.0
    if "triangle" in plan:
        w = f"{where}.triangle"
        tri = _mapping(plan["triangle"], w)
        _check_keys(tri, ("velocities_mm_s", "periods_s", "phase_rad", "acquisition_periods", "sample_rate_Hz"),
                    ("velocities_mm_s", "periods_s", "sample_rate_Hz"), w)
        velocities = [v * 1e-3 for v in _number_list(tri["velocities_mm_s"], f"{w}.velocities_mm_s")]
        periods = _number_list(tri["periods_s"], f"{w}.periods_s")
        if len(periods) != len(velocities):
            raise ValueError(f"{w}.periods_s: {len(periods)} periods for {len(velocities)} velocities")
        tri_rate = _number(tri["sample_rate_Hz"], f"{w}.sample_rate_Hz", positive=True)
        phase = _number(tri.get("phase_rad", phase), f"{w}.phase_rad")
        acq = _number(tri.get("acquisition_periods", acq), f"{w}.acquisition_periods", positive=True)
    amplitudes, freq, sine_rate, sine_periods = [], 1.0, 1.0, 1.0
    if "sine" in plan:
        w = f"{where}.sine"
        sine = _mapping(plan["sine"], w)
        _check_keys(sine, ("frequency_Hz", "amplitudes_mm", "periods", "sample_rate_Hz"),
                    ("frequency_Hz", "amplitudes_mm", "periods", "sample_rate_Hz"), w)
        amplitudes = [a * 1e-3 for a in _number_list(sine["amplitudes_mm"], f"{w}.amplitudes_mm")]
        freq = _number(sine["frequency_Hz"], f"{w}.frequency_Hz", positive=True)
        sine_rate = _number(sine["sample_rate_Hz"], f"{w}.sample_rate_Hz", positive=True)
        sine_periods = _number(sine["periods"], f"{w}.periods", positive=True)
    return paper_plan(velocities, periods, amplitudes, freq, tri_rate, sine_rate, sine_periods,
                      phase_rad=phase, acquisition_periods=acq)


# --------------------------------------------------------------------------------------------
# Hydraulics (noise free)
# --------------------------------------------------------------------------------------------

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
    def from_damper(cls, damper: Damper, effects: Effects = NOMINAL) -> "Hydraulics":
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
        return math.copysign(2.0 * a / (c1 + math.sqrt(c1 * c1 + 4.0 * c2 * a)), dp_Pa) + self.leakage_conductance_m3_s_Pa * dp_Pa

    def flow_derivative(self, dp_Pa: float) -> float:
        """Scalar dQ_N/dΔp = 1/sqrt(c1² + 4 c2|Δp|) + g, for ODE Jacobians [m³/(s Pa)]."""
        root = math.sqrt(self.laminar_coefficient**2 + 4.0 * self.c2(float(dp_Pa)) * abs(dp_Pa))
        return (1.0 / root if root > 0 else 1e300) + self.leakage_conductance_m3_s_Pa


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
    def from_nodes(cls, tau, delta, slope, curvature, steady_Pa: float) -> "Relaxation":
        """Panel polynomials from node values δ, dδ/dτ and d²δ/dτ² (inf: unknown)."""
        tau = np.asarray(tau, dtype=float)
        coef = _panel_coefficients(np.diff(tau), delta[:-1], delta[1:], slope[:-1], slope[1:],
                                   curvature[:-1], curvature[1:])
        return cls(tau, coef, float(steady_Pa))

    @classmethod
    def constant(cls, dp_Pa: float) -> "Relaxation":
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
    c1, g = hyd.laminar_coefficient, hyd.leakage_conductance_m3_s_Pa
    c2p, c2n = hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg
    c2_max = max(c2p, c2n)
    out: list[Relaxation | None] = []
    params, node_sets = [], []
    for dp0, qp in zip(dp0_Pa, piston_flows_m3_s, strict=True):
        qp, dp0 = float(qp), float(dp0)
        q_star = steady_orifice_flow(qp, hyd)
        p_star = float(orifice_pressure_of_flow(q_star, hyd))
        q0 = float(orifice_flow_of_pressure(dp0, hyd))
        dist = abs(q_star - q0)
        if dist == 0.0 or not math.isfinite(dist):
            out.append(Relaxation.constant(dp0))
            continue
        s = math.copysign(1.0, q_star - q0)
        scale = max(abs(q_star), dist) if q_star * q0 >= 0 else abs(q_star)
        u0 = math.log(dist)
        special = []
        if q0 == 0.0:
            special.append(u0)
        elif q_star != 0.0 and q0 * q_star < 0.0:
            special.append(math.log(abs(q_star)))
        width = c1 / (2.0 * c2_max * abs(q_star)) if (c2_max > 0 and q_star != 0) else math.inf
        node_sets.append(_nodes(u0, math.log(max(abs(q_star), dist) * 1e-17), math.log(scale), step, special,
                                max(1e-12, 1e-2 * width)))
        params.append((q_star, s, qp, p_star, dp0))
        out.append(None)
    if not node_sets:
        return out

    # all nodes of all problems, each problem descending in u; panels join consecutive nodes
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
    q_star, s, qp, p_star, dp0 = np.array(params)[pp].T

    e = np.exp(uu)
    q = q_star - s * e
    aq = np.abs(q)
    aqs = np.abs(q_star)
    c2 = np.where(q >= 0, c2p, c2n)
    dpdq = c1 + 2.0 * c2 * aq                       # dΔp/dq, Eq. (7)
    same = (q * q_star > 0.0) | ((q_star == 0.0) & (q != 0.0))
    # same side as q*: A_pW - Q_N = (q* - q)(1 + g c1 + g c2 (|q*| + |q|)), exactly
    k_same = 1.0 + g * c1 + g * c2 * (aqs + aq)
    dtau = dpdq / k_same                            # dτ/du magnitude (τ grows as u falls)
    f = s * e * k_same                              # dΔp/dτ = A_p W - Q_N
    delta = -s * e * (c1 + c2 * (aq + aqs))         # Δp - Δp*
    if not same.all():
        o = ~same
        f[o] = qp[o] - q[o] - g * (c1 * q[o] + c2[o] * q[o] * aq[o])
        dtau[o] = dpdq[o] * e[o] / np.abs(f[o])
        delta[o] = c1 * q[o] + c2[o] * q[o] * aq[o] - p_star[o]
    # τ at the nodes: cumulative panel integrals summed within each problem alone (one row per
    # problem). A running sum over the whole batch, less its value at the problem's first node,
    # would carry the rounding of the earlier problems' τ (often far larger) into this one's.
    z = np.zeros(n)
    z[hi + 1] = half * (dtau[n:].reshape(pts.shape) @ _GL_W)
    col = np.arange(n) - np.repeat(first, sizes)
    rows = np.zeros((sizes.size, int(sizes.max())))
    rows[prob, col] = z
    tau = np.cumsum(rows, axis=1)[prob, col]
    with np.errstate(divide="ignore", invalid="ignore"):
        # d²Δp/dτ² = f'(q) dq/dτ = -(1 + g dΔp/dq) f / (dΔp/dq); infinite where dΔp/dq = 0
        curv = np.where(dpdq[:n] > 0, -(1.0 + g * dpdq[:n]) * f[:n] / dpdq[:n], np.inf)
    delta = delta[:n]
    delta[first] = dp0[first] - p_star[first]       # exact start: Δp continuous across segments
    coef = _panel_coefficients(tau[hi + 1] - tau[hi], delta[hi], delta[hi + 1], f[hi], f[hi + 1],
                               curv[hi], curv[hi + 1])
    taus = np.split(tau, first[1:])
    coefs = np.split(coef, (first - np.arange(sizes.size))[1:])
    it = iter(zip(taus, coefs, params))
    return [r if r is not None else (lambda t, c, p: Relaxation(t, c, float(p[3])))(*next(it)) for r in out]


# --------------------------------------------------------------------------------------------
# Excitation and the play operator
# --------------------------------------------------------------------------------------------

def sample_times(case: CasePlan) -> np.ndarray:
    """t = k / fs for k = 0..round(duration fs), the endpoint included [s]."""
    n = int(round(case.duration_s * case.sample_rate_Hz))
    return np.arange(n + 1, dtype=float) / case.sample_rate_Hz


def record_end(case: CasePlan) -> float:
    """End of the simulated interval: the duration, or the last sample if rounding puts it later."""
    return max(case.duration_s, round(case.duration_s * case.sample_rate_Hz) / case.sample_rate_Hz)


def command_displacement(case: CasePlan, t_s) -> np.ndarray:
    """Ideal actuator command of the case: Eq. (26) triangle or Y sin(2πft) [m]."""
    if case.waveform == "triangle":
        return triangle_displacement(t_s, case.amplitude_m, case.period_s, case.phase_rad)
    if case.waveform == "sine":
        return sine_displacement(t_s, case.amplitude_m, case.frequency_Hz)
    raise ValueError(f"case {case.case}: the virtual rig cannot simulate waveform {case.waveform!r}")


def _snap(t: float, case: CasePlan) -> float:
    """A breakpoint within 1e-9 of the record length of a sample time is put on it."""
    k = round(t * case.sample_rate_Hz)
    ts = k / case.sample_rate_Hz
    return ts if abs(ts - t) <= 1e-9 * record_end(case) else t


def _turning_times(case: CasePlan) -> list[float]:
    """Actuator turning points in (0, record end): argument π/2 + kπ (triangle or sine)."""
    if case.waveform == "triangle":
        omega, phase = 2.0 * math.pi / case.period_s, case.phase_rad
    else:
        omega, phase = 2.0 * math.pi * case.frequency_Hz, 0.0
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
    edges = [0.0, *_turning_times(case), record_end(case)]
    omega = 2.0 * math.pi * (case.frequency_Hz if case.waveform == "sine" else 1.0 / case.period_s)
    phase = 0.0 if case.waveform == "sine" else case.phase_rad
    x = lambda t: float(command_displacement(case, t))  # noqa: E731
    segs: list[Segment] = []
    y = None
    for ta, tb in zip(edges[:-1], edges[1:]):
        d = 1.0 if math.cos(omega * 0.5 * (ta + tb) + phase) > 0 else -1.0
        xa = x(ta)
        if y is None:
            y = xa + d * b / 2.0
        x_contact = y + d * b / 2.0                   # actuator position that touches the piston
        if b == 0.0 or d * (x_contact - xa) <= 0.0:
            tc = ta
        elif d * (x(tb) - x_contact) <= 0.0:
            tc = tb
        else:
            tc = _contact_time(case, ta, tb, x_contact, d, omega, phase)
        if tc > ta:
            segs.append(Segment(ta, tc, False, y, 0.0, d))
        if tc < tb:
            segs.append(Segment(tc, tb, True, x(tc) - d * b / 2.0, -d * b / 2.0, d))
            y = x(tb) - d * b / 2.0
    return segs


def _contact_time(case: CasePlan, ta: float, tb: float, x_c: float, d: float, omega: float, phase: float) -> float:
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


def _check_stroke(case: CasePlan, hyd: Hydraulics) -> None:
    """The piston (|y| <= Y) must not empty a chamber (Eq. 12: T_max < T_lim)."""
    limit = min(hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3) / hyd.piston_area_m2
    if not case.amplitude_m < limit:
        raise ValueError(f"case {case.case}: amplitude {case.amplitude_m:g} m reaches the end of the "
                         f"cylinder (V0/A_p = {limit:g} m)")


def _segment_index(t: np.ndarray, segs: Sequence[Segment]) -> list[slice]:
    """Sample indices of each segment: [t_start, t_end), the last one closed."""
    starts = np.array([s.t_start_s for s in segs])
    i0 = np.searchsorted(t, starts, side="left")
    i1 = np.append(i0[1:], t.size)
    return [slice(int(a), int(b)) for a, b in zip(i0, i1)]


# --------------------------------------------------------------------------------------------
# Noise-free responses
# --------------------------------------------------------------------------------------------

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
    edges = [0.0, *_turning_times(case), max(record_end(case), float(drive_times(case, drive)[-1]))]
    omega, phase = 2.0 * math.pi / case.period_s, case.phase_rad
    y = float(command_displacement(case, 0.0))
    segs = []
    for j, (ta, tb) in enumerate(zip(edges[:-1], edges[1:])):
        d = 1.0 if math.cos(omega * 0.5 * (ta + tb) + phase) > 0 else -1.0
        segs.append(Segment(ta, tb, True, y, 0.0, d))
        y += d * drive.speed(j) * (tb - ta)
    return segs


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
    a = hyd.piston_area_m2
    drives = [None] * len(cases) if drives is None else list(drives)
    if len(drives) != len(cases):
        raise ValueError(f"{len(drives)} drives for {len(cases)} cases")
    plans = []
    for case, drive in zip(cases, drives):
        if case.waveform != "triangle":
            raise ValueError(f"case {case.case}: not a triangle")
        if drive is None:
            _check_stroke(case, hyd)
            w = 4.0 * case.amplitude_m / case.period_s
            segs = piston_segments(case, backlash_m)
            flows = [a * seg.direction * w if seg.contact else 0.0 for seg in segs]
        else:
            if backlash_m:
                raise ValueError(f"case {case.case}: a measured drive has no backlash model")
            segs = driven_segments(case, drive)
            flows = [a * seg.direction * drive.speed(j) for j, seg in enumerate(segs)]
            _check_positions(case, segs, flows, hyd)
        plans.append((case, drive, segs, flows))
    guesses = {}
    for _, _, segs, flows in plans:
        prev = 0.0
        for qp in flows:
            guesses.setdefault((prev, qp), None)
            prev = steady_pressure(qp, hyd)
    keys = list(guesses)
    tables_ = dict(zip(keys, relaxations([k[0] for k in keys], [k[1] for k in keys], hyd, step)))
    out = []
    for case, drive, segs, flows in plans:
        t = drive_times(case, drive)
        dp = np.empty(t.size)
        vel = np.zeros(t.size)
        p = 0.0
        for seg, idx, qp in zip(segs, _segment_index(t, segs), flows):
            key = (p, qp)
            if key not in tables_:
                tables_[key] = relaxation(p, qp, hyd, step)
            v = qp / a
            dt = np.append(t[idx], seg.t_end_s) - seg.t_start_s
            values = tables_[key].pressure(compressibility_time(dt, seg.piston_start_m, v, hyd))
            dp[idx] = values[:-1]
            vel[idx] = v
            p = float(values[-1])
        out.append((t, dp, vel))
    return out


def _check_positions(case: CasePlan, segs: Sequence[Segment], flows: Sequence[float], hyd: Hydraulics) -> None:
    """A driven piston must not empty a chamber anywhere on its path (Eq. 12)."""
    limit = min(hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3) / hyd.piston_area_m2
    for seg, qp in zip(segs, flows):
        end = seg.piston_start_m + qp / hyd.piston_area_m2 * (seg.t_end_s - seg.t_start_s)
        if max(abs(seg.piston_start_m), abs(end)) >= limit:
            raise ValueError(f"case {case.case}: the measured motion reaches the end of the cylinder "
                             f"(V0/A_p = {limit:g} m)")


def sine_response(case: CasePlan, hyd: Hydraulics, backlash_m: float = 0.0, rtol: float = 1e-12,
                  method: str = "LSODA"):
    """Δp and piston velocity of a sine case by stiff integration of Eq. (1) (solve_ivp).

    Split at turning points and gap contacts; atol = rtol × the steady Δp at peak velocity.
    Returns (t_s, dp_Pa, piston_velocity_m_s); Δp(0) = 0.
    """
    if case.waveform != "sine":
        raise ValueError(f"case {case.case}: not a sine")
    _check_stroke(case, hyd)
    t = sample_times(case)
    omega = 2.0 * math.pi * case.frequency_Hz
    amp = case.amplitude_m
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    v01, v02 = hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3
    atol = rtol * max(abs(steady_pressure(a * amp * omega, hyd)), abs(steady_pressure(-a * amp * omega, hyd)), 1.0)

    q_n, dq_n = hyd.flow, hyd.flow_derivative
    segs = piston_segments(case, backlash_m)
    dp = np.empty(t.size)
    vel = np.zeros(t.size)
    p = 0.0
    for seg, idx in zip(segs, _segment_index(t, segs)):
        if seg.contact:
            off = seg.offset_m

            def kin(tt, off=off):
                y = amp * math.sin(omega * tt) + off
                return a * amp * omega * math.cos(omega * tt), (v01 - a * y) * (v02 + a * y) / (v01 + v02)
        else:
            y0 = seg.piston_start_m
            vol0 = (v01 - a * y0) * (v02 + a * y0) / (v01 + v02)

            def kin(tt, vol0=vol0):
                return 0.0, vol0

        def rhs(tt, z, kin=kin):
            qp, vol = kin(tt)
            return [(qp - q_n(z[0])) / (beta * vol)]

        def jac(tt, z, kin=kin):
            return [[-dq_n(z[0]) / (beta * kin(tt)[1])]]

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


# --------------------------------------------------------------------------------------------
# Finite servo stiffness: the coupled actuator - gap - damper system
# --------------------------------------------------------------------------------------------

_GAP, _STICK, _SLIDE = "gap", "stick", "slide"


@dataclass(frozen=True)
class _Mode:
    """State of the attachment in :func:`servo_response`.

    ``side`` s is the contact side: +1 the actuator pushes the piston up (y = x - b/2, F >= 0),
    -1 down (y = x + b/2, F <= 0), 0 bilateral (no gap, b = 0). ``sense`` σ is the sliding
    direction of the piston (SLIDE), ``piston_m`` its position while it stands (GAP, STICK).
    """

    kind: str
    side: float = 0.0
    sense: float = 1.0
    piston_m: float = 0.0


def servo_response(case: CasePlan, hyd: Hydraulics, effects: Effects = NOMINAL,
                   servo_stiffness_N_m: float = math.inf, rtol: float = 1e-10, method: str = "LSODA"):
    """Triangle or sine case with a servo of finite stiffness k, backlash b and Coulomb friction.

    The rig is in displacement control; the actuator x lags its command c under load,
    x = c - F/k (massless, quasi-static servo), and the LVDT measures x. F is the force
    transmitted by the attachment (what the load cell reads). The piston y is massless; the seal
    friction is Coulomb, static = kinetic = F_C (Stribeck terms are refused). Per mode:

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

    Transitions are located as events (solve_ivp, terminal, directional): SLIDE -> STICK when ẏ
    reaches 0; STICK -> SLIDE when the friction demand reaches ±F_C; contact -> GAP when the
    transmitted force falls to zero (s·F = 0); GAP -> contact (STICK, or SLIDE without friction)
    when the actuator closes the gap. At every event and turning point the mode is made
    consistent with the state (contact and friction complementarity, judged on the trend). The
    piston starts at the far side of the gap with Δp = 0, as in :func:`piston_segments`.

    Backlash spikes: in contact near F = 0, ẋ = (1 - κ) ċ + κ Q_N/A_p with κ = k_h/(k + k_h) and
    k_h = A_p²/(β_eff 𝒱) the hydraulic stiffness (and ẋ = 0 while the piston sticks); once the
    load vanishes the actuator catches up with its command and crosses the gap at ċ. The LVDT
    velocity therefore jumps up for b/|ċ| at each force zero crossing. With k = inf there is no
    lag and no spike (use :func:`sine_response` / :func:`triangle_responses` then).

    Returns (t_s, dp_Pa, piston_velocity_m_s, force_N, actuator_m, piston_m).
    """
    k = float(servo_stiffness_N_m)
    if not (k > 0 and math.isfinite(k)):
        raise ValueError(f"servo_stiffness_N_m must be finite and > 0 here, got {servo_stiffness_N_m!r}")
    if case.waveform not in ("triangle", "sine"):
        raise ValueError(f"case {case.case}: the virtual rig cannot simulate waveform {case.waveform!r}")
    if effects.stribeck_force_N:
        raise ValueError(f"case {case.case}: a finite servo stiffness supports Coulomb friction only "
                         "(stribeck_force_N must be 0)")
    _check_stroke(case, hyd)
    b, fc = float(effects.backlash_m), float(effects.coulomb_force_N)
    if b < 0:
        raise ValueError("backlash_m must be >= 0")
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    v01, v02 = hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3
    cs = a * a / k                                   # servo compliance as a volume compliance [m³/Pa]
    amp = case.amplitude_m
    tri = case.waveform == "triangle"
    if tri:
        omega, phase, speed = 2.0 * math.pi / case.period_s, case.phase_rad, 4.0 * amp / case.period_s
    else:
        omega, phase, speed = 2.0 * math.pi * case.frequency_Hz, 0.0, amp * 2.0 * math.pi * case.frequency_Hz
    q_n, dq_n = hyd.flow, hyd.flow_derivative
    pscale = max(abs(steady_pressure(a * speed, hyd)), abs(steady_pressure(-a * speed, hyd)), fc / a, 1.0)
    atol = rtol * pscale
    tol_f = 1e-9 * (a * pscale + fc)
    tol_x = 1e-12 * max(amp, b, 1e-9)
    probe = 1e-7 / omega       # trends at a transition are judged this much later (events are exact to ~1e-15)

    def cmd(tt: float) -> float:
        if tri:
            return amp * (2.0 / math.pi) * math.asin(max(-1.0, min(1.0, math.sin(omega * tt + phase))))
        return amp * math.sin(omega * tt)

    def rate(tt: float, d: float) -> float:
        return d * speed if tri else speed * math.cos(omega * tt)

    def rates(ts: np.ndarray, d: float) -> np.ndarray:
        return np.full(ts.shape, d * speed) if tri else speed * np.cos(omega * ts)

    def vol(y):
        return (v01 - a * y) * (v02 + a * y) / (v01 + v02)

    def slide_state(tt: float, p: float, m: _Mode, r: float):
        f = a * p + m.sense * fc
        y = cmd(tt) - f / k - m.side * b / 2.0
        dp = (a * r - q_n(p)) / (beta * vol(y) + cs)
        return f, y, dp, r - a * dp / k

    def contact(side: float, y: float) -> _Mode:
        return _Mode(_STICK, side, 1.0, y) if fc > 0 else _Mode(_SLIDE, side, side or 1.0)

    def gap(y: float, p: float) -> tuple[_Mode, float]:
        return _Mode(_GAP, 0.0, 1.0, y), min(max(p, -fc / a), fc / a)

    def settle(m: _Mode, tt: float, p: float, d: float) -> tuple[_Mode, float]:
        """The mode consistent with the state at tt (complementarity of contact and friction).

        Values are judged at tt, the sign of a quantity that sits at its threshold (a force at 0 or
        ±F_C, a piston velocity at 0) a short ``probe`` later, so that an event located a rounding
        error before the true crossing does not flip the mode back.
        """
        for _ in range(8):
            r, c = rate(tt, d), cmd(tt)
            r_probe = rate(tt + probe, d)
            if m.kind == _GAP:
                if c - (m.piston_m + b / 2.0) >= -tol_x and r > 0:
                    m = contact(1.0, m.piston_m)
                elif c - (m.piston_m - b / 2.0) <= tol_x and r < 0:
                    m = contact(-1.0, m.piston_m)
                else:
                    return m, p
            elif m.kind == _STICK:
                f = k * (c - (m.piston_m + m.side * b / 2.0))
                if b > 0 and (m.side * f < -tol_f or (abs(f) <= tol_f and m.side * r < 0)):
                    m, p = gap(m.piston_m, p)
                    continue
                demand = f - a * p
                rate_demand = k * r_probe + a * q_n(p) / (beta * vol(m.piston_m))
                if demand > fc + tol_f or (demand >= fc - tol_f and rate_demand > 0):
                    m = _Mode(_SLIDE, m.side, 1.0)
                elif demand < -fc - tol_f or (demand <= -fc + tol_f and rate_demand < 0):
                    m = _Mode(_SLIDE, m.side, -1.0)
                else:
                    return m, p
            else:
                f, y, dp, _ = slide_state(tt, p, m, r)
                yd = slide_state(tt + probe, p + probe * dp, m, r_probe)[3]
                if b > 0 and (m.side * f < -tol_f or (abs(f) <= tol_f and m.side * dp < 0)):
                    m, p = gap(y, p)
                elif fc > 0 and m.sense * yd < 0:
                    m = _Mode(_STICK, m.side, 1.0, y)
                else:
                    return m, p
        return m, p

    def event(fun, direction: float, target):
        def g(tt, z):
            return fun(tt, z[0])
        g.terminal, g.direction, g.target = True, direction, target
        return g

    def system(m: _Mode, d: float):
        """rhs, jac and events of mode m on an interval of command direction d."""
        if m.kind == _SLIDE:
            def rhs(tt, z):
                return [slide_state(tt, z[0], m, rate(tt, d))[2]]

            def jac(tt, z):
                return [[-dq_n(z[0]) / (beta * vol(slide_state(tt, z[0], m, 0.0)[1]) + cs)]]

            events = []
            if fc > 0:
                events.append(event(lambda tt, p: slide_state(tt, p, m, rate(tt, d))[3], -m.sense,
                                    lambda tt, p: (_Mode(_STICK, m.side, 1.0, slide_state(tt, p, m, 0.0)[1]), p)))
            if b > 0:
                events.append(event(lambda tt, p: m.side * (a * p + m.sense * fc), -1.0,
                                    lambda tt, p: gap(slide_state(tt, p, m, 0.0)[1], p)))
            return rhs, jac, events
        y = m.piston_m
        compliance = beta * vol(y)

        def rhs(tt, z):
            return [-q_n(z[0]) / compliance]

        def jac(tt, z):
            return [[-dq_n(z[0]) / compliance]]

        if m.kind == _GAP:
            events = [event(lambda tt, p: cmd(tt) - (y + b / 2.0), 1.0, lambda tt, p: (contact(1.0, y), p)),
                      event(lambda tt, p: cmd(tt) - (y - b / 2.0), -1.0, lambda tt, p: (contact(-1.0, y), p))]
            return rhs, jac, events
        x = y + m.side * b / 2.0
        events = [event(lambda tt, p: k * (cmd(tt) - x) - a * p - fc, 1.0,
                        lambda tt, p: (_Mode(_SLIDE, m.side, 1.0), p)),
                  event(lambda tt, p: k * (cmd(tt) - x) - a * p + fc, -1.0,
                        lambda tt, p: (_Mode(_SLIDE, m.side, -1.0), p))]
        if b > 0:
            events.append(event(lambda tt, p: m.side * k * (cmd(tt) - x), -1.0, lambda tt, p: gap(y, p)))
        return rhs, jac, events

    def outputs(ts: np.ndarray, ps: np.ndarray, m: _Mode, d: float):
        c = command_displacement(case, ts)
        if m.kind == _SLIDE:
            f = a * ps + m.sense * fc
            x = c - f / k
            y = x - m.side * b / 2.0
            dp = (a * rates(ts, d) - total_flow(ps, hyd)) / (beta * vol(y) + cs)
            return f, x, y, rates(ts, d) - a * dp / k
        y = np.full(ts.shape, m.piston_m)
        if m.kind == _STICK:
            x = np.full(ts.shape, m.piston_m + m.side * b / 2.0)
            return k * (c - x), x, y, np.zeros(ts.shape)
        return np.zeros(ts.shape), c + 0.0, y, np.zeros(ts.shape)

    t = sample_times(case)
    end = record_end(case)
    edges = [0.0, *_turning_times(case), end]
    out = {name: np.empty(t.size) for name in ("dp", "force", "actuator", "piston", "velocity")}
    d0 = 1.0 if math.cos(omega * 0.5 * (edges[0] + edges[1]) + phase) > 0 else -1.0
    if b > 0:
        m = _Mode(_GAP, 0.0, 1.0, cmd(0.0) + d0 * b / 2.0)
    else:
        m = contact(0.0, cmd(0.0))
    tt, p, i = 0.0, 0.0, 0
    stalls = 0
    for ta, tb in zip(edges[:-1], edges[1:]):
        d = 1.0 if math.cos(omega * 0.5 * (ta + tb) + phase) > 0 else -1.0
        m, p = settle(m, tt, p, d)
        while tt < tb:
            j = int(np.searchsorted(t, tb, side="right"))
            ts = t[i:j]
            t_eval = ts if ts.size and ts[-1] == tb else np.append(ts, tb)
            rhs, jac, events = system(m, d)
            sol = solve_ivp(rhs, (tt, tb), [p], method=method, jac=jac, rtol=rtol, atol=atol, t_eval=t_eval,
                            events=events or None)
            if sol.status == -1:
                raise RuntimeError(f"case {case.case}: servo integration failed: {sol.message}")
            t_sol = np.asarray(sol.t, dtype=float)
            n_done = min(t_sol.size, ts.size)
            if n_done:
                p_sol = np.asarray(sol.y, dtype=float)[0, :n_done]
                f, x, y, yd = outputs(t_sol[:n_done], p_sol, m, d)
                sl = slice(i, i + n_done)
                out["dp"][sl], out["force"][sl], out["actuator"][sl] = p_sol, f, x
                out["piston"][sl], out["velocity"][sl] = y, yd
                i += n_done
            if sol.status == 1:
                hits = [(float(te[0]), n) for n, te in enumerate(sol.t_events) if te.size]
                t_e, n = min(hits)
                p_e = float(sol.y_events[n][0][0])
                stalls = stalls + 1 if t_e - tt <= 1e-12 * end else 0
                if stalls > 20:
                    raise RuntimeError(f"case {case.case}: servo model chatters at t = {t_e:.9g} s ({m.kind})")
                m, p = events[n].target(t_e, p_e)
                tt = t_e
                m, p = settle(m, tt, p, d)
            else:
                tt, p = tb, float(np.asarray(sol.y, dtype=float)[0, -1])
    if i != t.size:
        raise RuntimeError(f"case {case.case}: servo integration covered {i} of {t.size} samples")
    return t, out["dp"], out["velocity"], out["force"], out["actuator"], out["piston"]


def true_response(case: CasePlan, damper: Damper, effects: Effects = NOMINAL,
                  hydraulics: Hydraulics | None = None, servo_stiffness_N_m: float = math.inf) -> pd.DataFrame:
    """Noise-free record: time_s, command_m, actuator_m, piston_velocity_m_s, dp_Pa, force_N (Eq. 8).

    ``hydraulics`` overrides the coefficients derived from damper and effects (e.g. c2 = 0);
    friction and backlash always come from ``effects``. ``actuator_m`` is what the LVDT sees: the
    command itself for a rigid servo (k = inf), command - F/k otherwise (:func:`servo_response`).
    """
    return true_responses([case], damper, effects, hydraulics, servo_stiffness_N_m)[0]


def true_responses(cases: Sequence[CasePlan], damper: Damper, effects: Effects = NOMINAL,
                   hydraulics: Hydraulics | None = None,
                   servo_stiffness_N_m: float = math.inf) -> list[pd.DataFrame]:
    """:func:`true_response` of many cases (triangle tables built in one batch).

    A rigid servo (k = inf) uses the quadrature (triangle) and the LSODA play-operator model
    (sine); a finite k integrates the coupled actuator-gap-damper system (:func:`servo_response`)
    for both waveforms.
    """
    hyd = Hydraulics.from_damper(damper, effects) if hydraulics is None else hydraulics
    servo = _stiffness(servo_stiffness_N_m, "servo_stiffness_N_m")
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


# --------------------------------------------------------------------------------------------
# Measurement and cases
# --------------------------------------------------------------------------------------------

def quantise(x, resolution: float) -> np.ndarray:
    """Nearest integer multiple of ``resolution`` (0: unchanged); never -0.0."""
    x = np.asarray(x, dtype=float)
    if resolution == 0.0:
        return x + 0.0
    return np.rint(x / resolution) * resolution + 0.0


def case_rng(seed: int, case_id: str) -> np.random.Generator:
    """Independent, reproducible noise stream of one case: SeedSequence([seed, crc32(case)])."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(case_id.encode("utf-8"))]))


def simulate_case(case: CasePlan, damper: Damper, effects: Effects, measurement: Measurement,
                  seed: int) -> pd.DataFrame:
    """Measured record of one case (tables.TIMESERIES): row, time_s, displacement_m, force_N, command_m.

    displacement = LVDT on the actuator (the command for a rigid servo, command - F/k otherwise;
    plus noise), force = transmitted force (Eq. 8 in contact) + additive and |F|-proportional
    noise; both then quantised (``measurement`` resolutions).
    """
    return measure(case, true_response(case, damper, effects, servo_stiffness_N_m=measurement.servo_stiffness_N_m),
                   measurement, seed)


def measure(case: CasePlan, truth: pd.DataFrame, measurement: Measurement, seed: int) -> pd.DataFrame:
    """Sensor model applied to a noise-free record (:func:`true_response`) of ``case``.

    Draws, in this order from ``case_rng(seed, case.case)``: LVDT noise, additive force noise,
    relative force noise (standard normals of the record length).
    """
    n = len(truth)
    rng = case_rng(seed, case.case)
    z_disp = rng.standard_normal(n)
    z_add = rng.standard_normal(n)
    z_rel = rng.standard_normal(n)
    f = truth["force_N"].to_numpy()
    cmd = truth["command_m"].to_numpy()
    lvdt = truth["actuator_m"].to_numpy() if "actuator_m" in truth else cmd
    force = f + measurement.force_noise_N * z_add + measurement.force_noise_rel * np.abs(f) * z_rel
    disp = lvdt + measurement.displacement_noise_m * z_disp
    return pd.DataFrame({
        "row": np.arange(n, dtype=np.int64),
        "time_s": truth["time_s"].to_numpy(),
        "displacement_m": quantise(disp, measurement.displacement_resolution_m),
        "force_N": quantise(force, measurement.force_resolution_N),
        "command_m": quantise(cmd, measurement.command_resolution_m),
    })


def simulate_cases(cases: Sequence[CasePlan], damper: Damper, effects: Effects, measurement: Measurement,
                   seed: int) -> dict[str, pd.DataFrame]:
    """:func:`simulate_case` of many cases, physics batched; {case id: record}, in the given order."""
    truths = true_responses(cases, damper, effects, servo_stiffness_N_m=measurement.servo_stiffness_N_m)
    return {c.case: measure(c, truth, measurement, seed) for c, truth in zip(cases, truths)}


def simulate_campaign(vc: VirtualCampaign) -> dict[str, pd.DataFrame]:
    """Every case of the campaign, in plan order: {case id: simulate_case(...)}."""
    return simulate_cases(vc.cases, vc.damper, vc.effects, vc.measurement, vc.seed)


# --------------------------------------------------------------------------------------------
# CSV / campaign export
# --------------------------------------------------------------------------------------------

def _decimals(resolution_si: float, unit_si: float) -> tuple[float, int]:
    """Resolution in the CSV unit and the decimals that print its multiples exactly."""
    r = Decimal(repr(resolution_si)) / Decimal(repr(unit_si))
    r = r.normalize()
    digits = r.as_tuple()
    if len(digits.digits) > 6:
        raise ValueError(f"resolution {resolution_si!r} is not a short decimal in the export unit")
    return float(r), max(0, -digits.exponent)


def _format_channel(values_si: np.ndarray, resolution_si: float, unit_si: float) -> list[str]:
    """Exact decimal strings of quantised values (shortest round-trip repr if unquantised)."""
    if resolution_si == 0.0:
        return [repr(v) for v in (values_si / unit_si + 0.0).tolist()]
    r, d = _decimals(resolution_si, unit_si)
    counts = np.rint(values_si / resolution_si) + 0.0
    if np.abs(counts).max(initial=0.0) * 10 ** d >= 2.0**52:
        raise ValueError("value too large for exact decimal printing")
    return [f"{v:.{d}f}" for v in (counts * r + 0.0).tolist()]


def case_csv(series: pd.DataFrame, measurement: Measurement) -> str:
    """The raw-format CSV text of a simulated case (header time_s,disp_mm,force_kN,cmd_mm)."""
    cols = [
        [repr(v) for v in series["time_s"].tolist()],
        _format_channel(series["displacement_m"].to_numpy(), measurement.displacement_resolution_m, 1e-3),
        _format_channel(series["force_N"].to_numpy(), measurement.force_resolution_N, 1e3),
        _format_channel(series["command_m"].to_numpy(), measurement.command_resolution_m, 1e-3),
    ]
    header = ",".join(RAW_COLUMNS[k][0] for k in ("time", "displacement", "force", "command"))
    return header + "\n" + "\n".join(map(",".join, zip(*cols))) + "\n"


def case_sha256(series: pd.DataFrame, measurement: Measurement) -> str:
    """raw_sha256 of a simulated case: sha256 of its exported CSV bytes (:func:`case_csv`)."""
    return hashlib.sha256(case_csv(series, measurement).encode("utf-8")).hexdigest()


def _cases_table(campaign: str, cases: Sequence[CasePlan], series: Mapping[str, pd.DataFrame],
                 measurement: Measurement) -> pd.DataFrame:
    rows = []
    for c in cases:
        rows.append({"campaign": campaign, "case": c.case, "waveform": c.waveform,
                     "sample_rate_Hz": float(c.sample_rate_Hz), "amplitude_m": float(c.amplitude_m),
                     "period_s": float(c.period_s), "frequency_Hz": float(c.frequency_Hz),
                     "phase_rad": float(c.phase_rad), "duration_s": float(c.duration_s),
                     "raw_file": f"virtual_rig:{campaign}/{c.case}",
                     "raw_sha256": case_sha256(series[c.case], measurement),
                     "timeseries_file": timeseries_relpath(c.case),
                     "n_samples": int(len(series[c.case])), "status": "ok"})
    df = pd.DataFrame(rows)
    return df.astype({"n_samples": "int64"})


def write_campaign(vc: VirtualCampaign, campaign_root: str | os.PathLike) -> Path:
    """Simulate and write ``campaign_root/ingest/`` (campaign.write_ingested); returns the ingest dir.

    campaign.json carries the *nominal* damper only; raw_sha256 is the sha256 of the case CSV
    that :func:`export_raw_campaign` would write (same series, same bytes).
    """
    series = simulate_campaign(vc)
    meta = {"format_version": 1, "campaign": vc.name, "source": "simulation", "description": vc.description,
            "temperature_C": vc.temperature_C, "damper": vc.damper.to_dict(), "manifest_file": "",
            "manifest_sha256": "", "metadata": _generated_by(vc, [c.case for c in vc.cases], None)}
    assert set(meta) == set(CAMPAIGN_KEYS)
    ingest = Path(campaign_root) / "ingest"
    write_ingested(ingest, meta, _cases_table(vc.name, vc.cases, series, vc.measurement),
                   tables.empty(tables.QUARANTINE), series)
    return ingest


def _generated_by(vc: VirtualCampaign, cases: list[str], sample_rate_Hz: float | None) -> dict:
    return {"generated_by": {"generator": "isokinetic.virtual_rig", "config_campaign": vc.name,
                             "seed": vc.seed, "cases": list(cases), "sample_rate_Hz": sample_rate_Hz}}


def _short(x: float) -> float:
    """Derived plan value without float noise (15 significant digits; 0.654 not 0.6540000000000001)."""
    return float(f"{x:.15g}")


def campaign_manifest(vc: VirtualCampaign, cases: Sequence[CasePlan], name: str,
                      sample_rate_Hz: float | None) -> dict:
    """campaign.yaml content (raw-campaign format v1) of an export."""
    rates = [c.sample_rate_Hz for c in cases]
    default_rate = max(rates, key=lambda r: (rates.count(r), -rates.index(r)))
    entries = []
    for c in cases:
        e = {"id": c.case, "waveform": c.waveform}
        if c.waveform == "triangle":
            e.update(period_s=float(c.period_s), amplitude_mm=_short(c.amplitude_m * 1e3),
                     phase_rad=float(c.phase_rad))
        else:
            e.update(frequency_Hz=float(c.frequency_Hz), amplitude_mm=_short(c.amplitude_m * 1e3))
        if c.sample_rate_Hz != default_rate:
            e["sample_rate_Hz"] = float(c.sample_rate_Hz)
        e["duration_s"] = _short(c.duration_s)
        e["file"] = f"{c.case}.csv"
        entries.append(e)
    return {"format_version": 1, "campaign": name, "description": vc.description, "source": "simulation",
            "temperature_C": float(vc.temperature_C), "sample_rate_Hz": float(default_rate),
            "columns": {k: {"name": v[0], "unit": v[1]} for k, v in RAW_COLUMNS.items()},
            "damper": vc.damper.to_dict(),
            **_generated_by(vc, [c.case for c in cases], sample_rate_Hz),
            "cases": entries}


def export_raw_campaign(vc: VirtualCampaign, out_dir: str | os.PathLike, cases: Sequence[str] | None = None,
                        sample_rate_Hz: float | None = None, name: str | None = None) -> Path:
    """Write a raw campaign folder (spec raw-campaign-format.md) of simulated cases; returns it.

    ``out_dir`` is the campaign folder itself (it must not exist or be empty); the spec wants the
    campaign id equal to the folder name, so ``name`` defaults to the folder name and must equal it
    when given. ``cases`` selects case ids (plan order kept); ``sample_rate_Hz`` simulates every
    selected case at that rate. Byte reproducible: same config, seed and arguments, same bytes.
    campaign.yaml carries the nominal damper and a ``generated_by`` block (config campaign, seed,
    cases, sample rate override); the truth effects are not written.
    """
    out = Path(out_dir)
    name = out.name if name is None else name
    if not CAMPAIGN_NAME.match(name):
        raise ValueError(f"campaign name {name!r} must match [a-z0-9][a-z0-9_-]* (the spec's campaign id)")
    if out.name != name:
        raise ValueError(f"the campaign folder must be named like the campaign ({name!r}), got {out.name!r}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"refusing to write into existing non-empty {out}")
    if cases is None:
        selected = list(vc.cases)
    else:
        wanted = list(cases)
        if len(set(wanted)) != len(wanted) or not wanted:
            raise ValueError(f"cases: must be a non-empty list without duplicates, got {wanted}")
        for cid in wanted:
            vc.case(cid)
        selected = [c for c in vc.cases if c.case in set(wanted)]
    if sample_rate_Hz is not None:
        rate = _number(sample_rate_Hz, "sample_rate_Hz", positive=True)
        selected = [dataclasses.replace(c, sample_rate_Hz=rate) for c in selected]
        sample_rate_Hz = rate
    manifest = campaign_manifest(vc, selected, name, sample_rate_Hz)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{name}."))
    try:
        for case_id, series in simulate_cases(selected, vc.damper, vc.effects, vc.measurement, vc.seed).items():
            with open(tmp / f"{case_id}.csv", "w", encoding="utf-8", newline="\n") as fh:
                fh.write(case_csv(series, vc.measurement))
        with open(tmp / "campaign.yaml", "w", encoding="utf-8", newline="\n") as fh:
            yaml.safe_dump(manifest, fh, sort_keys=False, default_flow_style=False, allow_unicode=True, width=100)
        os.chmod(tmp, 0o755)
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out

