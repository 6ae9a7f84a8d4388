"""Ingest of files as rigs write them (manifest 1.2): an MTS 793 export in in/lbf, a Windows-1252 file, a
units row checked against the manifest, one record sliced into several cases, per-case gas forces,
standstill cases and warnings for keys that look like slips."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages.ingest import ingest_campaign
from test_rawfile import mts793_text

IN_M = 0.0254                   # inch, exact
LBF_N = 4.4482216152605         # pound-force, exact (0.45359237 kg x 9.80665 m/s^2)
RATE_HZ = 100.0


def sweep_si(n: int = 2600, seed: int = 3) -> pd.DataFrame:
    """A record in SI: 8 s at rest, then a sine of 1 Hz at 12.7 mm; force = 300 N + c v + noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE_HZ
    x = np.where(t < 8.0, 0.0, 12.7e-3 * np.sin(2 * np.pi * (t - 8.0)))
    v = np.gradient(x, t)
    force = 300.0 + 2000.0 * v + rng.normal(0.0, 2.0, n)
    return pd.DataFrame({"time_s": t, "displacement_m": x, "force_N": force})


def write_campaign(raw: Path, name: str, columns: dict, cases: list[dict], files: dict[str, bytes],
                   **top) -> Path:
    """A raw campaign folder ``raw/name`` with its manifest and case files; returns it."""
    folder = raw / name
    folder.mkdir(parents=True)
    manifest = {"format_version": 1, "campaign": name, "sample_rate_Hz": RATE_HZ, "columns": columns,
                "cases": cases, **top}
    (folder / "campaign.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")
    for file, data in files.items():
        (folder / file).parent.mkdir(parents=True, exist_ok=True)
        (folder / file).write_bytes(data)
    return folder


def csv_bytes(si: pd.DataFrame, encoding: str = "utf-8", temperature_name: str | None = None) -> bytes:
    """The record as a plain CSV in s, mm and N (and an oil temperature column)."""
    table = pd.DataFrame({"time_s": si["time_s"], "disp_mm": si["displacement_m"] * 1e3, "force_N": si["force_N"]})
    if temperature_name:
        table[temperature_name] = 40.0 + 0.001 * np.arange(len(si))
    return table.to_csv(index=False, float_format="%.17g").encode(encoding)


MM_N = {"time": {"name": "time_s", "unit": "s"}, "displacement": {"name": "disp_mm", "unit": "mm"},
        "force": {"name": "force_N", "unit": "N"}}
MTS_COLUMNS = {"time": {"name": "Time", "unit": "Sec"}, "displacement": {"name": "Axial Displacement", "unit": "in"},
               "force": {"name": "Axial Force", "unit": "lbf"}}


def mts_bytes(si: pd.DataFrame) -> bytes:
    data = {"Time": si["time_s"].to_numpy(), "Axial Displacement": si["displacement_m"].to_numpy() / IN_M,
            "Axial Force": si["force_N"].to_numpy() / LBF_N}
    return mts793_text(data, ("Sec", "in", "lbf")).encode("utf-8")


def test_mts793_export_ingests_to_the_same_si_series_as_a_plain_csv(tmp_path):
    si = sweep_si()
    cases = [{"id": "S01", "waveform": "free", "file": "sweep.txt"}]
    mts = write_campaign(tmp_path / "raw", "mts", MTS_COLUMNS, cases, {"sweep.txt": mts_bytes(si)},
                         csv={"format": "mts793"})
    plain = write_campaign(tmp_path / "raw", "plain", MM_N, [{**cases[0], "file": "sweep.csv"}],
                           {"sweep.csv": csv_bytes(si)})
    ingest_campaign(mts, tmp_path / "results/mts")
    ingest_campaign(plain, tmp_path / "results/plain")
    got, want = CampaignFolder.at(tmp_path / "results/mts"), CampaignFolder.at(tmp_path / "results/plain")
    assert (got.ingested_cases()["status"] == "ok").all() and got.ingested_quarantine().empty
    a, b = got.timeseries("S01"), want.timeseries("S01")
    assert a["row"].tolist() == list(range(len(si)))
    for column in ("time_s", "displacement_m", "force_N"):
        np.testing.assert_allclose(a[column], si[column], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(a[column], b[column], rtol=1e-12, atol=1e-15)
    assert got.meta.csv["format"] == "mts793"


def test_cp1252_campaign_reads_with_its_encoding_like_its_utf8_twin(tmp_path):
    si = sweep_si(300)
    columns = {**MM_N, "temperature": {"name": "oil [°C]", "unit": "C"}}
    case = [{"id": "F01", "waveform": "free", "file": "F01.csv"}]
    win = write_campaign(tmp_path / "raw", "win", columns, case, {"F01.csv": csv_bytes(si, "cp1252", "oil [°C]")},
                         csv={"encoding": "cp1252"})
    utf = write_campaign(tmp_path / "raw", "utf", columns, case, {"F01.csv": csv_bytes(si, "utf-8", "oil [°C]")})
    ingest_campaign(win, tmp_path / "results/win")
    ingest_campaign(utf, tmp_path / "results/utf")
    pd.testing.assert_frame_equal(CampaignFolder.at(tmp_path / "results/win").timeseries("F01"),
                                  CampaignFolder.at(tmp_path / "results/utf").timeseries("F01"), check_exact=True)


def test_cp1252_file_without_encoding_is_set_aside_naming_the_key_to_set(tmp_path):
    columns = {**MM_N, "temperature": {"name": "oil [°C]", "unit": "C"}}
    folder = write_campaign(tmp_path / "raw", "win", columns, [{"id": "F01", "waveform": "free", "file": "F01.csv"}],
                            {"F01.csv": csv_bytes(sweep_si(300), "cp1252", "oil [°C]")})
    ingest_campaign(folder, tmp_path / "results")
    reason = CampaignFolder.at(tmp_path / "results").ingested_quarantine()["reason"].tolist()
    assert len(reason) == 1 and reason[0].startswith("campaign win, case F01, key 'file': not UTF-8: byte 0xb0")
    assert reason[0].endswith("set `encoding:` in the manifest's csv block (for example cp1252)")


def test_units_row_must_agree_with_the_manifest(tmp_path):
    si = sweep_si(300)
    text = csv_bytes(si).decode().split("\n", 1)
    files = {"F01.csv": (text[0] + "\nSec,in,N\n" + text[1]).encode(),     # disp_mm's unit cell says in
             "F02.csv": (text[0] + "\n[s],[mm],N\n" + text[1]).encode()}
    cases = [{"id": "F01", "waveform": "free", "file": "F01.csv"}, {"id": "F02", "waveform": "free", "file": "F02.csv"}]
    folder = write_campaign(tmp_path / "raw", "u", MM_N, cases, files, csv={"units_row": True})
    ingest_campaign(folder, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    assert got.ingested_cases().set_index("case")["status"].to_dict() == {"F01": "quarantined", "F02": "ok"}
    assert got.ingested_quarantine()["reason"].tolist() == [
        "campaign u, case F01, column 'disp_mm': the file's units row says 'in' (means 'in'), the manifest declares "
        "'mm' for displacement: fix the manifest's unit"]
    np.testing.assert_allclose(got.timeseries("F02")["displacement_m"], si["displacement_m"], rtol=1e-15)


def test_slices_give_their_rows_with_time_re_zeroed(tmp_path):
    si = sweep_si()
    cases = [{"id": "Z01", "waveform": "standstill", "file": "sweep.txt", "time_range_s": [0.5, 7.5]},
             {"id": "S01", "waveform": "sine", "frequency_Hz": 1.0, "amplitude_mm": 12.7, "file": "sweep.txt",
              "time_range_s": [12.0, 20.0]},
             {"id": "S02", "waveform": "sine", "frequency_Hz": 1.0, "amplitude_mm": 12.7, "file": "sweep.txt",
              "rows": [2000, 2400]}]
    folder = write_campaign(tmp_path / "raw", "steps", MTS_COLUMNS, cases, {"sweep.txt": mts_bytes(si)},
                            csv={"format": "mts793"})
    ingest_campaign(folder, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    assert (got.ingested_cases()["status"] == "ok").all()
    expected = {"Z01": (50, 750), "S01": (1200, 2000), "S02": (2000, 2400)}     # 100 Hz: t = row / 100 s
    table = got.ingested_cases().set_index("case")
    for case, (first, stop) in expected.items():
        series = got.timeseries(case)
        assert series["row"].tolist() == list(range(first, stop))
        assert (table.loc[case, "row_start"], table.loc[case, "row_stop"], table.loc[case, "n_samples"]) == (
            first, stop, stop - first)
        assert table.loc[case, "slice_start_s"] == pytest.approx(si["time_s"][first], abs=1e-12)
        np.testing.assert_allclose(series["time_s"], si["time_s"][first:stop] - si["time_s"][first], atol=1e-12)
        np.testing.assert_allclose(series["force_N"], si["force_N"][first:stop], rtol=1e-12)


@pytest.mark.parametrize("key, value, words", [
    ("time_range_s", [20.0, 40.0], "[20, 40) s lies outside the file's time axis (0 .. 25.99 s)"),
    ("rows", [2000, 3000], "rows [2000, 3000) run beyond the file's 2600 data rows"),
], ids=["time-range", "rows"])
def test_slice_beyond_the_file_sets_the_case_aside(tmp_path, key, value, words):
    cases = [{"id": "S01", "waveform": "free", "file": "sweep.csv", key: value},
             {"id": "S02", "waveform": "free", "file": "sweep.csv", "rows": [0, 100]}]
    folder = write_campaign(tmp_path / "raw", "c", MM_N, cases, {"sweep.csv": csv_bytes(sweep_si())})
    ingest_campaign(folder, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    assert got.ingested_quarantine()["reason"].tolist() == [f"campaign c, case S01, key {key!r}: {words}"]
    assert got.ingested_cases().set_index("case").loc["S02", "status"] == "ok"


def test_per_case_gas_force_is_subtracted_and_recorded(tmp_path):
    si = sweep_si(300)
    cases = [{"id": f"F0{i}", "waveform": "free", "file": "F.csv", **gas} for i, gas in
             enumerate([{}, {"gas_force_N": 50.0}, {"gas_force_N": -20.0}], start=1)]
    folder = write_campaign(tmp_path / "raw", "g", MM_N, cases, {"F.csv": csv_bytes(si)}, gas_force_N=10.0)
    ingest_campaign(folder, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    declared = {"F01": 10.0, "F02": 50.0, "F03": -20.0}
    assert got.ingested_cases().set_index("case")["gas_force_N"].to_dict() == declared
    for case, gas in declared.items():
        np.testing.assert_allclose(got.timeseries(case)["force_N"], si["force_N"] - gas, rtol=1e-12)


def test_near_miss_keys_are_warned_with_the_key_they_may_mean(tmp_path, caplog):
    cases = [{"id": "F01", "waveform": "free", "file": "F.csv", "gas_force_n": 40.0},
             {"id": "H01", "waveform": "sine", "frequency_hz": 1.0, "frequency_Hz": 1.0, "amplitude_mm": 12.7,
              "file": "F.csv", "rig_note": "far from any key"}]
    folder = write_campaign(tmp_path / "raw", "k", MM_N, cases, {"F.csv": csv_bytes(sweep_si(300))},
                            temprature_C=40.0)
    with caplog.at_level(logging.WARNING, logger="isokinetic"):
        ingest_campaign(folder, tmp_path / "results")
    warnings = CampaignFolder.at(tmp_path / "results").meta.warnings
    where = (folder / "campaign.yaml").as_posix()
    assert sorted(warnings) == sorted([
        f"{where}: key 'temprature_C' is not a key of the format, kept as metadata; did you mean 'temperature_C'?",
        f"{where}: key 'cases.F01.gas_force_n' is not a key of the format, kept as metadata; did you mean "
        "'gas_force_N'?",
        f"{where}: key 'cases.H01.frequency_hz' is not a key of the format, kept as metadata; did you mean "
        "'frequency_Hz'?",     # and (issue 20) both cases read the whole of one file
        "2 cases name the file 'F.csv' with the same or overlapping slices (F01, H01): the same record counts more "
        "than once"])
    assert all(any(w in r.getMessage() for r in caplog.records) for w in warnings)
    # the slip is not applied: F01's force keeps its gas force
    cases = CampaignFolder.at(tmp_path / "results").ingested_cases().set_index("case")
    assert math.isnan(cases.loc["F01", "gas_force_N"])


def test_case_file_in_a_subfolder(tmp_path):
    si = sweep_si(300)
    folder = write_campaign(tmp_path / "raw", "sub", MM_N, [{"id": "F01", "waveform": "free", "file": "run1/F.dat"}],
                            {"run1/F.dat": csv_bytes(si)})
    ingest_campaign(folder, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    assert got.ingested_cases()["raw_file"].tolist() == [(folder / "run1/F.dat").as_posix()]
    np.testing.assert_allclose(got.timeseries("F01")["force_N"], si["force_N"], rtol=1e-12)


def test_a_file_shared_by_cases_is_hashed_and_read_once(tmp_path, monkeypatch):
    import isokinetic.stages.ingest as ingest

    calls = {"sha": 0, "read": 0}
    sha, read = ingest.sha256_file, ingest.read_raw_table
    monkeypatch.setattr(ingest, "sha256_file", lambda p: (calls.__setitem__("sha", calls["sha"] + 1), sha(p))[1])
    monkeypatch.setattr(ingest, "read_raw_table",
                        lambda p, f=None, **kw: (calls.__setitem__("read", calls["read"] + 1), read(p, f, **kw))[1])
    cases = [{"id": f"F0{i}", "waveform": "free", "file": "F.csv", "rows": [100 * i, 100 * i + 100]}
             for i in range(3)]
    folder = write_campaign(tmp_path / "raw", "once", MM_N, cases, {"F.csv": csv_bytes(sweep_si(300))})
    ingest_campaign(folder, tmp_path / "results")
    assert calls == {"sha": 1, "read": 1}
    assert len(set(CampaignFolder.at(tmp_path / "results").ingested_cases()["raw_sha256"])) == 1


def test_a_voltage_column_named_as_force_is_refused_by_its_units_row(tmp_path):
    text = csv_bytes(sweep_si(300)).decode().split("\n", 1)
    folder = write_campaign(tmp_path / "raw", "v", MM_N, [{"id": "F01", "waveform": "free", "file": "F01.csv"}],
                            {"F01.csv": (text[0] + "\ns,mm,V\n" + text[1]).encode()}, csv={"units_row": True})
    ingest_campaign(folder, tmp_path / "results")
    assert CampaignFolder.at(tmp_path / "results").ingested_quarantine()["reason"].tolist() == [
        "campaign v, case F01, column 'force_N': the file's units row says 'V' (is not a unit of force), the "
        "manifest declares 'N' for force: fix the manifest's unit"]
