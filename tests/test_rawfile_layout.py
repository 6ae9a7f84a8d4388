"""rawfile (format 1.4): headerless files, a logger's preamble, marker rows inside the data, .xlsx worksheets."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import openpyxl
import pytest

from isokinetic.rawfile import FileFormat, RawFileError, read_delimited, read_raw_table, sniff_format

MR_REPO = Path("/work/.mirror/DanielMaurelE+vRTHS_AMBC_MRdamper/repo")
MR_FILE = "Cap7_ModeloMR/BoucWen Ajuste 2/Preprocesamiento-sinusoidales/Preprocesados/2mm5Hz0A.txt"
PREAMBLE = "Logger: DL-7\nDate: 2021-03-01\nRate: 100 Hz\ntime,disp,force,temp,cmd\n"
ROWS = "0,1,2,3,4\n0.1,1.5,2,3,4\n0.2,2,2,3,4\n"


def _write(tmp_path, text, name="x.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_headerless_file_keeps_its_first_row_under_positional_names(tmp_path):
    path = _write(tmp_path, "0.0 1.5 -2\n0.1 1.6 -3\n0.2 1.7 -4\n")
    table = read_raw_table(path, FileFormat(delimiter="whitespace", header="none"), numeric=True)
    assert list(table.frame.columns) == ["col1", "col2", "col3"]
    assert table.frame["col2"].tolist() == [1.5, 1.6, 1.7] and table.rows.tolist() == [0, 1, 2]


def test_a_numeric_first_row_declared_as_header_is_refused_naming_header_none(tmp_path):
    path = _write(tmp_path, "0,1,2\n1,2,3\n")
    with pytest.raises(RawFileError, match="headerless file\\? set `header: none`"):
        read_raw_table(path, FileFormat())


@pytest.mark.skipif(not MR_REPO.exists(), reason="the MR damper repository is not mirrored here")
def test_a_real_headerless_whitespace_file_is_sniffed_and_read_whole(tmp_path):
    text = subprocess.run(["git", "-C", str(MR_REPO), "show", f"HEAD:{MR_FILE}"], capture_output=True,
                          check=True).stdout
    path = tmp_path / "2mm5Hz0A.txt"
    path.write_bytes(text)
    fmt = sniff_format(path)
    assert (fmt.header, fmt.delimiter) == ("none", "whitespace")
    table = read_raw_table(path, fmt, numeric=True)
    assert len(table.frame) == len(text.strip().splitlines())     # the first data row is kept
    assert float(table.frame["col1"].iloc[0]) == float(text.split()[0])


def test_sniff_reports_a_header_row_for_a_file_with_one(tmp_path):
    assert sniff_format(_write(tmp_path, "t,x\n0,1\n1,2\n")).header == "row"


@pytest.mark.parametrize("reader", [read_raw_table, read_delimited])
def test_a_preamble_before_the_header_is_skipped_and_noted(tmp_path, reader):
    table = reader(_write(tmp_path, PREAMBLE + ROWS), FileFormat())
    assert list(table.frame.columns) == ["time", "disp", "force", "temp", "cmd"] and len(table.frame) == 3
    assert table.warnings[0] == ("skipped 3 preamble line(s) before the header (file lines 1..3, the first "
                                 "'Logger: DL-7')")


def test_sniff_finds_the_delimiter_behind_a_preamble(tmp_path):
    fmt = sniff_format(_write(tmp_path, "Logger DL-7\n" + "time;disp\n" + "0;1\n1;2\n2;3\n"))
    assert (fmt.delimiter, fmt.header) == (";", "row")


@pytest.mark.parametrize("reader", [read_raw_table, read_delimited])
@pytest.mark.parametrize("marker", ["0.15,Switched from 1 to 2,,,", "0.15,Switched from 1 to 2"])
def test_marker_rows_inside_the_data_are_skipped_and_named(tmp_path, reader, marker):
    text = "time,disp,force,temp,cmd\n0,1,2,3,4\n0.1,1,2,3,4\n" + marker + "\n0.2,1,2,3,4\n"
    table = reader(_write(tmp_path, text), FileFormat(), numeric=True)
    assert table.rows.tolist() == [0, 1, 3] and table.frame["disp"].dtype == np.int64
    assert table.warnings == ["skipped 1 marker row(s) without a sample (text inside the data): data rows 2, the "
                              "first 'Switched from 1 to 2'"]


def test_a_full_row_with_one_bad_value_is_no_marker(tmp_path):
    table = read_raw_table(_write(tmp_path, "t,x,f\n0,1,2\n0.1,abc,2\n0.2,1,2\n"), FileFormat(), numeric=True)
    assert table.rows.tolist() == [0, 1, 2] and table.frame["x"].iloc[1] == "abc" and not table.warnings


def test_a_text_column_makes_no_row_a_marker(tmp_path):
    table = read_raw_table(_write(tmp_path, "t,x,note,empty\n0,1,a,\n0.1,2,b,\n"), FileFormat(), numeric=True)
    assert len(table.frame) == 2 and not table.warnings


def _workbook(path: Path, rows: list[list], title: str = "Data") -> Path:
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = title
    for row in rows:
        sheet.append(row)
    book.save(path)
    return path


def test_an_xlsx_sheet_is_read_by_name_with_its_numbers(tmp_path):
    path = _workbook(tmp_path / "a.xlsx", [["report"], ["time (s)", "force (kip)"], [0.0, 1.5], [0.1, 2.5],
                                           [0.2, 3.5]])
    table = read_raw_table(path, FileFormat(format="xlsx", sheet="Data"), numeric=True)
    assert list(table.frame.columns) == ["time (s)", "force (kip)"]
    assert table.frame["force (kip)"].tolist() == [1.5, 2.5, 3.5] and len(table.warnings) == 1


def test_an_xlsx_sheet_that_does_not_exist_is_refused_naming_the_sheets(tmp_path):
    path = _workbook(tmp_path / "a.xlsx", [["t", "x"], [0, 1]])
    with pytest.raises(RawFileError, match="no worksheet 'Nope' in the workbook \\(sheets: Data\\)"):
        read_raw_table(path, FileFormat(format="xlsx", sheet="Nope"))


def test_a_file_that_is_no_workbook_is_refused_as_xlsx(tmp_path):
    with pytest.raises(RawFileError, match="not an xlsx workbook"):
        read_raw_table(_write(tmp_path, "t,x\n0,1\n", "a.xlsx"), FileFormat(format="xlsx"))


def test_a_workbook_that_unpacks_too_far_is_refused_unread(tmp_path, monkeypatch):
    from isokinetic import rawlayout

    path = _workbook(tmp_path / "a.xlsx", [["t", "x"], [0, 1], [1, 2]])
    monkeypatch.setattr(rawlayout, "MAX_UNPACKED_BYTES", 100)
    with pytest.raises(RawFileError, match="a zip bomb"):
        read_raw_table(path, FileFormat(format="xlsx"))


def test_a_worksheet_beyond_the_row_bound_is_refused(tmp_path, monkeypatch):
    from isokinetic import rawlayout

    path = _workbook(tmp_path / "a.xlsx", [["t", "x"]] + [[i, i] for i in range(20)])
    monkeypatch.setattr(rawlayout, "MAX_SHEET_ROWS", 10)
    with pytest.raises(RawFileError, match="more than 10 rows"):
        read_raw_table(path, FileFormat(format="xlsx"))
