"""Sniffing a case file: delimiter, decimal mark, '#' comment lines before the header, the header row."""

from __future__ import annotations

import codecs

import pytest

from isokinetic.contracts.manifest import CsvDialect
from isokinetic.init_campaign.sniff import SniffError, read_columns, sniff_file, sniff_text

ROWS = [["0.00", "-1.2200", "0.0836", "-1.220000"], ["0.01", "-1.2195", "0.0890", "-1.219878"],
        ["0.02", "-1.2190", "0.1023", "-1.219756"]]
HEADER = ["time_s", "disp_mm", "force_kN", "cmd_mm"]


def text(delimiter: str, decimal: str, comments: str = "") -> str:
    rows = [delimiter.join(cell.replace(".", decimal) for cell in row) for row in ROWS]
    return comments + "\n".join([delimiter.join(HEADER), *rows]) + "\n"


@pytest.mark.parametrize("delimiter, decimal", [(",", "."), (";", ","), (";", "."), ("\t", "."), ("\t", ","),
                                                ("|", "."), ("|", ",")])
def test_sniff_finds_delimiter_decimal_and_header(delimiter, decimal):
    sniffed = sniff_text(text(delimiter, decimal))
    assert sniffed.dialect == CsvDialect(delimiter=delimiter, decimal=decimal)
    assert sniffed.header == tuple(HEADER)
    assert sniffed.comments == ()


def test_sniff_keeps_comment_lines_before_the_header():
    sniffed = sniff_text(text(";", ",", comments="# rig: bench 2\n\n# operator: x; y\n"))
    assert sniffed.comments == ("# rig: bench 2", "# operator: x; y")
    assert sniffed.dialect == CsvDialect(delimiter=";", decimal=",") and sniffed.header == tuple(HEADER)


def test_sniff_tolerates_a_cut_off_last_row():
    sniffed = sniff_text(text(",", ".") + "0.03,-1.21")
    assert sniffed.dialect == CsvDialect() and sniffed.rows_sampled == 4


def test_sniff_refuses_a_file_without_header():
    with pytest.raises(SniffError, match="no header row"):
        sniff_text("# only a comment\n\n")


def test_sniff_refuses_a_single_column():
    with pytest.raises(SniffError, match="no delimiter"):
        sniff_text("time_s\n0.0\n0.1\n")


def test_sniff_names_a_utf16_file(tmp_path):
    path = tmp_path / "T01.csv"
    path.write_bytes(codecs.BOM_UTF16_LE + text(",", ".").encode("utf-16-le"))
    with pytest.raises(SniffError, match="UTF-16"):
        sniff_file(path)


def test_columns_are_read_as_numbers_in_the_sniffed_dialect(tmp_path):
    path = tmp_path / "T01.csv"
    path.write_text(text(";", ",", comments="# c\n"), encoding="utf-8")
    columns = read_columns(path, sniff_file(path).dialect)
    assert list(columns) == HEADER
    assert columns["disp_mm"].numbers.tolist() == [-1.22, -1.2195, -1.219]


def test_iso_stamps_are_read_as_seconds(tmp_path):
    path = tmp_path / "T01.csv"
    path.write_text("stamp,disp_mm,force_kN\n2024-05-01T10:00:00.00,1,2\n2024-05-01T10:00:00.25,1,2\n",
                    encoding="utf-8")
    stamps = read_columns(path, sniff_file(path).dialect)["stamp"]
    assert stamps.numbers is None and stamps.stamps_s.tolist() == [0.0, 0.25]
