"""A problem with one case: the unit of the quarantine table (ingest, validate) and of manifest checks."""

from __future__ import annotations

from dataclasses import dataclass


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
