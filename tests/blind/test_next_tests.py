"""The proof's machinery (isokinetic.blind.next_tests, isokinetic.blind.confounded): a plan's cases run on the
scenario's own reference rig, appended to a copy of its raw campaign, diagnosed again and judged."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from isokinetic.blind import confounded as cf
from isokinetic.blind import next_tests as nt
from isokinetic.blind.generate import DESCRIPTION, export_scenario, generate_scenarios, make_scenario
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

#: A tiny scenario: leakage at 1.5x detection on four turbulent speeds (0.8-1.5 mm/s), an ideal sensor chain.
TINY = dict(name="tiny", truth=("leakage",), seed=(5, 2), multiples={"leakage": 1.5})


def tiny_scenario(viscosity_drift: bool = True):
    s = make_scenario(TINY["name"], TINY["truth"], np.random.SeedSequence(list(TINY["seed"])), TINY["multiples"],
                      n_velocities=(4, 4), low_end_mm_s=(0.8, 0.8), high_end_mm_s=(1.5, 1.5), sensor_chain=False)
    return s if viscosity_drift else dataclasses.replace(s, rig=dataclasses.replace(s.rig, viscosity_drift_rel=0.0))


def write(scenario, cases, folder: Path) -> Path:
    rrc.write_campaign(folder / scenario.name, cases, rr.DamperDesign.from_mapping(scenario.damper.to_dict()),
                       scenario.effects, scenario.rig, scenario.noise_seed, description=DESCRIPTION,
                       write_phase=scenario.noise_seed % 2 == 0, declare_charge_pressure=True)
    return folder / scenario.name


def truth_of(scenario) -> dict:
    return json.loads(json.dumps(scenario.truth_record()))


def tree_hashes(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def tri(case: str, v: float, period: float) -> dict:
    return nt.plan_entry(rr.TriangleCase(case, v, period, 50.0))


SHORT = [rr.TriangleCase("N01", 1.0e-3, 4.0, 50.0), rr.TriangleCase("N02", 2.0e-4, 8.0, 50.0)]


def test_an_appended_case_is_the_case_the_rig_would_have_run_next(tmp_path):
    s = tiny_scenario(viscosity_drift=False)   # the drift's count is the campaign's cases: appended, it runs on
    whole = write(s, s.rig_cases() + SHORT, tmp_path / "whole")
    first = write(s, s.rig_cases(), tmp_path / "first")
    out = nt.extend_campaign(first, truth_of(s), [nt.plan_entry(c) for c in SHORT], tmp_path / "extended")
    assert tree_hashes(out) == tree_hashes(whole)


def test_the_original_campaign_is_never_written(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    before = tree_hashes(raw)
    out = nt.extend_campaign(raw, truth_of(s), [nt.plan_entry(c) for c in SHORT], tmp_path / "copy")
    assert tree_hashes(raw) == before
    assert {"N01.csv", "N02.csv"} <= set(tree_hashes(out)) and not {"N01.csv", "N02.csv"} & set(before)


def test_the_extension_is_deterministic(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    plan = [nt.plan_entry(c) for c in SHORT]
    assert tree_hashes(nt.extend_campaign(raw, truth_of(s), plan, tmp_path / "a")) == \
        tree_hashes(nt.extend_campaign(raw, truth_of(s), plan, tmp_path / "b"))


def test_a_campaign_without_a_command_channel_gets_none_in_its_new_cases(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    cf.drop_command_channel(raw)
    out = nt.extend_campaign(raw, truth_of(s), [nt.plan_entry(c) for c in SHORT], tmp_path / "copy")
    assert "command" not in nt.read_manifest(out)["columns"]
    assert (out / "N01.csv").read_text(encoding="utf-8").split("\n")[0] == "t_ms,lvdt_um,load_N"


def test_a_standstill_reads_the_load_cells_zero_at_its_time(tmp_path):
    s = tiny_scenario()
    rig = dataclasses.replace(s.rig, force_drift_N_s=0.05, dropout_fraction=0.0)
    s = dataclasses.replace(s, rig=rig)
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    still = {"case": "Z01", "waveform": "standstill", "duration_s": 60.0, "sample_rate_Hz": 50.0}
    out = nt.extend_campaign(raw, truth_of(s), [still], tmp_path / "copy")
    force = pd.read_csv(out / "Z01.csv")["load_N"].to_numpy()
    start = sum(c.duration_s + 1.0 / c.sample_rate_Hz for c in s.cases)
    zero = rig.force_offset_N + rig.force_drift_N_s * (start + 30.0)
    assert abs(force.mean() - zero) < 4.0 * rig.force_noise_N / np.sqrt(force.size)
    assert nt.read_manifest(out)["cases"][-1] == {"id": "Z01", "waveform": "standstill", "file": "Z01.csv"}


def test_a_case_the_reference_rig_cannot_run_is_refused_by_name():
    with pytest.raises(ValueError, match="N03.*'ramp'"):
        nt.rig_case({**tri("N03", 1e-3, 4.0), "waveform": "ramp"})
    with pytest.raises(ValueError, match="N04.*two periods"):
        nt.rig_case({**tri("N04", 1e-3, 4.0), "periods": 3})


def test_the_uniform_plan_spreads_the_plans_size_and_rig_time_over_the_campaigns_speeds(tmp_path):
    s = tiny_scenario()
    manifest = rrc.campaign_manifest(s.name, s.rig_cases(), rr.TABLE1)
    plan = [tri("N01", 3e-3, 8.0), tri("N02", 5e-3, 4.0), tri("N03", 1e-3, 12.0)]
    uniform = nt.uniform_plan(manifest, plan)
    speeds = [c.velocity_m_s for c in s.cases]
    assert [u["case"] for u in uniform] == ["U01", "U02", "U03"]
    assert sum(u["rig_time_s"] for u in uniform) == pytest.approx(48.0, rel=1e-3)
    assert uniform[0]["velocity_m_s"] == pytest.approx(min(speeds), rel=5e-3)
    assert uniform[-1]["velocity_m_s"] == pytest.approx(max(speeds), rel=5e-3)


CALIBRATION = {"check": "load_cell_gain", "channel": "force", "uncertainty_rel": 0.001, "rig_time_s": 1800.0}


def test_a_plans_calibration_is_declared_in_the_copy_as_the_rig_reads_it(tmp_path):
    s = tiny_scenario()
    s = dataclasses.replace(s, rig=dataclasses.replace(s.rig, force_gain=1.015))
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    before = tree_hashes(raw)
    out = nt.extend_campaign(raw, truth_of(s), [], tmp_path / "copy", [CALIBRATION])
    declared = nt.read_manifest(out)["columns"]["force"]["calibration"]
    assert declared["uncertainty_rel"] == 0.001
    assert declared["gain"] == pytest.approx(1.015, rel=5 * 0.001) and declared["gain"] != 1.015   # read, not known
    assert "calibration" not in nt.read_manifest(raw)["columns"]["force"] and tree_hashes(raw) == before
    again = nt.extend_campaign(raw, truth_of(s), [], tmp_path / "again", [CALIBRATION])
    assert nt.read_manifest(again)["columns"]["force"]["calibration"] == declared   # seeded


def test_an_lvdt_calibration_is_declared_on_the_displacement_channel_from_its_own_draw(tmp_path):
    s = tiny_scenario()
    s = dataclasses.replace(s, rig=dataclasses.replace(s.rig, force_gain=1.015, displacement_gain=1.012))
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    lvdt = {**CALIBRATION, "check": "lvdt_scale", "channel": "displacement"}
    both = nt.read_manifest(nt.extend_campaign(raw, truth_of(s), [], tmp_path / "both", [CALIBRATION, lvdt]))
    alone = nt.read_manifest(nt.extend_campaign(raw, truth_of(s), [], tmp_path / "alone", [CALIBRATION]))
    declared = both["columns"]["displacement"]["calibration"]
    assert set(declared) == {"scale", "uncertainty_rel"} and declared["scale"] == pytest.approx(1.012, rel=5e-3)
    assert both["columns"]["force"]["calibration"] == alone["columns"]["force"]["calibration"]   # draws apart
    assert "calibration" not in alone["columns"]["displacement"]


def test_a_plan_without_a_calibration_declares_none(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    out = nt.extend_campaign(raw, truth_of(s), [nt.plan_entry(SHORT[0])], tmp_path / "copy")
    assert "calibration" not in nt.read_manifest(out)["columns"]["force"]


def test_the_uniform_plan_spends_a_calibrations_rig_time_on_cases_at_least_one():
    s = tiny_scenario()
    manifest = rrc.campaign_manifest(s.name, s.rig_cases(), rr.TABLE1)
    uniform = nt.uniform_plan(manifest, [], extra_s=1800.0)
    assert len(uniform) == 1 and uniform[0]["rig_time_s"] == pytest.approx(1800.0, rel=1e-3)
    assert nt.uniform_plan(manifest, []) == []


BEFORE = {"status": "ok", "verdict": ["leakage"], "explained": True, "confounded": [["leakage", "discharge"]]}


def exact_after(s, **instrument) -> dict:
    """A diagnosis reporting the scenario's truth exactly (effects and instrument terms)."""
    truth = truth_of(s)
    inst = {"delay_s": truth["instrument"]["delay_s"], "force_offset_N": truth["instrument"]["force_offset_N"],
            "force_gain": truth["instrument"]["force_gain"], **instrument}
    return {"status": "ok", "verdict": list(s.truth), "explained": True, "confounded": [],
            "params": dict(truth["params"]), "instrument": inst}


def test_the_judge_calls_a_confounding_resolved_only_when_its_group_is_gone_and_the_verdict_is_the_truth():
    s = tiny_scenario()
    truth, span = truth_of(s), sum(c.duration_s + 1.0 / c.sample_rate_Hz for c in s.cases)
    assert nt.judge(truth, BEFORE, exact_after(s), span)["resolved"]
    assert nt.judge(truth, BEFORE, {**exact_after(s), "confounded": [["discharge", "leakage"]]},
                    span)["remaining"] == ["discharge+leakage"]
    assert nt.judge(truth, BEFORE, {**exact_after(s), "confounded": [["air", "force_lag"]]}, span)["new"] == \
        ["air+force_lag"]
    assert nt.judge(truth, BEFORE, {**exact_after(s), "verdict": ["discharge"]}, span)["misses"] == \
        ["verdict discharge (truth leakage)"]
    off = nt.judge(truth, BEFORE, exact_after(s, force_gain=truth["instrument"]["force_gain"] + 0.004), span)
    assert not off["resolved"] and off["misses"] == ["gain 0.4 %"]
    assert not nt.judge(truth, BEFORE, None, span)["resolved"]


@pytest.fixture(scope="module")
def confounded_tiny(tmp_path_factory):
    """The tiny scenario exported and diagnosed: leakage confounded with discharge."""
    from isokinetic.stages.blind_diagnose import diagnose_raw_campaign

    root = tmp_path_factory.mktemp("tiny")
    s = tiny_scenario()
    raw = export_scenario(s, root / "raw", root / "truth")
    before = diagnose_raw_campaign(raw, root / "work")
    return raw, truth_of(s), before, root, lambda r, w: diagnose_raw_campaign(r, w)


def test_the_tiny_scenario_is_confounded(confounded_tiny):
    _raw, _truth, before, _root, _diagnose = confounded_tiny
    assert before["verdict"] == ["leakage"] and [set(g) for g in before["confounded"]] == [{"leakage", "discharge"}]


def test_faster_cases_than_the_campaigns_resolve_leakage_from_discharge(confounded_tiny):
    raw, truth, before, root, diagnose = confounded_tiny
    result = nt.run_plan(raw, truth, before, [tri("N01", 3e-3, 8.0), tri("N02", 5e-3, 4.0)], root / "faster",
                         diagnose)
    assert result["resolved"], result


def test_more_cases_in_the_campaigns_own_speed_range_leave_it_confounded(confounded_tiny):
    raw, truth, before, root, diagnose = confounded_tiny
    result = nt.run_plan(raw, truth, before, [tri("N01", 1.1e-3, 20.0), tri("N02", 1.4e-3, 20.0)], root / "same",
                         diagnose)
    assert not result["resolved"] and result["remaining"] == ["leakage+discharge"]


def test_drawing_the_confounded_kinds_leaves_the_suites_scenario_files_unchanged(tmp_path):
    def suite_files(folder: Path) -> dict[str, str]:
        (scenario,) = generate_scenarios(3, 0, 0, 1, n_velocities=(2, 2), low_end_mm_s=(0.5, 0.5),
                                         high_end_mm_s=(1.5, 1.5))
        raw = export_scenario(scenario, folder / "raw", folder / "truth")
        return {**tree_hashes(raw), **tree_hashes(folder / "truth")}

    first = suite_files(tmp_path / "a")
    kind, scenario = cf.generate_confounded(3, ["gain_discharge"])[0]
    assert scenario.name not in first and scenario.name.startswith(cf.NAME_PREFIX)
    assert suite_files(tmp_path / "b") == first


def test_a_confounded_kind_carries_its_rig_terms_and_expected_group():
    kind = cf.BY_NAME["scale_no_command"]
    scenario = cf.make_confounded(kind, 3, 2)
    record = cf.truth_record(kind, scenario)
    assert record["rig"]["displacement_gain"] == 1.012 and record["instrument"]["displacement_scale"] == 1.012
    assert record["confounding"] == {"kind": "scale_no_command", "expected": ["displacement_scale", "force_gain",
                                                                             "discharge"], "command_channel": False}


def test_the_proofs_rates_count_a_confounded_scenario_without_a_plan_as_unresolved():
    rows = [{"scenario": "a", "in_proof": True, "resolved": True, "uniform_resolved": False, "n_cases": 2},
            {"scenario": "b", "in_proof": True, "resolved": False, "uniform_resolved": False, "n_cases": 0},
            {"scenario": "c", "in_proof": False}]
    summary = nt.proof_summary(rows)
    assert (summary["n"], summary["with_plan"], summary["rate"], summary["uniform_rate"]) == (2, 1, 0.5, 0.0)
    assert summary["pass"] is False and summary["not_in_proof"] == ["c"]


def test_a_scenario_enters_the_proof_only_with_a_confounding_and_without_a_plan_resolves_nothing(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    clear = {"status": "ok", "verdict": ["leakage"], "confounded": [],
             "next_tests": {"needed": False, "note": "no confounding: no further test proposed", "plan": []}}
    row = nt.proof_row(raw, truth_of(s), tmp_path / "a", lambda r, w: clear)
    assert not row["in_proof"] and row["note"] == "no confounding: no further test proposed"
    stuck = {**BEFORE, "next_tests": {"needed": True, "note": "no case separates them", "plan": [],
                                      "separation_se": {"leakage+discharge": 0.4}}}
    row = nt.proof_row(raw, truth_of(s), tmp_path / "b", lambda r, w: stuck)
    assert row["in_proof"] and row["n_cases"] == 0 and not row["resolved"] and not row["uniform_resolved"]
    assert row["predicted_se"] is None and row["confounded"] == "leakage+discharge"


def test_a_plan_the_rig_cannot_run_resolves_nothing_and_says_why_in_strict_json(tmp_path):
    s = tiny_scenario()
    raw = write(s, s.rig_cases(), tmp_path / "raw")
    plan = [{**tri("N01", 1e-3, 4.0), "waveform": "ramp"}]
    row = nt.prove_scenario(raw, truth_of(s), BEFORE, plan, tmp_path / "p", lambda r, w: pytest.fail("diagnosed"))
    assert not row["resolved"] and "'ramp'" in row["proposed"]["error"] and "'ramp'" in row["uniform"]["error"]
    json.dumps(row, allow_nan=False)
    assert not (tmp_path / "p" / "proposed" / "raw").exists()
