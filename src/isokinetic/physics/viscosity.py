"""Oil viscosity against temperature: the Walther equation of ASTM D341, and what a viscosity deviation
means as a temperature.

The paper's model (Sec. 2.2) takes one viscosity μ into the laminar coefficient c1 = 8 π μ l_O / A_O²;
a damper warms during a campaign, and its oil's viscosity falls by several per cent per kelvin. A
manifest (format 1.1) may give the law as two reference points, ``damper.viscosity_law: {kind: walther,
points: [[40.0, 0.030], [100.0, 0.006]]}`` ([°C, Pa s]); each case is then modelled at its own
temperature.

Walther (ASTM D341): log10 log10(ν + 0.7) = A - B log10 T, with ν the kinematic viscosity in mm²/s
(cSt) and T the absolute temperature in K; two points fix A and B. The dynamic viscosity is μ = ρ ν
with the damper's constant density: the oil's thermal expansion (about 0.07 % per K) is neglected, as
the model's density is one number. The form holds for ν above about 2 mm²/s (ASTM D341's range of the
plain 0.7 offset), which every damper oil meets in its working range.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

#: Absolute temperature of 0 °C [K].
ZERO_CELSIUS_K = 273.15
#: Offset of the Walther equation (ASTM D341) for ν in mm²/s.
WALTHER_OFFSET_MM2_S = 0.7
#: Viscosity-temperature laws a manifest may name.
LAW_KINDS = ("walther",)
#: Lowest kinematic viscosity at a reference point [mm²/s]: log10(ν + 0.7) must be positive.
MIN_KINEMATIC_MM2_S = 0.31


@dataclass(frozen=True)
class ViscosityLaw:
    """A viscosity-temperature law through reference points ``((T [°C], μ [Pa s]), ...)`` of an oil of
    ``density_kg_m3`` (kinematic ν = μ / ρ)."""

    kind: str
    points: tuple[tuple[float, float], ...]
    density_kg_m3: float

    def __post_init__(self):
        if self.kind not in LAW_KINDS:
            raise ValueError(f"viscosity law: unknown kind {self.kind!r}; known: {', '.join(LAW_KINDS)}")
        if len(self.points) != 2:
            raise ValueError(f"viscosity law {self.kind}: needs exactly two points [T_C, mu_Pa_s], "
                             f"got {len(self.points)}")
        (t1, mu1), (t2, mu2) = self.points
        if not all(math.isfinite(x) for x in (t1, mu1, t2, mu2)) or mu1 <= 0 or mu2 <= 0:
            raise ValueError("viscosity law: temperatures must be finite and viscosities positive numbers")
        if min(t1, t2) <= -ZERO_CELSIUS_K:
            raise ValueError("viscosity law: temperatures must lie above absolute zero (-273.15 C)")
        if t1 == t2:
            raise ValueError(f"viscosity law: the two points are at the same temperature ({t1:g} C)")
        if (mu2 - mu1) * (t2 - t1) >= 0:
            raise ValueError("viscosity law: viscosity must fall as the temperature rises, got "
                             f"{mu1:g} Pa s at {t1:g} C and {mu2:g} Pa s at {t2:g} C")
        for mu in (mu1, mu2):
            if mu / self.density_kg_m3 * 1e6 < MIN_KINEMATIC_MM2_S:
                raise ValueError(f"viscosity law: {mu:g} Pa s at density {self.density_kg_m3:g} kg/m3 is "
                                 f"below {MIN_KINEMATIC_MM2_S} mm2/s, outside the Walther equation's range")

    def to_dict(self) -> dict:
        """The manifest form ``{kind: walther, points: [[T_C, mu_Pa_s], ...]}`` (:func:`law_from_mapping`)."""
        return {"kind": self.kind, "points": [list(p) for p in self.points]}

    @property
    def coefficients(self) -> tuple[float, float]:
        """(A, B) of the Walther equation through the two points."""
        (t1, mu1), (t2, mu2) = self.points
        w1 = walther_w(mu1 / self.density_kg_m3)
        w2 = walther_w(mu2 / self.density_kg_m3)
        x1, x2 = math.log10(t1 + ZERO_CELSIUS_K), math.log10(t2 + ZERO_CELSIUS_K)
        b = (w1 - w2) / (x2 - x1)
        return w1 + b * x1, b

    def viscosity_Pa_s(self, temperature_C):
        """μ(T) [Pa s] (Walther, ASTM D341)."""
        a, b = self.coefficients
        w = a - b * np.log10(np.asarray(temperature_C, dtype=float) + ZERO_CELSIUS_K)
        return (10.0 ** (10.0 ** w) - WALTHER_OFFSET_MM2_S) * 1e-6 * self.density_kg_m3

    def temperature_C(self, viscosity_Pa_s):
        """T(μ) [°C], the inverse of :meth:`viscosity_Pa_s`."""
        a, b = self.coefficients
        w = walther_w(np.asarray(viscosity_Pa_s, dtype=float) / self.density_kg_m3)
        return 10.0 ** ((a - w) / b) - ZERO_CELSIUS_K


def walther_w(kinematic_m2_s):
    """W = log10 log10(ν + 0.7), ν in mm²/s (ASTM D341), of a kinematic viscosity in m²/s."""
    return np.log10(np.log10(np.asarray(kinematic_m2_s, dtype=float) * 1e6 + WALTHER_OFFSET_MM2_S))


def law_from_mapping(block, density_kg_m3: float) -> ViscosityLaw:
    """A :class:`ViscosityLaw` from the manifest form ``{kind: walther, points: [[T_C, mu_Pa_s], ...]}``;
    raises ValueError saying what is wrong."""
    if not isinstance(block, dict):
        raise ValueError(f"expected a mapping {{kind: walther, points: [[T_C, mu_Pa_s], [T_C, mu_Pa_s]]}}, "
                         f"got {block!r}")
    unknown = sorted(set(block) - {"kind", "points"})
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r} (a law has kind and points)")
    points = block.get("points")
    if not isinstance(points, Sequence) or isinstance(points, str) or not all(
            isinstance(p, Sequence) and not isinstance(p, str) and len(p) == 2 for p in points):
        raise ValueError(f"points must be a list of [T_C, mu_Pa_s] pairs, got {points!r}")
    try:
        pairs = tuple((_finite(t), _finite(mu)) for t, mu in points)
    except (TypeError, ValueError):
        raise ValueError(f"points must hold numbers, got {points!r}") from None
    return ViscosityLaw(kind=block.get("kind"), points=pairs, density_kg_m3=float(density_kg_m3))


def _finite(value) -> float:
    if isinstance(value, bool):
        raise TypeError(value)
    out = float(value)
    if not math.isfinite(out):
        raise ValueError(value)
    return out


def equivalent_temperature_offset_C(law: ViscosityLaw, temperature_C: float, viscosity_ratio: float) -> float:
    """ΔT [K] such that μ(T + ΔT) = ratio · μ(T): a viscosity deviation read as a temperature error
    (a ratio above 1, oil more viscous than the law says, is a negative ΔT: the oil runs colder)."""
    return float(law.temperature_C(law.viscosity_Pa_s(temperature_C) * viscosity_ratio)) - float(temperature_C)


def case_viscosity_scales(temperatures_C, law: ViscosityLaw | None, viscosity_Pa_s: float) -> np.ndarray:
    """μ(T_case) / μ_nominal [-] of each case: the factor on the laminar coefficient c1 (Sec. 2.2). 1 where
    the law or the case's temperature is unknown (NaN): the damper block's viscosity_Pa_s then holds."""
    t = np.asarray(temperatures_C, dtype=float)
    if law is None:
        return np.ones(t.shape)
    known = np.isfinite(t)
    out = np.ones(t.shape)
    out[known] = law.viscosity_Pa_s(t[known]) / viscosity_Pa_s
    return out
