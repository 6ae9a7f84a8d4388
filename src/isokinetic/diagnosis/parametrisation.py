"""Optimiser units of each candidate damper effect: scaled to order one, bounded, mapped to SI.

The catalogue's effects (:data:`isokinetic.contracts.scenarios.CATALOGUE`) each have one parameter:
Coulomb friction force, leakage conductance, discharge asymmetry, one-sided flow-path resistance,
discharge coefficient, viscosity and air volume fraction, the effect forms of :mod:`isokinetic.physics.damper`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from isokinetic.contracts.scenarios import CATALOGUE
from isokinetic.physics.damper import AIR_COMPRESSIBILITY_1_PA, Damper, Effects, laminar_coefficient


@dataclass(frozen=True)
class Parametrisation:
    """Optimiser units of each effect's parameter, scaled to order one for this campaign.

    friction: F_C / F_ref (F_ref median |F| of the windows); leakage: g·c1 (leakage relative to the
    orifice's laminar conductance); asymmetry: a; path_asymmetry: ln(1 + b); discharge, viscosity: ln(θ/θ_nominal);
    air: V_G/V_C · β_air/β_oil (air compressibility relative to the oil's).
    """

    damper: Damper
    force_ref_N: float

    @property
    def _c1(self) -> float:
        return float(laminar_coefficient(self.damper))

    @property
    def _air_ratio(self) -> float:
        return AIR_COMPRESSIBILITY_1_PA / self.damper.oil_compressibility_1_Pa

    def bounds(self, effect: str) -> tuple[float, float]:
        return {"friction": (0.0, 20.0), "leakage": (0.0, 1.0e3), "asymmetry": (-0.9, 0.9),
                "path_asymmetry": (math.log(0.2), math.log(5.0)),
                "discharge": (math.log(0.1), math.log(10.0)), "viscosity": (math.log(0.02), math.log(50.0)),
                "air": (0.0, 0.5 * AIR_COMPRESSIBILITY_1_PA / self.damper.oil_compressibility_1_Pa)}[effect]

    def starts(self, effect: str) -> list[float]:
        """Starting points of a single-effect fit (two, to avoid a local minimum)."""
        return {"friction": [0.01, 0.3], "leakage": [0.05, 3.0], "asymmetry": [0.02, -0.02],
                "path_asymmetry": [0.02, -0.02],
                "discharge": [0.2, -0.2], "viscosity": [0.2, -0.2], "air": [0.05, 5.0]}[effect]

    def si(self, effect: str, x: float) -> tuple[str, float]:
        """(SI parameter name, value) of an optimiser value (clipped to the effect's bounds)."""
        d = self.damper
        lo, hi = self.bounds(effect)
        x = min(max(float(x), lo), hi)
        # only the requested effect is evaluated: exp() of another effect's value may overflow
        if effect == "friction":
            return "coulomb_force_N", x * self.force_ref_N
        if effect == "leakage":
            return "leakage_conductance_m3_s_Pa", x / self._c1
        if effect == "asymmetry":
            return "asymmetry", x
        if effect == "path_asymmetry":
            return "path_asymmetry", math.expm1(x)
        if effect == "discharge":
            return "discharge_coefficient", d.discharge_coefficient * math.exp(x)
        if effect == "viscosity":
            return "viscosity_Pa_s", d.viscosity_Pa_s * math.exp(x)
        if effect == "air":
            return "air_volume_fraction", x / self._air_ratio
        raise KeyError(f"unknown effect {effect!r}; known: {CATALOGUE}")

    def effects(self, names: Sequence[str], x: Sequence[float]) -> Effects:
        return Effects(**dict(self.si(n, v) for n, v in zip(names, x, strict=True)))
