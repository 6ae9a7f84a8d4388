"""Readers of raw case files (docs/raw-campaign-format.md, "Case files"): text tables as rigs write them.

:func:`read_raw_table` reads one file in a :class:`FileFormat` (the manifest's ``csv`` block) to a
:class:`RawTable` of text cells; the decimal mark and the units are applied later, at ingest. Two formats:

* ``delimited`` (the format's CSV): a header row, optionally a units row (``units_row``), data rows split on
  ``,`` ``;`` tabs ``|`` or runs of whitespace; ``#`` comment lines and blank lines before the header;
* ``mts793`` (MTS 793 / TestSuite text export): a first line ``MTS793|...`` whose sixth field is the decimal
  mark, then blocks of a ``Data Acquisition ...`` line, a header row, a units row and the block's data rows,
  tab (or whitespace) separated; the blocks are joined into one table.

Every hostile-input check lives here: an empty file, bytes the declared encoding cannot decode (naming row and
column, with the key to set), byte-order marks of another encoding, a header split by another delimiter, and a
data row whose field count differs from the header's (a file cut off mid-row, decimal commas). Problems raise
:class:`RawFileError` (column, reason, row); a last row without a line end is kept, with a warning. Files are
only ever opened for reading. This module is a bottom layer: it imports nothing of isokinetic.

Hostile input (issue 20): binary data (a gzip file renamed ``.csv``, NUL bytes) is refused as such, never quoted
as a byte dump; a field longer than the csv module's limit names its row and column. Memory: a delimited file
with a one-character delimiter, no quotes and an ASCII-compatible encoding takes the *fast path*
(:func:`_read_fast`): the bytes are checked without a Python object per line (field counts and blank lines by
numpy over the bytes, the encoding by an incremental decoder) and parsed by pandas' C parser, with
``numeric=True`` straight to float64 columns. Peak memory is then a small multiple of the file size
(docs/hostile-input.md); other files take the line-by-line path.
"""

from __future__ import annotations

import codecs
import csv
import io
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from isokinetic.rawlayout import (  # noqa: F401  (RawFileError, ENCODING_HINT, MAX_QUOTED: re-exported)
    ENCODING_HINT,
    MAX_PREAMBLE_ROWS,
    MAX_QUOTED,
    RawFileError,
    SheetError,
    _binary_problem,
    _BufferReader,
    _check_names,
    _csv_problem,
    _cut_last,
    _cut_note,
    _data_lines,
    _decode_problem,
    _field_count_problem,
    _file_error,
    _headerless_problem,
    _listed,
    _positional,
    _preamble_note,
    _quoted,
    _split,
    _texts,
    _units,
    all_numbers,
    cut_off_last,
    data_like,
    excel_sep,
    find_start,
    is_number,
    marker_rows,
    ragged_marker,
    row_layout,
    sep_problem,
    sheet_rows,
)

if TYPE_CHECKING:  # pandas is imported where a table is read: the raw check's job, which reads the manifest's
    import pandas as pd  # formats only, never loads it (issue 23)

#: File formats :func:`read_raw_table` reads.
FORMATS = ("delimited", "mts793", "xlsx")
#: Field delimiters of the ``delimited`` format, with the words used in messages (``whitespace``: runs of
#: spaces and tabs).
DELIMITERS = {",": "','", ";": "';'", "\t": "tabs", "|": "'|'", "whitespace": "whitespace"}
DECIMALS = (".", ",")
#: Thousands separators a file may group its numbers with (1.5: ``1.234,5``, ``1,234.5``, ``1 234,5``, ``1'234.5``).
THOUSANDS = (".", ",", " ", "'")
#: Whether a file has a header row (``row``, after any preamble) or none (columns ``col1``, ``col2``, ...).
HEADER_KINDS = ("row", "none")
#: Byte-order marks of encodings other than UTF-8, refused under a UTF-8 (default) encoding.
FOREIGN_BOMS = {codecs.BOM_UTF32_LE: "UTF-32", codecs.BOM_UTF32_BE: "UTF-32",
                codecs.BOM_UTF16_LE: "UTF-16", codecs.BOM_UTF16_BE: "UTF-16"}
MTS_MAGIC = "MTS793"
MTS_BLOCK = "Data Acquisition"
#: Bytes decoded at a time when an encoding is checked without decoding the whole file at once.
DECODE_CHUNK = 1 << 22


@dataclass(frozen=True)
class FileFormat:
    """How a campaign's case files are written (the manifest's ``csv`` block): format, field delimiter,
    decimal mark, text encoding (a Python codec name) and whether a units row follows the header. (Fields in
    this order so that the 1.1 ``CsvDialect(delimiter, decimal)`` still reads; give the others by keyword.)"""

    delimiter: str = ","
    decimal: str = "."
    encoding: str = "utf-8"
    units_row: bool = False
    format: str = "delimited"
    header: str = "row"
    sheet: str | None = None
    thousands: str | None = None
    timezone: str | None = None

    def __post_init__(self):
        """Refuse a format that no reader reads (a positional slip such as ``FileFormat("mts793")`` included)."""
        if self.format not in FORMATS:
            raise ValueError(f"FileFormat.format must be one of {FORMATS}, got {self.format!r}")
        if self.delimiter not in DELIMITERS:
            raise ValueError(f"FileFormat.delimiter must be one of {tuple(DELIMITERS)}, got {self.delimiter!r}")
        if self.decimal not in DECIMALS or self.decimal == self.delimiter:
            raise ValueError(f"FileFormat.decimal must be one of {DECIMALS} and differ from the delimiter, "
                             f"got {self.decimal!r}")
        codecs.lookup(self.encoding)            # LookupError for an unknown encoding
        if not isinstance(self.units_row, bool):
            raise ValueError(f"FileFormat.units_row must be true or false, got {self.units_row!r}")
        if self.header not in HEADER_KINDS or (self.header == "none" and self.units_row):
            raise ValueError(f"FileFormat.header must be one of {HEADER_KINDS} (none without a units row), "
                             f"got {self.header!r}")
        if self.thousands is not None and (self.thousands not in THOUSANDS
                                           or self.thousands in (self.decimal, self.delimiter)):
            raise ValueError(f"FileFormat.thousands must be one of {THOUSANDS} and differ from the decimal mark "
                             f"and the delimiter, got {self.thousands!r}")

    def to_dict(self) -> dict:
        """The manifest's csv block (1.4 keys ``header`` and ``sheet``, 1.5 ``thousands`` and ``timezone`` only when
        not their defaults)."""
        out = {"format": self.format, "delimiter": self.delimiter, "decimal": self.decimal,
               "encoding": self.encoding, "units_row": self.units_row}
        optional = (("header", self.header), ("sheet", self.sheet), ("thousands", self.thousands),
                    ("timezone", self.timezone))
        return out | {k: v for k, v in optional if v not in ("row", None)}


@dataclass(frozen=True)
class RawTable:
    """One case file as text: ``frame`` (str cells, NaN for empty ones; columns: stripped header names, or
    ``col1``, ``col2``, ... of a headerless file), ``units`` (column -> unit text of a units row, {} without one),
    ``rows`` (0-based data-row numbers of the frame's rows in the file: marker rows left out), ``warnings`` (the
    preamble and marker rows skipped among them) and ``decimal`` (the decimal mark to read the cells with)."""

    frame: pd.DataFrame
    units: dict[str, str]
    rows: np.ndarray
    warnings: list[str] = field(default_factory=list)
    decimal: str = "."


def _delimiter_problem(header: str, fmt: FileFormat | None) -> RawFileError | None:
    """A one-field header that holds another delimiter than the file's: ';' or tabs without a ``csv``
    block (the format's ','), any other of :data:`DELIMITERS` with one."""
    if fmt is None:
        for sep, label in ((";", "';'"), ("\t", "tabs")):
            if sep in header:
                return _file_error(f"fields are separated by {label}, not ',' (header {header!r}): the format "
                                   "needs ',' between fields and '.' as the decimal mark")
        return None
    for sep, label in DELIMITERS.items():
        if sep not in (fmt.delimiter, "whitespace") and sep in header:
            return _file_error(f"fields are separated by {label}, not {DELIMITERS[fmt.delimiter]} as the "
                               f"manifest's csv block declares (header {header[:80]!r})")
    return None


def _read_bytes(path: Path, fmt: FileFormat) -> bytes:
    """The file's bytes, a UTF-8 byte-order mark dropped; refuses an empty file, binary data and (under UTF-8)
    byte-order marks of another encoding."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise _file_error(f"unreadable file: {exc}") from None
    if not data:
        raise _file_error("empty file (0 bytes)")
    utf8 = codecs.lookup(fmt.encoding).name == "utf-8"
    if utf8:
        for bom, encoding in FOREIGN_BOMS.items():
            if data.startswith(bom):
                raise _file_error(f"{encoding} byte-order mark: the file is {encoding}, the format needs UTF-8 "
                                  f"(or set `encoding: {encoding.lower()}` in the manifest's csv block)")
        if data.startswith(codecs.BOM_UTF8):
            data = data[len(codecs.BOM_UTF8):]
    problem = _binary_problem(data, fmt)
    if problem is not None:
        raise problem
    return data


def _decoded(data: bytes, fmt: FileFormat) -> str:
    try:
        return data.decode(fmt.encoding)
    except UnicodeDecodeError as exc:
        raise _decode_problem(data, exc, fmt) from None
    except UnicodeError as exc:     # e.g. utf-16 with an odd byte count
        raise _file_error(f"not {fmt.encoding}: {str(exc)[:120]}") from None


def _text(path: Path, fmt: FileFormat) -> tuple[str, list[str]]:
    """The file's text in ``fmt.encoding`` (line ends kept), its byte-order mark dropped; checks emptiness,
    binary data and foreign byte-order marks (under UTF-8)."""
    text = _decoded(_read_bytes(path, fmt), fmt)
    if text.startswith("\ufeff"):
        text = text[1:]
    if "\r" in text:           # CRLF, old Mac lone CRs, or a mix of line ends: each ends a line
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    return text, lines


def _lines(lines: list[str]) -> tuple[list[str], bool]:
    """Lines without their CR, and whether the text ended in a line end."""
    ends_in_newline = lines[-1] == ""
    if ends_in_newline:
        lines = lines[:-1]
    return [line[:-1] if line.endswith("\r") else line for line in lines], ends_in_newline


def _frame(data_lines: list[str], names: list[str], delimiter: str, numeric: bool = False,
           decimal: str = ".") -> pd.DataFrame:
    """The data lines as a DataFrame of text cells (NaN for empty and NA cells); ``numeric``: columns whose every
    cell is a number in ``decimal`` as float64 (or int64) columns."""
    import pandas as pd

    if not data_lines:
        return pd.DataFrame({name: pd.Series([], dtype=object) for name in names})
    body = io.StringIO("\n".join(data_lines) + "\n")
    sep = r"\s+" if delimiter == "whitespace" else delimiter
    options = {"decimal": decimal} if numeric else {"dtype": str}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pd.errors.DtypeWarning)
            df = pd.read_csv(body, sep=sep, header=None, names=names, skipinitialspace=True,
                             engine="python" if delimiter == "whitespace" else "c", **options)
    except pd.errors.ParserError as exc:
        raise _file_error(f"unreadable table: {str(exc)[:150]}") from None
    return df


#: Text that is the same in ASCII and in an encoding the fast path reads byte by byte.
_ASCII_PROBE = "azAZ09,;\t|\n\r.#-+eE\" :/"
#: Bytes that make a line non-blank (anything but space, tab, CR, LF).
_NONBLANK = np.ones(256, dtype=bool)
_NONBLANK[[9, 10, 13, 32]] = False


def ascii_compatible(encoding: str) -> bool:
    """True when ``encoding`` writes ASCII text as ASCII bytes (UTF-8, cp1252, latin-1; not UTF-16)."""
    try:
        return _ASCII_PROBE.encode(encoding) == _ASCII_PROBE.encode("ascii")
    except (UnicodeError, LookupError):
        return False


def fast_path(fmt: FileFormat) -> bool:
    """Whether a file in ``fmt`` may take :func:`_read_fast` (the bytes decide the rest: no quotes, LF line ends)."""
    return fmt.format == "delimited" and fmt.delimiter != "whitespace" and ascii_compatible(fmt.encoding)


def _check_encoding(data: bytes, fmt: FileFormat) -> None:
    """Raise the problem of the first byte ``fmt.encoding`` cannot decode, decoding :data:`DECODE_CHUNK` bytes at a
    time (no copy of the whole text); ASCII bytes need no decoding."""
    if data.isascii():
        return
    decoder = codecs.getincrementaldecoder(fmt.encoding)()
    for start in range(0, len(data), DECODE_CHUNK):
        pending = len(decoder.getstate()[0])
        try:
            decoder.decode(data[start:start + DECODE_CHUNK], final=start + DECODE_CHUNK >= len(data))
        except UnicodeDecodeError as exc:
            at = start - pending + exc.start
            raise _decode_problem(data, UnicodeDecodeError(exc.encoding, data, at, at + 1, exc.reason), fmt) from None


def _next_line(data: bytes, pos: int, encoding: str) -> tuple[str, int]:
    """(the line at ``pos`` without its line end, the position after it)."""
    end = data.find(b"\n", pos)
    end = len(data) if end < 0 else end
    line = data[pos:end].decode(encoding)
    return (line[:-1] if line.endswith("\r") else line), end + 1


def _line_checks(body: bytes, start: int, delimiter: str, n_fields: int,
                 stop: int | None = None) -> tuple[int, tuple[int, int] | None]:
    """(non-blank lines, (byte offset, data row) of the first one whose field count differs from ``n_fields``, or
    None) of the data lines in ``body[start:stop]``, by numpy over :data:`DECODE_CHUNK` bytes at a time (whole
    lines): no Python object per line, memory bounded by the chunk."""
    pos, rows = start, 0
    stop = len(body) if stop is None else stop
    sep = ord(delimiter)
    while pos < stop:
        end = body.find(b"\n", min(pos + DECODE_CHUNK, stop) - 1, stop)
        end = stop if end < 0 else end + 1
        piece = np.frombuffer(body, dtype=np.uint8, count=end - pos, offset=pos)
        starts = np.concatenate([[0], np.flatnonzero(piece == 10) + 1])
        starts = starts[starts < piece.size]
        nonblank = np.logical_or.reduceat(_NONBLANK[piece], starts)
        seps = np.flatnonzero(piece == sep)
        fields = np.diff(np.searchsorted(seps, np.append(starts, piece.size))) + 1
        bad = np.flatnonzero(nonblank & (fields != n_fields))
        if bad.size:
            i = int(bad[0])
            return rows + int(nonblank.sum()), (pos + int(starts[i]), rows + int(nonblank[:i].sum()))
        rows += int(nonblank.sum())
        pos = end
    return rows, None



def _whole_table(frame: pd.DataFrame, n_rows: int, ends_in_newline: bool, units: dict, decimal: str
                 ) -> RawTable | None:
    """The fast readers' table when it holds every data row (None: the careful reader must look), with the
    note for a last row without a line end."""
    if len(frame) != n_rows:
        return None
    notes = []
    if n_rows and not ends_in_newline:
        notes.append(f"no line end after the last row ({n_rows - 1}): it may be cut off in its last value")
    return RawTable(frame=frame, units=units, rows=np.arange(n_rows, dtype="int64"), warnings=notes, decimal=decimal)

def _read_fast(path: Path, fmt: FileFormat, declared: FileFormat | None, numeric: bool) -> RawTable | None:
    """:func:`read_delimited` without a Python object per line (module doc), or None when the bytes need the
    line-by-line reader (quotes, CR without LF, a row count pandas reads otherwise). Same checks, same
    messages, same cells. The bytes are checked in memory, then dropped, and pandas reads the data rows from
    the file itself."""
    import pandas as pd

    data = _read_bytes(path, fmt)
    skip = Path(path).stat().st_size - len(data)       # a byte-order mark dropped
    if b'"' in data or data.count(b"\r") != data.count(b"\r\n"):
        return None
    _check_encoding(data, fmt)
    content, ends, pos, sep_checked = [], [], 0, False      # the first lines: a preamble, the header and data
    while pos < len(data) and len(content) < MAX_PREAMBLE_ROWS + 4:
        at = pos
        line, pos = _next_line(data, pos, fmt.encoding)
        if line.strip() and not sep_checked:
            _check_sep(line, fmt)
            sep_checked = True
        if _content_line(line):
            content.append((data.count(b"\n", 0, at), line))
            ends.append((at, pos))
    if not content:
        raise _file_error("no header row" if fmt.header == "row" else "no data rows")
    k = _start(content, fmt)
    notes = _preamble_note(content[:k], fmt.header == "row")
    names = _names([line for _, line in content], k, fmt, declared)
    pos = ends[k][1] if fmt.header == "row" else ends[k][0]
    units: dict[str, str] = {}
    if fmt.units_row:
        line = ""
        while pos < len(data) and not line.strip():
            line, pos = _next_line(data, pos, fmt.encoding)
        if not line.strip():
            raise _file_error("no units row under the header (the manifest's csv block sets units_row: true)")
        units = _units(names, line, fmt.delimiter)
    ends_in_newline = data.endswith(b"\n") or pos >= len(data)
    n_rows, bad = _line_checks(data, pos, fmt.delimiter, len(names))
    cut = None if ends_in_newline else _cut_last(data, fmt, len(names), n_rows, bad)
    if bad is not None and cut is None:
        line, after = _next_line(data, bad[0], fmt.encoding)
        if ragged_marker(_split(line, fmt.delimiter), _reference_at(data, pos, fmt, len(names)), fmt.decimal):
            return None         # marker rows of another width: the careful reader leaves them out
        last = after >= len(data) or not data[after:].strip()
        raise _field_count_problem(names, bad[1], _split(line, fmt.delimiter), last, ends_in_newline, fmt.delimiter)
    if cut is not None:
        n_rows, notes, ends_in_newline = n_rows - 1, notes + [_cut_note(n_rows - 1, cut, len(names))], True
    del data
    if n_rows == 0:
        return RawTable(frame=_frame([], names, fmt.delimiter), units=units, rows=np.arange(0, dtype="int64"),
                        warnings=notes, decimal=fmt.decimal)
    options = {"decimal": fmt.decimal} if numeric else {"dtype": str}
    try:
        with warnings.catch_warnings():      # a column numeric in one chunk, text in another: mixed, as documented
            warnings.simplefilter("ignore", pd.errors.DtypeWarning)
            with open(path, "rb") as handle:
                handle.seek(skip + pos)
                frame = pd.read_csv(handle, sep=fmt.delimiter, header=None, names=names, skipinitialspace=True,
                                    engine="c", encoding=fmt.encoding, nrows=n_rows, **options)
    except (pd.errors.ParserError, ValueError, OSError):
        return None
    table = _whole_table(frame, n_rows, ends_in_newline, units, fmt.decimal)
    if table is None:
        return None
    return _finish(table.frame, table.rows, names, fmt.decimal, numeric, notes + table.warnings, [], units)


def _start(content: list[tuple[int, str]], fmt: FileFormat) -> int:
    """Index in ``content`` ((line, text) of non-blank, non-comment lines) of the header row, or of a headerless
    file's first data row (:func:`isokinetic.rawlayout.find_start`)."""
    try:
        split = [_split(line, fmt.delimiter) for _, line in content[:MAX_PREAMBLE_ROWS + 4]]
    except csv.Error:
        return 0
    return find_start(split, fmt.header == "row", fmt.units_row, fmt.decimal)


def _finish(frame: pd.DataFrame, rows: np.ndarray, names: list[str], fmt_decimal: str, numeric: bool,
            notes: list[str], ragged: list[tuple[int, list[str]]], units: dict[str, str]) -> RawTable:
    """The table with its marker rows (:func:`isokinetic.rawlayout.marker_rows`; ``ragged``: (row, fields) of marker
    rows already left out for their field count) left out and noted; ``numeric``: columns that held a marker's
    text are numbers again."""
    import pandas as pd

    drop = marker_rows(frame, names, fmt_decimal)
    found = sorted([(int(rows[i]), _texts(frame.iloc[i], fmt_decimal)) for i in drop]
                   + [(r, _texts(fields, fmt_decimal)) for r, fields in ragged])
    if drop.size:
        keep = np.ones(len(frame), dtype=bool)
        keep[drop] = False
        frame, rows = frame[keep].reset_index(drop=True), rows[keep]
        for name in names if numeric and fmt_decimal == "." else ():
            if frame[name].dtype == object:
                converted = pd.to_numeric(frame[name], errors="coerce")
                if not (converted.isna() & frame[name].notna()).any():
                    frame[name] = converted
    if found:
        notes = notes + [f"skipped {len(found)} marker row(s) without a sample (text inside the data): data rows "
                         f"{_listed(r for r, _ in found)}, the first {found[0][1][:MAX_QUOTED]!r}"]
    return RawTable(frame=frame, units=units, rows=rows.astype("int64"), warnings=notes, decimal=fmt_decimal)


def _reference(rows: list[tuple[int, str]], names: list[str], delimiter: str) -> list[str] | None:
    """The first data row of the header's width, split (what a marker row's text is compared with)."""
    for _, line in rows:
        fields = _split(line, delimiter)
        if len(fields) == len(names):
            return fields
    return None


def _reference_at(data: bytes, pos: int, fmt: FileFormat, width: int) -> list[str] | None:
    """:func:`_reference` on the bytes from ``pos`` (the first data row)."""
    while pos < len(data):
        line, pos = _next_line(data, pos, fmt.encoding)
        fields = _split(line, fmt.delimiter) if line.strip() else []
        if len(fields) == width:
            return fields
    return None


def _names(lines: list[str], at: int, fmt: FileFormat, declared: FileFormat | None) -> list[str]:
    """The header's column names (checked: another delimiter, names twice, numbers like the data), or a
    headerless file's ``col1`` .. ``colN``."""
    names = _split(lines[at], fmt.delimiter)
    if fmt.header == "none":
        return _positional(len(names))
    if len(names) == 1:
        problem = _delimiter_problem(lines[at], declared)
        if problem is not None:
            raise problem
    if all_numbers(names, fmt.decimal):
        raise _headerless_problem(lines[at])
    return _check_names(names)


def read_delimited(path: Path, fmt: FileFormat | None = None, numeric: bool = False) -> RawTable:
    """A delimited text file (``fmt=None``: the format's ',' and '.' with no ``csv`` block, as before 1.1): a
    preamble before the header and marker rows inside the data are skipped with a note (1.4)."""
    declared = fmt
    fmt = fmt or FileFormat()
    _, lines = _text(path, fmt)
    lines, ends_in_newline = _lines(lines)
    _check_sep(next((line for line in lines if line.strip()), ""), fmt)
    content = [(i, line) for i, line in enumerate(lines) if _content_line(line)]
    if not content:
        raise _file_error("no header row" if fmt.header == "row" else "no data rows")
    k = _start(content, fmt)
    header, notes = content[k][0], _preamble_note(content[:k], fmt.header == "row")
    names = _names(lines, header, fmt, declared)
    start, units = header + (fmt.header == "row"), {}
    if fmt.units_row:
        unit_at = next((i for i in range(start, len(lines)) if lines[i].strip()), None)
        if unit_at is None:
            raise _file_error("no units row under the header (the manifest's csv block sets units_row: true)")
        units = _units(names, lines[unit_at], fmt.delimiter)
        start = unit_at + 1
    rows = _data_lines(lines, start)
    if fmt.delimiter == "whitespace":
        split_rows = (_split(line, "whitespace") for _, line in rows)
    else:
        split_rows = csv.reader([line for _, line in rows], delimiter=fmt.delimiter)
    ragged, kept, reference, tail, cut = [], [], None, (None, None), None
    try:
        for (row, line), fields in zip(rows, split_rows):
            if len(fields) == len(names):
                kept.append((row, line))
                reference, tail = reference or fields, (tail[1], fields)
            elif ragged_marker(fields, reference or _reference(rows, names, fmt.delimiter), fmt.decimal):
                ragged.append((row, fields))
            elif len(fields) < len(names) and row == len(rows) - 1 and not ends_in_newline:
                cut = (row, fields)             # a rig that stopped while writing: the row is left out
            else:
                raise _field_count_problem(names, row, fields, row == len(rows) - 1, ends_in_newline, fmt.delimiter)
    except csv.Error as exc:
        at = min(max(getattr(split_rows, "line_num", 1) - 1, 0), len(rows) - 1)
        raise _csv_problem(exc, names, at, rows[at][1], fmt.delimiter) from None
    if rows and not ends_in_newline and cut is None:
        last = kept and kept[-1][0] == rows[-1][0] and cut_off_last(tail[1], tail[0], fmt.decimal)
        cut = (kept.pop()[0], tail[1]) if last else None
        notes += [] if last else [f"no line end after the last row ({rows[-1][0]}): it may be cut off in its last "
                                  "value"]
    notes += [] if cut is None else [_cut_note(cut[0], cut[1], len(names))]
    frame = _frame([line for _, line in kept], names, fmt.delimiter, numeric, fmt.decimal)
    return _finish(frame, np.array([r for r, _ in kept], dtype="int64"), names, fmt.decimal, numeric, notes, ragged,
                   units)


def _content_line(line: str) -> bool:
    """A line that may be the header or a data row: not blank, no ``#`` comment, no Excel ``sep=`` line."""
    return bool(line.strip()) and not line.startswith("#") and excel_sep(line) is None


def _check_sep(first: str, fmt: FileFormat) -> None:
    """Refuse a file whose Excel ``sep=X`` first line names another delimiter than ``fmt``'s."""
    problem = sep_problem(first, fmt.delimiter)
    if problem is not None:
        raise problem


def mts_decimal(first_line: str) -> str:
    """The decimal mark of an MTS 793 export: the sixth ``|`` field of its first line
    (``MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A`` -> ``.``)."""
    fields = first_line.strip().split("|")
    if len(fields) < 6 or fields[5] not in DECIMALS:
        raise _file_error(f"MTS 793 first line {first_line[:80]!r} does not give the decimal mark "
                          "(sixth '|' field: '.' or ',')")
    return fields[5]


def _read_mts793_fast(path: Path, fmt: FileFormat, numeric: bool) -> RawTable | None:
    """:func:`read_mts793` without a Python object per line (as :func:`_read_fast`): the blocks are found and checked
    on the bytes, their data rows joined and parsed by pandas' C parser. None when the file needs the line-by-line
    reader: whitespace-separated, rows ending with a tab, quotes, lone CRs, or any problem (that reader names it)."""
    import pandas as pd

    data = _read_bytes(path, fmt)
    if b'"' in data or data.count(b"\r") != data.count(b"\r\n") or b"\t\n" in data or b"\t\r\n" in data:
        return None
    _check_encoding(data, fmt)
    first, pos = _next_line(data, 0, fmt.encoding)
    if not first.startswith(MTS_MAGIC):
        return None
    decimal = mts_decimal(first)
    marker = b"\n" + MTS_BLOCK.encode(fmt.encoding)
    starts, at = [], data.find(marker, pos - 1)
    while at >= 0:
        starts.append(at + 1)
        at = data.find(marker, at + 1)
    names: list[str] | None = None
    units: dict[str, str] = {}
    regions, n_rows = [], 0
    for k, start in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else len(data)
        _, at = _next_line(data, start, fmt.encoding)           # the block's "Data Acquisition" line
        line = ""
        while at < end and not line.strip():
            line, at = _next_line(data, at, fmt.encoding)
        if at >= end or "\t" not in line:
            return None
        unit_line, at = _next_line(data, at, fmt.encoding)
        if names is None:
            names = _check_names(_split(line, "\t"))
            units = _units(names, unit_line, "\t")
        elif [c.strip() for c in _split(line, "\t")] != names or _units(names, unit_line, "\t") != units:
            return None
        rows, bad = _line_checks(data, min(at, end), "\t", len(names), end)
        if bad is not None:
            return None
        regions.append((min(at, end), end))
        n_rows += rows
    if names is None:
        return None
    ends_in_newline = data.endswith(b"\n")
    joined, at = bytearray(sum(b - a for a, b in regions)), 0       # the blocks' data rows, one copy
    for a, b in regions:
        joined[at:at + b - a] = memoryview(data)[a:b]
        at += b - a
    del data
    options = {"decimal": decimal} if numeric else {"dtype": str}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", pd.errors.DtypeWarning)
            frame = pd.read_csv(io.BufferedReader(_BufferReader(joined)), sep="\t", header=None, names=names,
                                skipinitialspace=True, engine="c", encoding=fmt.encoding, **options)
    except (pd.errors.ParserError, ValueError):
        return None
    return _whole_table(frame, n_rows, ends_in_newline, units, decimal)


def read_mts793(path: Path, fmt: FileFormat, numeric: bool = False) -> RawTable:
    """An MTS 793 / TestSuite text export: its blocks (``Data Acquisition`` line, header, units row, data
    rows) joined into one table; every block must repeat the first block's header and units."""
    _, lines = _text(path, fmt)
    lines, ends_in_newline = _lines(lines)
    lines = [line.rstrip("\t ") for line in lines]     # a controller may end every row with a tab
    if not lines or not lines[0].startswith(MTS_MAGIC):
        raise _file_error(f"not an MTS 793 export: the first line is not {MTS_MAGIC}|... "
                          f"(got {lines[0][:60]!r})" if lines else "no lines")
    decimal = mts_decimal(lines[0])
    names: list[str] | None = None
    units: dict[str, str] = {}
    delimiter = "\t"
    data: list[str] = []
    i, n = 1, len(lines)
    while i < n and not lines[i].startswith(MTS_BLOCK):
        i += 1
    if i == n:
        raise _file_error(f"MTS 793 export without a '{MTS_BLOCK}' block")
    while i < n:
        block_line = i + 1          # 1-based line number of the block's first line
        i += 1
        while i < n and not lines[i].strip():
            i += 1
        if i + 1 >= n:
            raise _file_error(f"block at line {block_line}: no header and units rows")
        if names is None:
            delimiter = "\t" if "\t" in lines[i] else "whitespace"
            names = _check_names(_split(lines[i], delimiter))
            units = _units(names, lines[i + 1], delimiter)
        else:
            here = [c.strip() for c in _split(lines[i], delimiter)]
            if here != names:
                raise _file_error(f"block at line {block_line}: header {' | '.join(here)[:80]!r} differs from the "
                                  f"first block's {' | '.join(names)[:80]!r}")
            if _units(names, lines[i + 1], delimiter) != units:
                raise _file_error(f"block at line {block_line}: units row {lines[i + 1].strip()[:60]!r} differs "
                                  "from the first block's")
        i += 2
        while i < n and not lines[i].startswith(MTS_BLOCK):
            line = lines[i]
            if line.strip():
                try:
                    fields = _split(line, delimiter)
                except csv.Error as exc:
                    raise _csv_problem(exc, names, len(data), line, delimiter) from None
                if len(fields) < len(names) and i == n - 1 and not ends_in_newline:    # a rig stopped writing
                    return _mts_table(data, names, units, delimiter, numeric, decimal,
                                      [_cut_note(len(data), fields, len(names))])
                if len(fields) != len(names):
                    raise _field_count_problem(names, len(data), fields, i == n - 1, ends_in_newline, delimiter)
                data.append(line)
            i += 1
    warnings = []
    if data and not ends_in_newline:
        warnings.append(f"no line end after the last row ({len(data) - 1}): it may be cut off in its last value")
    return _mts_table(data, names, units, delimiter, numeric, decimal, warnings)


def _mts_table(data: list[str], names: list[str], units: dict, delimiter: str, numeric: bool, decimal: str,
               warnings: list[str]) -> RawTable:
    """An MTS 793 export's joined data rows as its table."""
    frame = _frame(data, names, delimiter, numeric, decimal)
    return RawTable(frame=frame, units=units, rows=np.arange(len(frame), dtype="int64"), warnings=warnings,
                    decimal=decimal)


def _sheet_text(value) -> str:
    return "" if value is None else value if isinstance(value, str) else repr(value)


def read_xlsx(path: Path, fmt: FileFormat, numeric: bool = False) -> RawTable:
    """A worksheet of an ``.xlsx`` export (1.4; ``fmt.sheet``, None: the first) read through openpyxl
    (:func:`isokinetic.rawlayout.sheet_rows`, bounded), then as a delimited file is: preamble, header (or
    none), units row, marker rows. Numbers come as the workbook holds them ('.' decimals)."""
    import pandas as pd

    try:
        cells = [[_sheet_text(v) for v in row] for row in sheet_rows(path, fmt.sheet)]
    except SheetError as exc:
        raise _file_error(str(exc)) from None
    if not cells:
        raise _file_error(f"worksheet {fmt.sheet or '(the first)'} holds no cells")
    k = find_start(cells[:MAX_PREAMBLE_ROWS + 4], fmt.header == "row", fmt.units_row)
    notes = _preamble_note([(i, " ".join(r)) for i, r in enumerate(cells[:k])], fmt.header == "row")
    if fmt.header == "none":
        names, start = _positional(max(len(r) for r in cells[k:])), k
    else:
        if all_numbers(cells[k]):
            raise _headerless_problem(",".join(cells[k]))
        names, start = _check_names(cells[k]), k + 1
    units = {}
    if fmt.units_row:
        if start >= len(cells):
            raise _file_error("no units row under the header (the manifest's csv block sets units_row: true)")
        units, start = _units(names, "\t".join(cells[start]), "\t"), start + 1
    data = cells[start:]
    wide = next((i for i, r in enumerate(data) if len(r) > len(names)), None)
    if wide is not None:
        raise _file_error(f"row {wide} has {len(data[wide])} cells, the header {len(names)}")
    frame = pd.DataFrame([r + [""] * (len(names) - len(r)) for r in data], columns=names, dtype=object)
    frame = frame.mask(frame.map(lambda v: not str(v).strip()))
    if numeric:
        for name in names:
            converted = pd.to_numeric(frame[name], errors="coerce")
            if not (converted.isna() & frame[name].notna()).any():
                frame[name] = converted
    return _finish(frame, np.arange(len(frame), dtype="int64"), names, ".", numeric, notes, [], units)


def read_raw_table(path: str | Path, fmt: FileFormat | None = None, numeric: bool = False) -> RawTable:
    """One case file read in ``fmt`` (None: the format's default CSV, ',' and '.', as without a ``csv``
    block); raises :class:`RawFileError` naming row and column. ``numeric``: columns whose every cell is a
    number (in the file's decimal mark) come as float64 (or int64) columns instead of text, which needs a
    fraction of the memory (the rest stay text); without it every cell is text."""
    path = Path(path)
    try:
        if fmt is not None and fmt.format == "xlsx":
            return read_xlsx(path, fmt, numeric)
        if fmt is not None and fmt.format == "mts793":
            table = _read_mts793_fast(path, fmt, numeric) if ascii_compatible(fmt.encoding) else None
            return table if table is not None else read_mts793(path, fmt, numeric)
        if fmt is None or fast_path(fmt):
            table = _read_fast(path, fmt or FileFormat(), fmt, numeric)
            if table is not None:
                return table
        return read_delimited(path, fmt, numeric)
    except csv.Error as exc:
        raise _file_error(f"unreadable table: {str(exc)[:150]}") from None


def sniff_format(path: str | Path, notes: list[str] | None = None, sheet: str | None = None) -> FileFormat:
    """A guess at a file's :class:`FileFormat`: ``mts793`` from a first line ``MTS793|...``; encoding UTF-8
    (UTF-16/32 from a byte-order mark), else cp1252 (with a note appended to ``notes``); the delimiter that
    splits the header and the next lines into the same number (> 1) of fields (``whitespace`` last); a
    decimal comma when numbers hold ',' and no '.'; a units row when the row under the header is text; ``header:
    none`` (1.4) when the first row (after any preamble) is numbers like the rest. An ``.xlsx`` file is ``xlsx``,
    worksheet ``sheet`` (None: the first), its header and units row found by the same rules."""
    if Path(path).suffix.lower() == ".xlsx":
        try:
            rows = [[_sheet_text(v) for v in row] for row in sheet_rows(path, sheet)]
        except SheetError as exc:
            raise _file_error(str(exc)) from None
        _, headerless, units_row = row_layout(rows) if rows else (0, False, False)
        return FileFormat(format="xlsx", units_row=units_row, header="none" if headerless else "row", sheet=sheet)
    data = Path(path).read_bytes()
    encoding = "utf-8"
    for bom, name in FOREIGN_BOMS.items():
        if data.startswith(bom):
            encoding = name.lower().replace("utf-", "utf-")
            break
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError:
        encoding = "cp1252"
        text = data.decode(encoding, errors="replace")
        if notes is not None:
            notes.append(f"{Path(path).name}: not UTF-8; read as cp1252 (set `encoding:` in the csv block if "
                         "it is another)")
    text = text.lstrip("\ufeff")
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")        # lone CRs end lines too
    if lines and lines[0].startswith(MTS_MAGIC):
        try:
            decimal = mts_decimal(lines[0])
        except RawFileError:
            decimal = "."
        block = next((i for i, line in enumerate(lines) if line.startswith(MTS_BLOCK)), None)
        header = next((line for line in lines[block + 1:] if line.strip()), "") if block is not None else ""
        return FileFormat(format="mts793", delimiter="\t" if "\t" in header or not header else "whitespace",
                          decimal=decimal, encoding=encoding, units_row=True)
    content = [line for line in lines if _content_line(line)][:MAX_PREAMBLE_ROWS + 20]
    if not content:
        return FileFormat(encoding=encoding)
    named = excel_sep(next((line for line in lines if line.strip()), ""))       # Excel's sep=; first line
    delimiter = named or ","
    for lines_ in () if named else (content[:20], content[-min(10, max(1, len(content) // 2)):]):  # or the last
        found = next((c for c in (",", ";", "\t", "|", "whitespace")
                      if len(counts := {len(_split(line, c)) for line in lines_}) == 1 and counts.pop() > 1), None)
        if found is not None:
            delimiter = found
            break
    rows = [_split(line, delimiter) for line in content]
    k, headerless, units_row = row_layout(rows)
    names_n = len(rows[k])
    rows = rows[k + (not headerless):]
    cells = [c.strip() for r in rows[1 if units_row else 0:] for c in r if len(r) == names_n]
    decimal = "."
    if delimiter != "," and any(re.fullmatch(r"[+-]?\d+,\d+(?:[eE][+-]?\d+)?", c) for c in cells) \
            and not any(re.fullmatch(r"[+-]?\d*\.\d+(?:[eE][+-]?\d+)?", c) for c in cells):
        decimal = ","
    return FileFormat(delimiter=delimiter, decimal=decimal, encoding=encoding, units_row=units_row,
                      header="none" if headerless else "row")
