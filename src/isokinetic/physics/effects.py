"""The effect registry: one :class:`Effect` record per effect of the damper model, the one place an effect is
described (issue 36).

Every consumer iterates :data:`REGISTRY` instead of a table of its own: the model's config groups and
:meth:`isokinetic.physics.damper.Effects.active`, the diagnosis' catalogue and its optimiser units
(:mod:`isokinetic.diagnosis.parametrisation`), the report's units (:mod:`isokinetic.report.diagnosis_section`),
the blind suite's draws (:mod:`isokinetic.blind.generate`, :mod:`isokinetic.contracts.scenarios`) and its
mapping onto the independent reference rig, which imports nothing of isokinetic and so is named here as data (the
field names of its ``TrueEffects``). ``tests/physics/test_effects.py`` walks every record through all of them.
Adding an effect: docs/architecture.md, "How to add an effect".

Imports nothing (the workflow reads the catalogue while it builds its graph).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Fit:
    """How the diagnosis fits the effect's one parameter (the record's ``field``, SI) in optimiser units.

    ``transform`` names the optimiser unit (a key of :data:`isokinetic.diagnosis.parametrisation.TRANSFORMS`):
    'per_force_ref' x = F / F_ref (F_ref the median |F| of the campaign's windows); 'laminar_conductance'
    x = g c1 (relative to the orifice's laminar conductance); 'identity' x = the value; 'log1p' x = ln(1 + b);
    'log_nominal' x = ln(θ / θ_nominal) (θ_nominal the damper's own value of the field); 'air_vs_oil'
    x = φ β_air / β_oil. ``bounds`` of x, in optimiser units, or in SI when ``bounds_si`` (mapped through the
    transform). ``starts``: the starting points of a single-effect fit (optimiser units).
    """

    transform: str
    bounds: tuple[float, float]
    starts: tuple[float, float]
    bounds_si: bool = False


@dataclass(frozen=True)
class BlindDraw:
    """How the blind suite draws the effect (:mod:`isokinetic.blind.generate`).

    ``form`` of the magnitude m (in ``unit``, the truth files' ``magnitude_unit``): 'absolute' the field is m;
    'signed' ±m (random sign); 'relative' the damper's nominal value times (1 ± m). ``bound``: the largest
    plausible magnitude; 5x the detection level must stay below it, else the scenario is re-drawn.
    """

    form: str
    bound: float
    unit: str

    @property
    def signed(self) -> bool:
        """Whether the magnitude carries a random sign."""
        return self.form != "absolute"


@dataclass(frozen=True)
class RigMapping:
    """The effect on the independent reference rig (:mod:`isokinetic.reference.rig`), as data: the field of its
    ``TrueEffects`` that carries it and, where the rig's form differs from the model's, the name of the rig's
    conversion from the model's value (a function of :mod:`isokinetic.reference.campaign`; '' the same value)."""

    field: str
    conversion: str = ""


@dataclass(frozen=True)
class Effect:
    """One effect of the damper model.

    ``name``: the effect's name and its config group (``virtual_campaigns.<c>.effects.<name>``); ``field``: the
    :class:`~isokinetic.physics.damper.Effects` field of its parameter (what the diagnosis fits and reports, SI)
    in ``unit`` (formula text, shown by the report); ``config``: (config key, Effects field) of its group;
    ``active_fields``: the fields that make it active away from their default; ``display_name``: the report's
    words for it. ``fit`` None: the diagnosis does not fit it (not in the catalogue); ``blind`` None: the blind
    suite does not draw it; ``rig`` None: the reference rig has no form of it.
    """

    name: str
    field: str
    unit: str
    display_name: str
    config: tuple[tuple[str, str], ...]
    active_fields: tuple[str, ...]
    fit: Fit | None = None
    rig: RigMapping | None = None
    blind: BlindDraw | None = None

    @property
    def config_keys(self) -> dict[str, str]:
        """{config key: Effects field} of the effect's config group."""
        return dict(self.config)


#: Every effect of the model, the diagnosis' catalogue first, in its canonical order (verdict and truth text).
REGISTRY: tuple[Effect, ...] = (
    Effect("friction", "coulomb_force_N", "N", "Coulomb friction force",
           (("coulomb_force_N", "coulomb_force_N"), ("stribeck_force_N", "stribeck_force_N"),
            ("stribeck_velocity_m_s", "stribeck_velocity_m_s")), ("coulomb_force_N", "stribeck_force_N"),
           Fit("per_force_ref", (0.0, 20.0), (0.01, 0.3)), RigMapping("coulomb_force_N"),
           BlindDraw("absolute", 2000.0, "coulomb_force_N")),
    Effect("leakage", "leakage_conductance_m3_s_Pa", "m^3/(s Pa)", "cross-piston leakage conductance",
           (("conductance_m3_s_Pa", "leakage_conductance_m3_s_Pa"),), ("leakage_conductance_m3_s_Pa",),
           Fit("laminar_conductance", (0.0, 1.0e3), (0.05, 3.0)),
           RigMapping("leakage_gap_m", "leakage_gap_from_conductance"),
           BlindDraw("absolute", 1.0e-10, "leakage_conductance_m3_s_Pa")),
    Effect("asymmetry", "asymmetry", "-", "discharge asymmetry",
           (("asymmetry", "asymmetry"),), ("asymmetry",),
           Fit("identity", (-0.9, 0.9), (0.02, -0.02)), RigMapping("asymmetry"),
           BlindDraw("signed", 0.5, "abs(asymmetry)")),
    Effect("path_asymmetry", "path_asymmetry", "-", "one-sided flow-path resistance",
           (("path_asymmetry", "path_asymmetry"),), ("path_asymmetry",),
           Fit("log1p", (math.log(0.2), math.log(5.0)), (0.02, -0.02)), RigMapping("path_resistance_neg")),
    Effect("discharge", "discharge_coefficient", "-", "discharge coefficient",
           (("discharge_coefficient", "discharge_coefficient"),), ("discharge_coefficient",),
           Fit("log_nominal", (math.log(0.1), math.log(10.0)), (0.2, -0.2)), RigMapping("discharge_coefficient"),
           BlindDraw("relative", 0.5, "abs(C_D/C_D0 - 1)")),
    Effect("viscosity", "viscosity_Pa_s", "Pa s", "oil viscosity",
           (("viscosity_Pa_s", "viscosity_Pa_s"),), ("viscosity_Pa_s",),
           Fit("log_nominal", (math.log(0.02), math.log(50.0)), (0.2, -0.2)), RigMapping("viscosity_Pa_s"),
           BlindDraw("relative", 0.8, "abs(mu/mu0 - 1)")),
    Effect("air", "air_volume_fraction", "-", "entrained air volume fraction",
           (("volume_fraction", "air_volume_fraction"),), ("air_volume_fraction",),
           Fit("air_vs_oil", (0.0, 0.5), (0.05, 5.0), bounds_si=True),
           RigMapping("air_fraction_at_charge", "air_fraction_from_catalogue"),
           BlindDraw("absolute", 0.2, "air_volume_fraction")),
    Effect("backlash", "backlash_m", "m", "free play in the attachment",
           (("gap_m", "backlash_m"),), ("backlash_m",), rig=RigMapping("backlash_m")),
)

#: Each effect by name.
BY_NAME: dict[str, Effect] = {e.name: e for e in REGISTRY}
#: The diagnosis' catalogue: the effects it fits, in canonical order.
CATALOGUE: tuple[str, ...] = tuple(e.name for e in REGISTRY if e.fit is not None)
#: The effects the blind suite draws, in canonical order.
BLIND_EFFECTS: tuple[str, ...] = tuple(e.name for e in REGISTRY if e.blind is not None)


def effect(name: str) -> Effect:
    """The record of effect ``name``; KeyError naming the known ones."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown effect {name!r}; known: {tuple(BY_NAME)}") from None
