"""The measured drive (paper Sec. 4.4-4.5): the half-period speeds and sample grid a case actually ran.

The model run "on equal terms" (:mod:`isokinetic.measurement.model_windows`) and the diagnosis'
observations drive the model with each case's measured half-period speeds (the least-squares slope of
the measured displacement in each window) on the record's own sample grid, rather than with the plan.
"""

from __future__ import annotations

import math

import pandas as pd

from isokinetic.measurement.windows import motion_start
from isokinetic.physics.responses import Drive


def grid_offset(first_time_s: float, motion_start_s: float, sample_rate_Hz: float) -> float:
    """Plan time in [0, 1/fs) of the first sample after the motion start, on a uniform grid [s]."""
    phase = (first_time_s - motion_start_s) * sample_rate_Hz
    frac = phase - math.floor(phase)
    return 0.0 if frac < 1e-9 or frac > 1.0 - 1e-9 else frac / sample_rate_Hz


def case_drives(cases: pd.DataFrame, windows: pd.DataFrame | None) -> dict[str, Drive]:
    """The measured drive of every status-ok triangle case with four measured windows.

    Speeds: |velocity_m_s| of the case's windows, segments 1-4 (the least-squares slope of the
    measured displacement in each half-period's window); grid offset from the record's first time
    stamp (``motion_start_s - delay_s``) and its motion start (:func:`grid_offset`).
    """
    if windows is None or windows.empty:
        return {}
    out = {}
    by_case = {c: g.sort_values("segment") for c, g in windows.groupby("case")}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    for _, row in ok.iterrows():
        g = by_case.get(str(row["case"]))
        if g is None:
            continue
        start = motion_start(row)
        delay = row.get("delay_s", 0.0)
        delay = float(delay) if delay is not None and math.isfinite(float(delay)) else 0.0
        drive = measured_drive(g["segment"], g["velocity_m_s"], start - delay, start, float(row["sample_rate_Hz"]))
        if drive is not None:
            out[str(row["case"])] = drive
    return out


def measured_drive(segments, velocities_m_s, first_time_s: float, motion_start_s: float,
                   sample_rate_Hz: float) -> Drive | None:
    """The drive of one case: |velocity| of its windows 1-4 (in segment order) and the plan time of its
    first sample on the uniform grid (:func:`grid_offset`); None without four finite, non-zero speeds."""
    pairs = sorted(zip((int(k) for k in segments), velocities_m_s))
    speeds = tuple(float(abs(v)) for _, v in pairs)
    if [k for k, _ in pairs] != [1, 2, 3, 4] or not all(math.isfinite(v) and v > 0 for v in speeds):
        return None
    return Drive(speeds, grid_offset(first_time_s, motion_start_s, sample_rate_Hz))
