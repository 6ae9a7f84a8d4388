"""Characteristic assembly (Sec. 4.5, Fig. 9): the steady force-velocity points of a campaign."""

from __future__ import annotations

import pandas as pd

from isokinetic.contracts import tables


def assemble(windows: pd.DataFrame, repeatability: pd.DataFrame) -> pd.DataFrame:
    """Windows joined with their case/direction repeatability flag, ordered by velocity."""
    keys = ["campaign", "case", "direction"]
    flags = repeatability[keys + ["flagged"]].rename(columns={"flagged": "repeatability_flagged"})
    char = windows.merge(flags, on=keys, how="left", validate="many_to_one")
    char["repeatability_flagged"] = char["repeatability_flagged"].fillna(False).astype(bool)
    char = char.sort_values(["velocity_m_s", "case", "segment"], ignore_index=True)
    return tables.validate_table(char, tables.CHARACTERISTIC)
