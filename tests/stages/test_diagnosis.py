"""Rule diagnosis, checked on virtual campaigns whose truth the diagnosis never sees."""

import json

import numpy as np
import pytest
import yaml

from isokinetic.blind.confounded import drop_command_channel
from isokinetic.diagnosis.plan_text import plan_yaml
from isokinetic.diagnosis.result import validate_diagnosis
from isokinetic.io import write_parquet
from isokinetic.measurement.repeatability import repeatability
from isokinetic.physics.damper import TABLE_1, Effects
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.virtual_rig import Measurement
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.stages import diagnosis as dg
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.characteristic import assemble, windows_stage
from isokinetic.stages.validate import write_validated
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign

# speeds [mm/s] and periods [s]: across the laminar-turbulent transition, the fast ones short
PLAN = [(0.01, 80.0), (0.05, 80.0), (0.2, 20.0), (0.5, 20.0), (1.0, 20.0), (1.5, 20.0)]


def process(tmp_path, effects: Effects, seed: int = 3):
    """Simulate a small campaign and run the real stage chain up to the characteristic."""
    cases = tuple(CasePlan(case=f"T{i:02d}", waveform="triangle", sample_rate_Hz=20.0, amplitude_m=w * 1e-3 * t / 4,
                           period_s=t, duration_s=2 * t) for i, (w, t) in enumerate(PLAN, start=1))
    vc = VirtualCampaign(name="virt", description="", seed=seed, temperature_C=40.0, damper=TABLE_1, effects=effects,
                         measurement=Measurement(force_noise_N=5.0, force_noise_rel=0.01, displacement_noise_m=1e-6),
                         cases=cases)
    root = tmp_path / "virt"
    write_campaign(vc, root)
    write_validated(root)
    win = windows_stage(root)
    rep = repeatability(win, 0.05)
    write_parquet(assemble(win, rep), root / "characteristic.parquet")
    return root


def test_nominal_damper_gets_an_empty_verdict(tmp_path):
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects()))
    assert result["verdict"] == [] and result["nominal_explains"]
    assert 0.5 < result["gap_before"] < 2.0  # noise only: rms_z about 1
    assert result["where"] == []


def test_leakage_is_attributed_and_its_conductance_recovered(tmp_path):
    truth = 1.5e-12
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects(leakage_conductance_m3_s_Pa=truth)))
    assert result["verdict"] == ["leakage"] and result["explained"]
    assert result["params"]["leakage_conductance_m3_s_Pa"] == pytest.approx(truth, rel=0.02)
    assert result["gap_after"] < 2.0 and result["holdout_gap_after"] < 2.0
    assert result["shrink"] == pytest.approx(result["gap_before"] / result["gap_after"])
    # leakage weakens the damper everywhere: every significant band has a negative relative error
    assert result["where"] and all(b["mean_rel_error"] < 0 for b in result["where"])


def test_the_next_tests_are_written_beside_the_diagnosis_as_a_manifest_fragment(tmp_path):
    root = process(tmp_path, Effects())
    out = dg.write_diagnosis(root, root / "diagnosis.json", None)
    assert out["next_tests"] == {"needed": False, "note": "no confounding: no further test proposed", "plan": []}
    assert (root / "next_tests.yaml").read_text(encoding="utf-8") == plan_yaml(out["next_tests"], "virt")


@pytest.mark.slow
def test_air_is_told_apart_from_leakage_by_the_transients(tmp_path):
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects(air_volume_fraction=0.002)))
    assert result["verdict"] == ["air"]
    assert result["params"]["air_volume_fraction"] == pytest.approx(0.002, rel=0.05)
    leak = next(c for c in result["candidates"] if c["effects"] == ["leakage"])
    assert not leak["explained"]


@pytest.mark.slow
def test_diagnosis_json_validates_against_the_repository_schema(tmp_path):
    root = process(tmp_path, Effects(coulomb_force_N=20.0))
    out = dg.write_diagnosis(root, tmp_path / "diagnosis.json", tmp_path / "gap.png")
    written = json.loads((tmp_path / "diagnosis.json").read_text())
    assert written["verdict"] == ["friction"] == out["verdict"]
    assert (tmp_path / "gap.png").stat().st_size > 0
    validate_diagnosis(written)
    for key in ("format_version", "campaign", "metric", "gap_before", "where", "candidates", "verdict",
                "gap_after", "holdout_gap_after", "shrink"):
        assert key in written
    scores = [c["score"] for c in written["candidates"] if c["explained"] and len(c["effects"]) == 1]
    assert scores == sorted(scores)


def test_campaign_times_put_the_cases_back_to_back_in_table_order():
    import types

    import numpy as np
    import pandas as pd

    cases = pd.DataFrame({"case": ["A", "B"], "sample_rate_Hz": [10.0, 10.0], "duration_s": [np.nan, np.nan],
                          "period_s": [4.0, 4.0], "motion_start_s": [0.5, 1.25]})
    plan = types.SimpleNamespace(sample_rate_Hz=10.0)
    obs = types.SimpleNamespace(case=np.array(["A", "B"]), case_index=np.array([0, 1]), plans=(plan, plan),
                                start=np.array([10, 10]), stop=np.array([20, 30]))
    spans = {"A": (0.25, 99.9), "B": (1.0, 50.0)}  # (first time stamp, record length) of each record
    times = dg.campaign_times(obs, cases, spans)
    # A: starts at 0, motion 0.25 s after its first stamp, samples 10..19 -> middle 1.5 s
    # B: starts after A's 99.9 s record and one sample, motion 0.25 s in, samples 10..29 -> middle 2.0 s
    assert times == pytest.approx([0.25 + 1.5, 100.0 + 0.25 + 2.0])


def test_a_sine_check_that_cannot_be_made_is_reported_and_leaves_the_verdict(monkeypatch):
    def failing(*_args, **_kwargs):
        raise FloatingPointError("overflow in a model run")

    class SineObservations:   # the one field the report of a failed check reads
        case = np.array(["H1", "H1", "H2"])

    monkeypatch.setattr(dg, "sine_check", failing)
    result = {"campaign": "c", "verdict": ["friction"], "explained": True}
    dg.check_verdict_on_sines(result, {"sine_obs": SineObservations, "sine_time_s": None, "time_ref_s": None},
                                 None, 1e-3)
    assert result == {"campaign": "c", "verdict": ["friction"], "explained": True,
                      "sine_check": {"cases": "H1,H2", "error": "FloatingPointError: overflow in a model run"}}


def test_a_plan_that_fails_leaves_the_diagnosis_standing_and_says_why(tmp_path, monkeypatch):
    def broken(*_args, **_kwargs):
        raise KeyError("rival")

    monkeypatch.setattr(dg, "next_tests", broken)
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects()))
    assert result["status"] == "ok" and result["verdict"] == []
    assert result["next_tests"]["plan"] == [] and "KeyError" in result["next_tests"]["note"]
    validate_diagnosis(result)


def test_a_declared_load_cell_calibration_reaches_the_triangles_and_the_sines_beside_them(tmp_path):
    raw = tmp_path / "raw" / "calibrated"
    cases = [rr.TriangleCase("T01", 0.1e-3, 20.0, 50.0), rr.TriangleCase("T02", 0.5e-3, 10.0, 50.0),
             rr.SineCase("H01", 0.5, 30e-6, 4, 200.0)]
    rrc.write_campaign(raw, cases, rr.TABLE1, rig=rr.RigImperfections(force_noise_N=3.0), seed=2, write_phase=False)
    manifest = yaml.safe_load((raw / "campaign.yaml").read_text(encoding="utf-8"))
    manifest["columns"]["force"]["calibration"] = {"gain": 1.012, "uncertainty_rel": 0.001}
    (raw / "campaign.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    root = process_raw_campaign(raw, tmp_path / "work")
    *_head, obs, reason, sensor = dg.prepare_sensor(root)
    assert obs is not None, reason
    assert obs.force_calibration == (1.012, 0.001)
    assert sensor["sine_obs"].force_calibration == (1.012, 0.001)


def _lvdt_campaign(tmp_path, name: str, cases, command: bool, calibration: dict | None):
    """A reference-rig campaign whose LVDT reads 1.2 % long, processed (with or without its command channel and a
    declared LVDT calibration), and its prepared sensor chain."""
    *_head, obs, reason, sensor = dg.prepare_sensor(_lvdt_results(tmp_path, name, cases, command, calibration))
    assert obs is not None, reason
    return obs, sensor


def _lvdt_results(tmp_path, name: str, cases, command: bool, calibration: dict | None):
    """The results folder of :func:`_lvdt_campaign`'s campaign, processed to its characteristic."""
    raw = tmp_path / "raw" / name
    rrc.write_campaign(raw, cases, rr.TABLE1, rig=rr.RigImperfections(force_noise_N=3.0, displacement_gain=1.012),
                       seed=4, write_phase=False)
    if not command:
        drop_command_channel(raw)
    if calibration is not None:
        manifest = yaml.safe_load((raw / "campaign.yaml").read_text(encoding="utf-8"))
        manifest["columns"]["displacement"]["calibration"] = calibration
        (raw / "campaign.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    return process_raw_campaign(raw, tmp_path / "work" / name)


SINES = [rr.SineCase(f"H0{i}", f, 40e-6, 4, 200.0) for i, f in enumerate((0.3, 0.8, 1.6), start=1)]


def test_a_sine_only_campaign_without_command_channel_is_driven_through_its_declared_lvdt_scale(tmp_path):
    plain, _ = _lvdt_campaign(tmp_path, "plain", SINES, command=False, calibration=None)
    obs, sensor = _lvdt_campaign(tmp_path, "declared", SINES, command=False,
                                 calibration={"scale": 1.012, "uncertainty_rel": 0.001})
    scale = sensor["displacement_scale"]
    assert (scale["estimate"], scale["applied"], scale["source"]) == (1.012, True, "calibration")
    amplitude = np.array([d.amplitude_m for d in obs.drives])
    assert amplitude.size and len(plain.drives) == amplitude.size
    np.testing.assert_allclose(amplitude * 1.012, [d.amplitude_m for d in plain.drives], rtol=1e-9)


TRIANGLES = [rr.TriangleCase("T01", 0.1e-3, 20.0, 50.0), rr.TriangleCase("T02", 0.5e-3, 10.0, 50.0),
             rr.TriangleCase("T03", 1.0e-3, 10.0, 50.0)]


def test_a_command_channels_measured_lvdt_scale_stands_beside_a_declared_calibration(tmp_path):
    _obs, sensor = _lvdt_campaign(tmp_path, "measured", TRIANGLES, command=True,
                                  calibration={"scale": 1.002, "uncertainty_rel": 0.001})
    scale = sensor["displacement_scale"]
    assert scale["source"] == "LVDT speed against the command channel" and scale["n_cases"] == 3
    assert scale["estimate"] == pytest.approx(1.012, rel=1e-3) and scale["applied"] is True
    assert scale["calibration"] == {"scale": 1.002, "uncertainty_rel": 0.001, "z": pytest.approx(
        (scale["estimate"] - 1.002) / np.hypot(scale["std_error"], 1.002e-3)), "agrees": False}   # 1 % apart: said


def test_a_declared_lvdt_calibration_the_command_channel_contradicts_is_said_in_the_diagnosis(tmp_path):
    # the rig's LVDT reads 1.2 % long, its declared calibration 1.002 ± 0.1 % is stale: the command channel's
    # scale is applied and the diagnosis says that the two disagree
    root = _lvdt_results(tmp_path, "stale", TRIANGLES, command=True,
                         calibration={"scale": 1.002, "uncertainty_rel": 0.001})
    result, _obs, _predictions = dg.diagnose(root)
    validate_diagnosis(result)
    assert result["instrument"]["displacement_scale"] == pytest.approx(1.012, rel=1e-3)
    assert result["instrument_tests"]["displacement_scale"]["calibration"]["agrees"] is False
    assert "the LVDT's declared calibration (scale 1.002" in result["calibration_note"]

