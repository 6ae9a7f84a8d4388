"""Characteristic assembly (Sec. 4.5, Fig. 9): the steady force-velocity points of a campaign.

Rule ``characteristic`` runs the stages from an ingested campaign folder to its characteristic in
one process (:func:`write_characteristic`): validate (:mod:`isokinetic.stages.validate`) ->
windows (:mod:`isokinetic.stages.windows`) -> repeatability
(:mod:`isokinetic.stages.repeatability`) -> :func:`assemble`. The blind suite runs the same function.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_parquet
from isokinetic.stages.repeatability import repeatability
from isokinetic.stages.validate import write_validated
from isokinetic.stages.windows import WindowSpec, windows_stage

log = logging.getLogger(__name__)

WINDOWS_FILE = STAGE_OUTPUTS["windows"]["windows"]
REPEATABILITY_FILE = STAGE_OUTPUTS["repeatability"]["repeatability"]
CHARACTERISTIC_FILE = STAGE_OUTPUTS["characteristic"]["characteristic"]


def assemble(windows: pd.DataFrame, repeatability: pd.DataFrame) -> pd.DataFrame:
    """Windows joined with their case/direction repeatability flag, ordered by velocity."""
    keys = ["campaign", "case", "direction"]
    flags = repeatability[keys + ["flagged"]].rename(columns={"flagged": "repeatability_flagged"})
    char = windows.merge(flags, on=keys, how="left", validate="many_to_one")
    char["repeatability_flagged"] = char["repeatability_flagged"].fillna(False).astype(bool)
    char = char.sort_values(["velocity_m_s", "case", "segment"], ignore_index=True)
    return tables.validate_table(char, tables.CHARACTERISTIC)


def write_characteristic(campaign_root: str | os.PathLike, spec: WindowSpec = WindowSpec(), *,
                         repeatability_tolerance: float = 0.05, sample_rate_tolerance: float = 0.05
                         ) -> pd.DataFrame:
    """validate -> windows -> repeatability -> characteristic of an ingested campaign folder
    (``results/<campaign>/`` holding ``ingest/``): writes cases, quarantine, windows, repeatability
    and characteristic tables there; returns the characteristic. Flagged repeatability is logged."""
    root = Path(campaign_root)
    write_validated(root, sample_rate_tolerance=sample_rate_tolerance, window_spec=spec)
    windows = windows_stage(root, spec)
    write_parquet(windows, root / WINDOWS_FILE)
    rep = repeatability(windows, repeatability_tolerance)
    write_parquet(rep, root / REPEATABILITY_FILE)
    for row in rep[rep["flagged"]].itertuples():
        log.warning("campaign %s, case %s, direction %s: period 2 differs from period 1 by %+.1f %% "
                    "(tolerance %.1f %%)", row.campaign, row.case, row.direction, 100 * row.rel_diff,
                    100 * row.tolerance)
    char = assemble(windows, rep)
    write_parquet(char, root / CHARACTERISTIC_FILE)
    log.info("%d windows from %d cases, %d characteristic points", len(windows),
             windows["case"].nunique() if len(windows) else 0, len(char))
    return char
