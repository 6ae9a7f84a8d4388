"""A case file's columns as numbers or seconds from ISO 8601 stamps (init_campaign.sniff.parse_column), and a
spreadsheet export's worksheet and layout (init_campaign.sniff.xlsx_format): drafted, checked and ingested."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from isokinetic.__main__ import main
from isokinetic.contracts.campaign import timeseries_relpath
from isokinetic.contracts.manifest import load_manifest
from isokinetic.init_campaign.draft import write_draft
from isokinetic.init_campaign.sniff import parse_column, xlsx_format
from isokinetic.rawfile import RawFileError
from isokinetic.stages.ingest import ingest_campaign

from .records import sine_record


def test_columns_are_read_as_numbers_in_the_files_decimal_mark():
    column = parse_column("disp_mm", pd.Series(["-1,2200", "-1,2195", "-1,2190"]), ",")
    assert column.numbers.tolist() == [-1.22, -1.2195, -1.219] and column.stamps_s is None


def test_iso_stamps_are_read_as_seconds():
    stamps = parse_column("stamp", pd.Series(["2024-05-01T10:00:00.00", "2024-05-01T10:00:00.25"]), ".")
    assert stamps.numbers is None and stamps.stamps_s.tolist() == [0.0, 0.25]


# --------------------------------------------------------------------------------------------
# Spreadsheet exports (.xlsx)
# --------------------------------------------------------------------------------------------

def write_workbook(path: Path, sheets: dict[str, list[list]]) -> Path:
    """An .xlsx workbook of the given worksheets (rows of cells), in order, written by openpyxl."""
    import openpyxl

    book = openpyxl.Workbook()
    book.remove(book.active)
    for title, rows in sheets.items():
        sheet = book.create_sheet(title)
        for row in rows:
            sheet.append(row)
    path.parent.mkdir(parents=True, exist_ok=True)
    book.save(path)
    return path


def sine_rows(rec: dict) -> list[list]:
    """Header, units row (as spreadsheets often have) and the record in s, mm, kN."""
    return [["Time (s)", "Position (mm)", "Force (kN)"], ["s", "mm", "kN"]] + [
        [float(t), float(x) * 1e3, float(f) / 1e3] for t, x, f in zip(rec["time_s"], rec["displacement_m"],
                                                                      rec["force_N"])]


def test_an_xlsx_export_with_a_units_row_is_drafted_checked_and_ingested_in_si(tmp_path):
    rec = sine_record(1.0, 0.01, 4, 200.0)
    folder = tmp_path / "raw" / "xl"
    write_workbook(folder / "run1.xlsx", {"Sheet1": sine_rows(rec)})
    manifest = load_manifest(write_draft(folder)[0])
    assert (manifest.csv.format, manifest.csv.units_row, manifest.csv.sheet) == ("xlsx", True, None)
    (case,) = manifest.cases
    assert case.file == "run1.xlsx" and case.plan.waveform == "sine"
    assert case.plan.frequency_Hz == pytest.approx(1.0, rel=1e-4) and case.plan.amplitude_m == pytest.approx(0.01, 1e-3)
    assert {c: (case.columns[c].name, case.columns[c].unit) for c in ("time", "displacement", "force")} == {
        "time": ("Time (s)", "s"), "displacement": ("Position (mm)", "mm"), "force": ("Force (kN)", "kN")}
    assert main(["init-campaign", "--check", str(folder)]) == 0
    root = tmp_path / "out" / "xl"
    ingest_campaign(folder, root)
    assert (pd.read_parquet(root / "ingest" / "cases.parquet")["status"] == "ok").all()
    series = pd.read_parquet(root / timeseries_relpath("run1"))
    assert len(series) == len(rec["time_s"])
    assert series["displacement_m"].to_numpy() == pytest.approx(rec["displacement_m"], abs=1e-9)
    assert series["force_N"].to_numpy() == pytest.approx(rec["force_N"], abs=1e-6)


def test_the_only_worksheet_holding_numbers_is_drafted_by_name(tmp_path):
    rec = sine_record(1.0, 0.01, 4, 200.0)
    folder = tmp_path / "xl"
    write_workbook(folder / "run1.xlsx", {"Summary": [["Rig 3, damper A"], ["operator", "xy"]],
                                          "Data": sine_rows(rec)})
    manifest = load_manifest(write_draft(folder)[0])
    assert (manifest.csv.format, manifest.csv.sheet) == ("xlsx", "Data") and len(manifest.cases) == 1
    assert main(["init-campaign", "--check", str(folder)]) == 0


def test_a_workbook_whose_numbers_lie_on_several_later_sheets_asks_for_the_sheet(tmp_path):
    rec = sine_record(1.0, 0.01, 4, 200.0)
    path = write_workbook(tmp_path / "run1.xlsx", {"Notes": [["see runs"]], "Run 1": sine_rows(rec),
                                                   "Run 2": sine_rows(rec)})
    with pytest.raises(RawFileError, match=r"'Run 1', 'Run 2' do .*name the sheet"):
        xlsx_format(path, [])
