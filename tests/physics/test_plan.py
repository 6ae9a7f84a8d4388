"""Test plans: half-periods of the triangle (Eq. 26) and a manifest's rounded phase."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.physics.plan import half_periods, snapped_phase_rad

EXACT = [[0.0, 150.0, 1.0], [150.0, 300.0, -1.0], [300.0, 450.0, 1.0], [450.0, 600.0, -1.0]]


@pytest.mark.parametrize("phase_rad", [-1.5707963, -1.5708])
def test_rounded_phase_keeps_the_first_half_period(phase_rad):
    # the rounding puts the first turning point ~1 us (-1.5707963) or ~175 us (-1.5708) before t = 0
    rows = half_periods(300.0, phase_rad, 600.0, tolerance_s=0.01)
    assert rows.tolist() == EXACT


def test_rounded_phase_means_minus_pi_over_2_exactly():
    for phase_rad in (-1.5707963, -1.5708, -1.571):
        assert snapped_phase_rad(300.0, phase_rad, 0.01) == -math.pi / 2


def test_turning_point_beyond_one_sample_interval_is_not_moved():
    phase_rad = -math.pi / 2 + 2 * math.pi * 0.05 / 300.0     # turning point 50 ms before t = 0
    assert snapped_phase_rad(300.0, phase_rad, 0.01) == phase_rad
    rows = half_periods(300.0, phase_rad, 600.0, tolerance_s=0.01)
    assert len(rows) == 3 and rows[0, 0] == pytest.approx(149.95)


def test_other_phases_keep_their_half_periods():
    rows = half_periods(20.0, 0.0, 40.0, tolerance_s=0.01)      # starts mid-stroke: first reversal at T/4
    np.testing.assert_allclose(rows, [[5.0, 15.0, -1.0], [15.0, 25.0, 1.0], [25.0, 35.0, -1.0]])
    assert half_periods(20.0, math.pi / 2, 40.0, tolerance_s=0.01)[0].tolist() == [0.0, 10.0, -1.0]


def test_default_tolerance_is_a_thousandth_of_a_radian():
    assert half_periods(300.0, -1.5708, 600.0).tolist() == EXACT
    assert len(half_periods(300.0, -math.pi / 2 + 0.01, 600.0)) == 3


def test_half_periods_stop_at_max_count_whatever_the_record_length():
    """Issue 20: a last time stamp of 1e308 s (or NaN) must not loop over 1e308 s of half-periods."""
    four = half_periods(300.0, -math.pi / 2, 600.0)
    for duration_s in (1e308, math.inf, math.nan):
        rows = half_periods(300.0, -math.pi / 2, duration_s, max_count=4)
        assert rows.tolist() == (four.tolist() if duration_s == duration_s else [])


def test_half_periods_without_a_bound_refuse_a_record_of_centuries():
    with pytest.raises(ValueError, match="more than 1000000 half-periods"):
        half_periods(4.0, -math.pi / 2, 1.26e9)          # a year typo in an ISO stamp: 40 years of record
    assert len(half_periods(4.0, -math.pi / 2, 4.0e5)) == 200_000      # a long real record is still listed
