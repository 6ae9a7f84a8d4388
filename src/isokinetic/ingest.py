"""Raw ingest: ``data/raw/<campaign>/`` (campaign.yaml + one CSV per case) to ``<campaign_root>/ingest/``.

Each case CSV is mapped to the canonical SI time series (``row``, ``time_s``,
``displacement_m``, ``force_N``, ``command_m``). A case whose file or columns are unusable is
quarantined (stage ``ingest``) and every other case carries on; a broken manifest raises
:class:`isokinetic.manifest.ManifestError`. Raw files are only ever opened for reading.

A case that parses but fails the time-series schema (NaN/inf, time not increasing) is
quarantined here too, naming the CSV column: ``campaign.write_ingested`` only accepts
schema-valid series.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from .campaign import timeseries_relpath, write_ingested
from .io import sha256_file
from .manifest import MANIFEST_NAME, UNITS, CaseSpec, Column, Manifest, load_manifest
from .validate import Problem, quarantine_frame, quarantine_rows, timeseries_problems

log = logging.getLogger("isokinetic")

#: Channel -> canonical column of the ingested time series.
CANONICAL = {"time": "time_s", "displacement": "displacement_m", "force": "force_N", "command": "command_m"}


class CaseFileError(Exception):
    """A case file that cannot be read as a CSV table; carries the Problem."""

    def __init__(self, problem: Problem):
        super().__init__(problem.message)
        self.problem = problem


def read_case_csv(path: str | Path) -> pd.DataFrame:
    """A case CSV as strings (NaN for empty/NA cells), opened read-only.

    Blank lines and ``#`` lines before the header are skipped; header names are stripped.
    """
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            while True:
                start = fh.tell()
                line = fh.readline()
                if not line or (line.strip() and not line.startswith("#")):
                    fh.seek(start)
                    break
            df = pd.read_csv(fh, dtype=str, skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise CaseFileError(Problem("file", "no header row", kind="key")) from None
    except (pd.errors.ParserError, UnicodeDecodeError, OSError) as exc:
        raise CaseFileError(Problem("file", f"unreadable CSV: {exc}", kind="key")) from None
    df.columns = [str(c).strip() for c in df.columns]
    return df


def to_si(raw: pd.Series, channel: str, column: Column) -> tuple[np.ndarray | None, Problem | None]:
    """One CSV column in SI (float64), or the first value that does not parse."""
    if column.unit == "datetime":
        stamps = pd.to_datetime(raw, format="ISO8601", utc=True, errors="coerce")
        bad = stamps.isna() & raw.notna()
        values = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(float) if len(raw) else np.empty(0)
        what = "invalid ISO 8601 timestamp"
    else:
        numbers = pd.to_numeric(raw, errors="coerce")
        bad = numbers.isna() & raw.notna()
        values = numbers.to_numpy(float) * UNITS[channel][column.unit]
        what = "non-numeric value"
    if bad.any():
        first = int(np.argmax(bad.to_numpy()))
        return None, Problem(column.name, f"{what} {raw.iloc[first]!r}", row=first)
    return (-values if column.invert else values), None


def canonical_timeseries(raw: pd.DataFrame, columns: dict[str, Column]) -> tuple[pd.DataFrame | None, list[Problem]]:
    """The canonical SI time series of a case, or the problems of its columns (one per column)."""
    present = ", ".join(map(str, raw.columns))
    problems = [Problem(col.name, f"column not in the file (header: {present})")
                for col in columns.values() if col.name not in raw.columns]
    if problems:
        return None, problems
    out = {"row": np.arange(len(raw), dtype="int64")}
    for channel, col in columns.items():
        values, problem = to_si(raw[col.name], channel, col)
        if problem is not None:
            problems.append(problem)
        out[CANONICAL[channel]] = values
    if problems:
        return None, problems
    return pd.DataFrame(out, columns=["row"] + [CANONICAL[ch] for ch in CANONICAL if ch in columns]), []


def ingest_case(campaign_dir: Path, campaign: str, spec: CaseSpec) -> tuple[dict, list[Problem], pd.DataFrame | None]:
    """One case: its CASES row, its problems, and its time series when it is ok."""
    problems = list(spec.problems)
    path = campaign_dir / spec.file if spec.file is not None else None
    sha, n_samples, df = "", 0, None
    if path is not None:
        if path.is_file():
            sha = sha256_file(path)
        else:
            problems.append(Problem("file", f"file not found: {path.as_posix()}", kind="key"))
    if not problems:
        try:
            raw = read_case_csv(path)
        except CaseFileError as exc:
            problems.append(exc.problem)
        else:
            n_samples = len(raw)
            df, problems = canonical_timeseries(raw, spec.columns)
    if df is not None:
        names = {CANONICAL[ch]: col.name for ch, col in spec.columns.items()}
        problems = [dataclasses.replace(p, column=names.get(p.column, p.column)) for p in timeseries_problems(df)]
    row = {"campaign": campaign, **dataclasses.asdict(spec.plan),
           "raw_file": path.as_posix() if path is not None else str(spec.keys.get("file") or ""),
           "raw_sha256": sha, "timeseries_file": "" if problems else timeseries_relpath(spec.id),
           "n_samples": n_samples, "status": "quarantined" if problems else "ok"}
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
        row, problems, df = ingest_case(campaign_dir, manifest.campaign, spec)
        rows.append(row)
        quarantined += quarantine_rows(manifest.campaign, spec.id, "ingest", problems)
        if df is not None:
            series[spec.id] = df
    log.info("campaign %s: %d of %d cases ingested, %d quarantined", manifest.campaign, len(series),
             len(rows), len(rows) - len(series))
    write_ingested(Path(campaign_root) / "ingest", campaign_meta(manifest, manifest_file.as_posix()),
                   pd.DataFrame(rows), quarantine_frame(quarantined), series)
