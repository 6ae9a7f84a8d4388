"""Repeatability (Sec. 4.4-4.5): the steady force of period 1 against period 2.

Triangle windows have two periods; a sine case's peak-velocity points (stages.characteristic) the
first and second half of its steady cycles. A case and direction without both periods (a sine case of
fewer than four steady cycles a direction) has no row.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from isokinetic.contracts import tables


def relative_difference(force_1, force_2):
    """(F2 - F1) / mean(|F1|, |F2|) [-]: signed, symmetric in magnitude."""
    f1 = np.asarray(force_1, dtype=float)
    f2 = np.asarray(force_2, dtype=float)
    return (f2 - f1) / (0.5 * (np.abs(f1) + np.abs(f2)))


def repeatability(windows: pd.DataFrame, tolerance: float) -> pd.DataFrame:
    """One row per case and direction; ``flagged`` where |relative difference| > tolerance."""
    if tolerance <= 0:
        raise ValueError(f"repeatability tolerance must be positive, got {tolerance}")
    keys = ["campaign", "case", "direction"]
    if windows.empty:
        return tables.empty(tables.REPEATABILITY)
    wide = windows.pivot_table(index=keys, columns="period", values=["force_N", "velocity_m_s"], aggfunc="first")
    if ("force_N", 1) not in wide or ("force_N", 2) not in wide:
        return tables.empty(tables.REPEATABILITY)
    wide = wide[wide[("force_N", 1)].notna() & wide[("force_N", 2)].notna()]
    out = pd.DataFrame({
        "velocity_m_s": wide[("velocity_m_s", 1)].to_numpy() * 0.5 + wide[("velocity_m_s", 2)].to_numpy() * 0.5,
        "force_period1_N": wide[("force_N", 1)].to_numpy(),
        "force_period2_N": wide[("force_N", 2)].to_numpy(),
    }, index=wide.index).reset_index()
    out["rel_diff"] = relative_difference(out["force_period1_N"], out["force_period2_N"])
    out["tolerance"] = float(tolerance)
    out["flagged"] = (out["rel_diff"].abs() > tolerance).astype(bool)
    out = out.sort_values(["campaign", "direction", "velocity_m_s"], ignore_index=True)
    return tables.validate_table(out, tables.REPEATABILITY)
