"""Segment tables of the virtual rig's quadrature (physics.hydraulics, Eq. 13-14 of the paper)."""

from __future__ import annotations

import numpy as np

from isokinetic.physics import damper as dm
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.hydraulics import Hydraulics, relaxations


def test_segment_table_does_not_depend_on_the_other_problems_of_its_batch():
    """relaxations() builds many tables in one pass; each must be the table built alone. A table
    of large τ placed first must not cost the one after it any digits."""
    hyd = Hydraulics.from_damper(TABLE_1, dm.Effects())
    a = TABLE_1.piston_area_m2
    large, small = (0.0, a * 1.5e-3), (0.0, a * 5e-6)   # (Δp0, A_p W): 1.5 and 0.005 mm/s from rest
    alone = relaxations([small[0]], [small[1]], hyd)[0]
    batched = relaxations([large[0], small[0]], [large[1], small[1]], hyd)[1]
    assert relaxations([large[0]], [large[1]], hyd)[0].tau[-1] > 10 * alone.tau[-1]
    np.testing.assert_array_equal(batched.tau, alone.tau)
    np.testing.assert_array_equal(batched.coef, alone.coef)
