"""The campaign page's diagnosis section: the residual-structure tests of the verdict (contract 1.3)."""

from __future__ import annotations

from isokinetic.diagnosis.result import validate_diagnosis
from isokinetic.io import write_json
from isokinetic.report.campaign_report import render_campaign_report

from .fixture_results import build_campaign, diagnosis, plain

NOTE = "the verdict's residuals are ordered along position beyond noise (Holm-adjusted p 2e-05)"


def with_structure(d: dict) -> dict:
    """The fixture's diagnosis with a position structure found (and a time axis tested without one)."""
    tests = [{"axis": "position", "n_units": 20, "n_bins": 4, "bins_F": 9.1, "bins_df": [3, 16], "bins_p": 1e-5,
              "trend_t": -5.2, "trend_p": 8e-6, "p": 1.6e-5, "p_adjusted": 2e-5, "significant": True},
             {"axis": "time", "n_units": 20, "n_bins": 5, "bins_F": 0.4, "bins_df": [4, 15], "bins_p": 0.8,
              "trend_t": 0.3, "trend_p": 0.77, "p": 1.0, "p_adjusted": 1.0, "significant": False}]
    entry = {"axis": "position", "quantity": "stroke amplitude", "range": [0.002, 0.003], "unit": "m",
             "mean_rel": -0.0456, "z": -6.25, "p_adjusted": 2e-5, "significant": True, "n_units": 4}
    d = {**d, "explained": False, "structure_note": NOTE, "where": [{"axis": "speed", **d["where"][0]}, entry],
         "structure": {"alpha": 1e-3, "tests": tests, "skipped": {"temperature": "not recorded"},
                       "axes": ["position"]}}
    validate_diagnosis(d)
    return d


def test_the_page_names_the_axis_with_structure_and_its_range(results):
    root = build_campaign(results)
    write_json(with_structure(diagnosis()), root / "diagnosis.json")
    page = render_campaign_report(root)
    text = plain(page)
    assert "Residual structure of the verdict on every axis" in text
    assert NOTE in text and "0.00200 to 0.00300 m" in text and "-4.56 %" in text
    assert "diagnosis.json where.1.z\"" in page   # the entry's place in where
    assert "Not tested: temperature: not recorded" in text


def test_a_diagnosis_before_contract_1_3_shows_no_structure_section(results):
    root = build_campaign(results)
    page = render_campaign_report(root)
    assert "Residual structure" not in plain(page)


def with_plan(d: dict) -> dict:
    """The fixture's diagnosis with a confounding and the next tests that resolve it (contract 1.5)."""
    plan = [{"case": "N01", "waveform": "triangle", "velocity_m_s": 6.35e-5, "amplitude_m": 1e-4, "period_s": 6.2992,
             "frequency_Hz": None, "periods": 2, "sample_rate_Hz": 50.0, "duration_s": 12.6, "rig_time_s": 42.6,
             "resolves": ["air+force_lag"], "separation_se": 17.5}]
    block = {"needed": True, "note": "1 case(s), 0.7 min of rig time, separate air+force_lag by 17.5 SE",
             "rivals": [], "plan": plan, "total_rig_time_s": 42.6, "separation_se": {"air+force_lag": 17.5},
             "separation_se_now": {"air+force_lag": 0.356}, "target_se": 5.0,
             "unresolvable": {"displacement_scale+force_gain+discharge": "no case separates them"}}
    d = {**d, "confounded": [["air", "force_lag"]], "next_tests": block}
    validate_diagnosis(d)
    return d


def test_the_page_shows_the_plan_beside_the_confounding_it_resolves(results):
    root = build_campaign(results)
    write_json(with_plan(diagnosis()), root / "diagnosis.json")
    page = render_campaign_report(root)
    text = plain(page)
    assert "Next tests" in text and "1 case(s), 0.7 min of rig time" in text
    assert "air+force_lag: separated by 0.356 SE now, 17.5 SE with the plan" in text
    assert "N01" in text and "0.0635" in text and "diagnosis.json next_tests.plan.0.separation_se\"" in page
    assert "displacement_scale+force_gain+discharge: no case separates them" in text


def test_a_campaign_without_confounding_shows_the_one_line_note(results):
    root = build_campaign(results)
    d = {**diagnosis(), "next_tests": {"needed": False, "note": "no confounding: no further test proposed", "plan": []}}
    write_json(d, root / "diagnosis.json")
    text = plain(render_campaign_report(root))
    assert "Next tests: no confounding: no further test proposed." in text
    assert "the cases that would separate" not in text


def with_calibration(d: dict) -> dict:
    """The fixture's diagnosis with the load cell's gain confounded and the calibration that resolves it, no case
    (contract 1.6)."""
    group = "force_gain+discharge+viscosity"
    calibration = {"check": "load_cell_gain", "channel": "force", "uncertainty_rel": 0.001, "rig_time_s": 1800.0,
                   "resolves": [group], "separation_se": 14.06, "separation_se_by_group": {group: 14.06},
                   "how": "mount a reference load cell in series"}
    block = {"needed": True, "note": f"a load-cell calibration against a reference force (±0.1 %, 30 min of rig "
                                     f"time) separates {group} by 14.1 SE",
             "rivals": [], "plan": [], "calibrations": [calibration], "total_rig_time_s": 1800.0,
             "separation_se": {group: 14.14}, "separation_se_now": {group: 1.49}, "target_se": 5.0, "unresolvable": {}}
    d = {**d, "confounded": [["force_gain", "discharge", "viscosity"]], "next_tests": block}
    validate_diagnosis(d)
    return d


def test_the_page_shows_the_calibration_beside_the_group_it_resolves(results):
    root = build_campaign(results)
    write_json(with_calibration(diagnosis()), root / "diagnosis.json")
    page = render_campaign_report(root)
    text = plain(page)
    assert ("force_gain+discharge+viscosity: separated by 1.49 SE now, 14.1 SE with the plan (target 5.0 SE); "
            "the load-cell calibration below alone separates it by 14.1 SE") in text
    assert "diagnosis.json next_tests.calibrations.0.separation_se\"" in page
    assert "Calibrate the load cell against a reference force: mount a reference load cell in series" in text
    assert "columns: force: calibration: {gain: <measured>, uncertainty_rel: 0.001}" in text


def with_lvdt_calibration(d: dict) -> dict:
    """The fixture's diagnosis with an LVDT scale confounded without a command channel (the verdict's own family, no
    case) and the LVDT calibration that resolves it (contract 1.6)."""
    group = "displacement_scale+force_gain+discharge"
    calibration = {"check": "lvdt_scale", "channel": "displacement", "uncertainty_rel": 0.001, "rig_time_s": 1800.0,
                   "resolves": [group], "separation_se": 13.05, "separation_se_by_group": {group: 13.05},
                   "how": "mount a micrometer calibrator against the rod"}
    block = {"needed": True, "note": f"an LVDT calibration against a reference displacement (±0.1 %, 30 min of rig "
                                     f"time) separates {group} by 13.0 SE and, declared, resolves its listing",
             "rivals": [], "plan": [], "calibrations": [calibration], "total_rig_time_s": 1800.0,
             "separation_se": {group: 13.05}, "target_se": 5.0,
             "unresolvable": {group: "no case of any waveform separates them"}}
    d = {**d, "confounded": [["displacement_scale", "force_gain", "discharge"]], "next_tests": block}
    validate_diagnosis(d)
    return d


def test_the_page_shows_the_lvdt_calibration_beside_the_scale_group(results):
    root = build_campaign(results)
    write_json(with_lvdt_calibration(diagnosis()), root / "diagnosis.json")
    page = render_campaign_report(root)
    text = plain(page)
    assert "the LVDT calibration below alone separates it by 13.1 SE" in text
    assert ("displacement_scale+force_gain+discharge: no case of any waveform separates them; the LVDT calibration "
            "below resolves its listing") in text
    assert "diagnosis.json next_tests.calibrations.0.separation_se\"" in page
    assert "Calibrate the LVDT against a reference displacement: mount a micrometer calibrator against the rod" in text
    assert "columns: displacement: calibration: {scale: <measured>, uncertainty_rel: 0.001}" in text
    assert "load-cell calibration" not in text


def test_the_page_warns_of_a_declared_calibration_the_data_contradict(results):
    root = build_campaign(results)
    note = ("the LVDT's declared calibration (scale 1.002, u 0.001) and the command channel disagree: the command "
            "reads the scale as 1.012, +9.9 standard errors from it")
    d = {**diagnosis(), "calibration_note": note}
    validate_diagnosis(d)
    write_json(d, root / "diagnosis.json")
    text = plain(render_campaign_report(root))
    assert "Calibration contradicted. " + note in text
