"""The candidate cases of the next tests (isokinetic.diagnosis.next_cases, issue 37): within the rig's limits, and
above the A-T diagram's quasi-steady boundary (Eq. 28, computed independently by bisection)."""

import numpy as np
import pytest

from isokinetic.contracts.settings import DEFAULTS
from isokinetic.diagnosis import next_cases as nc
from isokinetic.physics.convergence import quasi_steady_boundary
from isokinetic.physics.damper import NOMINAL, Effects

SPEC, N_BINS, DESIGN = DEFAULTS.window, 4, DEFAULTS.design


def test_every_candidate_lies_within_the_rig_and_starts_its_windows_after_convergence(campaign):
    obs, damper = campaign
    limits = nc.rig_limits(obs, damper, DESIGN)
    effects = [NOMINAL, Effects(air_volume_fraction=0.002)]
    probes = nc.candidate_cases(obs, damper, limits, effects, SPEC, N_BINS, DESIGN.convergence_fraction)
    triangles = [p.plan for p in probes if p.plan is not None]
    assert len(triangles) >= 10 and probes[-1].plan is None   # the grid, and a standstill
    for plan in triangles:
        assert plan.velocity_m_s <= limits.max_speed_m_s * (1 + 1e-12)
        assert DESIGN.min_amplitude_m * (1 - 1e-12) <= plan.amplitude_m <= DESIGN.max_amplitude_m * (1 + 1e-12)
        assert plan.period_s == pytest.approx(4.0 * plan.amplitude_m / plan.velocity_m_s)   # Eq. 26
        assert 2.0 * plan.period_s <= nc.MAX_CASE_S
        for eff in effects:   # the A-T diagram: above its quasi-steady boundary (Eq. 28, bisection)
            _t, y_min = quasi_steady_boundary([plan.velocity_m_s], damper, phi=DESIGN.convergence_fraction,
                                              start_fraction=SPEC.start_fraction, effects=eff)
            assert np.isfinite(y_min[0]) and plan.amplitude_m >= y_min[0]


def test_a_case_below_the_quasi_steady_boundary_is_refused(campaign):
    _obs, damper = campaign
    speed = 2e-3
    _t, y_min = quasi_steady_boundary([speed], damper, phi=DESIGN.convergence_fraction,
                                      start_fraction=SPEC.start_fraction)
    short = nc.triangle_plan("P", speed, 0.9 * float(y_min[0]), 1000.0)
    assert not nc.converges(short, damper, [NOMINAL], DESIGN.convergence_fraction, SPEC)
