"""The triangles' verdict checked on sine records (isokinetic.diagnosis.sine_check), on reference-rig sine records
with friction behind a force low-pass: the true effects pass, the nominal damper does not."""

import math

import numpy as np
import pytest

from isokinetic.diagnosis.sine_check import record_residuals, sine_check
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.diagnosis import prepare

FRICTION_N = 20.0
LAG_S = 1.0 / (2.0 * math.pi * 4.0)   # a 4 Hz first-order low-pass


@pytest.fixture(scope="module")
def sines(tmp_path_factory):
    """(sine observations, damper) of three reference-rig records (0.5-2 Hz, 1 kHz) with FRICTION_N of Coulomb
    friction, read through a 4 Hz first-order force low-pass, with white and proportional noise."""
    tmp = tmp_path_factory.mktemp("sine_check")
    cases = [rr.SineCase(f"H{i}", f, v * 1e-3 / (2 * math.pi * f), 5, 1000.0)
             for i, (f, v) in enumerate([(0.5, 0.3), (1.0, 0.6), (2.0, 1.0)], start=1)]
    rig = rr.RigImperfections(force_noise_N=2.0, force_noise_rel=0.003, force_filter_Hz=4.0, force_filter_order=1)
    rrc.write_campaign(tmp / "raw" / "sc", cases, rr.TABLE1, rr.TrueEffects(coulomb_force_N=FRICTION_N), rig=rig,
                       seed=6, write_phase=False)
    _c, damper, _cases, obs, reason = prepare(process_raw_campaign(tmp / "raw" / "sc", tmp / "work"))
    assert obs is not None, reason
    return obs, damper


def verdict(params: dict) -> dict:
    return {"params": params, "instrument": {"force_lag_s": LAG_S},
            "instrument_tests": {"force_lag": {"form": "low-pass, 1st order"}}}


def test_the_true_effects_through_the_true_channel_predict_the_sine_records(sines):
    obs, damper = sines
    check = sine_check(obs, damper, verdict({"coulomb_force_N": FRICTION_N}), None, None)
    assert check["consistent"] is True
    assert check["dof"] == len(obs) - 2 * 3 and check["cases"] == "H1,H2,H3"


def test_a_verdict_without_the_friction_the_records_show_fails_the_check(sines):
    obs, damper = sines
    check = sine_check(obs, damper, verdict({}), None, None)
    assert check["consistent"] is False and "does not predict the sine records" in check["note"]
    assert check["nominal"]["chi2"] == pytest.approx(check["verdict"]["chi2"])


def test_a_records_common_offset_and_proportional_error_leave_the_residuals():
    # one record: an offset of 3 N and 1 % of |M| in every bin beside an odd 2 N (a friction the model lacks):
    # the even mode goes, the odd part (orthogonal to it over a whole cycle) stays whole
    model = 1000.0 * np.sin(2 * np.pi * (np.arange(32) + 0.5) / 32)
    odd = 2.0 * np.sign(model)

    class Obs:   # the three fields record_residuals reads
        case = np.array(["H1"] * 32)
        sigma_N = np.full(32, 1.0)
        force_N = model + 3.0 + 0.01 * np.abs(model) + odd

    assert np.allclose(record_residuals(Obs, model), odd, atol=1e-9)
