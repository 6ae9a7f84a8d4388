"""Characteristic assembly (Sec. 4.5, Fig. 9): the steady force-velocity points of a campaign.

Rule ``characteristic`` runs the stages from an ingested campaign folder to its characteristic in
one process (:func:`write_characteristic`): validate (:mod:`isokinetic.stages.validate`) ->
windows (:mod:`isokinetic.measurement.windows`) -> repeatability
(:mod:`isokinetic.measurement.repeatability`) -> :func:`assemble`. The blind suite runs the same function.

Every point carries its ``method`` (tables.CHARACTERISTIC_METHODS):

- ``triangle_window``: a triangle case's constant-velocity window (four a case), as before;
- ``sine_peak``: a status-ok sine case's force at peak velocity (:mod:`isokinetic.measurement.peak_velocity`)
  over its steady cycles, per direction, the cycles averaged. So that repeatability applies as to a
  triangle case, period 1 averages the first half of the steady cycles and period 2 the second half
  (segments 1 '+', 2 '-' of period 1, 3 '+', 4 '-' of period 2; with 2-3 cycles a direction, period 1
  only; a step too short for two cycles a direction after the first period, e.g. a slice of a sweep,
  keeps its first period unless its force still drifts). ``n_samples`` counts the cycles and
  ``force_std_N`` is their scatter, so force_std_N / sqrt(n_samples) is the point's standard error, as
  for a window. ``planned_velocity_m_s`` is 2 pi f Y; the row range spans the samples of the fits;
- ``free_bin``: a status-ok free case's velocity bin (:func:`isokinetic.measurement.loops.binned_characteristic`),
  segment = the bin's number, period 1, ``planned_velocity_m_s`` the bin's centre, ``n_samples`` its samples.

The sine cases' energy per cycle goes to ``energy.parquet`` (tables.ENERGY).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_parquet
from isokinetic.measurement.loops import binned_characteristic, dominant_period_s, free_loop
from isokinetic.measurement.peak_velocity import (
    PeakSpec,
    cycle_energies,
    peak_points,
    settled,
    steady_range,
    summarise,
)
from isokinetic.measurement.repeatability import repeatability
from isokinetic.measurement.windows import WindowSpec, extract_windows
from isokinetic.stages.validate import GapTolerance, write_validated

log = logging.getLogger(__name__)

WINDOWS_FILE = STAGE_OUTPUTS["windows"]["windows"]
REPEATABILITY_FILE = STAGE_OUTPUTS["repeatability"]["repeatability"]
CHARACTERISTIC_FILE = STAGE_OUTPUTS["characteristic"]["characteristic"]
ENERGY_FILE = STAGE_OUTPUTS["characteristic"]["energy"]

#: The peak-velocity method's default settings.
PEAK_SPEC = PeakSpec()
#: Fewest cycles a direction a sine point averages (a scatter needs two); four give two periods.
MIN_CYCLES = 2
ENERGY_COLUMNS = list(tables.ENERGY.columns) + ["window_start_s", "window_end_s", "raw_file", "raw_sha256"]


def windows_stage(campaign_root, spec: WindowSpec = WindowSpec()) -> pd.DataFrame:
    """Windows of a validated campaign folder ``results/<campaign>/`` (reads cases.parquet)."""
    folder = CampaignFolder.at(campaign_root)
    return extract_windows(folder.validated_cases(), folder.timeseries, spec)


def assemble(windows: pd.DataFrame, repeatability: pd.DataFrame, records: pd.DataFrame | None = None) -> pd.DataFrame:
    """Windows (and the sine/free ``records`` points of :func:`record_points`) joined with their case/direction
    repeatability flag, ordered by velocity; ``method`` 'triangle_window' for the windows."""
    keys = ["campaign", "case", "direction"]
    parts = [windows.assign(method="triangle_window")]
    if records is not None and len(records):
        absent = [c for c in parts[0].columns if c not in records.columns]   # e.g. the windows' missing_samples
        parts.append(records.reindex(columns=parts[0].columns).astype({c: parts[0][c].dtype for c in absent}))
    char = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    flags = repeatability[keys + ["flagged"]].rename(columns={"flagged": "repeatability_flagged"})
    char = char.merge(flags, on=keys, how="left", validate="many_to_one")
    char["repeatability_flagged"] = char["repeatability_flagged"].eq(True).astype(bool)   # no flag: False
    char = char[[c for c in char.columns if c != "method"] + ["method"]]
    char = char.sort_values(["velocity_m_s", "case", "segment"], ignore_index=True)
    return tables.validate_table(char, tables.CHARACTERISTIC)


# ----------------------------------------------------------------------------------------------
# sine and free records
# ----------------------------------------------------------------------------------------------

def _base(case) -> dict:
    quality = case.get("quality", "ok")
    return {"campaign": str(case["campaign"]), "case": str(case["case"]), "raw_file": str(case["raw_file"]),
            "raw_sha256": str(case["raw_sha256"]), "quality": quality if isinstance(quality, str) else "ok"}


def _number(value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        return math.nan
    return value if math.isfinite(value) else math.nan


def _span(t: np.ndarray, rows: np.ndarray, i0: int, i1: int) -> dict:
    """Times and raw rows of the samples [i0, i1), and the samples of the record's grid (its median
    interval) missing between them."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    grid = int(round((t[i1 - 1] - t[i0]) / dt)) + 1 if dt > 0 else i1 - i0
    return {"window_start_s": float(t[i0]), "window_end_s": float(t[i1 - 1]), "row_start": int(rows[i0]),
            "row_stop": int(rows[i1 - 1]) + 1, "missing_samples": max(0, grid - (i1 - i0))}


def sine_points(case, series: pd.DataFrame, spec: PeakSpec = PEAK_SPEC) -> tuple[list[dict], dict | None]:
    """(characteristic rows, energy row or None) of one sine case (module doc). Raises ValueError when the
    record holds no whole period."""
    s = series.sort_values("time_s", kind="stable")
    t, x, f = (s[c].to_numpy(dtype=float) for c in ("time_s", "displacement_m", "force_N"))
    rows = s["row"].to_numpy(dtype=np.int64) if "row" in s else np.arange(len(s), dtype=np.int64)
    freq = _number(case.get("frequency_Hz"))
    if not freq > 0:
        freq = 1.0 / dominant_period_s(t, x)
    period = 1.0 / freq
    a, b = steady_range(t, f, period, spec)
    pts = settled(peak_points(t, x, f, period, t_start=a, t_stop=b, spec=spec))
    if spec.skip_periods and pts["direction"].value_counts().reindex(["+", "-"], fill_value=0).min() < MIN_CYCLES:
        # a short step (a slice of a sweep, not started from rest): no start-up period skipped by rule,
        # the drift check and the settling of the cycles' forces only
        short = replace(spec, skip_periods=0)
        a, b = steady_range(t, f, period, short)
        pts = settled(peak_points(t, x, f, period, t_start=a, t_stop=b, spec=short))
    steady = (t >= a) & (t < b)
    amp = _number(case.get("amplitude_m"))
    if not amp > 0:
        amp = 0.5 * float(x[steady].max() - x[steady].min())
    base = _base(case)
    out = []
    for d, sign in (("+", 1.0), ("-", -1.0)):
        p = pts[pts["direction"] == d]
        n = len(p)
        if n < MIN_CYCLES:
            continue
        halves = [(1, p.iloc[:n // 2]), (2, p.iloc[n // 2:])] if n >= 2 * MIN_CYCLES else [(1, p)]
        for period_no, part in halves:
            r = summarise(part).iloc[0]
            out.append({**base, "segment": (1 if sign > 0 else 2) + 2 * (period_no - 1), "direction": d,
                        "period": period_no, "planned_velocity_m_s": sign * 2.0 * math.pi * freq * amp,
                        "velocity_m_s": float(r["velocity_m_s"]), "force_N": float(r["force_N"]),
                        "force_std_N": float(r["force_std_N"]), "n_samples": int(r["n_cycles"]),
                        **_span(t, rows, int(part["i_start"].min()), int(part["i_stop"].max())),
                        "method": "sine_peak"})
    energy = cycle_energies(t, x, f, period, points=pts, spec=spec)
    if energy.empty:
        return out, None
    e = energy["energy_J"].to_numpy(float)
    n = e.size
    x_amp = float(energy["amplitude_m"].mean())
    w = 2.0 * math.pi * freq
    std = float(e.std(ddof=1)) if n > 1 else math.nan
    i0, i1 = int(energy["i_start"].min()), int(energy["i_stop"].max())
    return out, {"campaign": base["campaign"], "case": base["case"], "frequency_Hz": freq,
                 "displacement_amplitude_m": x_amp,
                 "velocity_amplitude_m_s": float(pts["velocity_m_s"].abs().mean()) if len(pts) else math.nan,
                 "energy_J": float(e.mean()), "energy_std_J": std, "energy_se_J": std / math.sqrt(n),
                 "n_cycles": n, "equivalent_damping_N_s_m": float(e.mean()) / (math.pi * w * x_amp ** 2)
                 if x_amp > 0 else math.nan,
                 **_span(t, rows, i0, min(i1, t.size)), "raw_file": base["raw_file"], "raw_sha256": base["raw_sha256"]}


def free_points(case, series: pd.DataFrame) -> list[dict]:
    """Characteristic rows of one free case: its velocity bins (module doc)."""
    lp = free_loop(series)
    bins = binned_characteristic(lp)
    base = _base(case)
    t = lp["time_s"].to_numpy(dtype=float)
    span = {**_span(t, np.zeros(t.size, dtype=np.int64), 0, t.size),
            "row_start": int(lp.attrs["row_start"]), "row_stop": int(lp.attrs["row_stop"])}
    return [{**base, "segment": k, "direction": r["direction"], "period": 1,
             "planned_velocity_m_s": 0.5 * (r["bin_low_m_s"] + r["bin_high_m_s"]),
             "velocity_m_s": float(r["velocity_m_s"]), "force_N": float(r["force_N"]),
             "force_std_N": float(r["force_std_N"]), "n_samples": int(r["n_points"]), **span, "method": "free_bin"}
            for k, r in enumerate(bins.to_dict("records"), start=1)]


def record_points(cases: pd.DataFrame, load_series: Callable, spec: PeakSpec = PEAK_SPEC
                  ) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """(characteristic rows of the status-ok sine and free cases, their energy table, notes). A case that
    cannot be reduced (shorter than a period, too few cycles) is named in the notes and logged."""
    rows: list[dict] = []
    energy: list[dict] = []
    notes: list[str] = []
    ok = cases[(cases["status"] == "ok") & cases["waveform"].isin(["sine", "free"])] if len(cases) else cases
    for _, case in ok.iterrows():
        name = f"campaign {case['campaign']}, case {case['case']}"
        try:
            series = load_series(case)
            if case["waveform"] == "sine":
                pts, e = sine_points(case, series, spec)
                if e is not None:
                    energy.append(e)
            else:
                pts = free_points(case, series)
        except (ValueError, KeyError, OSError) as exc:
            notes.append(f"{name}: {exc}")
            log.warning("%s: no characteristic point: %s", name, exc)
            continue
        if not pts:
            notes.append(f"{name}: fewer than {MIN_CYCLES} steady cycles or no velocity bin: no point")
            log.warning("%s: fewer than %d steady cycles a direction or no velocity bin: no characteristic point",
                        name, MIN_CYCLES)
        rows += pts
    columns = [c for c in tables.CHARACTERISTIC.columns if c != "repeatability_flagged"] + ["missing_samples"]
    points = pd.DataFrame(rows, columns=columns).astype(
        {"segment": "int64", "period": "int64", "n_samples": "int64", "row_start": "int64", "row_stop": "int64",
         "missing_samples": "Int64"})
    en = pd.DataFrame(energy, columns=ENERGY_COLUMNS).astype(
        {c: object if c in ("campaign", "case", "raw_file", "raw_sha256") else
         "int64" if c in ("n_cycles", "row_start", "row_stop") else "float64" for c in ENERGY_COLUMNS})
    return points, tables.validate_table(en, tables.ENERGY), notes


def records_stage(campaign_root, spec: PeakSpec = PEAK_SPEC) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(sine/free characteristic rows, energy table) of a validated campaign folder (reads cases.parquet)."""
    folder = CampaignFolder.at(campaign_root)
    records, energy, _notes = record_points(folder.validated_cases(), folder.timeseries, spec)
    return records, energy


def paired_repeatability(windows: pd.DataFrame, records: pd.DataFrame | None, tolerance: float) -> pd.DataFrame:
    """Repeatability of the triangle windows and the sine cases' two periods (free bins have one)."""
    paired = records[records["method"] == "sine_peak"] if records is not None and len(records) else None
    if paired is None or paired.empty:
        return repeatability(windows, tolerance)
    keys = ["campaign", "case", "direction", "period", "velocity_m_s", "force_N"]
    return repeatability(pd.concat([windows[keys], paired[keys]], ignore_index=True), tolerance)


# ----------------------------------------------------------------------------------------------
# the rule
# ----------------------------------------------------------------------------------------------

def write_characteristic(campaign_root: str | os.PathLike, spec: WindowSpec = WindowSpec(), *,
                         repeatability_tolerance: float = 0.05, sample_rate_tolerance: float = 0.05,
                         gap_tolerance: GapTolerance = GapTolerance()) -> pd.DataFrame:
    """validate -> windows -> repeatability -> characteristic of an ingested campaign folder
    (``results/<campaign>/`` holding ``ingest/``): writes cases, quarantine, windows, repeatability,
    characteristic and energy tables there; returns the characteristic. Flagged repeatability is logged."""
    root = Path(campaign_root)
    write_validated(root, sample_rate_tolerance=sample_rate_tolerance, window_spec=spec, gap_tolerance=gap_tolerance)
    windows = windows_stage(root, spec)
    write_parquet(windows, root / WINDOWS_FILE)
    records, energy = records_stage(root)
    rep = paired_repeatability(windows, records, repeatability_tolerance)
    write_parquet(rep, root / REPEATABILITY_FILE)
    for row in rep[rep["flagged"]].itertuples():
        log.info("campaign %s, case %s, direction %s: period 2 differs from period 1 by %+.1f %% "
                    "(tolerance %.1f %%)", row.campaign, row.case, row.direction, 100 * row.rel_diff,
                    100 * row.tolerance)
    char = assemble(windows, rep, records)
    write_parquet(char, root / CHARACTERISTIC_FILE)
    write_parquet(energy, root / ENERGY_FILE)
    log.info("%d windows from %d cases, %d sine/free points, %d characteristic points", len(windows),
             windows["case"].nunique() if len(windows) else 0, len(records), len(char))
    return char
