"""Input checks: bad cases are quarantined one by one, every other case carries on.

A :class:`Problem` says what is wrong with one case (column or manifest key, first bad data
row, message); :func:`reason` turns it into the quarantine text, which names campaign, case,
column and row, e.g. ``campaign demo, case T03, column 'force_kN', row 17: non-numeric value 'abc'``.

:func:`validate_campaign` checks every case an ingest left ``ok`` (raw or simulated alike):
the canonical time-series schema (NaN/inf, time not strictly increasing), too few samples,
a record shorter than the plan needs, a sample rate far from the manifest's.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pandera.pandas as pa

from . import tables
from .campaign import case_plan, read_ingested
from .io import write_parquet
from .plan import CasePlan

log = logging.getLogger("isokinetic")

#: Fewer samples than this cannot describe a record (and leave no sample interval to check).
MIN_SAMPLES = 10
QUARANTINE_COLUMNS = tuple(tables.QUARANTINE.columns)


@dataclass(frozen=True)
class Problem:
    """What is wrong with one case.

    ``column`` is a data column (``kind="column"``: the CSV's at ingest, the canonical one at
    validation) or a manifest key of the case (``kind="key"``: ``file``, ``period_s``, ...).
    ``row`` is the first bad 0-based data row, None when no single row is at fault.
    """

    column: str
    message: str
    row: int | None = None
    kind: str = "column"


def reason(campaign: str, case: str, problem: Problem) -> str:
    """The quarantine text: ``campaign C, case K, column 'x', row N: message``."""
    where = [f"campaign {campaign}", f"case {case}", f"{problem.kind} {problem.column!r}"]
    if problem.row is not None:
        where.append(f"row {problem.row}")
    return ", ".join(where) + ": " + problem.message


def quarantine_rows(campaign: str, case: str, stage: str, problems: Iterable[Problem]) -> list[dict]:
    """QUARANTINE rows for one case's problems; each reason is also logged."""
    rows = []
    for problem in problems:
        text = reason(campaign, case, problem)
        log.warning("quarantined at %s: %s", stage, text)
        rows.append({"campaign": campaign, "case": case, "stage": stage, "column": problem.column,
                     "row": problem.row, "reason": text})
    return rows


def quarantine_frame(rows: list[dict]) -> pd.DataFrame:
    """A QUARANTINE table from rows (empty rows give the empty table)."""
    if not rows:
        return tables.empty(tables.QUARANTINE)
    return pd.DataFrame(rows, columns=list(QUARANTINE_COLUMNS)).astype({"row": "Int64"})


def _failure_message(check: str, value, previous) -> str:
    if check == "not_nullable":
        return "missing value (NaN)"
    if check == "finite":
        return f"non-finite value {value}"
    if check == "time_increasing":
        return f"time {value} s is not above the previous row's {previous} s"
    if check == "column_in_dataframe":
        return "column missing"
    return f"failed {check}: {value}"


def timeseries_problems(df: pd.DataFrame) -> list[Problem]:
    """TIMESERIES schema failures, one per column, at the first bad data row (``row`` value)."""
    try:
        tables.TIMESERIES.validate(df, lazy=True)
    except pa.errors.SchemaErrors as exc:
        failures = exc.failure_cases
    else:
        return []
    data_rows = df["row"] if "row" in df else pd.Series(np.arange(len(df)), index=df.index)
    found: dict[str, Problem] = {}
    for f in failures.itertuples(index=False):
        column = f.failure_case if f.check == "column_in_dataframe" else f.column
        row, previous = None, None
        if not pd.isna(f.index):
            position = df.index.get_loc(f.index)
            row = int(data_rows.iloc[position])
            previous = df[column].iloc[position - 1] if position > 0 else None
        known = found.get(column)
        if known is None or (row is not None and (known.row is None or row < known.row)):
            found[column] = Problem(column, _failure_message(str(f.check), f.failure_case, previous), row=row)
    return list(found.values())


def record_problems(time_s: np.ndarray, plan: CasePlan, sample_rate_tolerance: float = 0.05,
                    min_samples: int = MIN_SAMPLES) -> list[Problem]:
    """Too few samples, shorter than the plan needs (one sample interval of slack), or a median
    sample interval off 1/sample_rate_Hz by more than the tolerance. Time must be valid already."""
    n = len(time_s)
    if n < min_samples:
        return [Problem("time_s", f"only {n} samples, at least {min_samples} needed")]
    problems = []
    dt_s = 1.0 / plan.sample_rate_Hz
    duration_s = float(time_s[-1] - time_s[0])
    need_s = plan.required_duration_s
    if duration_s < (need_s - dt_s) * (1.0 - 1e-9):
        problems.append(Problem("time_s", f"record lasts {duration_s:.6g} s, the {plan.waveform} plan needs "
                                          f"{need_s:.6g} s (less one sample interval, {dt_s:.6g} s)"))
    median_dt_s = float(np.median(np.diff(time_s)))
    off = median_dt_s / dt_s - 1.0
    if abs(off) > sample_rate_tolerance:
        problems.append(Problem("time_s", f"median sample interval {median_dt_s:.6g} s is {off:+.1%} off "
                                          f"1/sample_rate_Hz = {dt_s:.6g} s (tolerance {sample_rate_tolerance:.1%})"))
    return problems


def case_problems(df: pd.DataFrame, plan: CasePlan, sample_rate_tolerance: float = 0.05,
                  min_samples: int = MIN_SAMPLES) -> list[Problem]:
    """All checks of one canonical time series; record checks only once the schema holds."""
    return timeseries_problems(df) or record_problems(df["time_s"].to_numpy(), plan, sample_rate_tolerance,
                                                      min_samples)


def validate_campaign(campaign_root: str | Path, sample_rate_tolerance: float = 0.05,
                      min_samples: int = MIN_SAMPLES) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Check every ``ok`` case of ``<campaign_root>/ingest``.

    Returns (cases, quarantine): all cases with their final status, and the ingest's
    quarantine rows followed by this stage's (``stage="validate"``).
    """
    ingested = read_ingested(campaign_root)
    campaign = ingested.meta["campaign"]
    cases = ingested.cases.copy()
    rows = []
    for i, row in cases[cases["status"] == "ok"].iterrows():
        df = pd.read_parquet(ingested.root / row["timeseries_file"])
        problems = case_problems(df, case_plan(row), sample_rate_tolerance, min_samples)
        if problems:
            cases.loc[i, "status"] = "quarantined"
            rows += quarantine_rows(campaign, row["case"], "validate", problems)
    quarantine = ingested.quarantine
    if rows:
        new = quarantine_frame(rows)
        quarantine = new if quarantine.empty else pd.concat([quarantine, new], ignore_index=True)
    return cases, quarantine


def write_validated(campaign_root: str | Path, sample_rate_tolerance: float = 0.05,
                    min_samples: int = MIN_SAMPLES) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Validate and write ``<campaign_root>/cases.parquet`` and ``quarantine.parquet``."""
    root = Path(campaign_root)
    cases, quarantine = validate_campaign(root, sample_rate_tolerance, min_samples)
    write_parquet(tables.validate_table(quarantine, tables.QUARANTINE), root / "quarantine.parquet")
    write_parquet(tables.validate_table(cases, tables.CASES), root / "cases.parquet")
    return cases, quarantine
