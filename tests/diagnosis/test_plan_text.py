"""The next-test plan as text (isokinetic.diagnosis.plan_text): next_tests.yaml is a manifest fragment the manifest
reader takes, and ``python -m isokinetic next-test`` prints the plan (one line where none is needed); a proposed
load-cell calibration is a commented declaration of the force column's ``calibration``."""

import json

import pytest
import yaml

from isokinetic.__main__ import main
from isokinetic.contracts.manifest import force_calibration, load_manifest
from isokinetic.diagnosis.plan_text import plan_lines, plan_yaml

BLOCK = {
    "needed": True, "note": "2 case(s), 1.9 min of rig time, separate air+force_lag by 17.5 SE",
    "rivals": [{"label": "air", "group": "air+force_lag", "effects": ["air"], "instrument": {}, "params": {}},
               {"label": "force_lag", "group": "air+force_lag", "effects": [], "instrument": {}, "params": {}}],
    "plan": [{"case": "N01", "waveform": "triangle", "velocity_m_s": 6.35e-5, "amplitude_m": 1e-4, "period_s": 6.2992,
              "frequency_Hz": None, "periods": 2, "sample_rate_Hz": 50.0, "duration_s": 12.5984, "rig_time_s": 42.6,
              "resolves": ["air+force_lag"], "separation_se": 17.5, "separation_se_by_group": {"air+force_lag": 17.5},
              "label": "triangle 0.0635 mm/s, 0.1 mm"},
             {"case": "N02", "waveform": "standstill", "velocity_m_s": None, "amplitude_m": 0.0, "period_s": None,
              "frequency_Hz": None, "periods": 0, "sample_rate_Hz": 50.0, "duration_s": 60.0, "rig_time_s": 90.0,
              "resolves": [], "separation_se": 0.5, "label": "standstill at the end"}],
    "total_rig_time_s": 132.6, "separation_se": {"air+force_lag": 17.6}}
MANIFEST = """format_version: 1
campaign: bench
sample_rate_Hz: 50.0
columns:
  time: {name: time_s, unit: s}
  displacement: {name: disp_mm, unit: mm}
  force: {name: force_N, unit: N}
"""


def test_the_fragment_pasted_into_a_manifest_reads_as_its_cases(tmp_path):
    folder = tmp_path / "bench"
    folder.mkdir()
    (folder / "campaign.yaml").write_text(MANIFEST + plan_yaml(BLOCK, "bench"), encoding="utf-8")
    manifest = load_manifest(folder / "campaign.yaml")
    tri, still = manifest.cases
    assert [tri.id, still.id] == ["N01", "N02"] and not tri.problems and not still.problems
    assert tri.plan.waveform == "triangle" and tri.plan.period_s == pytest.approx(6.2992)
    assert tri.plan.amplitude_m == pytest.approx(1e-4) and tri.plan.velocity_m_s == pytest.approx(6.35e-5, rel=1e-3)
    assert still.plan.waveform == "standstill" and still.plan.duration_s == pytest.approx(60.0)
    assert tri.file == "N01.csv" and tri.plan.sample_rate_Hz == 50.0


def test_each_case_of_the_fragment_says_what_it_resolves():
    text = plan_yaml(BLOCK, "bench")
    assert "# N01: triangle 0.0635 mm/s, 0.1 mm; resolves air+force_lag (17.5 SE)" in text
    assert "# N02: standstill at the end; resolves adds to the separation below 1 SE" in text


def test_a_plan_without_cases_is_an_empty_list_of_cases():
    text = plan_yaml({"needed": False, "note": "no confounding: no further test proposed", "plan": []}, "bench")
    assert text.rstrip().endswith("cases: []") and "no confounding" in text


def test_the_command_prints_the_plan(tmp_path, capsys):
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "diagnosis.json").write_text(json.dumps({"next_tests": BLOCK}), encoding="utf-8")
    assert main(["next-test", "bench", "--results", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == BLOCK["note"]
    assert any(line.strip().startswith("N01") and "17.5 SE" in line and "air+force_lag" in line for line in out)
    assert out[-1].strip().startswith("total rig time 133 s")


def test_the_command_prints_one_line_where_no_test_is_needed(tmp_path, capsys):
    (tmp_path / "bench").mkdir()
    block = {"needed": False, "note": "no confounding: no further test proposed", "plan": []}
    (tmp_path / "bench" / "diagnosis.json").write_text(json.dumps({"next_tests": block}), encoding="utf-8")
    assert main(["next-test", "bench", "--results", str(tmp_path)]) == 0
    assert capsys.readouterr().out == "no confounding: no further test proposed\n"
    assert plan_lines(block) == ["no confounding: no further test proposed"]


CALIBRATION = {"check": "load_cell_gain", "channel": "force", "uncertainty_rel": 0.001, "rig_time_s": 1800.0,
               "resolves": ["force_gain+discharge+viscosity"], "separation_se": 14.1,
               "separation_se_by_group": {"force_gain+discharge+viscosity": 14.1}, "how": "a reference load cell"}
CALIBRATED = {**BLOCK, "calibrations": [CALIBRATION], "total_rig_time_s": 1932.6, "target_se": 5.0}


def declared_fragment(text: str) -> dict:
    """The commented declaration of a plan's calibration, uncommented, its <measured> value 1.012."""
    start = text.index("# columns:")
    block = [line[2:] for line in text[start:].splitlines()[:3]]
    return yaml.safe_load("\n".join(block).replace("<measured>", "1.012"))


def pasted_case_ids(tmp_path, text: str) -> list[str]:
    """The case ids of a manifest with the plan's fragment pasted under its cases."""
    folder = tmp_path / "bench"
    folder.mkdir()
    (folder / "campaign.yaml").write_text(MANIFEST + text, encoding="utf-8")
    return [c.id for c in load_manifest(folder / "campaign.yaml").cases]


def printed_plan(tmp_path, capsys, block: dict) -> tuple[list[str], str]:
    """(the lines `next-test` prints for a campaign whose diagnosis holds ``block``, its CAL line)."""
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "diagnosis.json").write_text(json.dumps({"next_tests": block}), encoding="utf-8")
    assert main(["next-test", "bench", "--results", str(tmp_path)]) == 0
    out = capsys.readouterr().out.splitlines()
    (line,) = [line for line in out if line.strip().startswith("CAL")]
    return out, line


def test_the_calibration_is_a_commented_declaration_of_the_force_columns_calibration(tmp_path):
    text = plan_yaml(CALIBRATED, "bench")
    assert "# Load-cell calibration (next_tests.calibrations): resolves force_gain+discharge+viscosity (14.1 SE)" \
        in text and "reading per unit true force" in text
    declared = declared_fragment(text)
    # the manifest reader's own key (columns.force.calibration) takes it
    assert force_calibration(declared["columns"], "bench") == {"gain": 1.012, "uncertainty_rel": 0.001}
    # commented, the fragment pasted into a manifest still reads as its cases
    assert pasted_case_ids(tmp_path, text) == ["N01", "N02"]


def test_the_command_prints_the_calibration(tmp_path, capsys):
    out, line = printed_plan(tmp_path, capsys, CALIBRATED)
    assert "load cell against a reference force" in line and "1800 s" in line and "14.1 SE" in line
    assert "force_gain+discharge+viscosity" in line
    assert any("columns: force: calibration: {gain: <measured>, uncertainty_rel: 0.001}" in x for x in out)
    assert out[-1].strip().startswith("total rig time 1933 s")


LVDT = {"check": "lvdt_scale", "channel": "displacement", "uncertainty_rel": 0.001, "rig_time_s": 1800.0,
        "resolves": ["displacement_scale+force_gain+discharge"], "separation_se": 13.0,
        "separation_se_by_group": {"displacement_scale+force_gain+discharge": 13.0}, "how": "a micrometer calibrator"}
LVDT_CALIBRATED = {**BLOCK, "calibrations": [LVDT], "total_rig_time_s": 1932.6, "target_se": 5.0}


def test_the_lvdt_calibration_is_a_commented_declaration_of_the_displacement_columns_calibration(tmp_path):
    text = plan_yaml(LVDT_CALIBRATED, "bench")
    assert "# LVDT calibration (next_tests.calibrations): resolves displacement_scale+force_gain+discharge (13.0 SE)" \
        in text and "reading per unit true displacement" in text
    assert declared_fragment(text) == \
        {"columns": {"displacement": {"calibration": {"scale": 1.012, "uncertainty_rel": 0.001}}}}
    # commented, the fragment pasted into a manifest still reads as its cases
    assert pasted_case_ids(tmp_path, text) == ["N01", "N02"]


def test_the_command_prints_the_lvdt_calibration(tmp_path, capsys):
    out, line = printed_plan(tmp_path, capsys, LVDT_CALIBRATED)
    assert "LVDT against a reference displacement" in line and "1800 s" in line and "13.0 SE" in line
    assert "displacement_scale+force_gain+discharge" in line
    assert any("columns: displacement: calibration: {scale: <measured>, uncertainty_rel: 0.001}" in x for x in out)
