"""Rule ``design_summary``: every campaign's plan check in one table (``results/design/plan_check.parquet``).

The per-campaign tables come from the rule ``design`` (:func:`isokinetic.stages.design.plan_check`,
Sec. 4.2-4.3 of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs", Titurus et al.); this stage only stacks them, in input order.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.io import write_parquet


def design_summary(plan_checks: Sequence[pd.DataFrame]) -> pd.DataFrame:
    """The plan checks stacked (tables.PLAN_CHECK), an empty table of that schema for none."""
    summary = pd.concat(plan_checks, ignore_index=True) if plan_checks else tables.empty(tables.PLAN_CHECK)
    return tables.validate_table(summary, tables.PLAN_CHECK)


def write_design_summary(plan_check_paths: Sequence[str | os.PathLike], out_path: str | os.PathLike) -> pd.DataFrame:
    """Read every campaign's ``design/plan_check.parquet``, write their stack to ``out_path``; returns it."""
    summary = design_summary([pd.read_parquet(Path(p)) for p in plan_check_paths])
    write_parquet(summary, out_path)
    return summary
