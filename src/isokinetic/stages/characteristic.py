"""Characteristic assembly (Sec. 4.5, Fig. 9): the steady force-velocity points of a campaign.

Rule ``characteristic`` runs the stages from an ingested campaign folder to its characteristic in
one process (:func:`write_characteristic`): validate (:mod:`isokinetic.stages.validate`) ->
windows (:mod:`isokinetic.measurement.windows`) -> repeatability
(:mod:`isokinetic.measurement.repeatability`) -> :func:`assemble`. The blind suite runs the same function.

Every point carries its ``method`` (tables.CHARACTERISTIC_METHODS), chosen by what the record is, not by its
manifest label (docs/method.md, "How each point is obtained"):

- ``triangle_window``: a triangle case's constant-velocity window (four a case), as before;
- ``sine_peak``: any periodic record, a ``sine`` case or a ``free`` case whose peaks repeat
  (:func:`isokinetic.measurement.peak_velocity.periodicity`: a distorted sine, a crank): the force at each
  extremum of the measured velocity (:mod:`isokinetic.measurement.peak_velocity`), per direction, over the
  cycles that have settled (measured on the record: peak speed and force repeat), the cycles averaged. One
  steady cycle is enough: the point then has no standard error (``force_se_N`` NaN; ``force_std_N`` is its
  fit's force noise) and its ``quality`` and the case's say so. So that repeatability applies as to a
  triangle case, with four cycles or more a direction period 1 averages the first half of the cycles and
  period 2 the second half (segments 1 '+', 2 '-' of period 1, 3 '+', 4 '-' of period 2); with one to three,
  period 1 only. ``n_samples`` counts the cycles and ``force_std_N`` is their scatter, so force_std_N /
  sqrt(n_samples) is the point's standard error, as for a window. A point whose force is not steady while the
  speed is at its peak (:func:`isokinetic.measurement.peak_velocity.window_force`: a backlash, a stick-slip) is
  the window's mean force, flagged in its ``quality`` and the case's, with ``force_se_N`` widened by the spread.
  ``planned_velocity_m_s`` is 2 pi f Y (the
  measured mean peak speed when the case has no amplitude); the row range spans the samples of the fits;
- ``free_bin``: a free record that is not periodic, only when it is quasi-static
  (:func:`isokinetic.measurement.quasi_static.quasi_static`: at every velocity bin the accelerating and the
  decelerating branch agree within their noise): its velocity bins
  (:func:`isokinetic.measurement.loops.binned_characteristic`), segment = the bin's number, period 1,
  ``planned_velocity_m_s`` the bin's centre, ``n_samples`` its samples. A free record that fails the test gives
  no point: its binned loops stay in harmonic/ (:mod:`isokinetic.stages.harmonic`), and the reason goes to the
  case's ``quality`` in cases.parquet (:func:`note_cases`), which the campaign page shows.

The periodic records' energy per cycle goes to ``energy.parquet`` (tables.ENERGY).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.contracts.settings import DEFAULTS, Settings
from isokinetic.io import write_parquet
from isokinetic.measurement.loops import binned_characteristic, dominant_period_s, free_loop
from isokinetic.measurement.peak_velocity import (
    PeakSpec,
    cycle_energies,
    peak_points,
    periodicity,
    settled,
    summarise,
)
from isokinetic.measurement.quasi_static import quasi_static
from isokinetic.measurement.repeatability import repeatability
from isokinetic.measurement.spikes import MAX_FRACTION, MIN_ALLOWED, spike_mask
from isokinetic.measurement.windows import WindowSpec, extract_windows
from isokinetic.stages.validate import GapTolerance, write_validated

log = logging.getLogger(__name__)

WINDOWS_FILE = STAGE_OUTPUTS["windows"]["windows"]
REPEATABILITY_FILE = STAGE_OUTPUTS["repeatability"]["repeatability"]
CHARACTERISTIC_FILE = STAGE_OUTPUTS["characteristic"]["characteristic"]
ENERGY_FILE = STAGE_OUTPUTS["characteristic"]["energy"]

#: The peak-velocity method's default settings.
PEAK_SPEC = PeakSpec()
#: Fewest steady cycles a direction a peak point rests on: one (flagged, no standard error) ...
MIN_CYCLES = 1
#: ... and from how many the cycles are split into two periods (two cycles each), for repeatability.
SPLIT_CYCLES = 4
#: The flag of a point resting on one cycle (its ``quality``, and the case's note).
ONE_CYCLE_NOTE = "one steady cycle a direction: no standard error"
#: The flag of a point whose force is not steady while the speed is at its peak (its ``quality``, the case's note).
UNSTEADY_NOTE = ("force not steady while the speed is at its peak (spread beyond the noise in the window where "
                 "|v| >= {fraction:g} % of the peak, {n} of {cycles} cycles, rms spread {spread:.4g} N): "
                 "the point is the window's mean force and its standard error includes that spread")
ENERGY_COLUMNS = list(tables.ENERGY.columns) + ["window_start_s", "window_end_s", "raw_file", "raw_sha256"]


def windows_stage(campaign_root, spec: WindowSpec = DEFAULTS.window, notes: dict[str, str] | None = None
                  ) -> pd.DataFrame:
    """Windows of a validated campaign folder ``results/<campaign>/`` (reads cases.parquet); ``notes`` receives
    what spikes did to a case's windows (:func:`isokinetic.measurement.windows.extract_windows`)."""
    folder = CampaignFolder.at(campaign_root)
    return extract_windows(folder.validated_cases(), folder.timeseries, spec, notes)


def assemble(windows: pd.DataFrame, repeatability: pd.DataFrame, records: pd.DataFrame | None = None) -> pd.DataFrame:
    """Windows (and the sine/free ``records`` points of :func:`record_points`) joined with their case/direction
    repeatability flag, ordered by velocity; ``method`` 'triangle_window' for the windows; ``force_se_N`` the
    standard error of each point's force (NaN for a peak point resting on one cycle)."""
    keys = ["campaign", "case", "direction"]
    parts = [windows.assign(method="triangle_window")]
    if records is not None and len(records):
        absent = [c for c in parts[0].columns if c not in records.columns]   # e.g. the windows' missing_samples
        own_se = ["force_se_N"] if "force_se_N" in records.columns and "force_se_N" not in parts[0].columns else []
        parts.append(records.reindex(columns=list(parts[0].columns) + own_se).astype(
            {c: parts[0][c].dtype for c in absent}))
    char = pd.concat(parts, ignore_index=True) if len(parts) > 1 else parts[0]
    flags = repeatability[keys + ["flagged"]].rename(columns={"flagged": "repeatability_flagged"})
    char = char.merge(flags, on=keys, how="left", validate="many_to_one")
    char["repeatability_flagged"] = char["repeatability_flagged"].eq(True).astype(bool)   # no flag: False
    char = char[[c for c in char.columns if c != "method"] + ["method"]]
    # the standard error of each point's force: its scatter over root n (windows: samples; sine peaks: cycles,
    # none for one cycle; bins: samples)
    one_cycle = char["method"].eq("sine_peak") & char["n_samples"].eq(1)
    scatter_se = (char["force_std_N"] / np.sqrt(char["n_samples"].astype(float))).where(~one_cycle)
    own = char["force_se_N"].astype(float) if "force_se_N" in char else pd.Series(np.nan, index=char.index)
    # a sine peak's own standard error (its spread in the speed window included) where it has one
    char["force_se_N"] = own.where(char["method"].eq("sine_peak") & own.notna(), scatter_se)
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


def _record(series: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(time, displacement, force, raw rows) of a case's series in time order."""
    s = series.sort_values("time_s", kind="stable")
    t, x, f = (s[c].to_numpy(dtype=float) for c in ("time_s", "displacement_m", "force_N"))
    rows = s["row"].to_numpy(dtype=np.int64) if "row" in s else np.arange(len(s), dtype=np.int64)
    return t, x, f, rows


def _flag(quality: str, flag: str) -> str:
    return flag if quality == "ok" else f"{quality}; {flag}"


def unsteady_note(summary, spec: PeakSpec = PEAK_SPEC) -> str:
    """The flag of a direction's point (a :func:`summarise` row) whose force is not steady in its speed window."""
    return UNSTEADY_NOTE.format(fraction=100 * spec.peak_fraction, n=int(summary["n_unsteady"]),
                                cycles=int(summary["n_cycles"]), spread=float(summary["force_spread_N"]))


def _peak_row(base: dict, part: pd.DataFrame, direction: str, period_no: int, planned: float, span: dict,
              spec: PeakSpec = PEAK_SPEC) -> dict:
    """One sine_peak row: the cycles of ``part`` averaged (module doc); one cycle: its fit noise as
    force_std_N, flagged in ``quality``. A force not steady in the speed window is flagged too, and its
    standard error is sqrt(SE_cycles^2 + spread^2) (the force at peak velocity is known no better than the
    force's spread while the speed is at its peak)."""
    r = summarise(part).iloc[0]
    n = int(r["n_cycles"])
    quality = base["quality"]
    if n == 1:
        quality = _flag(quality, ONE_CYCLE_NOTE)
    std = float(r["force_std_N"]) if n > 1 else float(r["force_noise_N"])
    se = float(r["force_se_N"])
    if int(r["n_unsteady"]):
        quality = _flag(quality, unsteady_note(r, spec))
        se = math.hypot(0.0 if math.isnan(se) else se, float(r["force_spread_N"]))
    return {**base, "quality": quality, "segment": (1 if direction == "+" else 2) + 2 * (period_no - 1),
            "direction": direction, "period": period_no, "planned_velocity_m_s": planned,
            "velocity_m_s": float(r["velocity_m_s"]), "force_N": float(r["force_N"]), "force_std_N": std,
            "n_samples": n, **span, "method": "sine_peak", "force_se_N": se,
            "spikes_excluded": int(r["spikes_excluded"])}


def periodic_points(case, series: pd.DataFrame, period_s: float, spec: PeakSpec = PEAK_SPEC
                    ) -> tuple[list[dict], dict | None, str]:
    """(characteristic rows, energy row or None, what spikes did: '' for none) of one periodic record, sine or not
    (module doc); a cycle with too many spikes in its speed window gives no point."""
    t, x, f, rows = _record(series)
    found = peak_points(t, x, f, period_s, spec=spec)
    pts = settled(found[~found["spike_set_aside"]], spec)
    freq = 1.0 / period_s
    amp = _number(case.get("amplitude_m"))
    base = _base(case)
    out = []
    for d, sign in (("+", 1.0), ("-", -1.0)):
        p = pts[pts["direction"] == d]
        n = len(p)
        if n < MIN_CYCLES:
            continue
        planned = sign * 2.0 * math.pi * freq * amp if amp > 0 else float(p["velocity_m_s"].mean())
        halves = [(1, p.iloc[:n // 2]), (2, p.iloc[n // 2:])] if n >= SPLIT_CYCLES else [(1, p)]
        for period_no, part in halves:
            span = _span(t, rows, int(part["i_start"].min()), int(part["i_stop"].max()))
            out.append(_peak_row(base, part, d, period_no, planned, span, spec))
    return out, _energy_row(base, t, x, f, rows, period_s, pts, spec), peak_spike_note(found)


def peak_spike_note(points: pd.DataFrame) -> str:
    """What spikes did to a periodic record's peak points (:func:`peak_points` rows), '' when it has none."""
    aside = points["spike_set_aside"].to_numpy(bool)
    n = int(points.loc[~aside, "spikes_excluded"].sum())
    said = [f"{n} spike sample{'s' if n > 1 else ''} excluded from the speed windows (Hampel filter, "
            f"docs/method.md)"] if n else []
    if aside.any():
        said.append(f"{int(aside.sum())} cycle(s) set aside: more than max({MIN_ALLOWED}, {100 * MAX_FRACTION:g} %) "
                    f"of the speed window's samples are spikes")
    return "; ".join(said)


def _energy_row(base: dict, t, x, f, rows, period_s: float, pts: pd.DataFrame, spec: PeakSpec) -> dict | None:
    """The energy table's row of a periodic record: its settled cycles' energies averaged, None without one."""
    energy = cycle_energies(t, x, f, period_s, points=pts, spec=spec)
    if energy.empty:
        return None
    e = energy["energy_J"].to_numpy(float)
    n = e.size
    x_amp = float(energy["amplitude_m"].mean())
    w = 2.0 * math.pi / period_s
    std = float(e.std(ddof=1)) if n > 1 else math.nan
    i0, i1 = int(energy["i_start"].min()), int(energy["i_stop"].max())
    return {"campaign": base["campaign"], "case": base["case"], "frequency_Hz": 1.0 / period_s,
            "displacement_amplitude_m": x_amp,
            "velocity_amplitude_m_s": float(pts["velocity_m_s"].abs().mean()) if len(pts) else math.nan,
            "energy_J": float(e.mean()), "energy_std_J": std, "energy_se_J": std / math.sqrt(n),
            "n_cycles": n, "equivalent_damping_N_s_m": float(e.mean()) / (math.pi * w * x_amp ** 2)
            if x_amp > 0 else math.nan,
            **_span(t, rows, i0, min(i1, t.size)), "raw_file": base["raw_file"], "raw_sha256": base["raw_sha256"]}


def sine_points(case, series: pd.DataFrame, spec: PeakSpec = PEAK_SPEC) -> tuple[list[dict], dict | None, str]:
    """(characteristic rows, energy row or None, spike note) of one sine case: :func:`periodic_points` with the
    manifest's period, else the displacement's dominant one."""
    freq = _number(case.get("frequency_Hz"))
    if not freq > 0:
        s = series.sort_values("time_s", kind="stable")
        freq = 1.0 / dominant_period_s(s["time_s"].to_numpy(float), s["displacement_m"].to_numpy(float))
    return periodic_points(case, series, 1.0 / freq, spec)


def _without_spikes(lp: pd.DataFrame) -> tuple[pd.DataFrame, np.ndarray]:
    """(the loop without the force's spikes, the velocity of each spike sample) of a free record's loop
    (:func:`isokinetic.measurement.spikes.spike_mask` over the whole loop); the loop itself when it has none."""
    spikes = spike_mask(lp["force_N"].to_numpy(dtype=float), 0, len(lp), context=0)
    if not spikes.any():
        return lp, np.zeros(0)
    kept = lp[~spikes].reset_index(drop=True)
    kept.attrs.update(lp.attrs)
    return kept, lp["velocity_m_s"].to_numpy(dtype=float)[spikes]


def _bin_spikes(r: Mapping, spike_velocity: np.ndarray) -> int:
    """The spike samples whose velocity lies in a velocity bin (a :func:`binned_characteristic` row)."""
    low, high = sorted((abs(r["bin_low_m_s"]), abs(r["bin_high_m_s"])))
    s = 1.0 if r["direction"] == "+" else -1.0
    return int(np.count_nonzero((s * spike_velocity > low) & (s * spike_velocity <= high)))


def free_points(case, series: pd.DataFrame, spec: PeakSpec = PEAK_SPEC
                ) -> tuple[list[dict], dict | None, str, str]:
    """(characteristic rows, energy row or None, note, spike note) of one free case (module doc): a periodic
    record's peak points; else, only when the record is quasi-static
    (:func:`isokinetic.measurement.quasi_static.quasi_static`, on the loop without its force spikes), its velocity
    bins; else no point, and the note says why. The spike note says what spikes did ('' for none)."""
    lp = free_loop(series)
    t, x, f, _rows = _record(series)
    period = periodicity(peak_points(t, x, f, 1.0 / float(lp.attrs["frequency_Hz"]), spec=spec))
    if period is not None:
        rows, energy, spikes = periodic_points(case, series, period, spec)
        return rows, energy, "", spikes
    lp, spike_v = _without_spikes(lp)
    spikes = (f"{spike_v.size} spike sample{'s' if spike_v.size > 1 else ''} excluded from the velocity bins "
              f"(Hampel filter, docs/method.md)" if spike_v.size else "")
    verdict = quasi_static(lp)
    if not verdict.passed:
        return [], None, (f"{verdict.reason}: not periodic, and its velocity bins average the two branches of a "
                          f"loop, so they are shown in harmonic/ and are no characteristic point"), spikes
    bins = binned_characteristic(lp)
    base = _base(case)
    tl = lp["time_s"].to_numpy(dtype=float)
    span = {**_span(tl, np.zeros(tl.size, dtype=np.int64), 0, tl.size),
            "row_start": int(lp.attrs["row_start"]), "row_stop": int(lp.attrs["row_stop"])}
    return [{**base, "segment": k, "direction": r["direction"], "period": 1,
             "planned_velocity_m_s": 0.5 * (r["bin_low_m_s"] + r["bin_high_m_s"]),
             "velocity_m_s": float(r["velocity_m_s"]), "force_N": float(r["force_N"]),
             "force_std_N": float(r["force_std_N"]), "n_samples": int(r["n_points"]), **span, "method": "free_bin",
             "spikes_excluded": _bin_spikes(r, spike_v)}
            for k, r in enumerate(bins.to_dict("records"), start=1)], None, "", spikes


def _case_points(case, series: pd.DataFrame, spec: PeakSpec) -> tuple[list[dict], dict | None, str]:
    """(rows, energy row or None, note) of one sine or free case; the note says why a case gives no point or
    rests on one cycle ('' when there is nothing to say)."""
    if case["waveform"] == "sine":
        pts, e, spikes = sine_points(case, series, spec)
        note = ""
    else:
        pts, e, note, spikes = free_points(case, series, spec)
    if not pts and not note:
        note = "no steady cycle with a peak of each velocity sign and no velocity bin: no characteristic point"
    flags = [ONE_CYCLE_NOTE] if any(r["n_samples"] == 1 and r["method"] == "sine_peak" for r in pts) else []
    flags += [f"{r['direction']}: {r['quality'].split('; ')[-1]}" for r in pts
              if r["method"] == "sine_peak" and "not steady" in r["quality"]]
    return pts, e, "; ".join([n for n in (note, spikes) if n] + flags)


def record_points(cases: pd.DataFrame, load_series: Callable, spec: PeakSpec = PEAK_SPEC
                  ) -> tuple[pd.DataFrame, pd.DataFrame, dict[str, str]]:
    """(characteristic rows of the status-ok sine and free cases, their energy table, {case: note}). A case
    that cannot be reduced, or whose bins are no characteristic, or whose point rests on one cycle, has a
    note; the notes are logged."""
    rows: list[dict] = []
    energy: list[dict] = []
    notes: dict[str, str] = {}
    ok = cases[(cases["status"] == "ok") & cases["waveform"].isin(["sine", "free"])] if len(cases) else cases
    for _, case in ok.iterrows():
        name = f"campaign {case['campaign']}, case {case['case']}"
        try:
            pts, e, note = _case_points(case, load_series(case), spec)
        except (ValueError, KeyError, OSError) as exc:
            pts, e, note = [], None, f"no characteristic point: {exc}"
        if e is not None:
            energy.append(e)
        if note:
            notes[str(case["case"])] = note
            log.warning("%s: %s", name, note)
        rows += pts
    columns = [c for c in tables.CHARACTERISTIC.columns if c != "repeatability_flagged"]
    points = pd.DataFrame(rows, columns=columns + ["missing_samples"]).astype(
        {"segment": "int64", "period": "int64", "n_samples": "int64", "row_start": "int64", "row_stop": "int64",
         "missing_samples": "Int64", "spikes_excluded": "Int64"})
    en = pd.DataFrame(energy, columns=ENERGY_COLUMNS).astype(
        {c: object if c in ("campaign", "case", "raw_file", "raw_sha256") else
         "int64" if c in ("n_cycles", "row_start", "row_stop") else "float64" for c in ENERGY_COLUMNS})
    return points, tables.validate_table(en, tables.ENERGY), notes


def records_stage(campaign_root, spec: PeakSpec = PEAK_SPEC) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(sine/free characteristic rows, energy table) of a validated campaign folder (reads cases.parquet)."""
    folder = CampaignFolder.at(campaign_root)
    records, energy, _notes = record_points(folder.validated_cases(), folder.timeseries, spec)
    return records, energy


def note_cases(campaign_root, notes: dict[str, str]) -> None:
    """Add each case's characteristic note to its ``quality`` in ``cases.parquet`` (the page's cases table
    shows it): 'characteristic: <note>', after the case's own warnings."""
    if not notes:
        return
    path = CampaignFolder.at(campaign_root).path("validate", "cases")
    cases = pd.read_parquet(path)
    if "quality" not in cases:
        cases["quality"] = np.where(cases["status"] == "ok", "ok", "quarantined")
    for case, note in notes.items():
        at = cases["case"].astype(str) == case
        old = cases.loc[at, "quality"].fillna("ok").astype(str)
        cases.loc[at, "quality"] = np.where(old == "ok", f"characteristic: {note}", old + f"; characteristic: {note}")
    write_parquet(tables.validate_table(cases, tables.CASES), path)


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

def write_characteristic(campaign_root: str | os.PathLike, spec: WindowSpec = DEFAULTS.window, *,
                         repeatability_tolerance: float = DEFAULTS.repeatability_tolerance,
                         sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                         gap_tolerance: GapTolerance = DEFAULTS.gap) -> pd.DataFrame:
    """validate -> windows -> repeatability -> characteristic of an ingested campaign folder
    (``results/<campaign>/`` holding ``ingest/``): writes cases, quarantine, windows, repeatability,
    characteristic and energy tables there; returns the characteristic. Flagged repeatability is logged."""
    root = Path(campaign_root)
    write_validated(root, sample_rate_tolerance=sample_rate_tolerance, window_spec=spec, gap_tolerance=gap_tolerance)
    notes: dict[str, str] = {}
    windows = windows_stage(root, spec, notes)
    write_parquet(windows, root / WINDOWS_FILE)
    for case, note in notes.items():
        log.warning("campaign %s, case %s: %s", root.name, case, note)
    records, energy, record_notes = record_points(CampaignFolder.at(root).validated_cases(),
                                                  CampaignFolder.at(root).timeseries)
    note_cases(root, {**notes, **record_notes})
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


def run_characteristic(campaign_root: str | os.PathLike, settings: Settings) -> pd.DataFrame:
    """The chain's characteristic step (:mod:`isokinetic.stages.chain`): :func:`write_characteristic` with the
    settings' window, tolerances and gap tolerance."""
    return write_characteristic(campaign_root, settings.window,
                                repeatability_tolerance=settings.repeatability_tolerance,
                                sample_rate_tolerance=settings.sample_rate_tolerance, gap_tolerance=settings.gap)
