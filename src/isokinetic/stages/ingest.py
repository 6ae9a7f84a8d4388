"""Raw ingest: ``data/raw/<campaign>/`` (campaign.yaml + one CSV per case) to ``<campaign_root>/ingest/``.

Each case CSV is mapped to the canonical SI time series (``row``, ``time_s``,
``displacement_m``, ``force_N``, ``command_m``). A case whose file or columns are unusable is
quarantined (stage ``ingest``) and every other case carries on; a broken manifest raises
:class:`isokinetic.contracts.manifest.ManifestError`. Raw files are only ever opened for reading.

A manifest's ``gas_force_N`` (format 1.1) is subtracted from every force sample here, at the edge
where the force becomes SI, and recorded in ``campaign.json`` (``gas_force_N``, null when none): every
stage downstream sees the damper's force alone.

A manifest's ``csv`` block (format 1.1, e.g. ``{delimiter: ";", decimal: ","}``, a spreadsheet export)
sets the delimiter every check of :func:`read_case_table` splits on and the decimal mark :func:`to_si`
reads; it is recorded in ``campaign.json`` (``csv``, null when none). The same data in either dialect
gives the same SI series, bit for bit. With a decimal comma, a value holding a '.' is refused, naming
row and column: ``1.234,5`` (thousands separator) or ``1.5`` (a '.' file declared ',') could otherwise
be misread by a factor of 1000. Without a ``csv`` block, files are read exactly as before 1.1.

Format 1.2 (docs/raw-campaign-format.md): files are read by :func:`isokinetic.rawfile.read_raw_table` in the
manifest's format (an MTS 793 export, an encoding, a units row, checked against the manifest's units by
:func:`units_problems`); a case may be a slice of its file (``time_range_s`` / ``rows``: its time re-zeroed at
the slice's first sample, ``row`` keeping the file's data-row numbers, ``slice_start_s``, ``row_start`` and
``row_stop`` in cases.parquet); a case's own ``gas_force_N`` overrides the campaign's (recorded per case);
a file shared by several cases is hashed and read once (:class:`FileCache`); the manifest's near-miss key
warnings are logged and recorded in campaign.json (``warnings``).

A case that parses but fails the time-series schema (NaN/inf, time not increasing) is
quarantined here too, naming the CSV column: ``campaign.write_ingested`` only accepts
schema-valid series.

Hostile input (issue 20; docs/hostile-input.md): a case file above ``max_case_file_MB`` is not read; any reader
failure costs its case, with a reason of at most :data:`MAX_REASON_CHARS` characters; a number beyond a float's
range is named as such; a sample beyond a declared ``full_scale`` (x 100) or :data:`PHYSICAL_LIMITS`, or a piston
speed beyond :data:`MAX_SPEED_M_S`, sets its case aside naming the row; a record spanning more than
:data:`MAX_RECORD_SPAN_FACTOR` times its plan's need is trimmed with a note; cases sharing one record are warned
about (campaign.json ``warnings``); the outcome is logged once the results are written. Files are read with
numbers as float64 columns (``numeric=True``), and a file's table is dropped after its last case.
"""

from __future__ import annotations

import csv
import dataclasses
import logging
import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import timeseries_relpath, write_ingested
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.campaign_meta import RAW_INGEST_KEYS, CampaignMeta
from isokinetic.contracts.manifest import (
    CHANNEL_DIMENSIONS,
    FULL_SCALE_FACTOR,
    MANIFEST_NAME,
    TEMPERATURE_RANGE_C,
    TIME_STAMPS,
    CaseSpec,
    Column,
    Manifest,
    channel_unit,
    load_manifest,
    si_conversion,
)
from isokinetic.contracts.problem import Problem
from isokinetic.contracts.settings import DEFAULTS, Settings
from isokinetic.io import jsonable, sha256_file
from isokinetic.rawfile import FOREIGN_BOMS as FOREIGN_BOMS  # re-exported for init_campaign
from isokinetic.rawfile import FileFormat, RawFileError, RawTable, read_raw_table
from isokinetic.stages.validate import quarantine_frame, quarantine_rows, timeseries_problems
from isokinetic.timestamps import TIME_TEXT_UNITS, time_seconds
from isokinetic.units import UnitError, parse_unit, unit_in_name

log = logging.getLogger("isokinetic")

#: Channel -> canonical column of the ingested time series.
CANONICAL = {"time": "time_s", "displacement": "displacement_m", "force": "force_N", "command": "command_m",
             "temperature": "temperature_C"}
#: What no damper rig produces, whatever the manifest declares (SI): a sample beyond sets its case aside, naming
#: the row. Force 10 MN; displacement and command 10 m; piston speed between two samples 100 m/s.
PHYSICAL_LIMITS = {"force_N": 1.0e7, "displacement_m": 10.0, "command_m": 10.0}
MAX_SPEED_M_S = 100.0
#: A record whose time axis spans more than this many times its plan's need (the longer of ``duration_s`` and
#: the plan's required record, or of its samples at the planned rate) is trimmed there, with a note: a broken last
#: time stamp (1e308 s, a year typo in an ISO stamp) must not make later stages work over centuries of record.
MAX_RECORD_SPAN_FACTOR = 10.0
#: A partial record (issue 34): rows with a blank or unreadable cell, or repeating the time stamp before, are left
#: out when they are at most this fraction of the record (a crash, a glitch); more is a column or a file read
#: wrongly, refused naming the first.
MAX_DAMAGED_FRACTION = 0.01
#: Longest unreadable cell taken for a glitch (a units row, ``n/a``, ``-1.2.3``); a longer one is refused, named.
MAX_DAMAGED_CELL_CHARS = 40
#: A displacement column is a velocity when the command's derivative leaves at most VELOCITY_RESIDUAL (rms, relative)
#: of it and the command itself more than COMMAND_RESIDUAL (a displacement follows its command to a few %).
#: (A displacement lagging a sine command by more than 72 degrees would look like one too: no working rig's does.)
VELOCITY_RESIDUAL, COMMAND_RESIDUAL = 0.3, 0.9
#: Longest reason text kept from a reader's refusal (characters): short, never a byte dump.
MAX_REASON_CHARS = 200
#: Texts that mean a non-finite value on purpose (reported as such, not as an overflow).
NONFINITE_TEXTS = frozenset({"inf", "+inf", "-inf", "infinity", "+infinity", "-infinity", "nan", "+nan", "-nan"})


class CaseFileError(Exception):
    """A case file that cannot be read as a table; carries the Problem."""

    def __init__(self, problem: Problem):
        super().__init__(problem.message)
        self.problem = problem


def short(text: str, limit: int = MAX_REASON_CHARS) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut)."""
    text = str(text)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def excerpt(value, limit: int = 40, head: int = 8) -> str:
    """A cell quoted for a reason: its repr when at most ``limit`` characters, else its first ``head`` characters
    and its length (a 200,000-character cell is no message)."""
    text = str(value)
    return repr(text) if len(text) <= limit else f"{text[:head]!r}... ({len(text)} characters)"


def raw_problem(exc: RawFileError) -> Problem:
    """A reader's refusal (:class:`isokinetic.rawfile.RawFileError`) as the case's Problem (reason at most
    :data:`MAX_REASON_CHARS` characters)."""
    return Problem(exc.column, short(exc.reason), row=exc.row, kind=exc.kind)


def read_case_table(path: str | Path, fmt: FileFormat | None = None, numeric: bool = False) -> RawTable:
    """A case file read by :func:`isokinetic.rawfile.read_raw_table` (every hostile-input check; ``numeric``:
    number columns as float64, not text); a refusal raises :class:`CaseFileError` with its Problem."""
    try:
        return read_raw_table(path, fmt, numeric=numeric)
    except RawFileError as exc:
        raise CaseFileError(raw_problem(exc)) from None
    except (ValueError, OverflowError, LookupError, UnicodeError, OSError, csv.Error) as exc:
        # a reader failure nobody foresaw costs this case, not the campaign (csv's field limit was one)
        raise CaseFileError(Problem("file", short(f"unreadable file ({type(exc).__name__}): {exc}"),
                                    kind="key")) from None


def _grouping(decimal: str, thousands: str | None) -> re.Pattern:
    """A number grouped by thousands separators: the declared ``thousands`` (an optional decimal part), or, none
    declared, the other of '.' and ',' followed by a decimal part (``1.234,5``, ``1,234.5``: unambiguous)."""
    sep = re.escape(thousands if thousands is not None else "," if decimal == "." else ".")
    fraction = rf"(?:{re.escape(decimal)}\d*)" + ("?" if thousands is not None else "")
    return re.compile(rf"[+-]?\d{{1,3}}(?:{sep}\d{{3}})+{fraction}(?:[eE][+-]?\d+)?")


def decimal_point(raw: pd.Series, decimal: str = ",", thousands: str | None = None) -> pd.Series:
    """Text numbers rewritten for parsing with '.' decimals and no thousands separators: ``-0,25`` -> ``-0.25``,
    ``1,5E-3`` -> ``1.5E-3``, ``1.234,5`` -> ``1234.5`` (grouped by :func:`_grouping`: the declared separator, or
    the other mark before a decimal part). Under a decimal comma any other value holding a '.' becomes NaN
    (refused by :func:`to_si`): ``1.5`` may be a '.' file declared ',', ``1.234`` a thousand; neither is guessed.
    Cells the reader already parsed as numbers (a number column, or a column numeric in one chunk of a large file,
    text in another) stay as they are."""
    if pd.api.types.is_numeric_dtype(raw):
        return raw
    text = raw.astype(object)
    strings = text.map(lambda v: isinstance(v, str)).to_numpy(bool)
    if not strings.any():
        return text
    cells = pd.Series(np.where(strings, text, ""), index=text.index, dtype=object).str.strip()
    grouped = cells.str.fullmatch(_grouping(decimal, thousands)).fillna(False).astype(bool)
    if grouped.any():
        mark = thousands if thousands is not None else "," if decimal == "." else "."
        cells = cells.where(~grouped, cells.str.replace(mark, "", regex=False))
    if decimal == ",":
        dotted = cells.str.contains(".", regex=False).astype(bool)
        cells = cells.str.replace(",", ".", regex=False).mask(dotted)
    return cells.where(strings, text)


def _time_values(raw: pd.Series, column: Column, decimal: str, timezone: str | None
                 ) -> tuple[np.ndarray, pd.Series, Problem | None]:
    """(seconds, cells that are no time, a problem the time alone shows) of a time column in a text unit."""
    if column.unit == TIME_STAMPS and pd.api.types.is_numeric_dtype(raw):     # plain numbers are no ISO stamps
        first = int(np.argmax(raw.notna().to_numpy())) if len(raw) else 0
        return np.empty(0), raw.isna(), Problem(column.name, f"invalid ISO 8601 timestamp {excerpt(raw.iloc[first])} "
                                                             "(a number: declare the unit s or ms?)", row=first)
    text = raw
    if column.unit == "excel_serial":
        text = decimal_point(raw, decimal) if decimal != "." else raw
    elif decimal != "." and not pd.api.types.is_numeric_dtype(raw):
        text = raw.astype(object).str.replace(",", ".", regex=False)
    values, problem = time_seconds(text, column.unit, timezone)
    bad = pd.Series(np.isnan(values), index=raw.index) & raw.notna()
    return values, bad, None if problem is None else Problem(column.name, problem[1], row=problem[0])


def to_si(raw: pd.Series, channel: str, column: Column, decimal: str = ".", thousands: str | None = None,
          timezone: str | None = None) -> tuple[np.ndarray | None, Problem | None]:
    """One CSV column in SI (float64; a temperature in C), or the first value that does not parse: the column's
    ``scale``/``offset`` (1.4) and its unit's factor applied (:func:`isokinetic.contracts.manifest.si_conversion`,
    through :mod:`isokinetic.units`). ``decimal`` and ``thousands`` are the files' (the manifest's ``csv`` block):
    text numbers go through :func:`decimal_point`; a time in ``datetime``, ``hms`` or ``excel_serial`` (1.5) is read
    by :func:`isokinetic.timestamps.time_seconds` (local stamps in ``timezone``), and ISO 8601 stamps may carry a
    decimal comma in their seconds (``10:59:59,95``)."""
    note = ""
    if column.unit in TIME_TEXT_UNITS:
        values, bad, problem = _time_values(raw, column, decimal, timezone)
        if problem is not None:
            return None, problem
        what = {"hms": "invalid clock time", "excel_serial": "invalid Excel serial date"}.get(
            column.unit, "invalid ISO 8601 timestamp")
    else:
        values, bad = si_values(raw, channel, column, decimal, thousands)
        what = "non-numeric value"
        if decimal != ".":
            note = (": the manifest's csv block declares ',' as the decimal mark, and a '.' is not read (a thousands "
                    "separator? declare `thousands: '.'` in the csv block; a file written with '.' decimals?)")
        if not bad.any():
            overflow = overflow_row(raw, values)
            if overflow is not None:
                return None, Problem(column.name, f"value {excerpt(str(raw.iloc[overflow]).strip())} lies beyond the "
                                                  f"range of a 64-bit float in SI ({column.unit} to SI)", row=overflow)
    if bad.any():
        first = int(np.argmax(bad.to_numpy()))
        value = raw.iloc[first]
        if what == "non-numeric value" and beyond_float(value):
            return None, Problem(column.name, f"value {excerpt(str(value).strip())} lies beyond the range of a 64-bit "
                                              "float", row=first)
        return None, Problem(column.name, f"{what} {excerpt(value)}" + (note if "." in str(value) else ""), row=first)
    if channel == "temperature":
        return temperature_values(values, column)
    return (-values if column.invert else values), None


def si_values(raw: pd.Series, channel: str, column: Column, decimal: str = ".", thousands: str | None = None
              ) -> tuple[np.ndarray, pd.Series]:
    """(the column's numbers in SI, before ``invert``; the cells that are no number) of a number column."""
    plain = pd.api.types.is_numeric_dtype(raw) or (decimal == "." and thousands is None and not _has_comma(raw))
    numbers = pd.to_numeric(raw if plain else decimal_point(raw, decimal, thousands), errors="coerce")
    factor, offset = si_conversion(channel, column)
    with np.errstate(over="ignore", invalid="ignore"):
        return numbers.to_numpy(float) * factor + offset, numbers.isna() & raw.notna()


def _has_comma(raw: pd.Series) -> bool:
    """True when a text column under '.' decimals may hold ``1,234.5`` (a ',' in a cell)."""
    return raw.dtype == object and bool(raw.astype(str).str.contains(",", regex=False).any())


def beyond_float(value) -> bool:
    """True for a number written beyond a float's range (a 309-digit integer, ``1e400``)."""
    text = str(value).strip()
    if text.lower() in NONFINITE_TEXTS:
        return False
    try:
        return math.isinf(float(text))
    except (ValueError, OverflowError):
        return False


def overflow_row(raw: pd.Series, values: np.ndarray) -> int | None:
    """The first position whose SI value is infinite though its text is no ``inf`` (``1e400``, a 309-digit
    number, 1e308 kN): a number beyond the range of a float, not a non-finite reading; None when none."""
    infinite = np.isinf(values)
    if not infinite.any():
        return None
    for i in np.flatnonzero(infinite):
        if str(raw.iloc[i]).strip().lower() not in NONFINITE_TEXTS:
            return int(i)
    return None


def temperature_values(values_C: np.ndarray, column: Column) -> tuple[np.ndarray | None, Problem | None]:
    """A temperature channel [C], or the first sample outside :data:`TEMPERATURE_RANGE_C` (a unit error:
    kelvin declared as C, or a broken sensor reading). ``invert`` does not apply to a temperature."""
    lo, hi = TEMPERATURE_RANGE_C
    outside = ~((values_C >= lo) & (values_C <= hi))
    if outside.any():
        first = int(np.argmax(outside))
        return None, Problem(column.name, f"temperature {values_C[first]:g} C (unit {column.unit}) lies outside "
                                          f"{lo:g}..{hi:g} C (a unit error?)", row=first)
    return values_C, None


def case_temperature(series: pd.DataFrame | None, case_C: float | None,
                     campaign_C: float | None) -> tuple[float, float, str]:
    """(temperature [C], span max - min [K], source) of a case: the mean of its temperature channel, else
    the case's ``temperature_C``, else the campaign's; (NaN, NaN, '') when none is known."""
    if series is not None and "temperature_C" in series:
        t = series["temperature_C"].to_numpy(float)
        return float(t.mean()), float(t.max() - t.min()), "channel"
    if case_C is not None:
        return float(case_C), math.nan, "case"
    if campaign_C is not None:
        return float(campaign_C), math.nan, "campaign"
    return math.nan, math.nan, ""


def canonical_timeseries(raw: pd.DataFrame, columns: dict[str, Column], decimal: str = ".",
                         fmt: FileFormat | None = None) -> tuple[pd.DataFrame | None, list[Problem]]:
    """The canonical SI time series of a case, or the problems of its columns (one per column);
    ``decimal``: the files' decimal mark, ``fmt``: their format (its ``thousands`` and ``timezone``, 1.5:
    :func:`to_si`)."""
    present = ", ".join(map(str, raw.columns))
    problems = [Problem(col.name, f"column not in the file (header: {present})")
                for col in columns.values() if col.name not in raw.columns]
    if problems:
        return None, problems
    thousands, timezone = (None, None) if fmt is None else (fmt.thousands, fmt.timezone)
    out = {"row": np.arange(len(raw), dtype="int64")}
    for channel, col in columns.items():
        values, problem = to_si(raw[col.name], channel, col, decimal, thousands, timezone)
        if problem is not None:
            problems.append(problem)
        out[CANONICAL[channel]] = values
    if problems:
        return None, problems
    return pd.DataFrame(out, columns=["row"] + [CANONICAL[ch] for ch in CANONICAL if ch in columns]), []


def damaged_rows(raw: pd.DataFrame, columns: dict[str, Column], decimal: str = ".",
                 fmt: FileFormat | None = None) -> np.ndarray:
    """Rows with a blank cell (or NaN) or a short cell that is no number (no time) in a channel's column: what a
    rig's glitch, a repeated units row or a half-written line leaves. A number beyond a float's range, ``inf`` or
    a cell longer than :data:`MAX_DAMAGED_CELL_CHARS` is no glitch (it is refused, named). Columns missing from
    the file are left to :func:`canonical_timeseries`."""
    damaged = np.zeros(len(raw), dtype=bool)
    thousands, timezone = (None, None) if fmt is None else (fmt.thousands, fmt.timezone)
    for channel, col in columns.items():
        if col.name not in raw.columns:
            continue
        cells = raw[col.name]
        if col.unit in TIME_TEXT_UNITS:
            bad = _time_values(cells, col, decimal, timezone)[1]
        elif pd.api.types.is_numeric_dtype(cells):
            bad = pd.Series(False, index=cells.index)
        else:
            bad = si_values(cells, channel, col, decimal, thousands)[1]
        bad = bad.to_numpy(bool)
        for i in np.flatnonzero(bad)[:int(MAX_DAMAGED_FRACTION * len(raw)) + 1]:   # more: no partial record
            text = str(cells.iloc[i]).strip()
            bad[i] = len(text) <= MAX_DAMAGED_CELL_CHARS and not beyond_float(text)
        damaged |= bad | cells.isna().to_numpy(bool)
    return damaged


def partial_record(raw: pd.DataFrame, file_rows: np.ndarray, drop: np.ndarray, what: str
                   ) -> tuple[pd.DataFrame, np.ndarray, list[str]]:
    """The record without the rows ``drop`` marks, when they are at most :data:`MAX_DAMAGED_FRACTION` of it (a
    partial record keeps what is good: the dropped rows are a gap in time, checked at validate as dropped samples
    are), with the note naming them; unchanged (nothing dropped) when there are none or more."""
    n = int(drop.sum())
    if n == 0 or n > MAX_DAMAGED_FRACTION * len(raw):
        return raw, file_rows, []
    note = (f"{n} row(s) {what} left out (data rows {', '.join(map(str, file_rows[drop][:8].tolist()))}"
            f"{' and more' if n > 8 else ''}): a gap in the record")
    return raw[~drop].reset_index(drop=True), file_rows[~drop], [note]


def case_series(table: RawTable, span: tuple[int, int] | None, spec: CaseSpec
                ) -> tuple[pd.DataFrame | None, list[Problem], int, list[str]]:
    """(canonical SI series or None, problems, samples, notes) of a case's table (``span``: its slice): rows with
    damaged cells and rows repeating the time stamp before dropped (:func:`partial_record`), ``row`` the file's
    data-row numbers, a slice's time re-zeroed at its first sample."""
    first, stop = span if span is not None else (0, len(table.frame))
    raw = table.frame if span is None else table.frame.iloc[first:stop].reset_index(drop=True)
    file_rows = np.asarray(table.rows[first:stop], dtype="int64")
    raw, file_rows, notes = partial_record(raw, file_rows, damaged_rows(raw, spec.columns, table.decimal, spec.csv),
                                           "with a blank or unreadable cell")
    df, problems = canonical_timeseries(raw, spec.columns, table.decimal, spec.csv)
    problems = [dataclasses.replace(p, row=None if p.row is None else int(file_rows[p.row])) for p in problems]
    if df is None:
        return None, problems, len(raw), notes
    t = df["time_s"].to_numpy(float)
    repeated = np.concatenate([[False], np.diff(t) == 0.0]) if len(t) else np.zeros(0, dtype=bool)
    kept, file_rows, more = partial_record(df, file_rows, repeated, "repeating the time stamp of the row before")
    df = kept.assign(row=file_rows)
    if span is not None and len(df):
        df["time_s"] = df["time_s"] - df["time_s"].iloc[0]
    return df, problems, len(df), notes + more


def subtract_gas_force(series: pd.DataFrame, gas_force_N: float | None) -> pd.DataFrame:
    """The canonical series with a known static gas force taken off its force (manifest ``gas_force_N``,
    format 1.1): F = F_measured - F_gas, so that the steady characteristic, the models and the
    diagnosis all see the damper's force alone. None or 0 leaves the series as it is."""
    if not gas_force_N:
        return series
    return series.assign(force_N=series["force_N"].to_numpy(float) - float(gas_force_N))


def units_problems(units: dict[str, str], columns: dict[str, Column]) -> list[Problem]:
    """Columns whose unit in the file differs from the manifest's, one Problem each naming the column: the units
    row's cell (1.2), else a unit in the column's header (1.4, ``friction force (kip)``, ``force_kN``:
    :func:`isokinetic.units.unit_in_name`), read by :func:`isokinetic.units.parse_unit`: ``in`` declared as ``mm``
    would be read 25.4 x off. Empty cells, ISO 8601 stamps and scaled columns (1.4: the file then holds the
    logger's unit, volts) are not checked; a units-row text that is no unit of the channel (``V``) is refused."""
    problems = []
    for channel, col in columns.items():
        if col.unit in TIME_TEXT_UNITS or (col.scale, col.offset) != (1.0, 0.0):
            continue
        text, said = str(units.get(col.name) or "").strip(), "units row"
        if not text:
            text, said = unit_in_name(col.name)[1] or "", "header"
            if not text or not _known(text, channel):
                continue
        try:
            unit = parse_unit(text, CHANNEL_DIMENSIONS[channel])
        except UnitError:
            problems.append(Problem(col.name, f"the file's {said} says {text!r} (is not a unit of {channel}), the "
                                              f"manifest declares {col.unit!r} for {channel}: fix the manifest's unit"))
            continue
        declared = channel_unit(channel, col.unit)
        if not (math.isclose(unit.scale, declared.scale, rel_tol=1e-9)
                and math.isclose(unit.offset, declared.offset, abs_tol=1e-9)):
            problems.append(Problem(col.name, f"the file's {said} says {text!r} (means {unit.symbol!r}), the manifest "
                                              f"declares {col.unit!r} for {channel}: fix the manifest's unit"))
    return problems


def _known(text: str, channel: str) -> bool:
    """True when ``text`` is a unit of the channel's dimension (a header's unit is checked only then)."""
    try:
        parse_unit(text, CHANNEL_DIMENSIONS[channel])
    except UnitError:
        return False
    return True


class FileCache:
    """Within one ingest, each case file is hashed once and read once per format (several cases may
    name one file, each with its own slice), and its time axis converted once."""

    def __init__(self):
        self.sha: dict[Path, str] = {}
        self.tables: dict[tuple, RawTable | CaseFileError] = {}
        self.times: dict[tuple, tuple[np.ndarray | None, Problem | None]] = {}

    def sha256(self, path: Path) -> str:
        if path not in self.sha:
            self.sha[path] = sha256_file(path)
        return self.sha[path]

    def release(self, path: Path) -> None:
        """Forget a file's tables and time axes (its last case is ingested): memory stays bounded by one file's."""
        self.tables = {k: v for k, v in self.tables.items() if k[0] != path}
        self.times = {k: v for k, v in self.times.items() if k[0] != path}

    def table(self, path: Path, fmt: FileFormat | None) -> RawTable:
        key = (path, fmt)
        if key not in self.tables:
            try:
                self.tables[key] = read_case_table(path, fmt, numeric=True)
            except CaseFileError as exc:
                self.tables[key] = exc
        got = self.tables[key]
        if isinstance(got, CaseFileError):
            raise got
        return got

    def time_s(self, path: Path, fmt: FileFormat | None, table: RawTable,
               column: Column) -> tuple[np.ndarray | None, Problem | None]:
        key = (path, fmt, column)
        if key not in self.times:
            self.times[key] = to_si(table.frame[column.name], "time", column, table.decimal)
        return self.times[key]


def slice_rows(spec: CaseSpec, table: RawTable, cache: FileCache, path: Path) -> tuple[tuple[int, int] | None,
                                                                                       float, Problem | None]:
    """(positions [start, stop) of the case's slice in the table, the slice's first time on the file's own time
    axis [s], problem) of a case with ``time_range_s`` or ``rows`` (1.2); (None, NaN, None) without a slice."""
    n = len(table.frame)
    if spec.rows is not None:
        rows_in_file = int(table.rows[-1]) + 1 if n else 0
        if spec.rows[1] > rows_in_file:
            return None, math.nan, Problem("rows", f"rows [{spec.rows[0]}, {spec.rows[1]}) run beyond the file's "
                                                   f"{rows_in_file} data rows", kind="key")
        # data-row numbers to the table's positions (marker rows, 1.4, are not in the table)
        first, stop = (int(np.searchsorted(table.rows, r)) for r in spec.rows)
        if first >= stop:
            return None, math.nan, Problem("rows", f"rows [{spec.rows[0]}, {spec.rows[1]}) hold no sample (marker "
                                                   "rows only)", kind="key")
        start_s = math.nan
        time_col = spec.columns["time"]
        if time_col.name in table.frame:
            t, problem = cache.time_s(path, spec.csv, table, time_col)
            start_s = float(t[first]) if problem is None else math.nan
        return (first, stop), start_s, None
    if spec.time_range_s is None:
        return None, math.nan, None
    time_col = spec.columns["time"]
    if time_col.name not in table.frame:
        return None, math.nan, Problem(time_col.name, "column not in the file (header: "
                                                      f"{', '.join(map(str, table.frame.columns))})")
    t, problem = cache.time_s(path, spec.csv, table, time_col)
    if problem is not None:
        return None, math.nan, problem
    a, b = spec.time_range_s
    if n == 0:
        return None, math.nan, Problem("time_range_s", "the file holds no data rows", kind="key")
    step = float(np.median(np.diff(t))) if n > 1 else 0.0
    if a < t[0] - 0.5 * abs(step) or b > t[-1] + 1.5 * abs(step):
        return None, math.nan, Problem("time_range_s", f"[{a:g}, {b:g}) s lies outside the file's time axis "
                                                       f"({t[0]:g} .. {t[-1]:g} s)", kind="key")
    inside = np.flatnonzero((t >= a) & (t < b))
    if len(inside) == 0:
        return None, math.nan, Problem("time_range_s", f"[{a:g}, {b:g}) s holds no sample", kind="key")
    return (int(inside[0]), int(inside[-1]) + 1), float(t[inside[0]]), None


def size_problem(path: Path, max_file_MB: float) -> Problem | None:
    """A case file larger than ``max_file_MB`` (checked on its size, before it is opened), else None."""
    size = path.stat().st_size
    if size <= max_file_MB * 1e6:
        return None
    return Problem("file", f"{size / 1e6:.4g} MB, more than the {max_file_MB:g} MB a case file may have (config "
                           "ingest.max_case_file_MB): not read", kind="key")


def range_problems(df: pd.DataFrame, columns: dict[str, Column]) -> list[Problem]:
    """Samples no sensor of the manifest, or no rig, produces (the measured values, before the gas force is
    taken off): beyond :data:`FULL_SCALE_FACTOR` times a column's declared ``full_scale`` or beyond
    :data:`PHYSICAL_LIMITS`, and a piston speed between two samples beyond :data:`MAX_SPEED_M_S`; one Problem
    per column (canonical name), at the first such row."""
    problems = []
    rows = df["row"].to_numpy()
    for channel, col in columns.items():
        name = CANONICAL[channel]
        if name not in PHYSICAL_LIMITS or name not in df:
            continue
        x = np.abs(df[name].to_numpy(float))
        factor = abs(channel_unit(channel, col.unit).scale)       # SI per the column's unit
        limits = [(PHYSICAL_LIMITS[name], f"the {PHYSICAL_LIMITS[name]:g} {name.split('_')[-1]} no rig produces")]
        if col.full_scale is not None:
            limits.append((FULL_SCALE_FACTOR * col.full_scale * factor,
                           f"{FULL_SCALE_FACTOR:g} x the declared full scale {col.full_scale:g} {col.unit}"))
        for limit, why in sorted(limits):
            beyond = x > limit
            if beyond.any():
                i = int(np.argmax(beyond))
                problems.append(Problem(name, f"|value| {x[i] / factor:.4g} {col.unit} lies beyond {why} (a unit "
                                              "error, a spike or a broken sensor?)", row=int(rows[i])))
                break
    if "displacement_m" in df and len(df) > 1 and not any(p.column == "displacement_m" for p in problems):
        dt = np.diff(df["time_s"].to_numpy(float))
        dy = np.diff(df["displacement_m"].to_numpy(float))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            fast = (dt > 0) & (np.abs(dy) > MAX_SPEED_M_S * dt)
        if fast.any():
            i = int(np.argmax(fast))
            problems.append(Problem("displacement_m", f"the piston moves {dy[i]:.4g} m in {dt[i]:.4g} s (|v| "
                                                      f"{abs(dy[i]) / dt[i]:.4g} m/s) from row {int(rows[i])}, beyond "
                                                      f"the {MAX_SPEED_M_S:g} m/s no rig produces (a spike or a "
                                                      "unit error?)", row=int(rows[i + 1])))
    return problems


def velocity_problem(df: pd.DataFrame, columns: dict[str, Column]) -> Problem | None:
    """A displacement column that is a velocity: the command's derivative times a constant (least squares, at most
    :data:`VELOCITY_RESIDUAL` rms left) while the command itself explains little of it (more than
    :data:`COMMAND_RESIDUAL` left). ``invert`` would not fix it, so it is refused before the sign check asks for
    one; None without a command column or when the displacement follows the command."""
    if "command_m" not in df or len(df) < 16:
        return None
    t, y, c = (df[k].to_numpy(float) for k in ("time_s", "displacement_m", "command_m"))
    dcdt = np.gradient(c, t)
    y0 = y - y.mean()
    fits = [_residual(y0, dcdt - dcdt.mean()), _residual(y0, c - c.mean())]
    if not (fits[0] < VELOCITY_RESIDUAL < COMMAND_RESIDUAL < fits[1]):
        return None
    if lagging_displacement(y0, c - c.mean(), dcdt - dcdt.mean()):
        return None
    name = columns["displacement"].name
    return Problem(name, f"looks like a velocity, not a displacement: it equals the command's derivative times a "
                         f"constant to {fits[0]:.1%} rms, while the command itself leaves {fits[1]:.0%} of it "
                         "unexplained; declare the displacement column (`invert` would not fix this)")


def lagging_displacement(y: np.ndarray, c: np.ndarray, dcdt: np.ndarray) -> bool:
    """Whether y (centred), which the command's derivative explains, is rather the displacement lagging a sine
    command by about a quarter period (a servo above its bandwidth): of a sine, a lagged copy and the derivative have
    one shape, but the displacement keeps the command's amplitude (rms ratio near 1) where the velocity has the
    command's angular frequency ω (ratio near ω [1/s]); decided by the nearer of the two, by more than a factor 2
    (ω within a factor 4 of 1/s cannot tell them apart)."""
    yy, cc, dd = (math.sqrt(float(v @ v)) for v in (y, c, dcdt))
    if not (yy > 0 and cc > 0 and dd > 0):
        return False
    ratio, omega = yy / cc, dd / cc
    return abs(math.log(ratio)) + math.log(2.0) < abs(math.log(ratio / omega))


def _residual(y: np.ndarray, x: np.ndarray) -> float:
    """The rms of y - k x (k by least squares) relative to y's (inf when either is zero)."""
    xx, yy = float(x @ x), float(y @ y)
    if not (xx > 0 and yy > 0 and math.isfinite(xx) and math.isfinite(yy)):
        return math.inf
    r = y - (float(x @ y) / xx) * x
    return math.sqrt(float(r @ r) / yy)


def planned_span_s(plan, n_samples: int) -> float:
    """The time span a record needs [s]: the longest of the plan's ``duration_s``, its required record
    (two periods of a triangle, one of a sine) and its samples at the planned rate."""
    spans = [plan.duration_s, plan.required_duration_s, n_samples / plan.sample_rate_Hz]
    return max(x for x in spans if math.isfinite(x))


def trimmed_record(df: pd.DataFrame, plan) -> tuple[pd.DataFrame, str | None]:
    """The record cut at :data:`MAX_RECORD_SPAN_FACTOR` times :func:`planned_span_s` after its first sample,
    with the note saying what was dropped (None: nothing was). Time must be valid (increasing) already."""
    t = df["time_s"].to_numpy(float)
    if len(t) < 2:
        return df, None
    need_s = planned_span_s(plan, len(t))
    limit_s = MAX_RECORD_SPAN_FACTOR * need_s
    if not t[-1] - t[0] > limit_s:
        return df, None
    keep = int(np.searchsorted(t - t[0], limit_s, side="right"))
    note = (f"record trimmed to its first {limit_s:.6g} s ({MAX_RECORD_SPAN_FACTOR:g} x the {need_s:.6g} s its plan "
            f"and samples need): {len(t) - keep} sample(s) from row {int(df['row'].iloc[keep])} on dropped, the last "
            f"at t = {t[-1]:.6g} s (a broken time stamp?)")
    return df.iloc[:keep].reset_index(drop=True), note


def ingest_case(campaign_dir: Path, campaign: str, spec: CaseSpec, campaign_temperature_C: float | None = None,
                cache: FileCache | None = None,
                max_file_MB: float = DEFAULTS.max_case_file_MB) -> tuple[dict, list[Problem], pd.DataFrame | None]:
    """One case: its CASES row, its problems, and its time series when it is ok (read in the manifest's
    format, ``spec.csv``; its units row checked against the manifest's units; its slice of the file (1.2,
    ``time_range_s`` / ``rows``) with time re-zeroed at the slice's first sample and ``row`` keeping the
    file's data-row numbers; less its gas force, ``spec.gas_force_N``: :func:`subtract_gas_force`). The row's
    temperature: :func:`case_temperature` (``campaign_temperature_C``: the manifest's). ``cache``: files
    shared by the cases of one ingest (:class:`FileCache`). Hostile input (issue 20): a file above
    ``max_file_MB`` is not read (:func:`size_problem`), samples beyond any sensor's or rig's range set the case
    aside (:func:`range_problems`), a record far longer than its plan is trimmed with a note
    (:func:`trimmed_record`)."""
    cache = cache or FileCache()
    problems = list(spec.problems)
    path = campaign_dir / spec.file if spec.file is not None else None
    sha, n_samples, df, warnings = "", 0, None, []
    span, slice_start_s = None, math.nan
    if path is not None:
        if path.is_file():
            too_large = size_problem(path, max_file_MB)
            if too_large is None:
                sha = cache.sha256(path)
            else:
                problems.append(too_large)
        else:
            problems.append(Problem("file", f"file not found: {path.as_posix()}", kind="key"))
    if not problems:
        try:
            table = cache.table(path, spec.csv)
        except CaseFileError as exc:
            problems.append(exc.problem)
        else:
            warnings = list(table.warnings)
            problems = units_problems(table.units, spec.columns)
            if not problems:
                span, slice_start_s, problem = slice_rows(spec, table, cache, path)
                problems = [] if problem is None else [problem]
            if not problems:
                df, problems, n_samples, notes = case_series(table, span, spec)
                warnings += notes
    if df is not None:
        measured = df
        df = subtract_gas_force(df, spec.gas_force_N)
        names = {CANONICAL[ch]: col.name for ch, col in spec.columns.items()}
        problems = timeseries_problems(df) or range_problems(measured, spec.columns)
        velocity = None if problems else velocity_problem(measured, spec.columns)
        problems += [] if velocity is None else [velocity]
        problems = [dataclasses.replace(p, column=names.get(p.column, p.column)) for p in problems]
        if not problems:
            df, note = trimmed_record(df, spec.plan)
            if note is not None:
                warnings.append(note)
                n_samples = len(df)
    row = {"campaign": campaign, **dataclasses.asdict(spec.plan),
           "raw_file": path.as_posix() if path is not None else str(spec.keys.get("file") or ""),
           "raw_sha256": sha, "timeseries_file": "" if problems else timeseries_relpath(spec.id),
           "n_samples": n_samples, "status": "quarantined" if problems else "ok",
           "quality": "quarantined" if problems else ("; ".join(warnings) or "ok"),
           "slice_start_s": slice_start_s, "row_start": math.nan, "row_stop": math.nan,
           "gas_force_N": math.nan if spec.gas_force_N is None else float(spec.gas_force_N)}
    if span is not None and len(table.rows):     # the file's data-row numbers (float64: NaN without a slice)
        row["row_start"], row["row_stop"] = float(table.rows[span[0]]), float(table.rows[span[1] - 1] + 1)
    row["temperature_C"], row["temperature_span_C"], row["temperature_source"] = case_temperature(
        None if problems else df, spec.temperature_C, campaign_temperature_C)
    return row, problems, (None if problems else df)


def campaign_meta(manifest: Manifest, manifest_file: str) -> CampaignMeta:
    """The ``campaign.json`` record of a manifest, with raw ingest's keys (RAW_INGEST_KEYS)."""
    return CampaignMeta(
        format_version=manifest.format_version, campaign=manifest.campaign, source=manifest.source,
        description=manifest.description, temperature_C=manifest.temperature_C, damper=manifest.damper,
        manifest_file=manifest_file, manifest_sha256=manifest.sha256, metadata=jsonable(manifest.metadata),
        # the oil's viscosity-temperature law (damper.viscosity_law, format 1.1), None when none was given
        viscosity_law_block=None if manifest.viscosity_law is None else manifest.viscosity_law.to_dict(),
        # the static gas force subtracted from every force sample (N), None when none was declared
        gas_force_N=manifest.gas_force_N,
        # the case files' dialect (manifest csv block, format 1.1), None when none was declared (',' and '.')
        csv=None if manifest.csv is None else manifest.csv.to_dict(),
        # keys that look like slips of known ones (1.2, manifest near misses), () when none
        warnings=tuple(manifest.warnings),
        # the load cell's and the LVDT's calibrations (columns.<channel>.calibration, 1.6), None when none declared
        force_calibration=manifest.force_calibration, displacement_calibration=manifest.displacement_calibration,
        present=frozenset(RAW_INGEST_KEYS))


def shared_file_warnings(manifest: Manifest, rows: list[dict]) -> list[str]:
    """One warning per case file that several cases name with the same or overlapping slices (issues 20.7/20.9):
    the same record would count more than once. Different slices of one file (a stepped record) are not warned
    about. Spans are the file's data rows a case took (``row_start``/``row_stop``; the whole file without a
    slice); a case set aside before its slice was found is left out."""
    spans: dict[str, list[tuple[str, float, float]]] = {}
    for spec, row in zip(manifest.cases, rows):
        if spec.file is None:
            continue
        if spec.time_range_s is None and spec.rows is None:
            a, b = 0.0, math.inf
        elif math.isfinite(row["row_start"]):
            a, b = row["row_start"], row["row_stop"]
        else:
            continue
        spans.setdefault(spec.file, []).append((spec.id, a, b))
    out = []
    for file, cases in spans.items():
        cases.sort(key=lambda c: c[1])
        overlapping, reach, last = set(), -math.inf, None
        for case, a, b in cases:
            if a < reach:
                overlapping.update({case, last})
            if b > reach:
                reach, last = b, case
        if overlapping:
            named = [c for c, _, _ in cases if c in overlapping]
            listed = ", ".join(named[:10]) + (f" and {len(named) - 10} more" if len(named) > 10 else "")
            out.append(f"{len(named)} cases name the file {file!r} with the same or overlapping slices ({listed}): "
                       "the same record counts more than once")
    return out


def ingest_campaign(campaign_dir: str | Path, campaign_root: str | Path,
                    max_case_file_MB: float = DEFAULTS.max_case_file_MB, cases: Sequence[str] | None = None) -> None:
    """Ingest ``campaign_dir`` (as given, e.g. ``data/raw/<c>``) into ``<campaign_root>/ingest``; case files
    above ``max_case_file_MB`` are not read (their cases are set aside); ``cases``: only these of the manifest's
    (in its order; ``trace`` re-derives the cases it traces), KeyError naming any it does not hold. The outcome is
    logged only once the results are written."""
    campaign_dir = Path(campaign_dir)
    manifest_file = campaign_dir / MANIFEST_NAME
    manifest = load_manifest(manifest_file)
    if cases is not None:
        unknown = sorted(set(cases) - {spec.id for spec in manifest.cases})
        if unknown:
            raise KeyError(f"{manifest_file}: no case {', '.join(unknown)}")
        wanted = set(cases)
        manifest = dataclasses.replace(manifest, cases=tuple(s for s in manifest.cases if s.id in wanted))
    for warning in manifest.warnings:
        log.warning("campaign %s: %s", manifest.campaign, warning)
    rows, quarantined, series, cache = [], [], {}, FileCache()
    uses: dict[str, int] = {}
    for spec in manifest.cases:
        uses[spec.file] = uses.get(spec.file, 0) + 1
    for spec in manifest.cases:
        row, problems, df = ingest_case(campaign_dir, manifest.campaign, spec, manifest.temperature_C, cache,
                                        max_case_file_MB)
        uses[spec.file] -= 1
        if spec.file is not None and uses[spec.file] == 0:
            cache.release(campaign_dir / spec.file)
        rows.append(row)
        quarantined += quarantine_rows(manifest.campaign, spec.id, "ingest", problems)
        if df is not None:
            series[spec.id] = df
    shared = shared_file_warnings(manifest, rows)
    for warning in shared:
        log.warning("campaign %s: %s", manifest.campaign, warning)
    meta = campaign_meta(manifest, manifest_file.as_posix())
    meta = dataclasses.replace(meta, warnings=meta.warnings + tuple(shared))
    write_ingested(CampaignFolder.at(campaign_root).ingest_dir, meta, pd.DataFrame(rows), quarantine_frame(quarantined),
                   series)
    log.info("campaign %s: %d of %d cases ingested, %d quarantined", manifest.campaign, len(series),
             len(rows), len(rows) - len(series))
    if manifest.csv is not None:
        log.info("campaign %s: case files read with delimiter %r and decimal mark %r (manifest csv block)",
                 manifest.campaign, manifest.csv.delimiter, manifest.csv.decimal)
    if manifest.gas_force_N:
        log.info("campaign %s: gas force %g N subtracted from every force sample (manifest gas_force_N)",
                 manifest.campaign, manifest.gas_force_N)
    own = [c.id for c in manifest.cases if c.case_gas_force_N is not None]
    if own:
        log.info("campaign %s: cases %s subtract their own gas_force_N", manifest.campaign, ", ".join(own))


def run_ingest(campaign_root: str | Path, settings: Settings, raw_dir: str | Path,
               cases: Sequence[str] | None = None) -> None:
    """The chain's ingest step (:mod:`isokinetic.stages.chain`): :func:`ingest_campaign` of ``raw_dir`` (its
    ``cases``, default all) into ``campaign_root`` with the settings' file-size limit."""
    ingest_campaign(raw_dir, campaign_root, max_case_file_MB=settings.max_case_file_MB, cases=cases)
