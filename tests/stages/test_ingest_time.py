"""Time columns as loggers and spreadsheets write them (format 1.5, issue 34): clock times ``HH:MM:SS.fff``, Excel
serial dates, local ISO 8601 stamps across a daylight-saving fall-back (refused naming the jump, or converted with
the declared ``timezone``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages.ingest import ingest_campaign

RATE_HZ = 100.0
N = 300


def _campaign(name: str, times: list[str], unit: str, csv_block: dict | None = None) -> Path:
    """A one-case free campaign at ``data/raw/<name>`` whose time column holds ``times`` in ``unit``."""
    raw_dir = Path("data", "raw", name)
    raw_dir.mkdir(parents=True)
    manifest = {"format_version": 1, "campaign": name, "sample_rate_Hz": RATE_HZ,
                "columns": {"time": {"name": "time", "unit": unit},
                            "displacement": {"name": "disp_mm", "unit": "mm"},
                            "force": {"name": "force_N", "unit": "N"}},
                "cases": [{"id": "C1", "waveform": "free", "file": "C1.csv"}]}
    if csv_block is not None:
        manifest["csv"] = csv_block
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(manifest), encoding="utf-8")
    t = np.arange(len(times)) / RATE_HZ
    rows = [f"{stamp},{0.2 * np.sin(2 * np.pi * 0.7 * s):.6f},{100 * np.cos(2 * np.pi * 0.7 * s):.4f}"
            for stamp, s in zip(times, t)]
    (raw_dir / "C1.csv").write_text("time,disp_mm,force_N\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return raw_dir


def _ingest(raw_dir: Path):
    root = Path("results", raw_dir.name)
    ingest_campaign(raw_dir, root)
    return CampaignFolder.at(root)


def test_clock_times_give_seconds_across_midnight(tmp_path, monkeypatch):
    """``23:59:59.990`` then ``00:00:00.000``: before, "does not increase from row to row"."""
    monkeypatch.chdir(tmp_path)
    start = pd.Timestamp("2024-05-01T23:59:58.500")
    times = [(start + pd.Timedelta(milliseconds=10 * k)).strftime("%H:%M:%S.%f")[:-3] for k in range(N)]
    assert "00:00:00.000" in times
    ingested = _ingest(_campaign("clock", times, "hms"))
    assert ingested.ingested_quarantine().empty, ingested.ingested_quarantine()["reason"].tolist()
    np.testing.assert_allclose(ingested.timeseries("C1")["time_s"], np.arange(N) / RATE_HZ, rtol=0, atol=1e-9)


def test_excel_serial_dates_give_seconds(tmp_path, monkeypatch):
    """Days since 1899-12-30 (45413.5 is 2024-05-01 12:00): before, "no plausible unit" (init-campaign)."""
    monkeypatch.chdir(tmp_path)
    days = 45413.5 + np.arange(N) / RATE_HZ / 86400.0
    ingested = _ingest(_campaign("serial", [f"{d:.12f}" for d in days], "excel_serial"))
    assert ingested.ingested_quarantine().empty, ingested.ingested_quarantine()["reason"].tolist()
    np.testing.assert_allclose(ingested.timeseries("C1")["time_s"], np.arange(N) / RATE_HZ, rtol=0, atol=2e-6)


def _fall_back_stamps() -> list[str]:
    """Local stamps (Europe/Berlin, no offset) across the fall-back of 2024-10-27 03:00 CEST -> 02:00 CET."""
    utc = pd.Timestamp("2024-10-27T00:59:59.000Z") + pd.to_timedelta(np.arange(N) * 10, unit="ms")
    local = utc.tz_convert("Europe/Berlin").tz_localize(None)
    return [s.isoformat(timespec="milliseconds") for s in local]


def test_local_stamps_across_a_fall_back_are_refused_naming_the_jump(tmp_path, monkeypatch):
    """Before: read as time running backwards an hour (and the draft wrote sample_rate_Hz: -1.1, "sure")."""
    monkeypatch.chdir(tmp_path)
    stamps = _fall_back_stamps()
    ingested = _ingest(_campaign("dst", stamps, "datetime"))
    reason = ingested.ingested_quarantine()["reason"].tolist()
    assert reason == [f"campaign dst, case C1, column 'time', row 100: local time stamps step back 1 h "
                      f"({stamps[99]} -> {stamps[100]}): a daylight-saving fall-back; declare the logger's zone in "
                      "the manifest's csv block (`timezone: Europe/Berlin`, say) or export UTC stamps"]


def test_local_stamps_in_a_declared_zone_are_converted(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    ingested = _ingest(_campaign("dst", _fall_back_stamps(), "datetime", {"timezone": "Europe/Berlin"}))
    assert ingested.ingested_quarantine().empty, ingested.ingested_quarantine()["reason"].tolist()
    np.testing.assert_allclose(ingested.timeseries("C1")["time_s"], np.arange(N) / RATE_HZ, rtol=0, atol=1e-9)
    assert ingested.meta.csv["timezone"] == "Europe/Berlin"


@pytest.mark.parametrize("unit", ["hms", "excel_serial"])
def test_a_time_unit_of_1_5_is_for_the_time_channel_only(tmp_path, monkeypatch, unit):
    monkeypatch.chdir(tmp_path)
    raw_dir = _campaign("wrong", [f"{k / RATE_HZ}" for k in range(N)], "s")
    manifest = yaml.safe_load((raw_dir / "campaign.yaml").read_text(encoding="utf-8"))
    manifest["columns"]["displacement"]["unit"] = unit
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(manifest), encoding="utf-8")
    ingested = _ingest(raw_dir)
    assert ingested.ingested_quarantine()["column"].tolist() == ["disp_mm"]
