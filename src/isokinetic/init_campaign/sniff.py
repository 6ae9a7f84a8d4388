"""A case file's columns read as numbers or time stamps (:func:`parse_column`, used by the survey and the
check). The file's format is sniffed by :func:`isokinetic.rawfile.sniff_format` and the file read by
:func:`isokinetic.rawfile.read_raw_table`, ingest's own reader with every hostile-input check, so a file the
draft accepts is a file ingest reads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.stages.ingest import decimal_point


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
