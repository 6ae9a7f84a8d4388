"""A case file's columns read as numbers or time stamps (:func:`parse_column`, used by the survey and the
check); and the format 1.1 dialect sniffer (the survey now uses :func:`isokinetic.rawfile.sniff_format`).

The delimiter is the one of :data:`isokinetic.contracts.manifest.CSV_DELIMITERS` (',' ';' tab '|') that splits
the header and every sampled data row into the same number of fields (two or more; the most fields wins a
tie). The decimal mark is ',' when numbers such as ``-0,25`` appear and none such as ``-0.25`` (only possible
with another delimiter than ','). Lines before the header that start with ``#`` are comments. The columns are
then read by ingest's own reader (:func:`isokinetic.stages.ingest.read_case_csv`, with every hostile-input
check), so a file the draft accepts is a file ingest reads.
"""

from __future__ import annotations

import codecs
import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.manifest import CSV_DELIMITERS, CsvDialect
from isokinetic.stages.ingest import FOREIGN_BOMS, decimal_point, read_case_csv

#: Bytes read to sniff a file (its comments, header and first rows).
SNIFF_BYTES = 256 * 1024
#: Data rows sampled for the delimiter and the decimal mark.
SNIFF_ROWS = 200
#: Fraction of the sampled rows that may split differently from the header (ragged, cut off).
RAGGED_FRACTION = 0.1
#: A number written with a decimal comma: ``-0,25``, ``1,5E-3``.
DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d+(?:[eE][+-]?\d+)?")
#: A number written with a decimal point: ``-0.25``, ``.5``, ``1.5e-3``.
DECIMAL_POINT = re.compile(r"[+-]?\d*\.\d+(?:[eE][+-]?\d+)?")
#: Words used for each delimiter in the draft's comments.
DELIMITER_WORDS = {",": "','", ";": "';'", "\t": "tabs", "|": "'|'", "whitespace": "whitespace"}


class SniffError(ValueError):
    """A file whose dialect or header cannot be found."""


@dataclass(frozen=True)
class Sniffed:
    """What the first lines of a case file say: dialect, comment lines before the header, header names."""

    dialect: CsvDialect
    comments: tuple[str, ...]
    header: tuple[str, ...]
    rows_sampled: int
    decimal_note: str = ""

    @property
    def default_dialect(self) -> bool:
        return self.dialect == CsvDialect()


def _lines(text: str) -> list[str]:
    if "\n" not in text and "\r" in text:
        text = text.replace("\r", "\n")
    return [line[:-1] if line.endswith("\r") else line for line in text.split("\n")]


def _field_counts(lines: list[str], delimiter: str) -> list[int]:
    return [len(fields) for fields in csv.reader(lines, delimiter=delimiter)]


def sniff_delimiter(header: str, rows: list[str]) -> str:
    """The delimiter that splits the header and the rows into the same number (>= 2) of fields (all rows but
    one or :data:`RAGGED_FRACTION` of them: a ragged or cut-off row is ingest's to report, naming it)."""
    best, best_fields = None, 1
    for delimiter in CSV_DELIMITERS:
        counts = _field_counts([header] + rows, delimiter)
        same = sum(c == counts[0] for c in counts[1:])
        ragged = max(1, int(RAGGED_FRACTION * len(rows)))
        if counts[0] >= 2 and same >= len(rows) - ragged and counts[0] > best_fields:
            best, best_fields = delimiter, counts[0]
    if best is None:
        tried = ", ".join(DELIMITER_WORDS[d] for d in CSV_DELIMITERS)
        raise SniffError(f"no delimiter ({tried}) splits the header {header[:80]!r} and the first rows into the "
                         "same number of fields (two or more)")
    return best


def sniff_decimal(rows: list[str], delimiter: str) -> tuple[str, str]:
    """('.' or ',', note) from the data fields: ',' only when decimal commas appear and decimal points do not."""
    if delimiter == ",":
        return ".", ""
    commas = points = 0
    for fields in csv.reader(rows, delimiter=delimiter):
        for field in fields:
            field = field.strip()
            commas += bool(DECIMAL_COMMA.fullmatch(field))
            points += bool(DECIMAL_POINT.fullmatch(field))
    if commas and points:
        return (",", f"{commas} numbers with a decimal comma and {points} with a point: decimal comma assumed, "
                     "the others will be refused by ingest") if commas > points else \
               (".", f"{points} numbers with a decimal point and {commas} with a comma: decimal point assumed")
    return ("," if commas else "."), ""


def sniff_text(text: str) -> Sniffed:
    """Dialect, comments and header of a case file's text (its first lines suffice)."""
    lines = _lines(text)
    header_at = next((i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")), None)
    if header_at is None:
        raise SniffError("no header row (the file holds only blank or '#' comment lines)")
    comments = tuple(line for line in lines[:header_at] if line.startswith("#"))
    rows = [line for line in lines[header_at + 1:] if line.strip()]
    if len(text) >= SNIFF_BYTES and rows:
        rows = rows[:-1]          # the last line read may be cut off
    rows = rows[:SNIFF_ROWS]
    delimiter = sniff_delimiter(lines[header_at], rows)
    decimal, note = sniff_decimal(rows, delimiter)
    header = tuple(name.strip() for name in next(csv.reader([lines[header_at]], delimiter=delimiter)))
    return Sniffed(CsvDialect(delimiter=delimiter, decimal=decimal), comments, header, len(rows), note)


def sniff_file(path: str | Path) -> Sniffed:
    """:func:`sniff_text` of a file's first :data:`SNIFF_BYTES` (UTF-8, a byte-order mark skipped)."""
    with open(path, "rb") as fh:
        data = fh.read(SNIFF_BYTES)
    for bom, encoding in FOREIGN_BOMS.items():
        if data.startswith(bom):
            raise SniffError(f"{encoding} byte-order mark: the file is {encoding}, the format needs UTF-8")
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(data) - 4:        # not a character cut at the end of what was read
            line = data.count(b"\n", 0, exc.start) + 1
            raise SniffError(f"not UTF-8: byte 0x{data[exc.start]:02x} in line {line}") from None
        text = data[:exc.start].decode("utf-8")
    return sniff_text(text)


@dataclass(frozen=True)
class ColumnData:
    """One column of a case file: numbers (NaN where a cell is not one), or seconds from ISO 8601 stamps."""

    name: str
    numbers: np.ndarray | None      # None when most cells are not numbers
    stamps_s: np.ndarray | None     # seconds from the first stamp when the cells are ISO 8601 stamps
    numeric_fraction: float
    rows: int = 0


def parse_column(name: str, raw: pd.Series, decimal: str) -> ColumnData:
    """A column of text cells as numbers (decimal mark ``decimal``) or as ISO 8601 time stamps."""
    text = raw if decimal == "." else decimal_point(raw)
    numbers = pd.to_numeric(text, errors="coerce").to_numpy(float)
    filled = max(int(raw.notna().sum()), 1)
    fraction = float(np.isfinite(numbers).sum()) / filled
    if fraction >= 0.99:
        return ColumnData(name, numbers, None, fraction, len(raw))
    stamps_text = raw if decimal == "." else raw.astype(object).str.replace(",", ".", regex=False)
    stamps = pd.to_datetime(stamps_text, format="ISO8601", utc=True, errors="coerce")
    if len(raw) and stamps.notna().all():
        seconds = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(float)
        return ColumnData(name, None, seconds, fraction, len(raw))
    return ColumnData(name, None, None, fraction, len(raw))


def read_columns(path: str | Path, dialect: CsvDialect, warnings: list[str] | None = None) -> dict[str, ColumnData]:
    """Every column of a case file under ``dialect``, read by ingest's reader (raises
    :class:`isokinetic.stages.ingest.CaseFileError` with ingest's reason for a file it would refuse)."""
    table = read_case_csv(path, warnings, dialect)
    return {str(name): parse_column(str(name), table[name], dialect.decimal) for name in table.columns}
