"""Optimiser units of each candidate damper effect: scaled to order one, bounded, mapped to SI.

The catalogue's effects (:data:`isokinetic.physics.effects.CATALOGUE`) each have one parameter, its record's
``field`` (Coulomb friction force, leakage conductance, discharge asymmetry, one-sided flow-path resistance,
discharge coefficient, viscosity and air volume fraction, the effect forms of :mod:`isokinetic.physics.damper`);
its record's :class:`~isokinetic.physics.effects.Fit` names the optimiser unit (:data:`TRANSFORMS`), the bounds
and the starting points.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from isokinetic.physics.damper import AIR_COMPRESSIBILITY_1_PA, Damper, Effects, laminar_coefficient
from isokinetic.physics.effects import BY_NAME, CATALOGUE, Effect


@dataclass(frozen=True)
class Transform:
    """An optimiser unit: ``to_si(p, field, x)`` the SI value of optimiser value x, ``from_si(p, field, v)`` its
    inverse (``p`` the campaign's :class:`Parametrisation`, ``field`` the effect's Effects field)."""

    to_si: Callable[[Parametrisation, str, float], float]
    from_si: Callable[[Parametrisation, str, float], float]


#: The optimiser units a record's Fit.transform names (:class:`isokinetic.physics.effects.Fit`).
TRANSFORMS = {
    "per_force_ref": Transform(lambda p, f, x: x * p.force_ref_N, lambda p, f, v: v / p.force_ref_N),
    "laminar_conductance": Transform(lambda p, f, x: x / p.c1, lambda p, f, v: v * p.c1),
    "identity": Transform(lambda p, f, x: x, lambda p, f, v: v),
    "log1p": Transform(lambda p, f, x: math.expm1(x), lambda p, f, v: math.log1p(v)),
    "log_nominal": Transform(lambda p, f, x: getattr(p.damper, f) * math.exp(x),
                             lambda p, f, v: math.log(v / getattr(p.damper, f))),
    "air_vs_oil": Transform(lambda p, f, x: x / p.air_ratio, lambda p, f, v: v * p.air_ratio),
}


@dataclass(frozen=True)
class Parametrisation:
    """Optimiser units of each effect's parameter, scaled to order one for this campaign.

    friction: F_C / F_ref (F_ref median |F| of the windows); leakage: g·c1 (leakage relative to the
    orifice's laminar conductance); asymmetry: a; path_asymmetry: ln(1 + b); discharge, viscosity: ln(θ/θ_nominal);
    air: V_G/V_C · β_air/β_oil (air compressibility relative to the oil's). Each from its registry record.
    """

    damper: Damper
    force_ref_N: float

    @property
    def c1(self) -> float:
        """The nominal orifice's laminar coefficient c1 [Pa s/m³]."""
        return float(laminar_coefficient(self.damper))

    @property
    def air_ratio(self) -> float:
        """β_air / β_oil of the damper's oil."""
        return AIR_COMPRESSIBILITY_1_PA / self.damper.oil_compressibility_1_Pa

    @staticmethod
    def _record(effect: str) -> Effect:
        record = BY_NAME.get(effect)
        if record is None or record.fit is None:
            raise KeyError(f"unknown effect {effect!r}; known: {CATALOGUE}")
        return record

    def bounds(self, effect: str) -> tuple[float, float]:
        """Bounds of the effect's optimiser value."""
        record = self._record(effect)
        fit = record.fit
        if not fit.bounds_si:
            return fit.bounds
        back = TRANSFORMS[fit.transform].from_si
        lo, hi = fit.bounds
        return back(self, record.field, lo), back(self, record.field, hi)

    def starts(self, effect: str) -> list[float]:
        """Starting points of a single-effect fit (two, to avoid a local minimum)."""
        return list(self._record(effect).fit.starts)

    def si(self, effect: str, x: float) -> tuple[str, float]:
        """(SI parameter name, value) of an optimiser value (clipped to the effect's bounds)."""
        record = self._record(effect)
        lo, hi = self.bounds(effect)
        x = min(max(float(x), lo), hi)
        # only the requested effect is evaluated: exp() of another effect's value may overflow
        return record.field, TRANSFORMS[record.fit.transform].to_si(self, record.field, x)

    def effects(self, names: Sequence[str], x: Sequence[float]) -> Effects:
        return Effects(**dict(self.si(n, v) for n, v in zip(names, x, strict=True)))
