"""Fixtures of the diagnosis tests: a small reference-rig campaign's observations."""

import pytest

from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.diagnosis import prepare

QUIET = {"force_noise_N": 3.0, "force_noise_rel": 0.005, "noise_corner_Hz": 2.0, "displacement_noise_m": 1e-6}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """(observations, damper) of a small reference-rig campaign through the real chain."""
    tmp = tmp_path_factory.mktemp("instrument")
    cases = [rr.TriangleCase("T01", 0.04e-3, 40.0, 50.0), rr.TriangleCase("T02", 0.5e-3, 10.0, 50.0)]
    rrc.write_campaign(tmp / "raw" / "small", cases, rr.TABLE1, rig=rr.RigImperfections(**QUIET), seed=2,
                       write_phase=False)
    root = process_raw_campaign(tmp / "raw" / "small", tmp / "work")
    _c, damper, _cases, obs, reason = prepare(root)
    assert obs is not None, reason
    return obs, damper
