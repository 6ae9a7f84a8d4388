"""Ingest of format 1.4 files: units pint reads (kip, cm), a unit in a header checked, scaled channels (volts),
a headerless file named by position, marker rows and a preamble, an .xlsx sheet; SI checked against factors
computed here from their definitions (1 kip = 1000 lbf = 4448.2216152605 N, 1 cm = 0.01 m)."""

from __future__ import annotations

import numpy as np
import openpyxl
import pandas as pd

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages.ingest import ingest_campaign
from stages.test_ingest_vendor import sweep_si, write_campaign

KIP_N = 1000 * 4.4482216152605
FREE = [{"id": "F01", "waveform": "free", "file": "F01.csv"}]


def _text(si: pd.DataFrame, names=("t", "x", "f"), x_per_m=100.0, f_per_N=1 / KIP_N, header=True) -> bytes:
    table = pd.DataFrame({names[0]: si["time_s"], names[1]: si["displacement_m"] * x_per_m,
                          names[2]: si["force_N"] * f_per_N})
    return table.to_csv(index=False, header=header, float_format="%.17g").encode()


def _ingest(tmp_path, columns, files, cases=FREE, **top):
    folder = write_campaign(tmp_path / "raw", "c", columns, cases, files, **top)
    ingest_campaign(folder, tmp_path / "results")
    return CampaignFolder.at(tmp_path / "results")


def test_kip_and_cm_columns_are_written_in_si(tmp_path):
    si = sweep_si(300)
    columns = {"time": {"name": "t", "unit": "s"}, "displacement": {"name": "x", "unit": "cm"},
               "force": {"name": "f", "unit": "kip"}}
    got = _ingest(tmp_path, columns, {"F01.csv": _text(si)})
    series = got.timeseries("F01")
    np.testing.assert_allclose(series["force_N"], si["force_N"], rtol=1e-12)
    np.testing.assert_allclose(series["displacement_m"], si["displacement_m"], rtol=1e-12, atol=1e-18)


def test_a_unit_in_a_header_that_disagrees_with_the_manifest_sets_the_case_aside(tmp_path):
    columns = {"time": {"name": "t", "unit": "s"}, "displacement": {"name": "x", "unit": "cm"},
               "force": {"name": "friction force (kip)", "unit": "kN"}}
    got = _ingest(tmp_path, columns, {"F01.csv": _text(sweep_si(300), names=("t", "x", "friction force (kip)"))})
    assert got.ingested_quarantine()["reason"].tolist() == [
        "campaign c, case F01, column 'friction force (kip)': the file's header says 'kip' (means 'kip'), the "
        "manifest declares 'kN' for force: fix the manifest's unit"]


def test_a_scaled_volt_channel_is_raw_times_scale_plus_offset_in_its_unit(tmp_path):
    si = sweep_si(300)
    volts = (si["force_N"] / 1e3 - 0.5) / 2.0             # a load cell: kN = 2 V + 0.5
    table = pd.DataFrame({"t": si["time_s"], "x": si["displacement_m"] * 100, "f": volts})
    columns = {"time": {"name": "t", "unit": "s"}, "displacement": {"name": "x", "unit": "cm"},
               "force": {"name": "f", "unit": "kN", "scale": 2.0, "offset": 0.5}}
    got = _ingest(tmp_path, columns, {"F01.csv": table.to_csv(index=False, float_format="%.17g").encode()})
    np.testing.assert_allclose(got.timeseries("F01")["force_N"], si["force_N"], rtol=1e-12)


def test_a_headerless_file_is_ingested_by_position_with_its_first_row(tmp_path):
    si = sweep_si(300)
    columns = {"time": {"name": 1, "unit": "s"}, "displacement": {"name": "col2", "unit": "cm"},
               "force": {"name": 3, "unit": "kip"}}
    got = _ingest(tmp_path, columns, {"F01.csv": _text(si, header=False)}, csv={"header": "none"})
    series = got.timeseries("F01")
    assert len(series) == 300 and series["row"].iloc[0] == 0
    np.testing.assert_allclose(series["force_N"], si["force_N"], rtol=1e-12)


def test_marker_rows_and_a_preamble_are_skipped_and_noted_in_the_quality(tmp_path):
    si = sweep_si(300)
    head, body = _text(si).decode().split("\n", 1)
    lines = body.split("\n")
    lines.insert(100, "1.005,Switched from 1 to 2,")
    columns = {"time": {"name": "t", "unit": "s"}, "displacement": {"name": "x", "unit": "cm"},
               "force": {"name": "f", "unit": "kip"}}
    got = _ingest(tmp_path, columns, {"F01.csv": ("Logger DL-7\nRate 100 Hz\n" + head + "\n"
                                                  + "\n".join(lines)).encode()})
    quality = got.ingested_cases().set_index("case").loc["F01", "quality"]
    assert "skipped 2 preamble line(s)" in quality and "marker row(s)" in quality and "data rows 100" in quality
    series = got.timeseries("F01")
    assert len(series) == 300 and 100 not in series["row"].tolist()
    np.testing.assert_allclose(series["force_N"], si["force_N"], rtol=1e-12)


def test_an_xlsx_sheet_is_ingested_in_si(tmp_path):
    si = sweep_si(300)
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "Run 1"
    sheet.append(["t", "x", "f"])
    for t, x, f in zip(si["time_s"], si["displacement_m"] * 100, si["force_N"] / KIP_N):
        sheet.append([float(t), float(x), float(f)])
    path = tmp_path / "F01.xlsx"
    book.save(path)
    columns = {"time": {"name": "t", "unit": "s"}, "displacement": {"name": "x", "unit": "cm"},
               "force": {"name": "f", "unit": "kip"}}
    got = _ingest(tmp_path, columns, {"F01.xlsx": path.read_bytes()},
                  cases=[{"id": "F01", "waveform": "free", "file": "F01.xlsx"}],
                  csv={"format": "xlsx", "sheet": "Run 1"})
    np.testing.assert_allclose(got.timeseries("F01")["force_N"], si["force_N"], rtol=1e-12)
