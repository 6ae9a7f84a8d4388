"""Raw ingest: canonical SI time series, per-case quarantine, raw folder left untouched."""

from __future__ import annotations

import json
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from conftest import CAMPAIGN, CASE_IDS, assert_quarantine, set_cell, tree_hashes
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.manifest import ManifestError
from isokinetic.io import sha256_file
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.static_force import static_force_stage


def test_good_campaign(raw_campaign):
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [])
    ingested = CampaignFolder.at(raw_campaign.root)
    row = ingested.ingested_cases().set_index("case").loc["T01"]
    assert row["raw_file"] == "data/raw/demo/T01.csv"
    assert row["raw_sha256"] == sha256_file("data/raw/demo/T01.csv")
    assert ingested.meta.manifest_file == "data/raw/demo/campaign.yaml"
    assert ingested.meta.damper.piston_area_m2 == 4.0e-3
    assert ingested.meta.metadata["operator"] == "fixture"
    for case in ("T01", "T02", "T03"):   # force resists velocity, T03 through its inverted column
        ts = ingested.timeseries(case)
        assert list(ts.columns) == ["row", "time_s", "displacement_m", "force_N", "command_m"]
        velocity = np.gradient(ts["command_m"], ts["time_s"])
        assert np.mean(np.sign(velocity) == np.sign(ts["force_N"])) > 0.95
    t02 = ingested.timeseries("T02")
    assert t02["displacement_m"].abs().max() == pytest.approx(0.5e-3, rel=0.02)
    assert t02["time_s"].iloc[-1] == pytest.approx(3.99)


def set_cells(rows, column: str, value: str):
    """A table edit: ``column`` of every row in ``rows`` replaced (more than a partial record's damage)."""
    def edit(table: pd.DataFrame) -> pd.DataFrame:
        table.loc[list(rows), column] = value
        return table
    return edit


def _drop_column(name):
    return lambda t: t.drop(columns=name)


def _rename_column(old, new):
    return lambda t: t.rename(columns={old: new})


@pytest.mark.parametrize("case, edit, column, row, message", [
    ("T01", _drop_column("force_kN"), "force_kN", None,
     "column not in the file (header: time_s, disp_mm, cmd_mm, temp_C)"),
    ("T02", _rename_column("disp_mm", "disp_MM"), "disp_mm", None,   # T02's columns are in reverse order
     "column not in the file (header: temp_C, cmd_mm, force_kN, disp_MM, time_s)"),
    ("T02", set_cells(range(17, 30), "force_kN", "abc"), "force_kN", 17, "non-numeric value 'abc'"),
    ("H01", set_cells(range(10), "time_s", "0,0"), "time_s", 0, "non-numeric value '0,0'"),
], ids=["missing-column", "misnamed-column", "non-numeric", "decimal-comma"])
def test_bad_column_quarantines_only_its_case(raw_campaign, case, edit, column, row, message):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, case, "ingest", column, row)])
    where = f"campaign demo, case {case}, column {column!r}" + ("" if row is None else f", row {row}")
    assert quarantine["reason"].tolist() == [f"{where}: {message}"]
    assert not (raw_campaign.root / "ingest" / "timeseries" / f"{case}.parquet").exists()


def test_a_subset_of_cases_is_ingested_as_the_whole_campaign_ingests_them(raw_campaign):
    # trace re-derives only the cases it traces, through the build's own ingest step
    ingest_campaign(raw_campaign.raw_dir, "results/all")
    ingest_campaign(raw_campaign.raw_dir, "results/some", cases=["T02"])
    all_cases = CampaignFolder.at("results/all").ingested_cases().set_index("case")
    some = CampaignFolder.at("results/some").ingested_cases().set_index("case")
    assert list(some.index) == ["T02"]
    pd.testing.assert_series_equal(some.loc["T02"], all_cases.loc["T02"])
    with pytest.raises(KeyError, match="no case T09"):
        ingest_campaign(raw_campaign.raw_dir, "results/none", cases=["T02", "T09"])


def test_file_missing(raw_campaign):
    (raw_campaign.raw_dir / "H01.csv").unlink()
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "H01", "ingest", "file", None)])
    assert quarantine["reason"].iloc[0] == "campaign demo, case H01, key 'file': file not found: data/raw/demo/H01.csv"
    h01 = cases.set_index("case").loc["H01"]
    assert (h01["raw_sha256"], h01["timeseries_file"], h01["n_samples"]) == ("", "", 0)


@pytest.mark.parametrize("name", ["../T02.csv", "sub/../../T02.csv", "/tmp/T02.csv", "sub\\T02.csv", "C:T02.csv",
                                  "sub//T02.csv"])
def test_file_name_with_a_path(raw_campaign, name):
    """A file name leading out of the folder (or not a plain relative path) refuses the whole manifest before
    any file is read (hostile input)."""
    Path("data/raw/T02.csv").write_bytes((raw_campaign.raw_dir / "T02.csv").read_bytes())  # a tempting target
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T02").update(file=name))
    with pytest.raises(ManifestError) as info:
        raw_campaign.run()
    assert info.value.key == "cases.T02.file"
    assert str(info.value) == ("data/raw/demo/campaign.yaml: key 'cases.T02.file': must be a bare file name "
                               f"inside the campaign folder, got {name!r} (or a path into a subfolder: "
                               "run1/T01.csv, with '/' and no '..')")
    assert not raw_campaign.root.exists()   # nothing written


def test_unknown_unit_in_a_case(raw_campaign):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "H01").update(columns={"force": {"unit": "kp"}}))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "H01", "ingest", "force_kN", None)])
    assert quarantine["reason"].iloc[0] == ("campaign demo, case H01, column 'force_kN': "
                                           "unknown unit 'kp'; nearest known force units: kip, kN")


def test_unknown_unit_in_campaign_columns_quarantines_every_case(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["columns"]["displacement"].update(unit="inch"))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine,
                      [(CAMPAIGN, case, "ingest", "disp_mm", None) for case in CASE_IDS])


def test_broken_manifest_fails_the_campaign(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["columns"]["force"].pop("name"))
    with pytest.raises(ManifestError, match=r"^data/raw/demo/campaign.yaml: key 'columns.force.name': missing$"):
        ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    assert not raw_campaign.root.exists()


def test_quarantine_is_logged(raw_campaign, caplog):
    raw_campaign.edit_table("T01", set_cells(range(3, 13), "disp_mm", "n/a?"))
    with caplog.at_level(logging.WARNING, logger="isokinetic"):
        raw_campaign.run()
    assert "campaign demo, case T01, column 'disp_mm', row 3: non-numeric value 'n/a?'" in caplog.text


def test_raw_folder_bytes_unchanged(raw_campaign):
    raw_campaign.edit_table("T02", set_cell(5, "force_kN", "abc"))
    (raw_campaign.raw_dir / "H01.csv").unlink()
    before = tree_hashes(Path("data"))
    raw_campaign.run()
    raw_campaign.run()            # twice: a rerun overwrites results only
    assert tree_hashes(Path("data")) == before


def _mini_campaign(name: str, columns: dict, csv_text: str, **case) -> Path:
    """A one-case free campaign at ``data/raw/<name>`` (no damper block)."""
    raw_dir = Path("data", "raw", name)
    raw_dir.mkdir(parents=True)
    manifest = {"format_version": 1, "campaign": name, "sample_rate_Hz": 100.0, "columns": columns,
                "cases": [{"id": "C1", "waveform": "free", "file": "C1.csv", **case}]}
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(manifest), encoding="utf-8")
    (raw_dir / "C1.csv").write_text(csv_text, encoding="utf-8")
    return raw_dir


def test_unit_conversions(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    n = 12
    text = "# exported by rig 7\n# units: ms um N m\nnote,time_ms,force_N,disp_um,cmd_m,flags\n"
    text += "".join(f"x{i},{10 * i},{i * 0.5:g},{-250 * i},{i * 1e-5:g},{i % 3}\n" for i in range(n))
    columns = {"time": {"name": "time_ms", "unit": "ms"},
               "displacement": {"name": "disp_um", "unit": "um", "invert": True},
               "force": {"name": "force_N", "unit": "N"},
               "command": {"name": "cmd_m", "unit": "m"}}
    raw_dir = _mini_campaign("units", columns, text)
    ingest_campaign(raw_dir, "results/units")
    ingested = CampaignFolder.at("results/units")
    assert ingested.meta.damper is None and ingested.ingested_quarantine().empty
    ts = ingested.timeseries("C1")
    i = np.arange(n)
    np.testing.assert_array_equal(ts["row"], i)
    np.testing.assert_allclose(ts["time_s"], 1e-2 * i)
    np.testing.assert_allclose(ts["displacement_m"], 250e-6 * i)      # inverted
    np.testing.assert_allclose(ts["force_N"], 0.5 * i)
    np.testing.assert_allclose(ts["command_m"], 1e-5 * i)
    assert ts["force_N"].dtype == np.float64


def test_kilonewton_millimetre_and_datetime_time(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    stamps = pd.date_range("2025-03-01T10:59:59.95", periods=12, freq="10ms")
    lines = [f"{s.isoformat()}Z,{k * 0.1:g},{k * 2:g}" for k, s in enumerate(stamps)]
    lines[3] = lines[3].replace("T", " ", 1)                            # space separator, also ISO 8601
    text = "stamp,disp_mm,force_kN\n" + "\n".join(lines) + "\n"
    columns = {"time": {"name": "stamp", "unit": "datetime"},
               "displacement": {"name": "disp_mm", "unit": "mm"},
               "force": {"name": "force_kN", "unit": "kN", "invert": True}}
    ingest_campaign(_mini_campaign("stamps", columns, text), "results/stamps")
    ts = CampaignFolder.at("results/stamps").timeseries("C1")
    k = np.arange(12)
    np.testing.assert_allclose(ts["time_s"], 0.01 * k, atol=1e-9)
    np.testing.assert_allclose(ts["displacement_m"], 1e-4 * k)
    np.testing.assert_allclose(ts["force_N"], -2000.0 * k)
    assert "command_m" not in ts


def test_bad_timestamp_names_row(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    text = "t,y,f\n" + "\n".join(f"2025-03-01T11:00:{k:02d},0,0" for k in range(12)) + "\n"
    text = text.replace("11:00:07", "11:00:07 tomorrow")
    columns = {"time": {"name": "t", "unit": "datetime"}, "displacement": {"name": "y", "unit": "m"},
               "force": {"name": "f", "unit": "N"}}
    ingest_campaign(_mini_campaign("stamps", columns, text), "results/stamps")
    q = CampaignFolder.at("results/stamps").ingested_quarantine()
    assert q["reason"].tolist() == ["campaign stamps, case C1, column 't', row 7: "
                                    "invalid ISO 8601 timestamp '2025-03-01T11:00:07 tomorrow'"]


def test_unreadable_csv(raw_campaign):
    (raw_campaign.raw_dir / "F01.csv").write_text("# only a comment\n", encoding="utf-8")
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "F01", "ingest", "file", None)])
    assert quarantine["reason"].iloc[0].endswith("no header row")


def test_gas_force_shifts_the_characteristic_and_is_recorded(raw_campaign):
    ingest_campaign(raw_campaign.raw_dir, "results/plain")
    raw_campaign.edit_manifest(lambda m: m.update(gas_force_N=25.0))
    ingest_campaign(raw_campaign.raw_dir, "results/gas")
    plain, gas = write_characteristic("results/plain"), write_characteristic("results/gas")
    if "method" in plain:                              # sine and free points beside the triangle windows
        plain, gas = (c[c["method"] == "triangle_window"].reset_index(drop=True) for c in (plain, gas))
    assert len(plain) == 12                            # three triangle cases, four windows each
    np.testing.assert_allclose(gas["force_N"] - plain["force_N"], -25.0, atol=1e-9)
    pd.testing.assert_frame_equal(gas.drop(columns="force_N"), plain.drop(columns="force_N"))
    # T03's force column is inverted: the gas force is taken off in the spec's sign convention, as declared
    t03 = CampaignFolder.at("results/gas").timeseries("T03")["force_N"] - CampaignFolder.at("results/plain").timeseries(
        "T03")["force_N"]
    np.testing.assert_allclose(t03, -25.0, atol=1e-9)
    assert CampaignFolder.at("results/gas").meta.gas_force_N == 25.0
    assert CampaignFolder.at("results/plain").meta.gas_force_N is None
    # the static force carries the declared gas force and moves by it
    before, after = static_force_stage("results/plain"), static_force_stage("results/gas")
    assert after.static_force_N - before.static_force_N == pytest.approx(-25.0, abs=1e-6)
    assert (after.gas_force_N, math.isnan(before.gas_force_N)) == (25.0, True)


def test_a_declared_force_calibration_is_carried_into_campaign_json(raw_campaign):
    calibration = {"gain": 0.987, "uncertainty_rel": 0.0015}
    raw_campaign.edit_manifest(lambda m: m["columns"]["force"].update(calibration=calibration))
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    folder = CampaignFolder.at(raw_campaign.root)
    assert json.loads(folder.ingest_path("meta").read_text())["force_calibration"] == calibration
    assert folder.meta.calibration == (0.987, 0.0015)


def test_a_declared_lvdt_calibration_is_carried_into_campaign_json(raw_campaign):
    calibration = {"scale": 1.008, "uncertainty_rel": 0.0005}
    raw_campaign.edit_manifest(lambda m: m["columns"]["displacement"].update(calibration=calibration))
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    folder = CampaignFolder.at(raw_campaign.root)
    written = json.loads(folder.ingest_path("meta").read_text())
    assert (written["displacement_calibration"], written["force_calibration"]) == (calibration, None)
    assert folder.meta.lvdt_calibration == (1.008, 0.0005)
