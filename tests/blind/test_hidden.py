"""The blind suite's hidden out-of-catalogue kinds (issue 35): signatures by hand, strengths, the truth's expected
answer."""

import math

import numpy as np
import pytest

from isokinetic.blind import hidden as bh
from isokinetic.blind.generate import generate_scenarios, make_scenario
from isokinetic.contracts.scenarios import HIDDEN_AXES, OUT_OF_CATALOGUE, suite_composition
from isokinetic.physics.plan import CasePlan
from isokinetic.reference import rig as rr

WHITE = rr.RigImperfections(force_noise_N=2.0)          # white noise only: SE of a mean of n = 2 / sqrt(n)


def _plan():
    cases = [CasePlan("T01", "triangle", 10.0, amplitude_m=0.5e-3, period_s=20.0, duration_s=40.0),
             CasePlan("T02", "triangle", 10.0, amplitude_m=2.0e-3, period_s=80.0, duration_s=160.0)]
    return cases, bh.window_plan("c", cases)


def test_time_signature_is_each_windows_mean_change_in_its_standard_error():
    cases, windows = _plan()
    without = [np.full(401, 100.0), np.full(1601, 300.0)]
    with_effect = [np.full(401, 104.0), np.full(1601, 297.0)]        # +4 N in T01, -3 N in T02
    z = bh.signature_z("time", with_effect, without, cases, windows, WHITE)
    n = windows.stop - windows.start
    expected = np.where(windows.case_index == 0, 4.0, -3.0) / (2.0 / np.sqrt(n))
    assert z.shape == (8,) and np.allclose(z, expected, rtol=1e-12)


def test_position_signature_is_the_change_within_each_window_by_part():
    """A step of 6 N at the start of the third of four parts of every window of T02 (201 samples: parts of 51,
    50, 50 and 50): each part's mean change less the window's (6 x 100/201 N), in 2/sqrt(n) N; a constant change
    (T01) gives no signature at all."""
    cases, windows = _plan()
    without = [np.full(401, 100.0), np.full(1601, 300.0)]
    stepped = without[1].copy()
    second = windows.case_index == 1
    assert np.all((windows.stop - windows.start)[second] == 201)
    for a, b in zip(windows.start[second], windows.stop[second], strict=True):
        stepped[a + 101:b] += 6.0
    z = bh.signature_z("position", [without[0] + 5.0, stepped], without, cases, windows, WHITE)
    mean = 6.0 * 100 / 201
    part = np.array([(0.0 - mean) / (2 / math.sqrt(51)), (0.0 - mean) / (2 / math.sqrt(50)),
                     (6.0 - mean) / (2 / math.sqrt(50)), (6.0 - mean) / (2 / math.sqrt(50))])
    assert np.allclose(z[:16], 0.0, atol=1e-12)                         # T01: only a constant change
    assert np.allclose(z[16:], np.tile(part, 4), rtol=1e-12)


@pytest.mark.parametrize("kind", sorted(HIDDEN_AXES))
def test_hidden_scenario_expects_explained_false_on_its_axis_where_its_signature_is_beyond_the_noise(kind):
    s = make_scenario("blind-000", (), np.random.SeedSequence([5, 1]), out_of_catalogue=kind)
    h = s.hidden
    assert h["kind"] == kind and h["axis"] == HIDDEN_AXES[kind] and 0 < h["strength"] <= bh.STRENGTH_BOUND[kind]
    assert h["visible"] == (h["rms_z"] >= 3.0) and h["multiple"] == pytest.approx(h["rms_z"] / 3.0)
    fields = bh.hidden_fields(kind, h["strength"], s.damper)
    assert all(getattr(s.effects, k) == v for k, v in fields.items())
    record = s.truth_record()
    assert record["format_version"] == 3 and record["truth"] == [] and record["out_of_catalogue"] == kind
    if h["visible"]:
        assert record["expected"] == {"explained": False, "where_axis": HIDDEN_AXES[kind], "verdict": None}
    else:
        assert record["expected"] == {"explained": None, "where_axis": None, "verdict": []}
    # the signature measured again at the drawn strength, on the scenario's own plan and rig
    base = rr.TrueEffects(charge_pressure_Pa=s.effects.charge_pressure_Pa)
    without = bh.rig_forces(s.damper, s.cases, base, s.rig)
    again = bh.signature_rms_z(kind, h["strength"], s.damper, s.cases, base, s.rig,
                               bh.window_plan(s.name, s.cases), without)
    assert again == pytest.approx(h["rms_z"], rel=1e-9)


def test_expected_answer_of_old_kinds_hidden_kinds_and_catalogue_scenarios():
    assert bh.expected_answer("relief", (), {}) == {"explained": False, "where_axis": None, "verdict": None}
    assert bh.expected_answer("bypass", (), {"visible": True})["where_axis"] == "position"
    assert bh.expected_answer("wear", ("air",), {"visible": False}) == {"explained": None, "where_axis": None,
                                                                         "verdict": ["air"]}
    assert bh.expected_answer("", ("friction",), {})["verdict"] == ["friction"]


def test_out_of_catalogue_scenarios_cycle_through_every_kind():
    kinds = [k[2] for k in suite_composition(3, 0, 0, 0, len(OUT_OF_CATALOGUE))]
    assert sorted(kinds) == sorted(OUT_OF_CATALOGUE) and set(HIDDEN_AXES) < set(OUT_OF_CATALOGUE)
    assert OUT_OF_CATALOGUE[:3] == ("stribeck", "bypass", "backlash")    # the default suite holds a hidden kind
    assert len(generate_scenarios(3, 0, 0, 0, 2, names=["blind-001"])) == 1
