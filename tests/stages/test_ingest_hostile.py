"""Hostile input at ingest (issue 20, findings 1, 3, 4, 7/9 and 10): a broken time stamp, an oversized or binary
file, an over-long field, absurd values, one file named by many cases, misleading messages."""

from __future__ import annotations

import gzip
import logging
import math
import re

import numpy as np
import pandas as pd
import pytest

from conftest import CAMPAIGN, CASE_IDS, N_SAMPLES, assert_quarantine, set_cell
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages import ingest as ingest_module
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.validate import write_validated
from stages.test_ingest_vendor import MM_N, csv_bytes, sweep_si, write_campaign

#: The longest reason a reader's refusal may give, beyond the "campaign C, case K, column 'x', row N: " prefix.
MAX_MESSAGE = 200


def _message(reason: str) -> str:
    return reason.split(": ", 1)[1]


def _append_row(time_s: str):
    """A table edit: the last row repeated once more, at time ``time_s``."""
    def edit(table: pd.DataFrame) -> pd.DataFrame:
        extra = table.iloc[[-1]].copy()
        extra["time_s"] = time_s
        return pd.concat([table, extra], ignore_index=True)
    return edit


def test_broken_last_time_stamp_is_trimmed_with_a_note(raw_campaign):
    """A last sample at 1e308 s in T01: dropped, said in the quality note, and the later stages work on the
    planned record (before: a runaway loop over 1e308 s of half-periods)."""
    n = N_SAMPLES["T01"]
    raw_campaign.edit_table("T01", _append_row("1e308"))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [])
    t01 = cases.set_index("case").loc["T01"]
    assert t01["n_samples"] == n
    assert f"1 sample(s) from row {n} on dropped" in t01["quality"] and "1e+308" in t01["quality"]
    ts = CampaignFolder.at(raw_campaign.root).timeseries("T01")
    assert len(ts) == n and ts["row"].iloc[-1] == n - 1


def test_year_typo_in_the_last_iso_stamp_is_trimmed(tmp_path):
    stamps = pd.date_range("2022-03-01T10:00:00", periods=400, freq="10ms")
    text = [s.isoformat() for s in stamps]
    text[-1] = text[-1].replace("2022", "2062", 1)
    si = sweep_si(400)
    table = pd.DataFrame({"stamp": text, "disp_mm": si["displacement_m"] * 1e3, "force_N": si["force_N"]})
    columns = {**MM_N, "time": {"name": "stamp", "unit": "datetime"}}
    folder = write_campaign(tmp_path / "raw", "typo", columns, [{"id": "F01", "waveform": "free", "file": "F.csv"}],
                            {"F.csv": table.to_csv(index=False).encode()})
    ingest_campaign(folder, tmp_path / "results")
    ingested = CampaignFolder.at(tmp_path / "results")
    row = ingested.ingested_cases().iloc[0]
    assert (row["status"], row["n_samples"]) == ("ok", 399)
    assert "from row 399 on dropped" in row["quality"]
    assert ingested.timeseries("F01")["time_s"].iloc[-1] == pytest.approx(3.98)


def test_case_file_above_the_size_limit_is_set_aside_unread(raw_campaign, monkeypatch):
    sizes = {case: (raw_campaign.raw_dir / f"{case}.csv").stat().st_size for case in CASE_IDS}
    limit_MB = (sorted(sizes.values())[2] + 0.5) / 1e6              # the three smallest files stay under it
    too_large = sorted(case for case, size in sizes.items() if size > limit_MB * 1e6)
    read = []
    original = ingest_module.read_raw_table
    monkeypatch.setattr(ingest_module, "read_raw_table", lambda p, f=None, **kw: (read.append(p.name),
                                                                                   original(p, f, **kw))[1])
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root, max_case_file_MB=limit_MB)
    q = CampaignFolder.at(raw_campaign.root).ingested_quarantine()
    assert sorted(q["case"]) == too_large and len(too_large) == 2
    assert all("MB a case file may have (config ingest.max_case_file_MB): not read" in r for r in q["reason"])
    assert sorted(read) == sorted(f"{c}.csv" for c in set(CASE_IDS) - set(too_large))


@pytest.mark.parametrize("quoted", [False, True], ids=["plain", "quoted"])
def test_overlong_field_costs_one_case_naming_row_and_column(raw_campaign, quoted):
    """A 200,000-character cell (before: an uncaught csv error lost the whole campaign). A file with quotes is
    read line by line, where the csv module's field limit names the field."""
    cell = "x" * 200_000
    raw_campaign.edit_table("T02", set_cell(17, "force_kN", cell))
    if quoted:
        path = raw_campaign.raw_dir / "T02.csv"
        path.write_text(path.read_text(encoding="utf-8").replace(cell, f'"{cell}"'), encoding="utf-8")
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "ingest", "force_kN", 17)])
    reason = quarantine["reason"].iloc[0]
    assert reason.startswith("campaign demo, case T02, column 'force_kN', row 17: ")
    assert len(_message(reason)) <= MAX_MESSAGE and re.search(r"20000[02] characters", reason)


def test_gzip_file_is_refused_as_binary_data_in_few_words(raw_campaign):
    path = raw_campaign.raw_dir / "T01.csv"
    path.write_bytes(gzip.compress(path.read_bytes()))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "file", None)])
    reason = quarantine["reason"].iloc[0]
    assert "binary data (gzip?)" in reason and "\\x" not in reason and len(_message(reason)) <= MAX_MESSAGE


def test_force_no_rig_produces_sets_the_case_aside_naming_its_row(raw_campaign):
    """1e305 kN in one sample (before: the case stayed ok and broke the characteristic)."""
    raw_campaign.edit_table("T01", set_cell(100, "force_kN", "1e305"))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "force_kN", 100)])
    assert "|value| 1e+305 kN lies beyond the 1e+07 N no rig produces" in quarantine["reason"].iloc[0]


def test_declared_full_scale_bounds_its_channel(raw_campaign):
    """columns.force.full_scale (in the column's unit, here on T01's own columns): a sample beyond 100 x it sets
    the case aside, at the first such row of the file; a full scale the record respects leaves every case ok."""
    table = raw_campaign.read_table("T01")
    force_kN = table["force_kN"].astype(float).abs().to_numpy()
    full_scale = float(np.quantile(force_kN, 0.9)) / 100.0          # 10 % of T01's samples beyond 100 x it
    first = int(np.argmax(force_kN > 100.0 * full_scale))
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T01").update(
        columns={"force": {"full_scale": full_scale}}))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "force_kN", first)])
    assert f"100 x the declared full scale {full_scale:g} kN" in quarantine["reason"].iloc[0]
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T01").update(
        columns={"force": {"full_scale": float(force_kN.max())}}))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [])


def test_piston_speed_no_rig_produces_sets_the_case_aside(raw_campaign):
    """A displacement spike of 5 m (inside the 10 m bound) in one 0.02 s sample interval: 250 m/s."""
    raw_campaign.edit_table("T01", set_cell(50, "disp_mm", "5000"))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "disp_mm", 50)])
    assert "from row 49, beyond the 100 m/s no rig produces" in quarantine["reason"].iloc[0]


def test_bad_full_scale_is_the_case_problem(raw_campaign):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "F01").update(
        columns={"force": {"full_scale": -1}}))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "F01", "ingest", "columns.force.full_scale",
                                                         None)])


def _shared_file_campaign(tmp_path, slices: list[dict]):
    cases = [{"id": f"F{i:02d}", "waveform": "free", "file": "F.csv", **s} for i, s in enumerate(slices)]
    return write_campaign(tmp_path / "raw", "shared", MM_N, cases, {"F.csv": csv_bytes(sweep_si(300))})


def test_cases_sharing_one_record_are_warned(tmp_path, caplog):
    folder = _shared_file_campaign(tmp_path, [{"rows": [0, 100]}, {"rows": [50, 150]}, {"rows": [200, 300]},
                                              {"time_range_s": [0.1, 0.5]}])
    with caplog.at_level(logging.WARNING, logger="isokinetic"):
        ingest_campaign(folder, tmp_path / "results")
    warning = ("3 cases name the file 'F.csv' with the same or overlapping slices (F00, F03, F01): the same record "
               "counts more than once")
    assert CampaignFolder.at(tmp_path / "results").meta.warnings == (warning,)
    assert any(warning in r.getMessage() for r in caplog.records)


def test_different_slices_of_one_file_are_not_warned(tmp_path):
    """A stepped record (issue 19): one file, one case per step."""
    folder = _shared_file_campaign(tmp_path, [{"rows": [0, 100]}, {"rows": [100, 200]}, {"time_range_s": [2.0, 3.0]}])
    ingest_campaign(folder, tmp_path / "results")
    assert CampaignFolder.at(tmp_path / "results").meta.warnings == ()


@pytest.mark.slow
def test_thousand_cases_naming_one_whole_file_are_warned(tmp_path):
    folder = _shared_file_campaign(tmp_path, [{}] * 1000)
    ingest_campaign(folder, tmp_path / "results")
    warnings = CampaignFolder.at(tmp_path / "results").meta.warnings
    assert len(warnings) == 1 and warnings[0].startswith("1000 cases name the file 'F.csv'")
    assert "and 990 more" in warnings[0]


@pytest.mark.parametrize("value, message", [
    ("9" * 309, "value '99999999'... (309 characters) lies beyond the range of a 64-bit float"),
    ("1e308", "value '1e+308' lies beyond the range of a 64-bit float in SI (kN to SI)"),
])
def test_number_beyond_float_range_is_named_at_its_row(raw_campaign, value, message):
    """Before: 'non-finite value inf' for 1e308 kN, and the whole 309-digit number quoted."""
    raw_campaign.edit_table("T01", set_cell(300, "force_kN", value))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "force_kN", 300)])
    assert quarantine["reason"].iloc[0] == f"campaign demo, case T01, column 'force_kN', row 300: {message}"


def test_literal_inf_is_still_a_non_finite_value(raw_campaign):
    raw_campaign.edit_table("T01", set_cell(300, "force_kN", "inf"))
    cases, quarantine = raw_campaign.run()
    assert quarantine["reason"].tolist() == ["campaign demo, case T01, column 'force_kN', row 300: non-finite "
                                             "value inf"]


def test_success_is_logged_only_after_the_results_are_written(raw_campaign, monkeypatch, caplog):
    """A results folder that cannot be written: no "n of n cases ingested" line before the failure."""
    def refuse(*args, **kwargs):
        raise PermissionError("read-only results folder")
    original = ingest_module.write_ingested
    monkeypatch.setattr(ingest_module, "write_ingested", refuse)
    with caplog.at_level(logging.INFO, logger="isokinetic"), pytest.raises(PermissionError):
        ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    assert not any(re.search(r"cases ingested", r.getMessage()) for r in caplog.records)
    monkeypatch.setattr(ingest_module, "write_ingested", original)
    with caplog.at_level(logging.INFO, logger="isokinetic"):
        ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    assert any("5 of 5 cases ingested" in r.getMessage() for r in caplog.records)


def test_validate_runs_bounded_on_a_trimmed_record(raw_campaign):
    """The trimmed case validates like the others (its windows come from the planned half-periods)."""
    raw_campaign.edit_table("T02", _append_row("1e308"))
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    cases, quarantine = write_validated(raw_campaign.root)
    assert quarantine.empty and math.isfinite(cases.set_index("case").loc["T02", "motion_start_s"])


@pytest.mark.slow
def test_bad_cell_far_into_a_large_decimal_comma_file_is_named_at_its_row(tmp_path):
    """A large file is parsed in chunks: the chunk holding the bad cell is text, the others numbers. The bad cell's
    row is named, not the first parsed number: in the note of the row left out (a partial record, issue 34)."""
    n = 300_000
    force = [f"{i % 7},5" for i in range(n)]
    force[290_000] = "1.5"
    time_s = [f"{i / 100:.2f}".replace(".", ",") for i in range(n)]
    text = "time_s;disp_mm;force_N\n" + "".join(f"{t};0;{f}\n" for t, f in zip(time_s, force))
    folder = write_campaign(tmp_path / "raw", "comma", MM_N, [{"id": "F01", "waveform": "free", "file": "F.csv"}],
                            {"F.csv": text.encode()}, csv={"delimiter": ";", "decimal": ","})
    ingest_campaign(folder, tmp_path / "results")
    ingested = CampaignFolder.at(tmp_path / "results")
    assert ingested.ingested_quarantine().empty
    quality = ingested.ingested_cases()["quality"].iloc[0]
    assert "1 row(s) with a blank or unreadable cell left out (data rows 290000)" in quality
    assert len(ingested.timeseries("F01")) == n - 1
