"""Optimiser units of the candidate effects (isokinetic.diagnosis.parametrisation)."""

import math

import pytest

from isokinetic.contracts.scenarios import CATALOGUE
from isokinetic.diagnosis.parametrisation import Parametrisation
from isokinetic.physics.damper import TABLE_1, Effects


def test_parametrisation_maps_optimiser_units_to_si():
    p = Parametrisation(TABLE_1, force_ref_N=1000.0)
    c1 = 8 * math.pi * 0.03 * 5e-4 / 6e-8**2
    assert p.si("friction", 0.05) == ("coulomb_force_N", pytest.approx(50.0))
    assert p.si("leakage", 0.2) == ("leakage_conductance_m3_s_Pa", pytest.approx(0.2 / c1))
    assert p.si("discharge", math.log(1.5)) == ("discharge_coefficient", pytest.approx(0.9))
    assert p.si("viscosity", 0.0) == ("viscosity_Pa_s", pytest.approx(0.03))
    assert p.si("air", 2.0) == ("air_volume_fraction", pytest.approx(2.0 * 3.8e-9 / 9.9e-6))
    assert p.effects(("friction", "asymmetry"), (0.05, 0.1)) == Effects(coulomb_force_N=50.0, asymmetry=0.1)
    assert p.si("path_asymmetry", math.log(1.12)) == ("path_asymmetry", pytest.approx(0.12))


def test_parametrisation_never_overflows_at_any_bound():
    p = Parametrisation(TABLE_1, force_ref_N=1000.0)
    for effect in CATALOGUE:
        lo, hi = p.bounds(effect)
        for x in (lo, hi, hi + 1e6, lo - 1e6):
            name, value = p.si(effect, x)
            assert math.isfinite(value), (effect, x, name)
