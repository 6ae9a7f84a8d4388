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
import datetime as dt
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import timeseries_relpath, write_ingested
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
from isokinetic.io import sha256_file
from isokinetic.rawfile import FOREIGN_BOMS as FOREIGN_BOMS  # re-exported for init_campaign
from isokinetic.rawfile import FileFormat, RawFileError, RawTable, read_raw_table
from isokinetic.stages.validate import quarantine_frame, quarantine_rows, timeseries_problems
from isokinetic.units import UnitError, parse_unit, unit_in_name

log = logging.getLogger("isokinetic")

#: Channel -> canonical column of the ingested time series.
CANONICAL = {"time": "time_s", "displacement": "displacement_m", "force": "force_N", "command": "command_m",
             "temperature": "temperature_C"}
#: Largest case file ingest reads, MB (10^6 bytes), unless the config says otherwise (``ingest.max_case_file_MB``);
#: the same bound as init-campaign's. Checked before the file is opened: a larger file sets its case aside.
MAX_CASE_FILE_MB = 256.0
#: What no damper rig produces, whatever the manifest declares (SI): a sample beyond sets its case aside, naming
#: the row. Force 10 MN; displacement and command 10 m; piston speed between two samples 100 m/s.
PHYSICAL_LIMITS = {"force_N": 1.0e7, "displacement_m": 10.0, "command_m": 10.0}
MAX_SPEED_M_S = 100.0
#: A record whose time axis spans more than this many times its plan's need (the longer of ``duration_s`` and
#: the plan's required record, or of its samples at the planned rate) is trimmed there, with a note: a broken last
#: time stamp (1e308 s, a year typo in an ISO stamp) must not make later stages work over centuries of record.
MAX_RECORD_SPAN_FACTOR = 10.0
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


def decimal_point(raw: pd.Series) -> pd.Series:
    """Text numbers written with a decimal comma, rewritten with '.' for parsing: ``-0,25`` -> ``-0.25``,
    ``1,5E-3`` -> ``1.5E-3``. A value holding a '.' becomes NaN (refused by :func:`to_si`): ``1.234,5``
    has a thousands separator, ``1.5`` was written with '.' decimals; neither is guessed. Cells the reader
    already parsed as numbers (a column numeric in one chunk of a large file, text in another) stay as they are."""
    text = raw.astype(object)
    dotted = text.str.contains(".", regex=False, na=False).astype(bool)
    out = text.str.replace(",", ".", regex=False).mask(dotted)
    strings = text.map(lambda v: isinstance(v, str)).astype(bool)
    return out if strings.all() else out.where(strings | text.isna(), text)


def to_si(raw: pd.Series, channel: str, column: Column, decimal: str = ".") -> tuple[np.ndarray | None, Problem | None]:
    """One CSV column in SI (float64; a temperature in C), or the first value that does not parse: the column's
    ``scale``/``offset`` (1.4) and its unit's factor applied (:func:`isokinetic.contracts.manifest.si_conversion`,
    through :mod:`isokinetic.units`). ``decimal`` is the files' decimal mark (the manifest's ``csv`` block): with
    ',' numbers go through :func:`decimal_point`, and ISO 8601 stamps may carry a decimal comma in their seconds
    (``10:59:59,95``)."""
    note = ""
    if column.unit == TIME_STAMPS and pd.api.types.is_numeric_dtype(raw):     # plain numbers are no ISO stamps
        first = int(np.argmax(raw.notna().to_numpy())) if len(raw) else 0
        return None, Problem(column.name, f"invalid ISO 8601 timestamp {excerpt(raw.iloc[first])} (a number: "
                                          "declare the unit s or ms?)", row=first)
    if column.unit == TIME_STAMPS:
        text = raw if decimal == "." else raw.astype(object).str.replace(",", ".", regex=False)
        stamps = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
        bad = stamps.isna() & raw.notna()
        values = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(float) if len(raw) else np.empty(0)
        what = "invalid ISO 8601 timestamp"
    else:
        text = raw if decimal == "." or pd.api.types.is_numeric_dtype(raw) else decimal_point(raw)
        numbers = pd.to_numeric(text, errors="coerce")
        bad = numbers.isna() & raw.notna()
        factor, offset = si_conversion(channel, column)
        with np.errstate(over="ignore", invalid="ignore"):
            values = numbers.to_numpy(float) * factor + offset
        what = "non-numeric value"
        if decimal != ".":
            note = (": the manifest's csv block declares ',' as the decimal mark, and a '.' is not read (a thousands "
                    "separator? a file written with '.' decimals?)")
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


def canonical_timeseries(raw: pd.DataFrame, columns: dict[str, Column],
                         decimal: str = ".") -> tuple[pd.DataFrame | None, list[Problem]]:
    """The canonical SI time series of a case, or the problems of its columns (one per column);
    ``decimal``: the files' decimal mark (:func:`to_si`)."""
    present = ", ".join(map(str, raw.columns))
    problems = [Problem(col.name, f"column not in the file (header: {present})")
                for col in columns.values() if col.name not in raw.columns]
    if problems:
        return None, problems
    out = {"row": np.arange(len(raw), dtype="int64")}
    for channel, col in columns.items():
        values, problem = to_si(raw[col.name], channel, col, decimal)
        if problem is not None:
            problems.append(problem)
        out[CANONICAL[channel]] = values
    if problems:
        return None, problems
    return pd.DataFrame(out, columns=["row"] + [CANONICAL[ch] for ch in CANONICAL if ch in columns]), []


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
        if col.unit == TIME_STAMPS or (col.scale, col.offset) != (1.0, 0.0):
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
                max_file_MB: float = MAX_CASE_FILE_MB) -> tuple[dict, list[Problem], pd.DataFrame | None]:
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
                first, stop = span if span is not None else (0, len(table.frame))
                raw = table.frame if span is None else table.frame.iloc[first:stop].reset_index(drop=True)
                n_samples = len(raw)
                df, problems = canonical_timeseries(raw, spec.columns, table.decimal)
                problems = [dataclasses.replace(p, row=None if p.row is None else int(table.rows[first + p.row]))
                            for p in problems]
                if df is not None:
                    df["row"] = table.rows[first:stop].astype("int64")
                    if span is not None:
                        df["time_s"] = df["time_s"] - df["time_s"].iloc[0] if len(df) else df["time_s"]
    if df is not None:
        measured = df
        df = subtract_gas_force(df, spec.gas_force_N)
        names = {CANONICAL[ch]: col.name for ch, col in spec.columns.items()}
        problems = timeseries_problems(df) or range_problems(measured, spec.columns)
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


def jsonable(value):
    """Metadata from YAML made JSON-safe: dates as ISO text, keys as text, non-finite floats as text."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (dt.date, dt.datetime)):
        return value.isoformat()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)


def campaign_meta(manifest: Manifest, manifest_file: str) -> dict:
    """The ``campaign.json`` record (campaign.CAMPAIGN_KEYS) of a manifest."""
    return {"format_version": manifest.format_version, "campaign": manifest.campaign,
            "source": manifest.source, "description": manifest.description,
            "temperature_C": manifest.temperature_C,
            # the oil's viscosity-temperature law (damper.viscosity_law, format 1.1), None when none was given
            "viscosity_law": None if manifest.viscosity_law is None else manifest.viscosity_law.to_dict(),
            # the static gas force subtracted from every force sample (N), None when none was declared
            "gas_force_N": manifest.gas_force_N,
            # the case files' dialect (manifest csv block, format 1.1), None when none was declared (',' and '.')
            "csv": None if manifest.csv is None else manifest.csv.to_dict(),
            "damper": None if manifest.damper is None else manifest.damper.to_dict(),
            # keys that look like slips of known ones (1.2, manifest near misses), [] when none
            "warnings": list(manifest.warnings),
            "manifest_file": manifest_file, "manifest_sha256": manifest.sha256,
            "metadata": jsonable(manifest.metadata)}


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
                    max_case_file_MB: float = MAX_CASE_FILE_MB) -> None:
    """Ingest ``campaign_dir`` (as given, e.g. ``data/raw/<c>``) into ``<campaign_root>/ingest``; case files
    above ``max_case_file_MB`` are not read (their cases are set aside). The outcome is logged only once the
    results are written."""
    campaign_dir = Path(campaign_dir)
    manifest_file = campaign_dir / MANIFEST_NAME
    manifest = load_manifest(manifest_file)
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
    meta["warnings"] = list(meta["warnings"]) + shared
    write_ingested(Path(campaign_root) / "ingest", meta, pd.DataFrame(rows), quarantine_frame(quarantined), series)
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
