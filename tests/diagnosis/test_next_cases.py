"""The candidate cases of the next tests (isokinetic.diagnosis.next_cases, issue 37): within the rig's limits, and
above the A-T diagram's quasi-steady boundary (Eq. 28, computed independently by bisection)."""

import numpy as np
import pytest

from isokinetic.contracts.settings import DEFAULTS
from isokinetic.diagnosis import next_cases as nc
from isokinetic.physics.convergence import quasi_steady_boundary
from isokinetic.physics.damper import NOMINAL, TABLE_1, Effects

SPEC, N_BINS, DESIGN = DEFAULTS.window, 4, DEFAULTS.design


def test_every_candidate_lies_within_the_rig_and_starts_its_windows_after_convergence(campaign):
    obs, damper = campaign
    limits = nc.rig_limits(obs, damper, DESIGN)
    effects = [NOMINAL, Effects(air_volume_fraction=0.002)]
    probes = nc.candidate_cases(obs, damper, limits, effects, SPEC, N_BINS, DESIGN.convergence_fraction)
    triangles = [p.plan for p in probes]
    assert len(triangles) >= 10 and probes[-1].label == "repeat of T01 at the end"   # the grid, and a repeat
    assert {p.waveform for p in triangles} == {"triangle"}   # what a triangle campaign's diagnosis reads
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


def test_a_sine_only_campaign_gets_sine_candidates_within_the_rigs_speed_frequency_and_stroke():
    plans = [nc.sine_plan(f"H{i}", f, 0.6e-3 / (2 * np.pi * f), 500.0) for i, f in enumerate([0.5, 1.0, 2.0], 1)]
    obs = nc.sine_probe_observations("s", [nc.Probe(p.case, p, "", 0.0) for p in plans], 16, 1.0)
    obs = nc.replace(obs, force_N=np.where(obs.sign > 0, 500.0, -500.0))
    limits = nc.rig_limits(obs, TABLE_1, DESIGN)
    assert limits.max_frequency_Hz == pytest.approx(4.0)   # the stated default: twice the campaign's highest
    probes = nc.candidate_cases(obs, TABLE_1, limits, [NOMINAL], SPEC, N_BINS, DESIGN.convergence_fraction)
    assert len(probes) >= 5 and probes[-1].label == "repeat of H1 at the end"
    for p in (q.plan for q in probes):
        assert p.waveform == "sine" and p.frequency_Hz <= 4.0 * (1 + 1e-12)
        assert 2 * np.pi * p.frequency_Hz * p.amplitude_m <= limits.max_speed_m_s * (1 + 1e-12)
        assert DESIGN.min_amplitude_m * (1 - 1e-12) <= p.amplitude_m <= DESIGN.max_amplitude_m * (1 + 1e-12)
        cycles = p.duration_s * p.frequency_Hz
        assert cycles == pytest.approx(round(cycles)) and cycles >= nc.SINE_CYCLES and p.duration_s <= nc.MAX_CASE_S
    # the phase bins of every cycle after the first, 16 a cycle
    pobs = nc.sine_probe_observations("s", probes[:1], 16, 1.0)
    assert len(pobs) == 16 * (round(probes[0].plan.duration_s * probes[0].plan.frequency_Hz) - 1)

