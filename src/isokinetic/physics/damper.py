"""Damper parameters and the paper's closed-form physics (SI units throughout).

The paper is "A method for the identification of hydraulic damper characteristics from steady
velocity inputs" (Titurus et al.); equation and table numbers are its own. :data:`TABLE_1` is the
damper of its Table 1.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from isokinetic.physics.effects import REGISTRY

#: Isothermal compressibility of air at atmospheric pressure, Table 1 [1/Pa].
AIR_COMPRESSIBILITY_1_PA = 9.9e-6


@dataclass(frozen=True)
class Damper:
    """Nominal design data of a two-chamber symmetric damper (Table 1 quantities).

    ``charge_pressure_Pa`` (optional, not in Table 1) is the absolute pressure p0 of both chambers at
    rest (the accumulator's precharge). Declared, entrained air follows the isothermal gas law around
    it (:mod:`isokinetic.physics.gas_law`); without it the air term of Eq. (3) is constant.
    """

    piston_area_m2: float
    chamber_volume_1_m3: float
    chamber_volume_2_m3: float
    orifice_area_m2: float
    orifice_length_m: float
    discharge_coefficient: float
    density_kg_m3: float
    viscosity_Pa_s: float
    oil_compressibility_1_Pa: float
    charge_pressure_Pa: float | None = None

    #: Design data a damper block may leave out.
    OPTIONAL = ("charge_pressure_Pa",)

    @classmethod
    def required(cls) -> list[str]:
        """The field names a damper block must give."""
        return [f.name for f in dataclasses.fields(cls) if f.name not in cls.OPTIONAL]

    @classmethod
    def from_mapping(cls, values: Mapping[str, float]) -> Damper:
        """The damper of a mapping of the field names (the optional ones may be absent or None); raises
        KeyError naming a missing key, ValueError naming one that is not a positive number."""
        names = [f.name for f in dataclasses.fields(cls)]
        missing = [n for n in cls.required() if n not in values]
        if missing:
            raise KeyError(f"damper: missing key {missing[0]!r}")
        out = {}
        for n in names:
            v = values.get(n)
            if v is None and n in cls.OPTIONAL:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
                raise ValueError(f"damper: key {n!r} must be a positive number, got {v!r}")
            out[n] = float(v)
        return cls(**out)

    def to_dict(self) -> dict[str, float]:
        """The design data by field name; an optional datum left out is absent."""
        return {k: v for k, v in dataclasses.asdict(self).items() if not (v is None and k in self.OPTIONAL)}


@dataclass(frozen=True)
class Effects:
    """Physical effects the nominal model lacks; all zero/None means the nominal damper.

    friction
        Coulomb seal friction ``coulomb_force_N``, with an optional Stribeck term: an extra
        breakaway force ``stribeck_force_N`` decaying as exp(-(|v|/stribeck_velocity_m_s)^2).
    leakage
        Parallel laminar cross-piston path, Q_L = ``leakage_conductance_m3_s_Pa`` * Δp.
    asymmetry
        Direction-dependent discharge coefficient: C_D(1 + a) for positive flow (Δp > 0)
        and C_D(1 - a) for negative flow, a = ``asymmetry``.
    path_asymmetry
        One-sided resistance of the whole flow path (a second valve stack or a check valve in one
        direction): for negative flow (Δp < 0, the − direction) both the laminar and the turbulent
        coefficient of Eq. (7) are multiplied by (1 + b), b = ``path_asymmetry`` > -1, so that
        Δp = (1 + b)(c1 Q + c2 Q|Q|) for Q < 0; positive flow keeps the nominal path.
    discharge, viscosity
        ``discharge_coefficient`` / ``viscosity_Pa_s`` replacing the nominal value.
    air
        Entrained air volume fraction V_G/V_C in Eq. (3): the gas term of β_eff is φ β_G at rest. With
        the damper's ``charge_pressure_Pa`` it follows the gas law as the chamber pressures move
        (:mod:`isokinetic.physics.gas_law`).
    backlash
        Total free play ``backlash_m`` in the attachment (a play operator between actuator
        and piston).
    """

    coulomb_force_N: float = 0.0
    stribeck_force_N: float = 0.0
    stribeck_velocity_m_s: float = 1.0e-5
    leakage_conductance_m3_s_Pa: float = 0.0
    asymmetry: float = 0.0
    path_asymmetry: float = 0.0
    discharge_coefficient: float | None = None
    viscosity_Pa_s: float | None = None
    air_volume_fraction: float = 0.0
    backlash_m: float = 0.0

    #: config group name -> {config key: field name}, from the effect registry
    CONFIG_KEYS = {e.name: e.config_keys for e in REGISTRY}

    @classmethod
    def from_config(cls, groups: Mapping[str, Mapping[str, float]] | None) -> Effects:
        """The effects of the grouped config form ``{friction: {coulomb_force_N: 90}, ...}``."""
        kwargs: dict[str, float] = {}
        for group, values in (groups or {}).items():
            if group not in cls.CONFIG_KEYS:
                raise KeyError(f"effects: unknown effect {group!r}; known: {sorted(cls.CONFIG_KEYS)}")
            for key, value in (values or {}).items():
                if key not in cls.CONFIG_KEYS[group]:
                    raise KeyError(f"effects.{group}: unknown key {key!r}")
                kwargs[cls.CONFIG_KEYS[group][key]] = float(value)
        return cls(**kwargs)

    def active(self) -> list[str]:
        """The names of the effect groups that differ from the nominal model (registry order: a field of the record's
        ``active_fields`` away from its default)."""
        return [e.name for e in REGISTRY if any(getattr(self, f) != _FIELD_DEFAULTS[f] for f in e.active_fields)]


#: Each Effects field's default (the nominal model's value).
_FIELD_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Effects)}

NOMINAL = Effects()

#: Table 1 of the paper: geometry measured from the physical damper and the assumed oil properties, SI.
TABLE_1 = Damper(piston_area_m2=4.0e-3, chamber_volume_1_m3=3.0e-4, chamber_volume_2_m3=3.0e-4,
                 orifice_area_m2=6.0e-8, orifice_length_m=5.0e-4, discharge_coefficient=0.6,
                 density_kg_m3=815.0, viscosity_Pa_s=0.03, oil_compressibility_1_Pa=3.8e-9)


def laminar_coefficient(damper: Damper, effects: Effects = NOMINAL, direction: float = 0.0) -> float:
    """c1 = 8 π μ l_O / A_O² (Sec. 2.2, Table 1) [Pa s/m³].

    ``direction`` < 0 selects the negative-flow path, scaled by 1 + ``effects.path_asymmetry``.
    """
    mu = damper.viscosity_Pa_s if effects.viscosity_Pa_s is None else effects.viscosity_Pa_s
    c1 = 8.0 * np.pi * mu * damper.orifice_length_m / damper.orifice_area_m2**2
    return c1 * (1.0 + effects.path_asymmetry) if direction < 0 and effects.path_asymmetry else c1


def turbulent_coefficient(damper: Damper, effects: Effects = NOMINAL, direction: float = 0.0) -> float:
    """c2 = ρ / (2 C_D² A_O²) (Sec. 2.2, Table 1) [Pa s²/m⁶].

    ``direction`` > 0 or < 0 selects the asymmetric C_D(1 ± a) of ``effects.asymmetry``; < 0 also
    the negative-flow path's factor 1 + ``effects.path_asymmetry``.
    """
    cd = damper.discharge_coefficient if effects.discharge_coefficient is None else effects.discharge_coefficient
    cd = cd * (1.0 + np.sign(direction) * effects.asymmetry)
    c2 = damper.density_kg_m3 / (2.0 * cd**2 * damper.orifice_area_m2**2)
    return c2 * (1.0 + effects.path_asymmetry) if direction < 0 and effects.path_asymmetry else c2


def orifice_flow(dp_Pa, c1: float, c2: float):
    """Laminar-turbulent orifice flow Q(Δp), Eq. (7) [m³/s], c1 [Pa s/m³], c2 [Pa s²/m⁶]; c1 or c2 = 0: the limits."""
    dp = np.asarray(dp_Pa, dtype=float)
    if c2 == 0.0:
        return dp / c1
    a = np.abs(dp)
    if c1 == 0.0:
        return np.sign(dp) * np.sqrt(a / c2)
    # (-c1 + sqrt(c1² + 4 c2 |Δp|)) / (2 c2), written without cancellation for small |Δp|
    q = 2.0 * a / (c1 + np.sqrt(c1 * c1 + 4.0 * c2 * a))
    return np.sign(dp) * q


def orifice_pressure(q_m3_s, c1: float, c2: float):
    """Δp(Q) = c1 Q + c2 Q|Q|, Eq. (7) [Pa], c1 [Pa s/m³], c2 [Pa s²/m⁶]."""
    q = np.asarray(q_m3_s, dtype=float)
    return c1 * q + c2 * q * np.abs(q)


def effective_compressibility(damper: Damper, effects: Effects = NOMINAL) -> float:
    """β_eff ≈ β_0,F + (V_G/V_C) β_G, Eq. (3) with rigid walls and fixtures [1/Pa]."""
    return damper.oil_compressibility_1_Pa + effects.air_volume_fraction * AIR_COMPRESSIBILITY_1_PA


def chamber_volumes(y_m, damper: Damper):
    """V1 = V0,1 - A_p y, V2 = V0,2 + A_p y, Eq. (2) [m³]."""
    y = np.asarray(y_m, dtype=float)
    return (damper.chamber_volume_1_m3 - damper.piston_area_m2 * y,
            damper.chamber_volume_2_m3 + damper.piston_area_m2 * y)


def composite_volume(y_m, damper: Damper):
    """𝒱 = V1 V2 / (V1 + V2), Eq. (2) [m³]."""
    v1, v2 = chamber_volumes(y_m, damper)
    return v1 * v2 / (v1 + v2)


def friction_force(velocity_m_s, effects: Effects):
    """Seal friction F_f(v) = sign(v) [F_C + F_S exp(-(|v|/v_S)²)] (Coulomb with Stribeck) [N]."""
    v = np.asarray(velocity_m_s, dtype=float)
    stribeck = 0.0
    if effects.stribeck_force_N:
        stribeck = effects.stribeck_force_N * np.exp(-((v / effects.stribeck_velocity_m_s) ** 2))
    return np.sign(v) * (effects.coulomb_force_N + stribeck)


def nominal_force(velocity_m_s, damper: Damper, discharge_coefficient: float | None = None, laminar: bool = True):
    """Incompressible steady hydraulic force, Eq. (31)-(32) [N].

    F = A_p² c1 v + A_p³ c2 v|v|; ``laminar=False`` gives the purely turbulent 'T' family.
    """
    effects = NOMINAL if discharge_coefficient is None else Effects(discharge_coefficient=discharge_coefficient)
    v = np.asarray(velocity_m_s, dtype=float)
    a = damper.piston_area_m2
    c1 = laminar_coefficient(damper) if laminar else 0.0
    c2 = turbulent_coefficient(damper, effects)
    return a**2 * c1 * v + a**3 * c2 * v * np.abs(v)


def stroke_ratio(d, damper: Damper):
    """R(d) = (1 - d) / (1 + (V0,1/V0,2) d) [-] of the normalised stroke d [-], Eq. (15)."""
    d = np.asarray(d, dtype=float)
    return (1.0 - d) / (1.0 + damper.chamber_volume_1_m3 / damper.chamber_volume_2_m3 * d)


def laminar_step_pressure(t_s, velocity_m_s: float, damper: Damper, effects: Effects = NOMINAL):
    """Δp(t) after a velocity step from rest with Δp(0)=0, laminar flow (c2 = 0), Eq. (18) [Pa].

    The piston starts where the chamber volumes are ``damper.chamber_volume_*`` and moves
    with constant positive ``velocity_m_s``.
    """
    w = velocity_m_s
    a = damper.piston_area_m2
    c1 = laminar_coefficient(damper, effects)
    bulk = 1.0 / effective_compressibility(damper, effects)
    d = np.asarray(t_s, dtype=float) / (damper.chamber_volume_1_m3 / (a * w))
    return a * w * c1 * (1.0 - stroke_ratio(d, damper) ** (bulk / (a * w * c1)))


def turbulent_step_pressure(t_s, velocity_m_s: float, damper: Damper, effects: Effects = NOMINAL):
    """Δp(t) after a velocity step, turbulent flow (c1 = 0): solves the implicit Eq. (20) [Pa].

    Eq. (20) reads x = (1 - R^G e^{-x})², with x = sqrt(Δp / ((A_p W)² c2)) after taking the
    root and G = B_eff / (2 (A_p W)² c2) (G2 of Eq. 21); solved per sample by Newton's method.
    """
    w = velocity_m_s
    a = damper.piston_area_m2
    c2 = turbulent_coefficient(damper, effects)
    scale = (a * w) ** 2 * c2
    g2 = 1.0 / effective_compressibility(damper, effects) / (2.0 * scale)
    d = np.asarray(t_s, dtype=float) / (damper.chamber_volume_1_m3 / (a * w))
    rg = stroke_ratio(d, damper) ** g2
    # s = sqrt(Δp/scale) solves s = 1 - rg e^{-s}; f(s) = s - 1 + rg e^{-s} is monotone (f' >= 1 - rg > 0)
    s = 1.0 - rg
    for _ in range(60):
        f = s - 1.0 + rg * np.exp(-s)
        step = f / (1.0 - rg * np.exp(-s))
        s = s - step
        if np.all(np.abs(step) <= 1e-15 * np.maximum(np.abs(s), 1e-300)):
            break
    return scale * s**2
