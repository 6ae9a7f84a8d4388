"""Raw ingest: ``data/raw/<campaign>/`` (campaign.yaml + one CSV per case) to ``<campaign_root>/ingest/``.

Each case CSV is mapped to the canonical SI time series (``row``, ``time_s``,
``displacement_m``, ``force_N``, ``command_m``). A case whose file or columns are unusable is
quarantined (stage ``ingest``) and every other case carries on; a broken manifest raises
:class:`isokinetic.contracts.manifest.ManifestError`. Raw files are only ever opened for reading.

A manifest's ``gas_force_N`` (format 1.1) is subtracted from every force sample here, at the edge
where the force becomes SI, and recorded in ``campaign.json`` (``gas_force_N``, null when none): every
stage downstream sees the damper's force alone.

A manifest's ``csv`` block (format 1.1, e.g. ``{delimiter: ";", decimal: ","}``, a spreadsheet export)
sets the delimiter every check of :func:`read_case_csv` splits on and the decimal mark :func:`to_si`
reads; it is recorded in ``campaign.json`` (``csv``, null when none). The same data in either dialect
gives the same SI series, bit for bit. With a decimal comma, a value holding a '.' is refused, naming
row and column: ``1.234,5`` (thousands separator) or ``1.5`` (a '.' file declared ',') could otherwise
be misread by a factor of 1000. Without a ``csv`` block, files are read exactly as before 1.1.

A case that parses but fails the time-series schema (NaN/inf, time not increasing) is
quarantined here too, naming the CSV column: ``campaign.write_ingested`` only accepts
schema-valid series.
"""

from __future__ import annotations

import codecs
import csv
import dataclasses
import datetime as dt
import io
import logging
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import timeseries_relpath, write_ingested
from isokinetic.contracts.manifest import (
    CSV_DELIMITERS,
    MANIFEST_NAME,
    TEMPERATURE_RANGE_C,
    UNIT_OFFSETS,
    UNITS,
    CaseSpec,
    Column,
    CsvDialect,
    Manifest,
    load_manifest,
)
from isokinetic.io import sha256_file
from isokinetic.stages.validate import Problem, quarantine_frame, quarantine_rows, timeseries_problems

log = logging.getLogger("isokinetic")

#: Channel -> canonical column of the ingested time series.
CANONICAL = {"time": "time_s", "displacement": "displacement_m", "force": "force_N", "command": "command_m",
             "temperature": "temperature_C"}


class CaseFileError(Exception):
    """A case file that cannot be read as a CSV table; carries the Problem."""

    def __init__(self, problem: Problem):
        super().__init__(problem.message)
        self.problem = problem


#: Byte-order marks of encodings other than UTF-8 (refused: the format is UTF-8).
FOREIGN_BOMS = {codecs.BOM_UTF32_LE: "UTF-32", codecs.BOM_UTF32_BE: "UTF-32",
                codecs.BOM_UTF16_LE: "UTF-16", codecs.BOM_UTF16_BE: "UTF-16"}
_INTEGER = re.compile(r"[+-]?\d+")
_DIGITS = re.compile(r"\d+(?:[eE][+-]?\d+)?")


def _data_lines(lines: list[str], header: int) -> list[tuple[int, str]]:
    """(data row, line) of the non-blank lines after the header: rows as pandas numbers them."""
    out = []
    for line in lines[header + 1:]:
        if line.strip():
            out.append((len(out), line))
    return out


def _encoding_problem(data: bytes, exc: UnicodeDecodeError, delimiter: str = ",") -> Problem:
    """The row and column of the first byte that is not UTF-8 (fields split on ``delimiter``)."""
    start = exc.start
    bad = data[start]
    line_start = data.rfind(b"\n", 0, start) + 1
    line_end = data.find(b"\n", start)
    line_end = len(data) if line_end < 0 else line_end
    lines = data[:line_start].decode("utf-8", errors="replace").split("\n")[:-1]
    header = next((i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")), None)
    if header is None:     # in a comment or the header itself
        text = data[line_start:line_end].rstrip(b"\r")
        return Problem("file", f"not UTF-8: byte 0x{bad:02x} in line {len(lines) + 1} ({text!r}), "
                               "before the data", kind="key")
    names = next(csv.reader([lines[header].rstrip("\r")], delimiter=delimiter))
    row = len(_data_lines(lines, header))
    sep = delimiter.encode()
    field = data.count(sep, line_start, start)
    fields = data[line_start:line_end].rstrip(b"\r").split(sep)
    raw = fields[field] if field < len(fields) else b""
    column = names[field].strip() if field < len(names) else "file"
    return Problem(column, f"not UTF-8: byte 0x{bad:02x} in {raw!r}", row=row,
                   kind="column" if field < len(names) else "key")


def _field_count_problem(names: list[str], row: int, fields: list[str], last: bool, ends_in_newline: bool,
                         delimiter: str = ","):
    """A data row whose field count differs from the header's (cut off, ragged, decimal commas when the
    fields are separated by ',')."""
    n, want = len(fields), len(names)
    if n < want:
        cut = last and not ends_in_newline
        what = "the file is cut off mid-row" if cut else "a ragged row"
        return Problem(names[n], f"row ends after {n} of {want} fields: {what}", row=row)
    extra, i = n - want, 0
    while delimiter == "," and extra > 0 and i < want and i + 1 < n:
        if _INTEGER.fullmatch(fields[i].strip()) and _DIGITS.fullmatch(fields[i + 1].strip()):
            return Problem(names[i], f"decimal comma in '{fields[i].strip()},{fields[i + 1].strip()}' (row has "
                                     f"{n} fields, the header {want}): the format needs ',' between fields "
                                     f"and '.' as the decimal mark", row=row)
        i += 1
    return Problem("file", f"row has {n} fields, the header {want}", row=row, kind="key")


def _delimiter_problem(header: str, dialect: CsvDialect | None) -> Problem | None:
    """A one-field header that holds another delimiter than the file's: ';' or tabs without a ``csv``
    block (the format's ','), any other of :data:`CSV_DELIMITERS` with one."""
    if dialect is None:
        for sep, label in ((";", "';'"), ("\t", "tabs")):
            if sep in header:
                return Problem("file", f"fields are separated by {label}, not ',' (header {header!r}): the format "
                                       "needs ',' between fields and '.' as the decimal mark", kind="key")
        return None
    for sep, label in CSV_DELIMITERS.items():
        if sep != dialect.delimiter and sep in header:
            return Problem("file", f"fields are separated by {label}, not {CSV_DELIMITERS[dialect.delimiter]} as "
                                   f"the manifest's csv block declares (header {header!r})", kind="key")
    return None


def read_case_csv(path: str | Path, warnings: list[str] | None = None,
                  dialect: CsvDialect | None = None) -> pd.DataFrame:
    """A case CSV as strings (NaN for empty/NA cells), opened read-only.

    Blank lines and ``#`` lines before the header are skipped; header names are stripped; a
    UTF-8 byte-order mark is stripped. Raises :class:`CaseFileError` for an empty file, bytes
    that are not UTF-8 (naming row and column), a header split by another delimiter than the
    file's (``;`` or tabs without ``dialect``), and a data row whose field count differs from the
    header's (a file cut off mid-row, decimal commas). A last row without a line end is kept, with
    a warning appended to ``warnings``. ``dialect`` (the manifest's ``csv`` block) sets the delimiter
    of every check and of the table; cells stay text (the decimal mark is :func:`to_si`'s).
    """
    delimiter = "," if dialect is None else dialect.delimiter
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise CaseFileError(Problem("file", f"unreadable CSV: {exc}", kind="key")) from None
    if not data:
        raise CaseFileError(Problem("file", "empty file (0 bytes)", kind="key"))
    for bom, encoding in FOREIGN_BOMS.items():
        if data.startswith(bom):
            raise CaseFileError(Problem("file", f"{encoding} byte-order mark: the file is {encoding}, "
                                                "the format needs UTF-8", kind="key"))
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CaseFileError(_encoding_problem(data, exc, delimiter)) from None
    if "\n" not in text and "\r" in text:       # old Mac line ends
        text = text.replace("\r", "\n")
    lines = text.split("\n")
    ends_in_newline = lines[-1] == ""
    if ends_in_newline:
        lines.pop()
    lines = [line[:-1] if line.endswith("\r") else line for line in lines]
    header = next((i for i, line in enumerate(lines) if line.strip() and not line.startswith("#")), None)
    if header is None:
        raise CaseFileError(Problem("file", "no header row", kind="key"))
    names = next(csv.reader([lines[header]], delimiter=delimiter))
    if len(names) == 1:
        problem = _delimiter_problem(lines[header], dialect)
        if problem is not None:
            raise CaseFileError(problem)
    names = [name.strip() for name in names]
    rows = _data_lines(lines, header)
    for (row, _), fields in zip(rows, csv.reader([line for _, line in rows], delimiter=delimiter)):
        if len(fields) != len(names):
            raise CaseFileError(_field_count_problem(names, row, fields, row == len(rows) - 1, ends_in_newline,
                                                     delimiter))
    if rows and not ends_in_newline and warnings is not None:
        warnings.append(f"no line end after the last row ({rows[-1][0]}): it may be cut off in its last value")
    try:
        df = pd.read_csv(io.StringIO("\n".join(lines[header:]) + "\n"), sep=delimiter, dtype=str,
                         skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise CaseFileError(Problem("file", "no header row", kind="key")) from None
    except pd.errors.ParserError as exc:
        raise CaseFileError(Problem("file", f"unreadable CSV: {exc}", kind="key")) from None
    df.columns = [str(c).strip() for c in df.columns]
    return df


def decimal_point(raw: pd.Series) -> pd.Series:
    """Text numbers written with a decimal comma, rewritten with '.' for parsing: ``-0,25`` -> ``-0.25``,
    ``1,5E-3`` -> ``1.5E-3``. A value holding a '.' becomes NaN (refused by :func:`to_si`): ``1.234,5``
    has a thousands separator, ``1.5`` was written with '.' decimals; neither is guessed."""
    text = raw.astype(object)
    dotted = text.str.contains(".", regex=False, na=False).astype(bool)
    return text.str.replace(",", ".", regex=False).mask(dotted)


def to_si(raw: pd.Series, channel: str, column: Column, decimal: str = ".") -> tuple[np.ndarray | None, Problem | None]:
    """One CSV column in SI (float64), or the first value that does not parse. ``decimal`` is the files'
    decimal mark (the manifest's ``csv`` block): with ',' numbers go through :func:`decimal_point`, and
    ISO 8601 stamps may carry a decimal comma in their seconds (``10:59:59,95``)."""
    note = ""
    if column.unit == "datetime":
        text = raw if decimal == "." else raw.astype(object).str.replace(",", ".", regex=False)
        stamps = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
        bad = stamps.isna() & raw.notna()
        values = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(float) if len(raw) else np.empty(0)
        what = "invalid ISO 8601 timestamp"
    else:
        numbers = pd.to_numeric(raw if decimal == "." else decimal_point(raw), errors="coerce")
        bad = numbers.isna() & raw.notna()
        values = numbers.to_numpy(float) * UNITS[channel][column.unit] + UNIT_OFFSETS.get((channel, column.unit), 0.0)
        what = "non-numeric value"
        if decimal != ".":
            note = (": the manifest's csv block declares ',' as the decimal mark, and a '.' is not read (a thousands "
                    "separator? a file written with '.' decimals?)")
    if bad.any():
        first = int(np.argmax(bad.to_numpy()))
        value = raw.iloc[first]
        return None, Problem(column.name, f"{what} {value!r}" + (note if "." in str(value) else ""), row=first)
    if channel == "temperature":
        return temperature_values(values, column)
    return (-values if column.invert else values), None


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


def ingest_case(campaign_dir: Path, campaign: str, spec: CaseSpec,
                campaign_temperature_C: float | None = None) -> tuple[dict, list[Problem], pd.DataFrame | None]:
    """One case: its CASES row, its problems, and its time series when it is ok (read in the manifest's
    dialect, ``spec.csv``; less its gas force, ``spec.gas_force_N``: :func:`subtract_gas_force`). The row's
    temperature: :func:`case_temperature` (``campaign_temperature_C``: the manifest's)."""
    problems = list(spec.problems)
    path = campaign_dir / spec.file if spec.file is not None else None
    sha, n_samples, df, warnings = "", 0, None, []
    if path is not None:
        if path.is_file():
            sha = sha256_file(path)
        else:
            problems.append(Problem("file", f"file not found: {path.as_posix()}", kind="key"))
    if not problems:
        try:
            raw = read_case_csv(path, warnings, spec.csv)
        except CaseFileError as exc:
            problems.append(exc.problem)
        else:
            n_samples = len(raw)
            df, problems = canonical_timeseries(raw, spec.columns, "." if spec.csv is None else spec.csv.decimal)
    if df is not None:
        df = subtract_gas_force(df, spec.gas_force_N)
        names = {CANONICAL[ch]: col.name for ch, col in spec.columns.items()}
        problems = [dataclasses.replace(p, column=names.get(p.column, p.column)) for p in timeseries_problems(df)]
    row = {"campaign": campaign, **dataclasses.asdict(spec.plan),
           "raw_file": path.as_posix() if path is not None else str(spec.keys.get("file") or ""),
           "raw_sha256": sha, "timeseries_file": "" if problems else timeseries_relpath(spec.id),
           "n_samples": n_samples, "status": "quarantined" if problems else "ok",
           "quality": "quarantined" if problems else ("; ".join(warnings) or "ok")}
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
            "manifest_file": manifest_file, "manifest_sha256": manifest.sha256,
            "metadata": jsonable(manifest.metadata)}


def ingest_campaign(campaign_dir: str | Path, campaign_root: str | Path) -> None:
    """Ingest ``campaign_dir`` (as given, e.g. ``data/raw/<c>``) into ``<campaign_root>/ingest``."""
    campaign_dir = Path(campaign_dir)
    manifest_file = campaign_dir / MANIFEST_NAME
    manifest = load_manifest(manifest_file)
    rows, quarantined, series = [], [], {}
    for spec in manifest.cases:
        row, problems, df = ingest_case(campaign_dir, manifest.campaign, spec, manifest.temperature_C)
        rows.append(row)
        quarantined += quarantine_rows(manifest.campaign, spec.id, "ingest", problems)
        if df is not None:
            series[spec.id] = df
    log.info("campaign %s: %d of %d cases ingested, %d quarantined", manifest.campaign, len(series),
             len(rows), len(rows) - len(series))
    if manifest.csv is not None:
        log.info("campaign %s: case files read with delimiter %r and decimal mark %r (manifest csv block)",
                 manifest.campaign, manifest.csv.delimiter, manifest.csv.decimal)
    if manifest.gas_force_N:
        log.info("campaign %s: gas force %g N subtracted from every force sample (manifest gas_force_N)",
                 manifest.campaign, manifest.gas_force_N)
    write_ingested(Path(campaign_root) / "ingest", campaign_meta(manifest, manifest_file.as_posix()),
                   pd.DataFrame(rows), quarantine_frame(quarantined), series)
