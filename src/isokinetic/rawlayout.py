"""Where a raw table starts and which of its rows hold no sample (docs/raw-campaign-format.md, "1.4 additions"),
and the cells of a spreadsheet export: helpers of :mod:`isokinetic.rawfile`, below it, importing nothing of
isokinetic.

* :func:`find_start`: the header row behind a logger's *preamble* (lines before the header), or, in a headerless
  file, the first data row; a row is *data-like* when most of its filled fields are numbers.
* :func:`marker_rows`: text rows inside the data (``6724,Switched from 1 to 2,,,``, a repeated header): rows with
  text in a cell and an empty cell, or equal to the header. A full row with one bad value is no marker: ingest
  refuses it, naming row and column.
* the readers' errors (:class:`RawFileError`, naming row and column) and row helpers, re-exported by rawfile;
* :func:`sheet_rows`: a worksheet of an ``.xlsx`` workbook through openpyxl (read-only, cached values, imported
  lazily), bounded before and while it is read (:data:`MAX_SHEET_ROWS`, :data:`MAX_SHEET_CELLS`, the zip's
  unpacked size and ratio: a zip bomb is refused unread).
"""

from __future__ import annotations

import codecs
import csv
import datetime as dt
import io
import re
import zipfile
from pathlib import Path

import numpy as np

#: The fix named when a file is not in the declared encoding.
ENCODING_HINT = "set `encoding:` in the manifest's csv block (for example cp1252)"
#: Longest cell text quoted in a reason.
MAX_QUOTED = 40
_INTEGER = re.compile(r"[+-]?\d+")
_DIGITS = re.compile(r"\d+(?:[eE][+-]?\d+)?")
_WHITESPACE = re.compile(r"[ \t]+")

#: Most rows searched for the header behind a preamble (a logger's preamble is a few dozen lines).
MAX_PREAMBLE_ROWS = 200
#: Data rows that must follow a header found behind a preamble (or start a headerless table), like it.
CONFIRM_ROWS = 2
#: Bounds of a worksheet: Excel's own row limit, and cells (10 million: about 1 GB of Python objects at most).
MAX_SHEET_ROWS = 1_048_576
MAX_SHEET_CELLS = 10_000_000
#: A workbook whose parts unpack to more than this many bytes, or this many times their packed size, is refused
#: unread (a zip bomb).
MAX_UNPACKED_BYTES = 2_000_000_000
MAX_UNPACK_RATIO = 200.0


#: Leading bytes of binary formats a case file is sometimes mistaken for, with their names.
BINARY_MAGIC = {b"\x1f\x8b": "gzip", b"PK\x03\x04": "zip (an .xlsx workbook?)", b"BZh": "bzip2",
                b"\xfd7zXZ\x00": "xz", b"7z\xbc\xaf": "7-Zip", b"PAR1": "Parquet", b"\x89HDF": "HDF5",
                b"\x89PNG": "PNG", b"%PDF": "PDF", b"\xd0\xcf\x11\xe0": "OLE (an .xls workbook?)"}

class RawFileError(Exception):
    """A case file that cannot be read as a table. ``column``: the file's column name, or ``file`` (then
    ``kind`` is ``key``: the manifest's ``file`` key); ``row``: 0-based data row, None when no row is at fault."""

    def __init__(self, column: str, reason: str, row: int | None = None, kind: str = "column"):
        super().__init__(reason)
        self.column, self.reason, self.row, self.kind = column, reason, row, kind


def _file_error(reason: str) -> RawFileError:
    return RawFileError("file", reason, kind="key")


def _quoted(raw: bytes) -> str:
    return repr(raw if len(raw) <= MAX_QUOTED else raw[:MAX_QUOTED] + b"...")


def _split(line: str, delimiter: str) -> list[str]:
    """The fields of one line: csv quoting for a one-character delimiter, runs of blanks for ``whitespace``."""
    if delimiter == "whitespace":
        return _WHITESPACE.split(line.strip())
    return next(csv.reader([line], delimiter=delimiter))


def _header_index(lines: list[str]) -> int | None:
    return next((i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")), None)


def _data_lines(lines: list[str], start: int) -> list[tuple[int, str]]:
    """(data row, line) of the non-blank lines from ``start`` on: rows as pandas numbers them."""
    out = []
    for line in lines[start:]:
        if line.strip():
            out.append((len(out), line))
    return out


def _decode_problem(data: bytes, exc: UnicodeDecodeError, fmt) -> RawFileError:
    """The row and column of the first byte ``fmt.encoding`` (``fmt``: a :class:`isokinetic.rawfile.FileFormat`)
    cannot decode (ASCII-compatible codecs; others name the byte offset)."""
    start, bad = exc.start, data[exc.start]
    hint = f": {ENCODING_HINT}" if codecs.lookup(fmt.encoding).name == "utf-8" else ""
    what = "not UTF-8" if hint else f"not {fmt.encoding}"
    if codecs.lookup(fmt.encoding).name.startswith(("utf-16", "utf-32")) or fmt.format != "delimited":
        line_no = data.count(b"\n", 0, start) + 1
        return _file_error(f"{what}: byte 0x{bad:02x} in line {line_no}{hint}")
    delimiter = "\t" if fmt.delimiter == "whitespace" else fmt.delimiter
    line_start = data.rfind(b"\n", 0, start) + 1
    line_end = data.find(b"\n", start)
    line_end = len(data) if line_end < 0 else line_end
    lines = data[:line_start].decode(fmt.encoding, errors="replace").split("\n")[:-1]
    header = _header_index(lines)
    if header is None:     # in a comment or the header itself
        text = data[line_start:line_end].rstrip(b"\r")
        return _file_error(f"{what}: byte 0x{bad:02x} in line {len(lines) + 1} ({_quoted(text)}), "
                           f"before the data{hint}")
    names = _split(lines[header].rstrip("\r"), fmt.delimiter)
    row = len(_data_lines(lines, header + 1)) - (1 if fmt.units_row else 0)
    if row < 0:             # in the units row
        text = data[line_start:line_end].rstrip(b"\r")
        return _file_error(f"{what}: byte 0x{bad:02x} in the units row ({_quoted(text)}){hint}")
    if fmt.delimiter == "whitespace":
        fields = _WHITESPACE.split(data[line_start:line_end].rstrip(b"\r").decode("latin-1").strip())
        field_no = len(_WHITESPACE.split(data[line_start:start + 1].decode("latin-1").lstrip())) - 1
        raw = fields[field_no].encode("latin-1") if field_no < len(fields) else data[start:start + 1]
    else:
        sep = delimiter.encode()
        field_no = data.count(sep, line_start, start)
        parts = data[line_start:line_end].rstrip(b"\r").split(sep)
        raw = parts[field_no] if field_no < len(parts) else b""
    if field_no < len(names):
        return RawFileError(names[field_no].strip(), f"{what}: byte 0x{bad:02x} in {_quoted(raw)}{hint}", row=row)
    return RawFileError("file", f"{what}: byte 0x{bad:02x} in {_quoted(raw)}{hint}", row=row, kind="key")


def _field_count_problem(names: list[str], row: int, fields: list[str], last: bool, ends_in_newline: bool,
                         delimiter: str) -> RawFileError:
    """A data row whose field count differs from the header's (cut off, ragged, decimal commas when the
    fields are separated by ',')."""
    n, want = len(fields), len(names)
    if n < want:
        cut = last and not ends_in_newline
        what = "the file is cut off mid-row" if cut else "a ragged row"
        return RawFileError(names[n], f"row ends after {n} of {want} fields: {what}", row=row)
    extra, i = n - want, 0
    while delimiter == "," and extra > 0 and i < want and i + 1 < n:
        if _INTEGER.fullmatch(fields[i].strip()) and _DIGITS.fullmatch(fields[i + 1].strip()):
            return RawFileError(names[i], f"decimal comma in '{fields[i].strip()},{fields[i + 1].strip()}' (row "
                                          f"has {n} fields, the header {want}): the format needs ',' between "
                                          f"fields and '.' as the decimal mark", row=row)
        i += 1
    return RawFileError("file", f"row has {n} fields, the header {want}", row=row, kind="key")


def _csv_problem(exc: csv.Error, names: list[str], row: int, line: str, delimiter: str) -> RawFileError:
    """The csv module's refusal of a data row (a field beyond its length limit), naming row and column (the
    longest field's) with its length, never the field itself."""
    sep = None if delimiter == "whitespace" else delimiter
    parts = line.split(sep)
    longest = max(range(len(parts)), key=lambda i: len(parts[i])) if parts else 0
    what = (f"a field of {len(parts[longest])} characters, more than the {csv.field_size_limit()} a field may have"
            if "field limit" in str(exc) else f"unreadable row: {str(exc)[:120]}")
    column = names[longest] if longest < len(names) else "file"
    return RawFileError(column, what, row=row, kind="column" if column != "file" else "key")


def _binary_problem(data: bytes, fmt) -> RawFileError | None:
    """Binary data where text is expected: a known binary format by its leading bytes, or NUL bytes (under an
    encoding other than UTF-16/32). The reason names the format, never the bytes."""
    for magic, name in BINARY_MAGIC.items():
        if data.startswith(magic):
            return _file_error(f"binary data ({name}?), not a text table: unpack or export it as text first")
    if not codecs.lookup(fmt.encoding).name.startswith(("utf-16", "utf-32")):
        nul = data.find(b"\0", 0, 1 << 20)
        if nul >= 0:
            line_no = data.count(b"\n", 0, nul) + 1
            return _file_error(f"binary data (a NUL byte in line {line_no}), not a text table (or UTF-16 without "
                               "a byte-order mark: set `encoding: utf-16` in the manifest's csv block)")
    return None


def _units(names: list[str], line: str, delimiter: str) -> dict[str, str]:
    """Column -> unit text of a units row (missing trailing cells are empty)."""
    cells = [c.strip() for c in _split(line, delimiter)] if line.strip() else []
    cells += [""] * (len(names) - len(cells))
    if len(cells) > len(names):
        raise _file_error(f"units row has {len(cells)} fields, the header {len(names)}")
    return dict(zip(names, cells))


def _check_names(names: list[str]) -> list[str]:
    names = [name.strip() for name in names]
    seen = set()
    for name in names:
        if name in seen:
            raise RawFileError(name, "column name appears twice in the header")
        seen.add(name)
    return names


def _positional(n: int) -> list[str]:
    """A headerless file's column names: ``col1`` .. ``colN`` (1-based, as the manifest names them)."""
    return [f"col{i}" for i in range(1, n + 1)]


def _listed(rows, limit: int = 8) -> str:
    rows = [int(r) for r in rows]
    return ", ".join(map(str, rows[:limit])) + (f" and {len(rows) - limit} more" if len(rows) > limit else "")


def _preamble_note(preamble: list[tuple[int, str]], header: bool) -> list[str]:
    """The note for lines skipped before the header (or before a headerless file's first data row)."""
    if not preamble:
        return []
    where = "the header" if header else "the first data row"
    return [f"skipped {len(preamble)} preamble line(s) before {where} (file lines {preamble[0][0] + 1}.."
            f"{preamble[-1][0] + 1}, the first {preamble[0][1].strip()[:MAX_QUOTED]!r})"]


def _headerless_problem(line: str) -> RawFileError:
    return _file_error(f"the header row {line.strip()[:60]!r} holds numbers like the data, not column names: a "
                       "headerless file? set `header: none` in the manifest's csv block and name the columns by "
                       "position (name: 4 or col4)")


def _texts(cells, decimal: str) -> str:
    """A marker row's text cells (not its numbers), joined."""
    return " ".join(str(v).strip() for v in cells if isinstance(v, str) and v.strip() and not is_number(v, decimal))


class SheetError(ValueError):
    """A workbook or worksheet that cannot be read as a table (the reason names what and where)."""


def is_number(cell, decimal: str = ".") -> bool:
    """True for a cell that reads as a number (a decimal comma when ``decimal`` is ',')."""
    text = str(cell).strip()
    if decimal == ",":
        text = text.replace(",", ".")
    try:
        float(text)
    except ValueError:
        return False
    return True


def data_like(fields: list[str], decimal: str = ".") -> bool:
    """True for a row at least half of whose filled fields, and at least one, are numbers."""
    filled = [f for f in fields if str(f).strip()]
    numbers = sum(is_number(f, decimal) for f in filled)
    return numbers >= 1 and 2 * numbers >= len(filled)


def all_numbers(fields: list[str], decimal: str = ".") -> bool:
    """True for a row whose every filled field is a number (a header row never is)."""
    filled = [f for f in fields if str(f).strip()]
    return bool(filled) and all(is_number(f, decimal) for f in filled)


def _confirmed(rows: list[list[str]], first: int, width: int, decimal: str) -> bool:
    """True when the rows from ``first`` on (up to :data:`CONFIRM_ROWS`, as many as there are) have ``width``
    fields and are data-like."""
    following = rows[first:first + CONFIRM_ROWS]
    return bool(following) and all(len(r) == width and data_like(r, decimal) for r in following)


def find_start(rows: list[list[str]], header: bool, units_row: bool, decimal: str = ".") -> int:
    """Index in ``rows`` (the non-blank, non-comment rows, split) of the header row (``header``) or of the first
    data row (headerless): the first that :data:`CONFIRM_ROWS` data-like rows of its width follow; 0 when none
    does (the readers then say what is wrong with the first). Behind a preamble the header is a row of two or more
    fields, not data-like, followed (after the units row) by :data:`CONFIRM_ROWS` data-like rows of as many fields."""
    skip = 1 + int(units_row) if header else 0
    for i in range(min(len(rows), MAX_PREAMBLE_ROWS + 1)):
        width = len(rows[i])
        if width < 2 or data_like(rows[i], decimal) != (not header):
            continue
        if _confirmed(rows, i + skip, width, decimal):
            return i
    return 0


def _numeric(cell: str) -> bool:
    try:
        float(cell.strip().replace(",", "."))
    except ValueError:
        return False
    return True


def row_layout(rows: list[list[str]]) -> tuple[int, bool, bool]:
    """(index of the header, or of the first data row when headerless; headerless; a units row under the header)
    of a table's rows (split, blank and comment rows left out): the layout rules of
    :func:`isokinetic.rawfile.sniff_format`."""
    first = find_start(rows, False, False)          # the first data row: a header of its width just above it?
    headed = any(len(rows[i]) == len(rows[first]) and not data_like(rows[i]) for i in range(max(0, first - 2), first))
    headerless = not headed and all_numbers(rows[first])
    plain, with_units = find_start(rows, True, False), find_start(rows, True, True)
    k = first if headerless else min(plain, with_units)
    after = rows[k + 1:]
    units_row = not headerless and (with_units < plain or (bool(after) and any(c.strip() for c in after[0])
                                                           and not any(_numeric(c) for c in after[0] if c.strip())))
    return k, headerless, units_row


def marker_rows(frame, names: list[str], decimal: str = ".") -> np.ndarray:
    """Positions of the frame's rows that hold no sample: text (not a number) in a column of numbers (most of its
    filled cells) with an empty cell in the row (``6724,Switched from 1 to 2,,,``), or every cell equal to its
    column's name (a repeated header). A text column (a note, ISO stamps) makes no row a marker."""
    import pandas as pd

    n = len(frame)
    if n == 0:
        return np.empty(0, dtype="int64")
    text = np.zeros(n, dtype=bool)
    repeat = np.ones(n, dtype=bool)
    for name in names:
        column = frame[name]
        if column.dtype != object:
            repeat[:] = False
            continue
        cells = column.astype(object)
        strings = cells.map(lambda v: isinstance(v, str)).to_numpy(bool)
        probe = cells.str.replace(",", ".", regex=False) if decimal == "," else cells
        numbers = (pd.to_numeric(probe.where(strings), errors="coerce").notna().to_numpy(bool)
                   | (~strings & cells.notna().to_numpy(bool)))
        filled = cells.notna().to_numpy(bool)
        if 2 * numbers.sum() > filled.sum():         # a column of numbers
            text |= filled & ~numbers
        repeat &= (cells.astype(str).str.strip() == name).to_numpy(bool)
    empty = frame.isna().any(axis=1).to_numpy(bool)
    return np.flatnonzero((text & empty) | repeat)


#: An Excel ``sep=;`` first line (Excel writes it, and reads it, to name the delimiter): the delimiter it names.
_EXCEL_SEP = re.compile(r"\s*\"?sep=(.)\"?\s*")


def excel_sep(line: str) -> str | None:
    """The delimiter an Excel ``sep=X`` line names (``sep=;`` -> ``;``), None for any other line."""
    match = _EXCEL_SEP.fullmatch(line.rstrip("\r\n"))
    return match.group(1) if match and match.group(1) in ",;\t|" else None


def sep_problem(line: str, delimiter: str) -> RawFileError | None:
    """An Excel ``sep=X`` line naming another delimiter than the declared one (None when it agrees)."""
    named = excel_sep(line)
    if named is None or named == delimiter or (delimiter == "whitespace" and named == "\t"):
        return None
    said = "tabs" if named == "\t" else repr(named)
    return _file_error(f"the file's first line {line.strip()!r} (Excel's) says fields are separated by {said}, the "
                       f"manifest's csv block declares {delimiter!r}: set `delimiter: {named!r}` in the csv block")


def cut_off_last(last: list[str], previous: list[str] | None, decimal: str = ".") -> bool:
    """True when the last field of a file's last row, written without a line end, is visibly cut short: empty, ending
    in the decimal mark, an exponent or a sign (``-1.``), or with fewer decimals than the row before's (``-1.2``
    under ``-1.22``). A cut that leaves as many decimals is not seen."""
    if not last:
        return False
    cell = str(last[-1]).strip()
    before = str(previous[-1]).strip() if previous else ""
    if not cell:
        return bool(before)
    if cell[-1] in (decimal, "e", "E", "+", "-") or not is_number(cell, decimal):
        return True
    return decimal in before and is_number(before, decimal) and _decimals(cell, decimal) < _decimals(before, decimal)


def _cut_note(row: int, fields: list[str], want: int) -> str:
    """The note for a last row cut off (no line end) and left out: short of fields, or in its last value."""
    if len(fields) < want:
        return (f"the last row ({row}) ends after {len(fields)} of {want} fields without a line end: the file is cut "
                "off mid-row, the row left out")
    return (f"the last row ({row}) ends in {str(fields[-1]).strip()[:MAX_QUOTED]!r} without a line end: cut off in "
            "its last value, the row left out")


def _cut_last(data: bytes, fmt, width: int, n_rows: int, bad: tuple[int, int] | None
              ) -> list[str] | None:
    """The fields of a file's last row when it is cut off (no line end after it; short of fields, the only such
    row, or visibly cut in its last value: :func:`cut_off_last`), else None. Only the last two lines are copied."""
    end = len(data)
    start = data.rfind(b"\n", 0, end) + 1
    fields = _split(data[start:end].decode(fmt.encoding).rstrip("\r"), fmt.delimiter)
    if bad is not None:
        return fields if bad[1] == n_rows - 1 and len(fields) < width else None
    at = start - 1                      # the line end before the last row; blank lines above it skipped
    while at > 0 and not data[data.rfind(b"\n", 0, at) + 1:at].strip():
        at = data.rfind(b"\n", 0, at)
    line = data[data.rfind(b"\n", 0, max(at, 0)) + 1:max(at, 0)].decode(fmt.encoding).rstrip("\r")
    before = _split(line, fmt.delimiter) if n_rows > 1 else None
    return fields if n_rows and cut_off_last(fields, before, fmt.decimal) else None


def _decimals(cell: str, decimal: str) -> int:
    mantissa = re.split(r"[eE]", cell)[0]
    return len(mantissa.split(decimal, 1)[1]) if decimal in mantissa else 0


def ragged_marker(fields: list[str], reference: list[str] | None, decimal: str = ".") -> bool:
    """True for a row of fewer fields than the header's whose text lies where the ``reference`` row (the first of
    full width) holds a number: a marker (``6724,Switched from 1 to 2``), not a row cut off or split."""
    if reference is None or len(fields) >= len(reference):
        return False
    return any(f.strip() and not is_number(f, decimal) and is_number(reference[i], decimal)
               for i, f in enumerate(fields))


class _BufferReader(io.RawIOBase):
    """A read-only file over a bytearray, without the copy io.BytesIO makes of one."""

    def __init__(self, buffer: bytearray):
        self.view, self.at = memoryview(buffer), 0

    def readable(self) -> bool:
        return True

    def readinto(self, out) -> int:
        n = min(len(out), len(self.view) - self.at)
        out[:n] = self.view[self.at:self.at + n]
        self.at += n
        return n


def _check_zip(path: Path) -> None:
    """Refuse a workbook that is no zip, or whose parts would unpack beyond the bounds, before it is opened."""
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
    except (zipfile.BadZipFile, OSError) as exc:
        raise SheetError(f"not an xlsx workbook (a zip archive): {str(exc)[:100]}") from None
    packed = sum(i.compress_size for i in infos) or 1
    unpacked = sum(i.file_size for i in infos)
    if unpacked > MAX_UNPACKED_BYTES or unpacked > MAX_UNPACK_RATIO * max(packed, 1 << 16):
        raise SheetError(f"the workbook unpacks to {unpacked / 1e6:.4g} MB from {packed / 1e6:.4g} MB (more than "
                         f"{MAX_UNPACKED_BYTES / 1e6:g} MB or {MAX_UNPACK_RATIO:g} x): not read (a zip bomb?)")


def _cell_text(value) -> str | float | None:
    """A worksheet cell as the readers take it: numbers as float, dates as ISO 8601 text, other text stripped."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, (dt.datetime, dt.date, dt.time)):
        return value.isoformat()
    return str(value).strip()


def sheet_rows(path: str | Path, sheet: str | None = None) -> list[list]:
    """The non-empty rows of a worksheet (``sheet``: its name; None: the first), each a list of cells
    (:func:`_cell_text`; trailing empty cells dropped). Raises :class:`SheetError` naming the sheet, or the
    bound a worksheet exceeds."""
    path = Path(path)
    _check_zip(path)
    import openpyxl

    try:
        book = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception as exc:       # noqa: BLE001  (openpyxl raises many kinds on a broken workbook)
        raise SheetError(f"unreadable xlsx workbook ({type(exc).__name__}): {str(exc)[:100]}") from None
    try:
        if sheet is not None and sheet not in book.sheetnames:
            raise SheetError(f"no worksheet {sheet!r} in the workbook (sheets: {', '.join(book.sheetnames)[:120]})")
        ws = book[sheet] if sheet is not None else book.worksheets[0]
        rows, cells = [], 0
        for values in ws.iter_rows(values_only=True):
            row = [_cell_text(v) for v in values]
            while row and row[-1] is None:
                row.pop()
            if not row:
                continue
            rows.append(row)
            cells += len(row)
            if len(rows) > MAX_SHEET_ROWS or cells > MAX_SHEET_CELLS:
                raise SheetError(f"worksheet {ws.title!r} holds more than {MAX_SHEET_ROWS} rows or "
                                 f"{MAX_SHEET_CELLS} cells: not read")
        return rows
    finally:
        book.close()
