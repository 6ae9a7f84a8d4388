"""The raw-file readers (isokinetic.rawfile): MTS 793 text exports and delimited text with a units row, an
encoding, or whitespace between fields; each refusal names row and column."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from isokinetic.rawfile import FileFormat, RawFileError, read_raw_table, sniff_format

MTS = FileFormat(format="mts793", delimiter="\t", units_row=True)
NAMES = ("Time", "Axial Displacement", "Axial Force")
UNITS = ("Sec", "in", "lbf")


def mts793_text(columns: dict[str, np.ndarray], units: tuple[str, ...], block_rows: int = 1024,
                sep: str = "\t", first: str = "MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A") -> str:
    """An MTS 793 / TestSuite text export of ``columns`` (name -> values, written with repr): the first line,
    then blocks of ``block_rows`` data rows, each with its Data Acquisition line, a blank line, the header
    and the units row; CRLF line ends."""
    names = list(columns)
    n = len(next(iter(columns.values())))
    lines = [first]
    for block, start in enumerate(range(0, n, block_rows)):
        lines += [f"Data Acquisition: Sweep   Time: 12:{block:02d}:33 PM 3/14/2024", "", sep.join(names),
                  sep.join(units)]
        for i in range(start, min(n, start + block_rows)):
            lines.append(sep.join(repr(float(columns[name][i])) for name in names))
    return "\r\n".join(lines) + "\r\n"


def sweep(n: int = 2500) -> dict[str, np.ndarray]:
    t = np.arange(n) / 100.0
    return {NAMES[0]: t, NAMES[1]: 0.5 * np.sin(2 * np.pi * t), NAMES[2]: 100.0 * np.cos(2 * np.pi * t) + 3.0}


def test_mts793_blocks_join_into_one_table(tmp_path):
    data = sweep(2500)                                       # blocks of 1024, 1024 and 452 rows
    path = tmp_path / "sweep.txt"
    path.write_bytes(mts793_text(data, UNITS).encode())
    table = read_raw_table(path, MTS)
    assert list(table.frame.columns) == list(NAMES)
    assert table.units == dict(zip(NAMES, UNITS))
    assert table.rows.tolist() == list(range(2500))
    assert table.decimal == "."
    for name in NAMES:
        np.testing.assert_array_equal(table.frame[name].astype(float).to_numpy(), data[name])


def test_mts793_decimal_mark_comes_from_the_first_line(tmp_path):
    path = tmp_path / "sweep.txt"
    text = mts793_text(sweep(10), UNITS, first="MTS793|MPT|DEU|1|2|,|.|:|1|0|0|A").replace(".", ",")
    text = text.replace("MTS793|MPT|DEU|1|2|,|,|:", "MTS793|MPT|DEU|1|2|,|.|:")
    path.write_bytes(text.encode())
    table = read_raw_table(path, MTS)
    assert table.decimal == ","
    assert table.frame[NAMES[0]].iloc[1] == "0,01"


def test_mts793_whitespace_separated_export(tmp_path):
    data = {"Time": np.arange(5) * 0.1, "Disp": np.arange(5) * 1.0, "Force": np.arange(5) * -2.0}
    path = tmp_path / "ws.dat"
    path.write_bytes(mts793_text(data, ("Sec", "in", "lbf"), sep="   ").encode())
    table = read_raw_table(path, FileFormat(format="mts793", delimiter="whitespace", units_row=True))
    assert list(table.frame.columns) == ["Time", "Disp", "Force"]
    np.testing.assert_array_equal(table.frame["Force"].astype(float), data["Force"])


def test_mts793_block_with_another_header_is_refused_naming_its_line(tmp_path):
    text = mts793_text(sweep(1100), UNITS)
    lines = text.split("\r\n")
    second = lines.index("Data Acquisition: Sweep   Time: 12:01:33 PM 3/14/2024")
    lines[second + 2] = "Time\tAxial Displacement\tLoad"
    (tmp_path / "x.txt").write_bytes("\r\n".join(lines).encode())
    with pytest.raises(RawFileError) as info:
        read_raw_table(tmp_path / "x.txt", MTS)
    assert f"block at line {second + 1}" in info.value.reason and "differs" in info.value.reason


def test_mts793_row_cut_off_is_left_out_with_a_note(tmp_path):
    """A rig that stopped while writing (issue 34; before: refused, naming row 1029 and 'Axial Force')."""
    text = mts793_text(sweep(1030), UNITS).rstrip("\r\n")
    text = text.rsplit("\t", 1)[0]                            # the last row loses its force
    (tmp_path / "x.txt").write_bytes(text.encode())
    table = read_raw_table(tmp_path / "x.txt", MTS)
    assert len(table.frame) == 1029
    assert table.warnings == ["the last row (1029) ends after 2 of 3 fields without a line end: the file is cut off "
                              "mid-row, the row left out"]


def test_cp1252_file_reads_with_its_encoding(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("time_s,force_N,oil [°C]\n0.0,1.5,40.0\n0.1,2.5,40.5\n".encode("cp1252"))
    table = read_raw_table(path, FileFormat(encoding="cp1252"))
    assert list(table.frame.columns) == ["time_s", "force_N", "oil [°C]"]
    assert table.frame["oil [°C]"].tolist() == ["40.0", "40.5"]


def test_cp1252_byte_without_encoding_is_refused_with_the_hint(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("time_s,force_N,note\n0.0,1.5,ok\n0.1,2.5,40 °C\n".encode("cp1252"))
    with pytest.raises(RawFileError) as info:
        read_raw_table(path, FileFormat())
    assert (info.value.column, info.value.row) == ("note", 1)
    assert "set `encoding:` in the manifest's csv block (for example cp1252)" in info.value.reason
    assert len(info.value.reason) <= 200


def test_cp1252_header_without_encoding_is_refused_with_the_hint(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("time_s,oil [°C]\n0.0,40.0\n".encode("cp1252"))
    with pytest.raises(RawFileError) as info:
        read_raw_table(path)
    assert info.value.column == "file" and "before the data" in info.value.reason
    assert "encoding:" in info.value.reason


def test_units_row_is_read_and_data_rows_count_from_zero(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("time;force\ns;kN\n0,0;1,5\n\n0,1;2,5\n", encoding="utf-8")
    table = read_raw_table(path, FileFormat(delimiter=";", decimal=",", units_row=True))
    assert table.units == {"time": "s", "force": "kN"}
    assert table.frame["force"].tolist() == ["1,5", "2,5"] and table.rows.tolist() == [0, 1]
    assert table.decimal == ","


def test_ragged_row_after_a_units_row_names_its_data_row(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("time,force\ns,N\n0.0,1.5\n0.1\n0.2,2.0\n", encoding="utf-8")
    with pytest.raises(RawFileError) as info:
        read_raw_table(path, FileFormat(units_row=True))
    assert (info.value.column, info.value.row) == ("force", 1) and "ragged" in info.value.reason


def test_whitespace_delimiter(tmp_path):
    path = tmp_path / "t.dat"
    path.write_text("time  force\n 0.0   1.5\n0.1\t2.5\n", encoding="utf-8")
    table = read_raw_table(path, FileFormat(delimiter="whitespace"))
    assert table.frame.to_dict("list") == {"time": ["0.0", "0.1"], "force": ["1.5", "2.5"]}


def test_utf16_file_reads_when_declared(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("time,force\n0.0,1.5\n".encode("utf-16"))
    assert read_raw_table(path, FileFormat(encoding="utf-16")).frame["force"].tolist() == ["1.5"]
    with pytest.raises(RawFileError, match="UTF-16 byte-order mark"):
        read_raw_table(path)


def test_sniff_format_finds_an_mts793_export(tmp_path):
    path = tmp_path / "sweep.txt"
    path.write_bytes(mts793_text(sweep(10), UNITS).encode())
    assert sniff_format(path) == MTS


def test_sniff_format_finds_cp1252_semicolons_decimal_comma_and_a_units_row(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("Zeit;Kraft;Öl\ns;N;°C\n0,0;1,5;40,0\n0,1;2,5;40,5\n".encode("cp1252"))
    notes: list[str] = []
    got = sniff_format(path, notes)
    assert got == FileFormat(delimiter=";", decimal=",", encoding="cp1252", units_row=True)
    assert notes and "cp1252" in notes[0]
    assert read_raw_table(path, got).units == {"Zeit": "s", "Kraft": "N", "Öl": "°C"}


def test_sniff_format_of_a_plain_csv_is_the_default(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("# rig 2\ntime_s,force_N\n0.0,1.5\n0.1,2.5\n", encoding="utf-8")
    assert sniff_format(path) == FileFormat()


SNIFF_ROWS = [["0.00", "-1.2200", "0.0836", "-1.220000"], ["0.01", "-1.2195", "0.0890", "-1.219878"],
              ["0.02", "-1.2190", "0.1023", "-1.219756"]]
SNIFF_HEADER = ["time_s", "disp_mm", "force_kN", "cmd_mm"]


def sniff_text(delimiter: str, decimal: str, comments: str = "") -> str:
    rows = [delimiter.join(cell.replace(".", decimal) for cell in row) for row in SNIFF_ROWS]
    return comments + "\n".join([delimiter.join(SNIFF_HEADER), *rows]) + "\n"


@pytest.mark.parametrize("delimiter, decimal", [(",", "."), (";", ","), (";", "."), ("\t", "."), ("\t", ","),
                                                ("|", "."), ("|", ",")])
def test_sniff_format_finds_delimiter_and_decimal_mark(tmp_path, delimiter, decimal):
    path = tmp_path / "t.csv"
    path.write_text(sniff_text(delimiter, decimal), encoding="utf-8")
    assert sniff_format(path) == FileFormat(delimiter=delimiter, decimal=decimal)
    assert read_raw_table(path, sniff_format(path)).frame.columns.tolist() == SNIFF_HEADER


def test_sniff_format_passes_over_comment_lines_and_a_cut_off_last_row(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text(sniff_text(";", ",", comments="# rig: bench 2\n\n# operator: x; y\n"), encoding="utf-8")
    assert sniff_format(path) == FileFormat(delimiter=";", decimal=",")
    path.write_text(sniff_text(",", ".") + "0.03,-1.21", encoding="utf-8")
    assert sniff_format(path) == FileFormat()


def test_cp1252_units_row_without_encoding_is_refused_with_the_hint(tmp_path):
    path = tmp_path / "t.csv"
    path.write_bytes("time,oil\ns,°C\n0.0,40.0\n".encode("cp1252"))
    with pytest.raises(RawFileError) as info:
        read_raw_table(path, FileFormat(units_row=True))
    assert (info.value.column, info.value.row) == ("file", None)
    assert info.value.reason == ("not UTF-8: byte 0xb0 in the units row (b's,\\xb0C'): set `encoding:` in the "
                                 "manifest's csv block (for example cp1252)")


def test_mts793_rows_ending_in_a_tab_read_as_without(tmp_path):
    data = sweep(30)
    plain, tabbed = tmp_path / "a.txt", tmp_path / "b.txt"
    text = mts793_text(data, UNITS)
    plain.write_bytes(text.encode())
    tabbed.write_bytes(text.replace("\r\n", "\t\r\n").encode())
    a, b = read_raw_table(plain, MTS), read_raw_table(tabbed, MTS)
    pd.testing.assert_frame_equal(a.frame, b.frame)
    assert a.units == b.units


@pytest.mark.parametrize("kwargs", [{"delimiter": "mts793"}, {"format": "xls"}, {"decimal": ";"},
                                    {"delimiter": ",", "decimal": ","}, {"encoding": "klingon"}, {"units_row": "yes"}])
def test_a_format_no_reader_reads_is_refused_when_made(kwargs):
    with pytest.raises((ValueError, LookupError)):
        FileFormat(**kwargs)


# --- issue 20: the fast path, binary data, over-long fields ------------------------------------------------------

def _delimited_text(n: int = 3000, sep: str = ",", decimal: str = ".", crlf: bool = False) -> str:
    """Comments, a blank line, a header, rows (data rows 0 .. n - 3: two are blank lines), no line end after the
    last row."""
    rng = np.random.default_rng(7)
    rows = [sep.join([repr(float(v)).replace(".", decimal) for v in rng.normal(0, 1e3, 2)] + [f"x{i}", ""])
            for i in range(n)]
    rows[10] = "   "                                          # a blank (whitespace) line among the rows
    rows[20] = ""
    end = "\r\n" if crlf else "\n"
    return end.join(["# rig 7", "", sep.join(["a", "b", "note", "empty"])] + rows)


@pytest.mark.parametrize("sep, decimal, crlf", [(",", ".", False), (";", ",", True), ("\t", ".", True),
                                                ("|", ",", False)])
def test_fast_path_reads_the_cells_the_line_reader_reads(tmp_path, sep, decimal, crlf):
    from isokinetic.rawfile import read_delimited

    path = tmp_path / "x.csv"
    path.write_bytes(_delimited_text(sep=sep, decimal=decimal, crlf=crlf).encode())
    fmt = FileFormat(delimiter=sep, decimal=decimal)
    fast, slow = read_raw_table(path, fmt), read_delimited(path, fmt)
    pd.testing.assert_frame_equal(fast.frame, slow.frame)
    assert fast.rows.tolist() == slow.rows.tolist() and fast.warnings == slow.warnings
    numbers = read_raw_table(path, fmt, numeric=True).frame
    assert numbers["a"].dtype == np.float64 and numbers["note"].dtype == object
    expected = pd.to_numeric(slow.frame["a"].str.replace(decimal, ".", regex=False))
    np.testing.assert_array_equal(numbers["a"].to_numpy(), expected.to_numpy())     # bit for bit


@pytest.mark.parametrize("edit, column, row, reason", [
    (lambda lines: lines.__setitem__(1500, lines[1500] + ",1"), "file", 1495, "row has 5 fields, the header 4"),
    (lambda lines: lines.__setitem__(2000, "1.5,2.5"), "note", 1995, "row ends after 2 of 4 fields: a ragged row"),
])
def test_fast_path_refuses_a_row_as_the_line_reader_does(tmp_path, edit, column, row, reason):
    from isokinetic.rawfile import read_delimited

    lines = _delimited_text().split("\n")
    edit(lines)
    path = tmp_path / "x.csv"
    path.write_bytes("\n".join(lines).encode())
    errors = []
    for reader in (read_raw_table, read_delimited):
        with pytest.raises(RawFileError) as info:
            reader(path, FileFormat())
        errors.append((info.value.column, info.value.row, info.value.reason))
    assert errors == [(column, row, reason)] * 2


@pytest.mark.parametrize("data, said", [
    (b"\x1f\x8b\x08\x00" + bytes(range(256)) * 20, "binary data (gzip?)"),
    (b"PK\x03\x04" + bytes(200), "binary data (zip (an .xlsx workbook?)?)"),
    (b"time,force\n0,1\n1,\x002\n", "binary data (a NUL byte in line 3)"),
])
def test_binary_data_is_named_never_dumped(tmp_path, data, said):
    (tmp_path / "x.csv").write_bytes(data)
    with pytest.raises(RawFileError) as info:
        read_raw_table(tmp_path / "x.csv", FileFormat())
    assert info.value.reason.startswith(said) and "\\x" not in info.value.reason and len(info.value.reason) <= 200


def test_field_beyond_the_csv_limit_names_row_and_column_in_an_mts_export(tmp_path):
    """Rows ending with a tab are read line by line, where the csv module's field limit applies."""
    text = [line + "\t" for line in mts793_text(sweep(30), UNITS).split("\r\n")]
    text[10] = text[10].split("\t")[0] + "\t" + "7" * 200_000 + "\t1.0\t"
    (tmp_path / "x.txt").write_bytes("\r\n".join(text).encode())
    with pytest.raises(RawFileError) as info:
        read_raw_table(tmp_path / "x.txt", MTS)
    assert (info.value.column, info.value.row) == ("Axial Displacement", 5)
    assert info.value.reason == "a field of 200000 characters, more than the 131072 a field may have"


def test_mts793_fast_path_reads_the_cells_the_line_reader_reads(tmp_path):
    from isokinetic.rawfile import read_mts793

    path = tmp_path / "sweep.txt"
    path.write_bytes(mts793_text(sweep(2500), UNITS).encode())
    fast, slow = read_raw_table(path, MTS), read_mts793(path, MTS)
    pd.testing.assert_frame_equal(fast.frame, slow.frame)
    assert (fast.units, fast.rows.tolist(), fast.warnings) == (slow.units, slow.rows.tolist(), slow.warnings)
    numbers = read_raw_table(path, MTS, numeric=True).frame
    for name in NAMES:     # as ingest parsed the text before (pandas' parser, not float())
        np.testing.assert_array_equal(numbers[name].to_numpy(), pd.to_numeric(slow.frame[name]).to_numpy())
