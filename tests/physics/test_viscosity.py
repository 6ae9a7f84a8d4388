"""The viscosity-temperature law (Walther, ASTM D341) and a viscosity deviation read as a temperature."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.physics.viscosity import (
    ViscosityLaw,
    case_viscosity_scales,
    equivalent_temperature_offset_C,
    law_from_mapping,
)
from isokinetic.reference import rig as rr

DENSITY = 815.0
LAW = ViscosityLaw("walther", ((40.0, 0.030), (100.0, 0.006)), DENSITY)


def test_the_law_passes_through_its_two_points():
    assert LAW.viscosity_Pa_s([40.0, 100.0]) == pytest.approx([0.030, 0.006], rel=1e-12)


def test_the_law_is_the_walther_line_of_astm_d341():
    # independent evaluation: log10 log10(nu + 0.7) is a straight line in log10 T (T in K, nu in mm2/s)
    def w(mu):
        return math.log10(math.log10(mu / DENSITY * 1e6 + 0.7))

    x40, x100, x70 = (math.log10(t + 273.15) for t in (40.0, 100.0, 70.0))
    w70 = w(0.030) + (w(0.006) - w(0.030)) * (x70 - x40) / (x100 - x40)
    nu70_mm2_s = 10 ** (10 ** w70) - 0.7
    assert float(LAW.viscosity_Pa_s(70.0)) == pytest.approx(nu70_mm2_s * 1e-6 * DENSITY, rel=1e-12)


def test_between_its_points_the_law_follows_a_vogel_oil_within_one_per_cent():
    # a mineral oil following Vogel's law (the reference rig's truth), given as two datasheet points
    t = np.linspace(40.0, 100.0, 13)
    vogel = 0.030 * rr.vogel_viscosity_ratio(t, 40.0, 977.0, 150.0)
    law = ViscosityLaw("walther", ((40.0, 0.030), (100.0, float(vogel[-1]))), DENSITY)
    assert np.max(np.abs(law.viscosity_Pa_s(t) / vogel - 1.0)) < 0.01


def test_temperature_of_a_viscosity_inverts_the_law():
    t = np.array([20.0, 40.0, 55.5, 80.0, 120.0])
    assert LAW.temperature_C(LAW.viscosity_Pa_s(t)) == pytest.approx(t, abs=1e-9)


def test_a_more_viscous_oil_reads_as_a_colder_one():
    dt = equivalent_temperature_offset_C(LAW, 50.0, 1.10)
    assert dt < 0
    assert float(LAW.viscosity_Pa_s(50.0 + dt)) == pytest.approx(1.10 * float(LAW.viscosity_Pa_s(50.0)), rel=1e-10)
    assert equivalent_temperature_offset_C(LAW, 50.0, 1.0) == pytest.approx(0.0, abs=1e-9)
    assert equivalent_temperature_offset_C(LAW, 50.0, 0.9) > 0


def test_case_scales_are_one_where_law_or_temperature_is_unknown():
    scales = case_viscosity_scales([40.0, math.nan, 100.0], LAW, 0.030)
    assert scales == pytest.approx([1.0, 1.0, 0.2])
    assert case_viscosity_scales([60.0, 70.0], None, 0.030).tolist() == [1.0, 1.0]


@pytest.mark.parametrize("block, words", [
    ({"kind": "vogel", "points": [[40, 0.03], [100, 0.006]]}, "unknown kind 'vogel'"),
    ({"kind": "walther", "points": [[40, 0.03]]}, "exactly two points"),
    ({"kind": "walther", "points": [[40, 0.03], [40, 0.006]]}, "same temperature"),
    ({"kind": "walther", "points": [[40, 0.006], [100, 0.03]]}, "must fall as the temperature rises"),
    ({"kind": "walther", "points": [[40, 0.03], [100, -0.006]]}, "positive"),
    ({"kind": "walther", "points": [[40, 0.03], [100, "thin"]]}, "must hold numbers"),
    ({"kind": "walther", "points": "40:0.03"}, "list of [T_C, mu_Pa_s] pairs"),
    ({"kind": "walther", "points": [[40, 0.03], [100, 0.006]], "units": "cSt"}, "unknown key 'units'"),
    ({"kind": "walther", "points": [[40, 0.03], [100, 1e-5]]}, "outside the Walther equation's range"),
])
def test_a_malformed_law_is_refused_saying_why(block, words):
    with pytest.raises(ValueError, match=words.replace("[", r"\[").replace("]", r"\]")):
        law_from_mapping(block, DENSITY)
