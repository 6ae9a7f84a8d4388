"""A mixed campaign's verdict judged on all its records (isokinetic.diagnosis.joint): what replaces what, and what
the auditor keeps. The joint search itself runs on reference-rig campaigns in tests/stages/test_diagnosis_mixed.py."""

from types import SimpleNamespace

import numpy as np
import pytest

from isokinetic.diagnosis.candidate import Candidate
from isokinetic.diagnosis.joint import JointCandidate, block_parameters, judged_on_all_records

FORCE_N = np.array([100.0, -100.0, 50.0, -50.0])
KIND = np.array(["window", "window", "transient", "transient"])


def triangles_part(effects: tuple[str, ...], explained: bool, prediction: np.ndarray) -> Candidate:
    return Candidate(effects=effects, x=np.ones(len(effects)), params={f"{e}_value": 1.0 for e in effects},
                     prediction=prediction, chi2_fit=3.0, chi2_holdout=4.0, n_fit=2, n_holdout=2, gap_after=0.5,
                     holdout_gap_after=0.6, score=7.0, explained=explained)


def joint(effects=("friction", "air"), triangles_explain=True, sines_pass=True) -> JointCandidate:
    return JointCandidate(triangles_part(effects, triangles_explain, 0.99 * FORCE_N), 250.0, 260, 240.0, 250,
                          sines_pass)


DG = SimpleNamespace(obs=SimpleNamespace(force_N=FORCE_N, is_window=KIND == "window"))
RESULT = {"campaign": "m", "verdict": ["friction"], "explained": True, "params": {"coulomb_force_N": 15.0},
          "gap_before": 60.0, "gap_after": 0.9, "holdout_gap_after": 1.5, "shrink": 66.7, "rms_rel_after": 0.006,
          "instrument": {"force_gain": None, "force_lag_s": 0.03}, "sine_check": {"consistent": False}}


def test_a_joint_candidate_explains_only_where_the_triangles_and_the_sines_both_pass():
    assert joint().explained is True
    assert joint(triangles_explain=False).explained is False
    assert joint(sines_pass=False).explained is False
    assert joint().score == pytest.approx(7.0 + 240.0)   # the triangles' score plus the sines' held-out chi2


def test_a_joint_verdict_that_explains_both_replaces_the_triangles_verdict_which_is_kept():
    out = judged_on_all_records(RESULT, {"verdict": ["friction", "air"], "explained": True, "candidates": []},
                                joint(), DG)
    assert out["verdict"] == ["friction", "air"] and out["explained"] is True
    assert out["params"] == {"friction_value": 1.0, "air_value": 1.0}
    assert out["gap_after"] == 0.5 and out["shrink"] == pytest.approx(120.0)
    assert out["rms_rel_after"] == pytest.approx(0.01)
    assert out["instrument"]["force_lag_s"] is None   # the joint verdict's channel: ideal
    kept = out["triangles_verdict"]
    assert kept["verdict"] == ["friction"] and kept["explained"] is True and kept["instrument"]["force_lag_s"] == 0.03
    assert out["sine_check"] == {"consistent": False} and "replaces it" in out["mixed_note"]


def test_where_no_joint_candidate_explains_the_triangles_verdict_stands_not_explained():
    out = judged_on_all_records(RESULT, {"explained": False, "candidates": []}, joint(sines_pass=False), DG)
    assert out["verdict"] == ["friction"] and out["params"] == {"coulomb_force_N": 15.0}
    assert out["explained"] is False and out["triangles_verdict"]["explained"] is True
    assert "stands, not explained" in out["mixed_note"]


def test_without_a_joint_search_the_verdict_is_not_explained_and_the_note_says_why():
    out = judged_on_all_records(RESULT, {"skipped": "no candidate explains the triangles"}, None, None)
    assert out["verdict"] == ["friction"] and out["explained"] is False
    assert "joint says why" in out["mixed_note"] and out["joint"]["skipped"]


def test_each_block_of_sine_bins_costs_two_parameters_or_one_where_it_holds_one_bin():
    # two full cycles of 16 bins, and a record's last cycle cut after its first bin
    blocks = SimpleNamespace(case=np.array(["H01/0"] * 16 + ["H01/2"] * 16 + ["H02/0"], dtype=object))
    assert block_parameters(blocks) == 5
