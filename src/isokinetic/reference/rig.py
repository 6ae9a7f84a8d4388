"""Independent reference rig: a two-state compressible damper on an imperfect test rig.

This module (with its sibling :mod:`isokinetic.reference.rig_measurement`: sensors and
raw-campaign export) is the separately written reference against which the project's diagnosis is
tested. It shares no code with the rest of ``isokinetic``: it imports only numpy, scipy, pandas
and the standard library, and keeps its own copy of Table 1 (:data:`TABLE1`) on purpose. Equation
numbers refer to the paper "A method for the identification of hydraulic damper characteristics
from steady velocity inputs" (Titurus et al.); SI units throughout unless a name says otherwise.

Damper (noise free)
    The states are the two chamber pressures p1, p2 (absolute; integrated as p_i - p0 so that the
    error control acts on the pressure rise, not on the charge pressure p0). Mass balance of the
    oil in each chamber (the per-chamber form of Eq. 1)::

        dp1/dt = (A dy/dt - Q12(p1 - p2)) / C1(p1, y),   C_i = beta_i V_i
        dp2/dt = (Q12(p1 - p2) - A dy/dt) / C2(p2, y)

    with V1 = V01 - A y, V2 = V02 + A y (Eq. 2), y the piston position (y = 0 at the stroke
    centre). Q12 = orifice (Eq. 7, asymmetric C_D) + annular leakage + relief valve. The load cell
    reads F = A (p1 - p2) + F_f(dy/dt) (Eq. 8, massless piston) while the actuator pushes the
    piston. Integration: ``scipy.integrate.solve_ivp`` with LSODA and an analytic Jacobian, split
    at every discontinuity of the piston velocity or its derivative (delayed command corners,
    actuator reversals, backlash contacts), ``t_eval`` at the sample times.

Rig
    Actuator rod x: dx/dt = (c(t - d) - x) / tau_s, solved in closed form per linear piece of the
    delayed command (x = c(t - d) when tau_s = 0). The LVDT measures x, not the piston. Backlash b
    is a play operator between x and y (:func:`piston_pieces`). A :class:`SineCase` commands
    Y sin(2 pi f t) from rest through the same delay, servo (its first-order response in closed form) and
    play operator; the rest is the triangle's. The sensor noise model is a
    parameter of the rig (:class:`RigImperfections`); it is applied in the sibling module.

Speed (measured on one core, 2 CPUs shared, Table-1 damper, 2T recorded, velocities
0.005-1.5 mm/s, with or without air, leakage, friction, delay, lag and noise): simulation plus
noise 0.015-0.04 s per case for T in {20, 80, 240} s at 50 or 100 Hz (LSODA takes few steps
on the quasi-steady ramps); writing the CSV adds 0.003-0.06 s (2 000-48 000 rows).
Agreement with the project's virtual rig on the clean nominal damper: max |dF| ~1e-9 to 6e-9
of the force scale at the default rtol 1e-10 (tests/reference/test_rig.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.reference.cases import RigCase, SineCase, TriangleCase, sine_command, triangle_command  # noqa: F401
from isokinetic.reference.motion import PistonPiece, SineActuatorPiece, piston_pieces

# ---------------------------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class DamperDesign:
    """Nominal design data of a two-chamber symmetric damper (Table 1), SI units.

    Field names are those of the raw-campaign ``damper`` block, so any object with these
    attributes (e.g. ``isokinetic.physics.damper.Damper``) is accepted wherever a design is expected.
    """

    piston_area_m2: float = 4.0e-3
    chamber_volume_1_m3: float = 3.0e-4
    chamber_volume_2_m3: float = 3.0e-4
    orifice_area_m2: float = 6.0e-8
    orifice_length_m: float = 5.0e-4
    discharge_coefficient: float = 0.6
    density_kg_m3: float = 815.0
    viscosity_Pa_s: float = 0.03
    oil_compressibility_1_Pa: float = 3.8e-9

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"DamperDesign.{f.name} must be a positive number, got {v!r}")

    @classmethod
    def from_mapping(cls, values: Mapping[str, float]) -> DamperDesign:
        """Build from a mapping holding at least the field names (extra keys ignored)."""
        return cls(**{f.name: float(values[f.name]) for f in dataclasses.fields(cls)})

    def to_dict(self) -> dict[str, float]:
        return {f.name: float(getattr(self, f.name)) for f in dataclasses.fields(self)}


#: Table 1 geometry and fluid (this rig's own copy: it imports nothing from ``isokinetic``).
TABLE1 = DamperDesign()


@dataclass(frozen=True)
class TrueEffects:
    """Physical deviations of the real damper from its design; all zero/None = nominal damper.

    friction
        Stribeck form F = tanh(v / v_eps) [F_C + F_S exp(-(|v|/v_S)^2)]; ``coulomb_force_N`` F_C,
        ``stribeck_force_N`` F_S, ``stribeck_velocity_m_s`` v_S, ``friction_regularisation_m_s``
        v_eps (a smooth sign).
    leakage
        Laminar annular gap across the piston, Q_L = pi D h^3 / (12 mu L) dp with
        ``leakage_gap_m`` h (radial), ``seal_length_m`` L, D = sqrt(4 A / pi), mu the actual
        (drifting) viscosity.
    asymmetry
        C_D (1 + a) for dp > 0, C_D (1 - a) for dp < 0.
    path_resistance_neg
        r > -1: a one-sided flow path (a valve stack on one side): for dp < 0 both c1 and c2 of Eq. 7
        are (1 + r) times their dp > 0 values.
    discharge_coefficient, viscosity_Pa_s
        Replace the design values (None: design value).
    air
        ``air_fraction_at_charge`` phi0: free-gas volume fraction at the charge pressure
        ``charge_pressure_Pa`` p0 (absolute; also the initial pressure of both chambers).
        The gas of each chamber obeys the isothermal law, V_Gi = phi0 V0i p0 / p_i.
    backlash
        ``backlash_m`` b: total free play between actuator rod and piston. The piston stands
        still (held by its seals) while the actuator crosses the gap after each reversal.
        ``backlash_gap_force`` says what the load cell reads meanwhile: "zero" (nothing
        connects rod and piston: F = 0, the seals carry A dp) or "hydraulic" (F = A dp).
    relief valve
        A spring-loaded valve pair in parallel with the orifice, see :func:`relief_flow`:
        ``relief_cracking_pressure_Pa`` (None: no valve), ``relief_area_gradient_m2_Pa``,
        ``relief_discharge_coefficient``.
    position-sensitive bypass (out of the catalogue)
        A groove in the bore, open while the piston is within ``bypass_half_width_m`` of mid-stroke (y = 0), as
        dampers' bleed grooves are: a second flow path of the orifice's form (Eq. 7) with flow area
        ``bypass_area_m2`` A_g, the orifice's length and design C_D (c1_g = 8 pi mu l_O / A_g^2,
        c2_g = rho / (2 C_D^2 A_g^2)), in parallel with the orifice and scaled by its opening s(y): 1 for
        |y| <= h - w/2, 0 for |y| >= h + w/2 and 1/2 (1 + cos(pi (|y| - h + w/2) / w)) between (the groove's
        ends taper over ``bypass_taper_m`` w; h the half width).
    worn bore (out of the catalogue)
        The bore worn around mid-stroke, where the piston travels most: the leakage gap is
        h + ``bore_wear_gap_m`` h_w (1 - (y/L)^2) for |y| < L = ``bore_wear_half_length_m`` (h elsewhere), the
        annular conductance pi D h(y)^3 / (12 mu L_s) of that gap.
    gas spring (out of the catalogue)
        A rod's gas volume, linearised about mid-stroke: the load cell also reads ``gas_spring_N_m`` y
        (the constant preload being an offset of the load cell's zero, not simulated).
    wear and warm-up over the campaign (out of the catalogue)
        ``orifice_wear_rel`` w: the orifice's flow area is A_O (1 + w (f - 1/2)) in the case whose middle lies at
        the fraction f of the campaign's time (erosion; the campaign-mean area is the design's); ``warmup_K``
        dT: the oil's temperature is T + dT (f - 1/2) (nothing logs it), its viscosity following Vogel's law
        (:data:`VOGEL_B_K`, :data:`VOGEL_C_K`). See :func:`campaign_drift`.
    """

    coulomb_force_N: float = 0.0
    stribeck_force_N: float = 0.0
    stribeck_velocity_m_s: float = 1.0e-4
    friction_regularisation_m_s: float = 1.0e-7
    leakage_gap_m: float = 0.0
    seal_length_m: float = 0.02
    asymmetry: float = 0.0
    path_resistance_neg: float = 0.0
    discharge_coefficient: float | None = None
    viscosity_Pa_s: float | None = None
    air_fraction_at_charge: float = 0.0
    charge_pressure_Pa: float = 5.0e6
    backlash_m: float = 0.0
    backlash_gap_force: str = "zero"
    relief_cracking_pressure_Pa: float | None = None
    relief_area_gradient_m2_Pa: float = 0.0
    relief_discharge_coefficient: float = 0.7
    bypass_area_m2: float = 0.0
    bypass_half_width_m: float = 1.0e-3
    bypass_taper_m: float = 1.0e-4
    bore_wear_gap_m: float = 0.0
    bore_wear_half_length_m: float = 2.0e-3
    gas_spring_N_m: float = 0.0
    orifice_wear_rel: float = 0.0
    warmup_K: float = 0.0

    def __post_init__(self):
        nonneg = ("coulomb_force_N", "stribeck_force_N", "leakage_gap_m", "air_fraction_at_charge",
                  "backlash_m", "relief_area_gradient_m2_Pa", "bypass_area_m2", "bore_wear_gap_m", "gas_spring_N_m",
                  "warmup_K")
        for name in nonneg:
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"TrueEffects.{name} must be >= 0, got {v!r}")
        for name in ("stribeck_velocity_m_s", "friction_regularisation_m_s", "seal_length_m",
                     "charge_pressure_Pa", "relief_discharge_coefficient", "bypass_half_width_m", "bypass_taper_m",
                     "bore_wear_half_length_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"TrueEffects.{name} must be > 0, got {v!r}")
        if not -1.0 < self.asymmetry < 1.0:
            raise ValueError(f"TrueEffects.asymmetry must lie in (-1, 1), got {self.asymmetry!r}")
        if not (math.isfinite(self.path_resistance_neg) and self.path_resistance_neg > -1.0):
            raise ValueError(f"TrueEffects.path_resistance_neg must be > -1, got {self.path_resistance_neg!r}")
        if not self.air_fraction_at_charge < 1.0:
            raise ValueError("TrueEffects.air_fraction_at_charge must be < 1")
        for name in ("discharge_coefficient", "viscosity_Pa_s", "relief_cracking_pressure_Pa"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise ValueError(f"TrueEffects.{name} must be None or > 0, got {v!r}")
        if self.backlash_gap_force not in ("zero", "hydraulic"):
            raise ValueError("TrueEffects.backlash_gap_force must be 'zero' or 'hydraulic'")
        if not (math.isfinite(self.orifice_wear_rel) and abs(self.orifice_wear_rel) < 1.0):
            raise ValueError("TrueEffects.orifice_wear_rel must lie in (-1, 1)")
        if not self.bypass_taper_m < 2.0 * self.bypass_half_width_m:
            raise ValueError("TrueEffects.bypass_taper_m must be shorter than the groove (2 bypass_half_width_m)")


NOMINAL_EFFECTS = TrueEffects()


@dataclass(frozen=True)
class RigImperfections:
    """Actuator, sensors and environment of the rig; the defaults are an ideal rig.

    ``delay_s`` d and ``servo_lag_s`` tau_s: dx/dt = (c(t - d) - x)/tau_s. Force channel
    F_meas = ``force_gain`` F_true + ``force_offset_N`` + ``force_noise_N`` w
    + |F_true| ``force_noise_rel`` c, c an AR(1) sequence of corner ``noise_corner_Hz``.
    ``displacement_noise_m``: white LVDT noise on x. ``viscosity_drift_rel``: the viscosity of
    case i of n is mu (1 + drift (i/(n-1) - 1/2)). Resolutions: ADC steps of the channels
    (> 0; each must be a short decimal in the export unit: N for force, um for displacement).

    Sensor chain (all off by default): ``force_filter_Hz`` f_f > 0 puts the force channel behind an
    analog Butterworth low-pass of order ``force_filter_order`` (1 or 2) and corner f_f (an
    anti-alias filter; low-frequency group delay 1/(2 pi f_f) or sqrt(2)/(2 pi f_f)), acting on
    g F_true + F0 before the noise; ``displacement_gain`` k: the LVDT reads k x (the command channel
    stays true); ``force_drift_N_s`` r: the load-cell zero drifts linearly in campaign time, F0 + r t_c
    (t_c counts from the first sample of the first case, the cases back to back);
    ``dropout_fraction``: that fraction of the samples is missing from the written record.
    """

    delay_s: float = 0.0
    servo_lag_s: float = 0.0
    force_noise_N: float = 0.0
    force_noise_rel: float = 0.0
    noise_corner_Hz: float = 1.0
    force_offset_N: float = 0.0
    force_gain: float = 1.0
    displacement_noise_m: float = 0.0
    viscosity_drift_rel: float = 0.0
    force_resolution_N: float = 0.01
    displacement_resolution_m: float = 1.0e-9
    command_resolution_m: float = 1.0e-9
    force_filter_Hz: float = 0.0
    force_filter_order: int = 2
    displacement_gain: float = 1.0
    force_drift_N_s: float = 0.0
    dropout_fraction: float = 0.0

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise ValueError(f"RigImperfections.{f.name} must be finite, got {v!r}")
        if self.force_filter_Hz < 0:
            raise ValueError("RigImperfections.force_filter_Hz must be >= 0 (0: no filter)")
        if self.force_filter_order not in (1, 2):
            raise ValueError("RigImperfections.force_filter_order must be 1 or 2")
        if self.displacement_gain <= 0:
            raise ValueError("RigImperfections.displacement_gain must be > 0")
        if not 0.0 <= self.dropout_fraction < 0.5:
            raise ValueError("RigImperfections.dropout_fraction must lie in [0, 0.5)")
        for name in ("delay_s", "servo_lag_s", "force_noise_N", "force_noise_rel", "displacement_noise_m"):
            if getattr(self, name) < 0:
                raise ValueError(f"RigImperfections.{name} must be >= 0")
        for name in ("noise_corner_Hz", "force_gain", "force_resolution_N", "displacement_resolution_m",
                     "command_resolution_m"):
            if getattr(self, name) <= 0:
                raise ValueError(f"RigImperfections.{name} must be > 0")
        if abs(self.viscosity_drift_rel) >= 2.0:
            raise ValueError("RigImperfections.viscosity_drift_rel must lie in (-2, 2)")

    def force_group_delay_s(self) -> float:
        """Low-frequency group delay of the force channel's low-pass: 1/(2 pi f_f) (1st order),
        sqrt(2)/(2 pi f_f) (2nd-order Butterworth); 0 without a filter."""
        if self.force_filter_Hz == 0.0:
            return 0.0
        return (1.0 if self.force_filter_order == 1 else math.sqrt(2.0)) / (2.0 * math.pi * self.force_filter_Hz)

    def noise_correlation(self, sample_rate_Hz: float) -> float:
        """rho = exp(-2 pi f_c / fs) of the coloured force noise."""
        return math.exp(-2.0 * math.pi * self.noise_corner_Hz / sample_rate_Hz)

    def mean_noise_variance_N2(self, n_samples: int, force_N: float, sample_rate_Hz: float) -> float:
        """Exact variance of the mean of n consecutive force-noise samples at true force F [N^2].

        sigma_w^2 / n + (sigma_rel F)^2 [n (1+rho)/(1-rho) - 2 rho (1-rho^n)/(1-rho)^2] / n^2,
        the second term being sum_{j,k} rho^|j-k| / n^2 of the AR(1) part. Excludes quantisation
        (about step^2/12 per sample when the step is small against the noise).
        """
        n = int(n_samples)
        if n < 1:
            raise ValueError("n_samples must be >= 1")
        rho = self.noise_correlation(sample_rate_Hz)
        s2 = (self.force_noise_rel * abs(force_N)) ** 2
        if rho >= 1.0:
            coloured = 1.0
        else:
            coloured = (n * (1.0 + rho) / (1.0 - rho) - 2.0 * rho * (1.0 - rho**n) / (1.0 - rho) ** 2) / n**2
        return self.force_noise_N**2 / n + s2 * coloured


IDEAL_RIG = RigImperfections()


# ---------------------------------------------------------------------------------------------
# Elementary physics (pure, vectorised)
# ---------------------------------------------------------------------------------------------
def laminar_coefficient(viscosity_Pa_s: float, length_m: float, area_m2: float) -> float:
    """c1 = 8 pi mu l_O / A_O^2 (Sec. 2.2, Table 1) [Pa s/m^3]."""
    return 8.0 * math.pi * viscosity_Pa_s * length_m / area_m2**2


def turbulent_coefficient(density_kg_m3: float, discharge_coefficient: float, area_m2: float) -> float:
    """c2 = rho / (2 C_D^2 A_O^2) (Sec. 2.2, Table 1) [Pa s^2/m^6]."""
    return density_kg_m3 / (2.0 * discharge_coefficient**2 * area_m2**2)


def orifice_flow(dp_Pa, c1: float, c2_pos: float, c2_neg: float, c1_neg: float | None = None):
    """Q(dp) solving dp = c1 Q + c2 Q|Q| (Eq. 7), c2 = c2_pos for dp > 0, c2_neg for dp < 0, and
    c1 = ``c1_neg`` for dp < 0 when given [m^3/s].

    Uses Q = 2 dp / (c1 + sqrt(c1^2 + 4 c2 |dp|)), free of cancellation for small dp (c1 > 0).
    """
    dp = np.asarray(dp_Pa, dtype=float)
    c2 = np.where(dp >= 0.0, c2_pos, c2_neg)
    c1 = c1 if c1_neg is None else np.where(dp >= 0.0, c1, c1_neg)
    return 2.0 * dp / (c1 + np.sqrt(c1 * c1 + 4.0 * c2 * np.abs(dp)))


def orifice_pressure(q_m3_s, c1: float, c2_pos: float, c2_neg: float, c1_neg: float | None = None):
    """dp = c1 Q + c2 Q|Q| (Eq. 7) with the direction's c2 (and c1 = ``c1_neg`` for Q < 0 when given) [Pa]."""
    q = np.asarray(q_m3_s, dtype=float)
    c1 = c1 if c1_neg is None else np.where(q >= 0.0, c1, c1_neg)
    return c1 * q + np.where(q >= 0.0, c2_pos, c2_neg) * q * np.abs(q)


def piston_diameter_m(piston_area_m2: float) -> float:
    """D = sqrt(4 A / pi)."""
    return math.sqrt(4.0 * piston_area_m2 / math.pi)


def annular_leakage_conductance(piston_area_m2: float, gap_m: float, viscosity_Pa_s: float,
                                seal_length_m: float) -> float:
    """Laminar flow through a narrow concentric annulus: pi D h^3 / (12 mu L) [m^3/(s Pa)]."""
    return math.pi * piston_diameter_m(piston_area_m2) * gap_m**3 / (12.0 * viscosity_Pa_s * seal_length_m)


def relief_flow(dp_Pa, cracking_pressure_Pa: float | None, area_gradient_m2_Pa: float,
                discharge_coefficient: float, density_kg_m3: float):
    """Flow of a symmetric pair of spring-loaded relief valves in parallel with the orifice [m^3/s].

    Closed for |dp| <= p_crack. Above it the spring lets the poppet lift in proportion to the
    excess pressure, so the open area is A_v = k_A (|dp| - p_crack); the flow through the
    opening is turbulent under the full pressure drop:
    Q_v = sign(dp) C_Dv k_A (|dp| - p_crack) sqrt(2 |dp| / rho). Q_v is continuous at the
    cracking pressure (zero), its slope jumps there.
    """
    dp = np.asarray(dp_Pa, dtype=float)
    if cracking_pressure_Pa is None or area_gradient_m2_Pa == 0.0:
        return np.zeros_like(dp)
    a = np.abs(dp)
    excess = np.maximum(a - cracking_pressure_Pa, 0.0)
    return np.sign(dp) * discharge_coefficient * area_gradient_m2_Pa * excess * np.sqrt(2.0 * a / density_kg_m3)


def gas_amount_Pa_m3(air_fraction_at_charge: float, chamber_volume_m3: float, charge_pressure_Pa: float) -> float:
    """G = p V_G = phi0 V0 p0, constant for an isothermal gas pocket [Pa m^3]."""
    return air_fraction_at_charge * chamber_volume_m3 * charge_pressure_Pa


def chamber_capacitance(p_Pa, volume_m3, gas_amount: float, oil_compressibility_1_Pa: float):
    """C = beta V = beta_oil V_L + V_G / p, the volume taken up per unit pressure rise [m^3/Pa].

    Derivation: the chamber (geometric volume V) holds oil V_L and gas V_G = G/p (isothermal,
    G fixed). Oil mass balance d(rho_L V_L)/dt = rho_L Q_in with d rho_L/rho_L = beta_oil dp,
    and V_L = V - G/p, give (beta_oil V_L + V_G/p) dp/dt = Q_in - dV/dt. Hence the mixture's
    compressibility beta = (beta_oil V_L + V_G/p) / (V_L + V_G) (the gas term of Eq. 3 with
    the gas bulk modulus B_G = p).
    """
    p = np.asarray(p_Pa, dtype=float)
    v_gas = gas_amount / p
    return oil_compressibility_1_Pa * (np.asarray(volume_m3, dtype=float) - v_gas) + v_gas / p


def mixture_compressibility(p_Pa, volume_m3, gas_amount: float, oil_compressibility_1_Pa: float):
    """beta_i = (beta_oil V_L + V_G/p) / (V_L + V_G) of an oil-gas chamber [1/Pa]."""
    return chamber_capacitance(p_Pa, volume_m3, gas_amount, oil_compressibility_1_Pa) / np.asarray(volume_m3)


def stribeck_friction(velocity_m_s, coulomb_force_N: float, stribeck_force_N: float = 0.0,
                      stribeck_velocity_m_s: float = 1.0e-4, regularisation_m_s: float = 1.0e-7):
    """F_f = tanh(v/v_eps) [F_C + F_S exp(-(|v|/v_S)^2)] (Stribeck with a smooth sign) [N]."""
    v = np.asarray(velocity_m_s, dtype=float)
    level = coulomb_force_N + stribeck_force_N * np.exp(-((v / stribeck_velocity_m_s) ** 2))
    return np.tanh(v / regularisation_m_s) * level


# ---------------------------------------------------------------------------------------------
# Hydraulic model of one case
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ChamberModel:
    """All coefficients of the two-state model of one case (after viscosity drift), SI."""

    piston_area_m2: float
    chamber_volume_1_m3: float
    chamber_volume_2_m3: float
    oil_compressibility_1_Pa: float
    charge_pressure_Pa: float
    gas_1_Pa_m3: float
    gas_2_Pa_m3: float
    c1: float
    c2_pos: float
    c2_neg: float
    leakage_m3_s_Pa: float
    relief_cracking_pressure_Pa: float | None
    relief_area_gradient_m2_Pa: float
    relief_discharge_coefficient: float
    density_kg_m3: float
    c1_neg: float | None = None       # c1 for dp < 0 (a one-sided flow path); None: c1 both ways
    bypass_c1: float = 0.0            # the groove's Eq. 7 coefficients (0: no groove)
    bypass_c2: float = 0.0
    bypass_half_width_m: float = 1.0e-3
    bypass_taper_m: float = 1.0e-4
    leakage_gap_m: float = 0.0        # worn bore: the gap's shape and pi D / (12 mu L_s)
    bore_wear_gap_m: float = 0.0
    bore_wear_half_length_m: float = 2.0e-3
    leakage_per_gap3: float = 0.0

    def bypass_opening(self, position_m):
        """s(y) of the groove (1 open, 0 closed; 0 everywhere without one), see :class:`TrueEffects`."""
        y = np.abs(np.asarray(position_m, dtype=float))
        if self.bypass_c1 == 0.0:
            return np.zeros_like(y)
        return np.vectorize(lambda a: groove_opening(a, self.bypass_half_width_m, self.bypass_taper_m),
                            otypes=[float])(y)

    def leakage_at(self, position_m):
        """The annular leakage conductance with the piston at y [m^3/(s Pa)] (the worn bore's shape)."""
        y = np.asarray(position_m, dtype=float)
        if self.bore_wear_gap_m == 0.0:
            return np.full_like(y, self.leakage_m3_s_Pa)
        u = np.clip(1.0 - (y / self.bore_wear_half_length_m) ** 2, 0.0, None)
        return self.leakage_per_gap3 * (self.leakage_gap_m + self.bore_wear_gap_m * u) ** 3

    def total_flow(self, dp_Pa, position_m: float | None = None):
        """Q12(dp): orifice (Eq. 7) + annular leakage + relief valves, and with the piston at ``position_m`` the
        groove and the worn bore's leakage there (None: away from both) [m^3/s]."""
        dp = np.asarray(dp_Pa, dtype=float)
        leak = self.leakage_m3_s_Pa if position_m is None else self.leakage_at(position_m)
        q = (orifice_flow(dp, self.c1, self.c2_pos, self.c2_neg, self.c1_neg) + leak * dp
             + relief_flow(dp, self.relief_cracking_pressure_Pa, self.relief_area_gradient_m2_Pa,
                           self.relief_discharge_coefficient, self.density_kg_m3))
        if position_m is not None and self.bypass_c1 > 0.0:
            q = q + self.bypass_opening(position_m) * orifice_flow(dp, self.bypass_c1, self.bypass_c2, self.bypass_c2)
        return q

    def scalar_flow(self, dp: float, position_m: float | None = None) -> tuple[float, float]:
        """Q12(dp) and dQ12/ddp for a float (fast path of the ODE right-hand side); ``position_m`` as in
        :meth:`total_flow`."""
        a = abs(dp)
        c2 = self.c2_pos if dp >= 0.0 else self.c2_neg
        c1 = self.c1 if dp >= 0.0 or self.c1_neg is None else self.c1_neg
        root = math.sqrt(c1 * c1 + 4.0 * c2 * a)
        leak = self.leakage_m3_s_Pa if position_m is None else float(self.leakage_at(position_m))
        q = 2.0 * dp / (c1 + root) + leak * dp
        dq = 1.0 / root + leak            # d(dp)/dQ = c1 + 2 c2 |Q| = root
        if position_m is not None and self.bypass_c1 > 0.0:
            s = groove_opening(abs(position_m), self.bypass_half_width_m, self.bypass_taper_m)
            root_g = math.sqrt(self.bypass_c1 ** 2 + 4.0 * self.bypass_c2 * a)
            q += s * 2.0 * dp / (self.bypass_c1 + root_g)
            dq += s / root_g
        pc = self.relief_cracking_pressure_Pa
        if pc is not None and a > pc and self.relief_area_gradient_m2_Pa > 0.0:
            k = self.relief_discharge_coefficient * self.relief_area_gradient_m2_Pa
            s = math.sqrt(2.0 * a / self.density_kg_m3)
            q += math.copysign(k * (a - pc) * s, dp)
            dq += k * (s + (a - pc) / (self.density_kg_m3 * s))
        return q, dq


def groove_opening(abs_position_m: float, half_width_m: float, taper_m: float) -> float:
    """s(|y|) of a groove open within ``half_width_m`` h of mid-stroke, its ends tapered over ``taper_m`` w:
    1 for |y| <= h - w/2, 0 for |y| >= h + w/2, 1/2 (1 + cos(pi (|y| - h + w/2) / w)) between."""
    lo = half_width_m - 0.5 * taper_m
    if abs_position_m <= lo:
        return 1.0
    if abs_position_m >= half_width_m + 0.5 * taper_m:
        return 0.0
    return 0.5 * (1.0 + math.cos(math.pi * (abs_position_m - lo) / taper_m))


#: Vogel's law of the oil, mu = A exp(b / (T - c)) (T in K): the warm-up's and :class:`OilTemperature`'s.
VOGEL_B_K = 977.0
VOGEL_C_K = 150.0


def campaign_drift(effects: TrueEffects, fraction: float, temperature_C: float = 40.0) -> tuple[float, float]:
    """(viscosity ratio, orifice area ratio) of the case whose middle lies at the fraction f of the campaign's
    time: mu(T + dT (f - 1/2)) / mu(T) of the unlogged warm-up (Vogel's law) and 1 + w (f - 1/2) of the
    orifice's wear (:class:`TrueEffects`); (1, 1) without them."""
    d = float(fraction) - 0.5
    visc = 1.0 if effects.warmup_K == 0.0 else float(
        vogel_viscosity_ratio(temperature_C + effects.warmup_K * d, temperature_C, VOGEL_B_K, VOGEL_C_K))
    return visc, 1.0 + effects.orifice_wear_rel * d


def true_viscosity(damper, effects: TrueEffects) -> float:
    """Campaign-mean viscosity of the real damper: ``effects.viscosity_Pa_s`` or the design value."""
    return float(damper.viscosity_Pa_s if effects.viscosity_Pa_s is None else effects.viscosity_Pa_s)


def case_viscosity(damper, effects: TrueEffects, rig: RigImperfections, case_index: int = 0,
                   n_cases: int = 1) -> float:
    """mu_case = mu_true (1 + drift (i/(n-1) - 1/2)), the temperature drift over a campaign."""
    frac = case_index / (n_cases - 1) - 0.5 if n_cases > 1 else 0.0
    return true_viscosity(damper, effects) * (1.0 + rig.viscosity_drift_rel * frac)


def vogel_viscosity_ratio(temperature_C, reference_C: float, b_K: float, c_K: float):
    """mu(T) / mu(T_ref) of an oil following Vogel's law, mu = A exp(b / (T - c)), T in K."""
    t = np.asarray(temperature_C, dtype=float) + 273.15
    return np.exp(b_K / (t - c_K) - b_K / (reference_C + 273.15 - c_K))


def chamber_model(damper, effects: TrueEffects = NOMINAL_EFFECTS, viscosity_Pa_s: float | None = None,
                  orifice_area_ratio: float = 1.0) -> ChamberModel:
    """Coefficients of the real damper (design + effects) at the viscosity ``viscosity_Pa_s``, its orifice's
    area times ``orifice_area_ratio`` (worn, :func:`campaign_drift`)."""
    mu = true_viscosity(damper, effects) if viscosity_Pa_s is None else float(viscosity_Pa_s)
    cd = damper.discharge_coefficient if effects.discharge_coefficient is None else effects.discharge_coefficient
    a_o = damper.orifice_area_m2 * float(orifice_area_ratio)
    p0 = effects.charge_pressure_Pa
    a_g = effects.bypass_area_m2
    return ChamberModel(
        piston_area_m2=float(damper.piston_area_m2),
        chamber_volume_1_m3=float(damper.chamber_volume_1_m3),
        chamber_volume_2_m3=float(damper.chamber_volume_2_m3),
        oil_compressibility_1_Pa=float(damper.oil_compressibility_1_Pa),
        charge_pressure_Pa=float(p0),
        gas_1_Pa_m3=gas_amount_Pa_m3(effects.air_fraction_at_charge, damper.chamber_volume_1_m3, p0),
        gas_2_Pa_m3=gas_amount_Pa_m3(effects.air_fraction_at_charge, damper.chamber_volume_2_m3, p0),
        c1=laminar_coefficient(mu, damper.orifice_length_m, a_o),
        c2_pos=turbulent_coefficient(damper.density_kg_m3, cd * (1.0 + effects.asymmetry), a_o),
        c2_neg=(1.0 + effects.path_resistance_neg)
        * turbulent_coefficient(damper.density_kg_m3, cd * (1.0 - effects.asymmetry), a_o),
        c1_neg=((1.0 + effects.path_resistance_neg) * laminar_coefficient(mu, damper.orifice_length_m, a_o)
                if effects.path_resistance_neg else None),
        leakage_m3_s_Pa=annular_leakage_conductance(damper.piston_area_m2, effects.leakage_gap_m, mu,
                                                    effects.seal_length_m),
        relief_cracking_pressure_Pa=effects.relief_cracking_pressure_Pa,
        relief_area_gradient_m2_Pa=float(effects.relief_area_gradient_m2_Pa),
        relief_discharge_coefficient=float(effects.relief_discharge_coefficient),
        density_kg_m3=float(damper.density_kg_m3),
        bypass_c1=laminar_coefficient(mu, damper.orifice_length_m, a_g) if a_g > 0.0 else 0.0,
        bypass_c2=turbulent_coefficient(damper.density_kg_m3, damper.discharge_coefficient, a_g) if a_g > 0.0 else 0.0,
        bypass_half_width_m=float(effects.bypass_half_width_m),
        bypass_taper_m=float(effects.bypass_taper_m),
        leakage_gap_m=float(effects.leakage_gap_m),
        bore_wear_gap_m=float(effects.bore_wear_gap_m),
        bore_wear_half_length_m=float(effects.bore_wear_half_length_m),
        leakage_per_gap3=annular_leakage_conductance(damper.piston_area_m2, 1.0, mu, effects.seal_length_m),
    )


def steady_pressure_difference(piston_flow_m3_s: float, model: ChamberModel) -> float:
    """Incompressible steady dp with Q12(dp) = A W (Eq. 24 with leakage and valves) [Pa].

    Bracketed root of the monotone Q12; used for error scales and tests.
    """
    qp = float(piston_flow_m3_s)
    if qp == 0.0:
        return 0.0
    # Q12(dp) >= orifice flow, so the orifice's dp for A W (plus a margin for rounding) brackets the root
    hi = 1.001 * abs(float(orifice_pressure(qp, model.c1, model.c2_pos, model.c2_neg, model.c1_neg))) + 1e-300
    f = lambda dp: model.scalar_flow(dp)[0] - qp  # noqa: E731
    lo, hi = (0.0, math.copysign(hi, qp)) if qp > 0 else (math.copysign(hi, qp), 0.0)
    from scipy.optimize import brentq  # scipy (~0.5 s) only where the rig runs: importers of this module need not

    return brentq(f, lo, hi, xtol=1e-300, rtol=8.9e-16, maxiter=500)


# ---------------------------------------------------------------------------------------------
# Noise-free response
# ---------------------------------------------------------------------------------------------

def _check_stroke(case: RigCase, model: ChamberModel) -> None:
    """The stroke must leave oil in both chambers (Eq. 12: T_max < T_lim)."""
    a = model.piston_area_m2
    for v0, gas in ((model.chamber_volume_1_m3, model.gas_1_Pa_m3), (model.chamber_volume_2_m3, model.gas_2_Pa_m3)):
        if not a * case.stroke_amplitude_m < 0.95 * (v0 - gas / model.charge_pressure_Pa):
            raise ValueError(f"case {case.case_id}: amplitude {case.amplitude_m:g} m empties a chamber")


def _position_flow(model: ChamberModel):
    """f(y, dp, |dp|) -> (Q, dQ/ddp) of the flow paths that depend on the piston's position, beyond the
    position-free ones of :meth:`ChamberModel.scalar_flow` (the groove's, the worn bore's extra leakage); None
    without them."""
    groove, worn = model.bypass_c1 > 0.0, model.bore_wear_gap_m > 0.0
    if not (groove or worn):
        return None
    gc1, four_gc2, gh, gw = model.bypass_c1, 4.0 * model.bypass_c2, model.bypass_half_width_m, model.bypass_taper_m
    leak = model.leakage_m3_s_Pa

    def flow(y: float, dp: float, ad: float) -> tuple[float, float]:
        q = dq = 0.0
        s = groove_opening(abs(y), gh, gw) if groove else 0.0
        if s > 0.0:
            root_g = math.sqrt(gc1 * gc1 + four_gc2 * ad)
            q, dq = s * 2.0 * dp / (gc1 + root_g), s / root_g
        if worn:
            extra = float(model.leakage_at(y)) - leak
            q, dq = q + extra * dp, dq + extra
        return q, dq

    return flow


def _piece_system(model: ChamberModel, piece: PistonPiece):
    """rhs and analytic Jacobian of the two pressure rises u = p_i - p0 on one piece.

    The ODE's fast path, one function of floats: the piston motion of :class:`PistonPiece`, the
    capacitances of :func:`chamber_capacitance` with their derivatives, and
    :meth:`ChamberModel.scalar_flow` written out (LSODA calls it ~5e5 times per blind suite, and
    function calls would cost more than the arithmetic).
    """
    a, p0 = model.piston_area_m2, model.charge_pressure_Pa
    v01, v02, beta = model.chamber_volume_1_m3, model.chamber_volume_2_m3, model.oil_compressibility_1_Pa
    g1, g2 = model.gas_1_Pa_m3, model.gas_2_Pa_m3
    c1, leak = model.c1, model.leakage_m3_s_Pa
    c1_neg = c1 if model.c1_neg is None else model.c1_neg
    c1_c1, c1n_c1n, four_c2_pos, four_c2_neg = c1 * c1, c1_neg * c1_neg, 4.0 * model.c2_pos, 4.0 * model.c2_neg
    pc, rho = model.relief_cracking_pressure_Pa, model.density_kg_m3
    relief = pc is not None and model.relief_area_gradient_m2_Pa > 0.0
    k_relief = model.relief_discharge_coefficient * model.relief_area_gradient_m2_Pa
    contact, rest = piece.contact, piece.rest_m
    act = piece.actuator
    sine = isinstance(act, SineActuatorPiece)       # a sine's kinematics from its own closed form
    ts, cs, v, tau, k = (0.0,) * 5 if sine else (act.t_start_s, act.command_start_m, act.velocity_m_s, act.lag_s,
                                                  act.transient_m)
    off = piece.offset_m
    lag = tau > 0.0
    at_position = _position_flow(model)

    def terms(tt, u):
        """(C1, dC1/dp1, C2, dC2/dp2, net flow A dy/dt - Q12, dQ12/ddp)."""
        u0, u1 = u.tolist()
        if not contact:
            y, ydot = rest, 0.0
        elif sine:
            y, ydot = act.state(tt)
            y += off
        elif lag:
            s = tt - ts
            e = math.exp(-s / tau)
            y, ydot = cs + v * (s - tau) + k * e + off, v - k / tau * e
        else:
            y, ydot = cs + v * (tt - ts) + off, v
        p, vol = p0 + u0, v01 - a * y
        if g1 == 0.0:
            c1_, d1 = beta * vol, 0.0
        else:
            c1_, d1 = beta * (vol - g1 / p) + g1 / (p * p), beta * g1 / (p * p) - 2.0 * g1 / (p * p * p)
        p, vol = p0 + u1, v02 + a * y
        if g2 == 0.0:
            c2_, d2 = beta * vol, 0.0
        else:
            c2_, d2 = beta * (vol - g2 / p) + g2 / (p * p), beta * g2 / (p * p) - 2.0 * g2 / (p * p * p)
        dp = u0 - u1
        ad = abs(dp)
        pos = dp >= 0.0
        root = math.sqrt((c1_c1 if pos else c1n_c1n) + (four_c2_pos if pos else four_c2_neg) * ad)
        q = 2.0 * dp / ((c1 if pos else c1_neg) + root) + leak * dp
        dq = 1.0 / root + leak
        if relief and ad > pc:
            sq = math.sqrt(2.0 * ad / rho)
            q += math.copysign(k_relief * (ad - pc) * sq, dp)
            dq += k_relief * (sq + (ad - pc) / (rho * sq))
        if at_position is not None:
            q_y, dq_y = at_position(y, dp, ad)
            q += q_y
            dq += dq_y
        return c1_, d1, c2_, d2, a * ydot - q, dq

    def rhs(tt, u):
        c1_, _, c2_, _, net, _ = terms(tt, u)
        return [net / c1_, -net / c2_]

    def jac(tt, u):
        c1_, d1, c2_, d2, net, dq = terms(tt, u)
        return [[-dq / c1_ - net * d1 / (c1_ * c1_), dq / c1_],
                [dq / c2_, -dq / c2_ + net * d2 / (c2_ * c2_)]]

    return rhs, jac


def integrate_pressures(case: RigCase, model: ChamberModel, pieces: Sequence[PistonPiece],
                        rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """p1, p2 (absolute) at the sample times by LSODA piece by piece (analytic Jacobian).

    Returns (t_s, p1_Pa, p2_Pa). Absolute tolerance: ``rtol`` times the steady dp at W (Eq. 24).
    Cavitation is not modelled: an oil-only chamber's equation is linear in p, so p < 0 (dp
    above about 2 p0, e.g. ~12 MPa at 1.5 mm/s for the Table-1 damper) is integrated as is;
    a chamber with gas keeps p > 0 (the expanding gas absorbs the volume), else ValueError.
    """
    from scipy.integrate import solve_ivp  # scipy.integrate (~0.4 s): only where the rig runs

    t = case.sample_times_s()
    p0 = model.charge_pressure_Pa
    atol = rtol * max(abs(steady_pressure_difference(model.piston_area_m2 * case.peak_speed_m_s, model)), 1.0)
    p1_out = np.empty_like(t)
    p2_out = np.empty_like(t)
    state = np.zeros(2)
    for piece in pieces:
        ta, tb = piece.t_start_s, piece.t_end_s
        sel = (t >= ta) & ((t < tb) | ((tb == pieces[-1].t_end_s) & (t <= tb)))
        t_sel = t[sel]
        if tb > ta:
            rhs, jac = _piece_system(model, piece)
            closed = t_sel.size > 0 and t_sel[-1] == tb
            t_eval = t_sel if closed else np.append(t_sel, tb)
            sol = solve_ivp(rhs, (ta, tb), state, method="LSODA", jac=jac, rtol=rtol, atol=atol, t_eval=t_eval)
            if not sol.success:
                raise RuntimeError(f"case {case.case_id}: integration failed on [{ta}, {tb}]: {sol.message}")
            p1_out[sel] = p0 + sol.y[0, :t_sel.size]
            p2_out[sel] = p0 + sol.y[1, :t_sel.size]
            state = sol.y[:, -1].copy()
    if (model.gas_1_Pa_m3 > 0.0 and np.any(p1_out <= 0.0)) or (model.gas_2_Pa_m3 > 0.0 and np.any(p2_out <= 0.0)):
        raise ValueError(f"case {case.case_id}: a gas-filled chamber reached zero pressure")
    return t, p1_out, p2_out


def true_series(case: RigCase, damper=TABLE1, effects: TrueEffects = NOMINAL_EFFECTS,
                rig: RigImperfections = IDEAL_RIG, case_index: int = 0, n_cases: int = 1,
                rtol: float = 1e-10, viscosity_ratio: float = 1.0, orifice_area_ratio: float = 1.0) -> pd.DataFrame:
    """Noise-free record of one case at the sample times; ``viscosity_ratio`` multiplies the case's
    viscosity (the oil at this case's temperature: :func:`vogel_viscosity_ratio`), ``orifice_area_ratio`` its
    orifice's area (wear: :func:`campaign_drift`).

    Columns: time_s, command_m (ideal, undelayed), actuator_m (x, what the LVDT sees), piston_m,
    piston_velocity_m_s, p1_Pa, p2_Pa (absolute), viscosity_Pa_s (this case, after drift),
    force_N (true load-cell force, Eq. 8, plus a gas spring's k y; 0 in a backlash gap unless
    ``effects.backlash_gap_force == "hydraulic"``).
    """
    mu = case_viscosity(damper, effects, rig, case_index, n_cases) * float(viscosity_ratio)
    model = chamber_model(damper, effects, mu, orifice_area_ratio)
    _check_stroke(case, model)
    pieces = piston_pieces(case, effects, rig)
    t, p1, p2 = integrate_pressures(case, model, pieces, rtol)
    actuator = np.empty_like(t)
    piston = np.empty_like(t)
    velocity = np.empty_like(t)
    contact = np.empty(t.size, dtype=bool)
    for i, piece in enumerate(pieces):
        last = i == len(pieces) - 1
        sel = (t >= piece.t_start_s) & ((t < piece.t_end_s) | (last & (t <= piece.t_end_s)))
        actuator[sel] = piece.actuator.position(t[sel])
        piston[sel] = piece.position(t[sel])
        velocity[sel] = piece.velocity(t[sel])
        contact[sel] = piece.contact
    friction = stribeck_friction(velocity, effects.coulomb_force_N, effects.stribeck_force_N,
                                 effects.stribeck_velocity_m_s, effects.friction_regularisation_m_s)
    force = model.piston_area_m2 * (p1 - p2) + friction + effects.gas_spring_N_m * piston
    if effects.backlash_gap_force == "zero":
        force = np.where(contact, force, 0.0)
    return pd.DataFrame({
        "time_s": t,
        "command_m": case.command_m(t),
        "actuator_m": actuator,
        "piston_m": piston,
        "piston_velocity_m_s": velocity,
        "p1_Pa": p1,
        "p2_Pa": p2,
        "viscosity_Pa_s": np.full(t.size, mu),
        "force_N": force + 0.0,
    })
