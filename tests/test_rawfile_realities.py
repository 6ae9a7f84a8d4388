"""What spreadsheets and loggers write (issue 34), read by both readers alike: a last row cut off (short of fields,
or in its last value), lone-CR and mixed line ends, an Excel ``sep=;`` first line."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from isokinetic.rawfile import FileFormat, RawFileError, read_delimited, read_raw_table, sniff_format

ROWS = ["0.00,-1.2196,0.0887", "0.01,-1.2170,0.1553", "0.02,-1.2164,0.2149", "0.03,-1.2118,0.2633"]


def _write(tmp_path, text: str, name: str = "x.csv"):
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def _both(path, fmt=None):
    """The table as the fast path and as the line-by-line reader read it (they must agree)."""
    fast, slow = read_raw_table(path, fmt), read_delimited(path, fmt)
    pd.testing.assert_frame_equal(fast.frame, slow.frame)
    assert fast.rows.tolist() == slow.rows.tolist() and fast.warnings == slow.warnings
    return fast


def test_a_last_row_cut_off_mid_row_is_left_out_with_a_note(tmp_path):
    """Before: 'row ends after 2 of 3 fields: the file is cut off mid-row', the whole file refused."""
    table = _both(_write(tmp_path, "t,x,F\n" + "\n".join(ROWS) + "\n0.04,-1.2"))
    assert len(table.frame) == 4 and table.rows.tolist() == [0, 1, 2, 3]
    assert table.warnings == ["the last row (4) ends after 2 of 3 fields without a line end: the file is cut off "
                              "mid-row, the row left out"]


@pytest.mark.parametrize("cut", ["-1.", "-1.2", "", "-1.2e"])
def test_a_last_number_cut_short_is_cut_off_not_a_value(tmp_path, cut):
    """``-1.`` for ``-1.22``: before, read as -1.0."""
    rows = [r + f",{-1.2 - k / 100:.2f}" for k, r in enumerate(ROWS)]
    table = _both(_write(tmp_path, "t,x,F,y\n" + "\n".join(rows) + "\n0.04,-1.2,0.3," + cut))
    assert len(table.frame) == 4
    assert table.warnings == [f"the last row (4) ends in {cut!r} without a line end: cut off in its last value, the "
                              "row left out"]


def test_a_last_row_without_a_line_end_but_whole_is_kept(tmp_path):
    table = _both(_write(tmp_path, "t,x,F\n" + "\n".join(ROWS)))
    assert len(table.frame) == 4 and table.frame["F"].iloc[-1] == "0.2633"
    assert table.warnings == ["no line end after the last row (3): it may be cut off in its last value"]


@pytest.mark.parametrize("ends", [["\r"] * 5, ["\r\n", "\r", "\n", "\r", "\r\n"]], ids=["lone-cr", "mixed"])
def test_lone_cr_and_mixed_line_ends_each_end_a_line(tmp_path, ends):
    """Before: "new-line character seen in unquoted field - do you need to open the file in universal-newline
    mode?" (ingest), a _csv.Error traceback (init-campaign's sniffing)."""
    lines = ["t,x,F", *ROWS]
    path = _write(tmp_path, "".join(line + end for line, end in zip(lines, ends)))
    assert sniff_format(path) == FileFormat()
    table = read_raw_table(path, FileFormat(), numeric=True)
    np.testing.assert_array_equal(table.frame["F"].to_numpy(), [0.0887, 0.1553, 0.2149, 0.2633])
    assert table.warnings == []


def test_an_excel_sep_line_names_the_delimiter(tmp_path):
    """Before: 'fields are separated by ';', not ',' as the manifest's csv block declares (header 'sep=;')' from
    init-campaign, before any manifest existed."""
    text = "sep=;\r\n" + "\r\n".join(line.replace(",", ";") for line in ["t,x,F", *ROWS]) + "\r\n"
    path = _write(tmp_path, text)
    fmt = sniff_format(path)
    assert fmt == FileFormat(delimiter=";")
    table = _both(path, fmt)
    assert list(table.frame.columns) == ["t", "x", "F"] and len(table.frame) == 4 and table.warnings == []


def test_an_excel_sep_line_naming_another_delimiter_is_refused_with_the_fix(tmp_path):
    path = _write(tmp_path, "sep=;\n" + "\n".join(["t,x,F", *ROWS]) + "\n")
    for reader in (read_raw_table, read_delimited):
        with pytest.raises(RawFileError) as info:
            reader(path, FileFormat())
        assert info.value.reason == ("the file's first line 'sep=;' (Excel's) says fields are separated by ';', the "
                                     "manifest's csv block declares ',': set `delimiter: ';'` in the csv block")

