"""Mixed campaigns judged on all their records (issue 35, part 3), on the independent reference rig: slow triangles
(0.01-0.04 mm/s, where entrained air barely shows) beside a 0.2-10 Hz sine sweep (where it shows at every reversal),
behind a delayed actuator and 0.2 Hz coloured force noise, through the whole chain as raw data.

Where the sine records fail the triangles' verdict, it is not explained and the search is repeated on both kinds of
record (isokinetic.diagnosis.joint); where they agree with it, it stands unchanged.
"""

import math

import pytest

from isokinetic.diagnosis.result import validate_diagnosis
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.stages.blind_diagnose import diagnose_raw_campaign
from isokinetic.stages.diagnosis import JOINT_SKIPPED, judge_on_all_records

QUIET = {"force_noise_N": 3.0, "force_noise_rel": 0.015, "noise_corner_Hz": 0.2, "displacement_noise_m": 1e-6,
         "force_resolution_N": 0.01, "displacement_resolution_m": 1e-8, "command_resolution_m": 1e-8,
         "delay_s": 0.01}
# slow triangles: speeds [mm/s] and periods [s]
SLOW = [(0.01, 80.0), (0.02, 80.0), (0.04, 40.0)]
# the sine sweep: frequency [Hz] and peak speed [mm/s], four cycles each at 1 kHz
SWEEP = [(0.2, 0.05), (0.5, 0.1), (1.0, 0.2), (2.0, 0.4), (5.0, 0.8), (10.0, 1.2)]
FRICTION_N = 15.0
AIR = 1e-4   # the catalogue's air volume fraction at the default 5 MPa charge


def diagnose_mixed(tmp_path, name: str, effects: rr.TrueEffects, seed: int = 5) -> dict:
    """A mixed campaign (SLOW triangles and the SWEEP) simulated on the reference rig, through the whole chain."""
    raw = tmp_path / "raw" / name
    cases = [rr.TriangleCase(f"T{i:02d}", w * 1e-3, t, 50.0) for i, (w, t) in enumerate(SLOW, start=1)]
    cases += [rr.SineCase(f"H{i:02d}", f, v * 1e-3 / (2 * math.pi * f), 4, 1000.0)
              for i, (f, v) in enumerate(SWEEP, start=1)]
    rrc.write_campaign(raw, cases, rr.TABLE1, effects, rr.RigImperfections(**QUIET), seed, write_phase=False)
    result = diagnose_raw_campaign(raw, tmp_path / "work")
    validate_diagnosis(result)
    return result


@pytest.mark.slow
def test_friction_and_air_beside_slow_triangles_get_both_from_the_sine_records(tmp_path):
    effects = rr.TrueEffects(coulomb_force_N=FRICTION_N, air_fraction_at_charge=rrc.air_fraction_from_catalogue(AIR))
    result = diagnose_mixed(tmp_path, "mixed-friction-air", effects)
    # the slow triangles alone see the friction only, and the sine records fail that verdict
    assert result["triangles_verdict"]["verdict"] == ["friction"]
    assert result["sine_check"]["consistent"] is False
    # judged on all the records: both effects, explained on both kinds of record
    assert sorted(result["verdict"]) == ["air", "friction"]
    assert result["explained"] is True
    assert result["joint"]["explained"] is True
    assert result["params"]["coulomb_force_N"] == pytest.approx(FRICTION_N, rel=0.15)
    assert result["params"]["air_volume_fraction"] == pytest.approx(AIR, rel=0.15)
    assert "replaces it" in result["mixed_note"]


def test_a_mixed_campaign_whose_sine_records_agree_keeps_its_verdict(tmp_path):
    result = diagnose_mixed(tmp_path, "mixed-friction", rr.TrueEffects(coulomb_force_N=FRICTION_N), seed=3)
    assert result["sine_check"]["consistent"] is True
    assert result["verdict"] == ["friction"] and result["explained"] is True
    assert result["params"]["coulomb_force_N"] == pytest.approx(FRICTION_N, rel=0.15)
    assert not {"joint", "triangles_verdict", "mixed_note"} & set(result)


@pytest.mark.slow
def test_an_effect_outside_the_catalogue_that_the_sine_records_show_is_not_explained(tmp_path):
    # a Stribeck hump of 20 N below 0.2 mm/s beside 15 N of Coulomb friction: the slow triangles read it as more
    # friction, which the sine records' faster reversals refute; no catalogue set explains both
    effects = rr.TrueEffects(coulomb_force_N=FRICTION_N, stribeck_force_N=20.0, stribeck_velocity_m_s=2e-4)
    result = diagnose_mixed(tmp_path, "mixed-stribeck", effects)
    assert result["sine_check"]["consistent"] is False
    assert result["explained"] is False
    assert result["joint"]["explained"] is False and result["joint"]["candidates"]
    assert result["verdict"] == result["triangles_verdict"]["verdict"]
    assert "stands, not explained" in result["mixed_note"]


def test_no_joint_search_where_no_catalogue_set_explains_the_triangles_alone():
    # none explains them beside the sines either: the verdict stays, not explained, and joint says why
    result = {"verdict": ["friction"], "explained": False, "unexplained_note": "no candidate ...",
              "sine_check": {"consistent": False}}
    out = judge_on_all_records(result, {}, None, {}, None, 0.001)
    assert out["joint"] == {"skipped": JOINT_SKIPPED}
    assert out["verdict"] == ["friction"] and out["explained"] is False
    assert out["triangles_verdict"]["unexplained_note"] == "no candidate ..."
