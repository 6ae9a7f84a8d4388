"""A case file's columns read as numbers or time stamps (:func:`parse_column`, used by the survey and the
check), and the worksheet of a spreadsheet export (:func:`xlsx_format`: the first, or the only one holding
numeric data). The file's format is sniffed by :func:`isokinetic.rawfile.sniff_format` and the file read by
:func:`isokinetic.rawfile.read_raw_table`, ingest's own reader with every hostile-input check, so a file the
draft accepts is a file ingest reads.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.rawfile import FileFormat, RawFileError, SheetError, all_numbers, sheet_rows, sniff_format
from isokinetic.stages.ingest import decimal_point
from isokinetic.stages.validate import MIN_SAMPLES
from isokinetic.timestamps import TIME_STAMPS, hms_seconds, iso_seconds, looks_hms


@dataclass(frozen=True)
class ColumnData:
    """One column of a case file: numbers (NaN where a cell is not one), or seconds from ISO 8601 stamps or clock
    times (``time_unit``: ``datetime`` or ``hms``); ``problem``: why a column of stamps gives no time axis (a
    daylight-saving step back of local stamps), "" when none."""

    name: str
    numbers: np.ndarray | None      # None when most cells are not numbers
    stamps_s: np.ndarray | None     # seconds from the first stamp when the cells are ISO 8601 stamps or clock times
    numeric_fraction: float
    rows: int = 0
    time_unit: str | None = None
    problem: str = ""


def parse_column(name: str, raw: pd.Series, decimal: str) -> ColumnData:
    """A column of text cells as numbers (decimal mark ``decimal``; thousands separators where unambiguous,
    :func:`isokinetic.stages.ingest.decimal_point`), as clock times ``HH:MM:SS.fff`` or as ISO 8601 time stamps
    (:mod:`isokinetic.timestamps`: local stamps stepping back an hour are no time axis, ``problem`` says why)."""
    text = decimal_point(raw, decimal)
    numbers = pd.to_numeric(text, errors="coerce").to_numpy(float)
    filled = max(int(raw.notna().sum()), 1)
    fraction = float(np.isfinite(numbers).sum()) / filled
    if fraction >= 0.99:
        return ColumnData(name, numbers, None, fraction, len(raw))
    if len(raw) and raw.notna().all() and looks_hms(raw):
        return ColumnData(name, None, hms_seconds(raw), fraction, len(raw), "hms")
    stamps_text = raw if decimal == "." else raw.astype(object).str.replace(",", ".", regex=False)
    seconds, problem = iso_seconds(stamps_text) if len(raw) and raw.notna().all() else (np.empty(0), None)
    if len(raw) and seconds.size and np.isfinite(seconds).all():
        if problem is not None:
            return ColumnData(name, None, None, fraction, len(raw), TIME_STAMPS, f"row {problem[0]}: {problem[1]}")
        return ColumnData(name, None, seconds, fraction, len(raw), TIME_STAMPS)
    return ColumnData(name, None, None, fraction, len(raw))


def numeric_rows(rows: list[list]) -> int:
    """How many rows of a worksheet hold two or more cells and only numbers (samples, not a summary's text)."""
    return sum(len(r) >= 2 and all_numbers(["" if v is None else str(v) for v in r]) for r in rows)


def sheet_names(path: Path) -> list[str]:
    """The worksheets of an ``.xlsx`` workbook, in order (openpyxl, imported here: a heavy import). Call it after
    :func:`isokinetic.rawfile.sheet_rows` has read the workbook once (its size and unpacking bounds checked)."""
    import openpyxl

    book = openpyxl.load_workbook(path, read_only=True)
    try:
        return list(book.sheetnames)
    finally:
        book.close()


def xlsx_format(path: Path, notes: list[str]) -> FileFormat:
    """The format of an ``.xlsx`` export: its first worksheet when that holds at least MIN_SAMPLES rows of numbers
    (``sheet`` left out: the first, whatever each file names it), else the only worksheet that does (named);
    raises :class:`RawFileError` when none or several do (then a person names the sheet)."""
    try:
        if numeric_rows(sheet_rows(path)) >= MIN_SAMPLES:
            return sniff_format(path, notes)
        names = sheet_names(path)
        numeric = [name for name in names[1:] if numeric_rows(sheet_rows(path, name)) >= MIN_SAMPLES]
    except SheetError as exc:
        raise RawFileError("file", str(exc), kind="key") from None
    if len(numeric) != 1:
        said = "none does" if not numeric else f"{', '.join(map(repr, numeric))} do"
        raise RawFileError("file", f"the first worksheet {names[0]!r} holds no rows of numbers and {said} of the "
                           f"others ({', '.join(map(repr, names))}): name the sheet in the csv block (`sheet:`)",
                           kind="key")
    notes.append(f"{path.name}: worksheet {numeric[0]!r}, the only one holding rows of numbers")
    return sniff_format(path, notes, sheet=numeric[0])
