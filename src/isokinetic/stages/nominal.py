"""The damper model run "on equal terms" with the rig (paper Sec. 4.5, Fig. 13-14).

The incompressible formula Eq. (31)/(32) is what a steady window would read after an infinitely
long settling. A measured window, however, sits at [0.45, 0.95] T/2 of a half-period that starts
from the previous half-period's force, so a short fast case may not have converged (Eq. 28-29).
To compare like with like, this module simulates the noise-free compressible model (Eq. 1-3, 7, 8;
:mod:`isokinetic.physics.responses`) through the campaign's *own* triangle plan - same period, amplitude,
phase, sample rate and record length as measured - and reduces it with the *same* windows
(:mod:`isokinetic.stages.windows`): one WINDOWS row per measured window, ``raw_file`` ``model:<label>``.

Record length
    The windows only use the first four complete half-periods and the response is causal, so the
    simulated record only needs to reach the last window sample. Whether the four half-periods are
    *complete* depends on the measured record length, taken (first found) from ``durations[case]``
    (e.g. the measured record's last time stamp), the case's ``duration_s``, ``(n_samples - 1) /
    sample_rate_Hz`` of the cases table, else the plan's two periods 2T. :func:`nominal_stage`
    passes the last time stamp of the measured series for cases whose ``duration_s`` is NaN (raw
    campaigns without a stated duration). The model's sample grid is k / fs from t = 0 (the plan's
    grid); a measured series with jittered time stamps is not reproduced sample by sample.

Speed
    Everything that does not depend on the damper or its effects (sample grids, window index
    ranges, the actuator's window velocity) is prepared once in a :class:`ModelPlan`; a call of
    :meth:`ModelPlan.forces` is one batched :func:`isokinetic.physics.responses.triangle_responses` pass plus one
    mean/std per window. Use a ModelPlan directly inside fits (hundreds of calls).
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import case_plan, viscosity_scales
from isokinetic.physics.damper import NOMINAL, Damper, Effects, friction_force
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.plan import CasePlan, triangle_displacement
from isokinetic.physics.responses import Drive, drive_times, triangle_responses_at
from isokinetic.stages.windows import WindowSpec, line_slope, window_ranges

log = logging.getLogger("isokinetic.nominal")

#: ``raw_file`` prefix of model windows (the rest is the label: 'nominal' or the active effects).
MODEL_PREFIX = "model:"

_INT_COLUMNS = ("segment", "period", "n_samples", "row_start", "row_stop")


def effects_label(effects: Effects) -> str:
    """'nominal' for the nominal model, else the active effect groups joined by '+'."""
    active = effects.active()
    return "nominal" if not active else "+".join(active)


def record_duration_s(row: Mapping, durations: Mapping[str, float] | None = None) -> float:
    """Measured record length of a case row: durations[case], duration_s, (n - 1)/fs, else 2T."""
    case = str(row["case"])
    if durations is not None and case in durations and durations[case] is not None \
            and math.isfinite(float(durations[case])):
        return float(durations[case])
    dur = float(row.get("duration_s", math.nan))
    if math.isfinite(dur) and dur > 0:
        return dur
    n = row.get("n_samples", None)
    fs = float(row["sample_rate_Hz"])
    if n is not None and not pd.isna(n) and int(n) > 1:
        return (int(n) - 1) / fs
    return 2.0 * float(row["period_s"])


@dataclass(frozen=True)
class ModelPlan:
    """The windows of a campaign's triangle plan, prepared for repeated model runs.

    ``plans`` are the simulated CasePlans (duration cut to the last window sample); the window
    arrays have one entry per window, in case order then segment 1..4; ``start``/``stop`` index
    into the case's simulated samples.
    """

    campaign: str
    spec: WindowSpec
    plans: tuple[CasePlan, ...]
    case_index: np.ndarray      # window -> index into plans
    segment: np.ndarray
    sign: np.ndarray            # +1 / -1
    start: np.ndarray
    stop: np.ndarray
    velocity_m_s: np.ndarray    # least-squares slope of the (noise-free) actuator displacement
    window_start_s: np.ndarray
    window_end_s: np.ndarray

    drives: tuple[Drive | None, ...] = ()
    #: per plan, μ(T_case)/μ_nominal (the oil's viscosity at the case's temperature); empty: all 1
    viscosity_scales: tuple[float, ...] = ()

    @classmethod
    def from_cases(cls, campaign: str, cases: pd.DataFrame, spec: WindowSpec = WindowSpec(),
                   durations: Mapping[str, float] | None = None,
                   drives: Mapping[str, Drive] | None = None,
                   viscosity_scales: Mapping[str, float] | None = None) -> ModelPlan:
        """Status-ok triangle cases of a cases table (tables.CASES).

        ``drives`` (case -> :class:`isokinetic.physics.responses.Drive`, :func:`case_drives`) runs a case with its
        measured half-period speeds on its measured sample grid; a case without one runs the plan.
        ``viscosity_scales`` (case -> μ(T_case)/μ_nominal, :func:`isokinetic.contracts.campaign.viscosity_scales`)
        runs a case at its own temperature's viscosity; a case without one at the damper's.

        Raises ValueError naming the case when its record does not hold four complete
        half-periods or a window holds fewer than MIN_WINDOW_SAMPLES samples (as
        :func:`windows.case_windows` does for the measured record).
        """
        ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
        plans, used, cols = [], [], {k: [] for k in ("case_index", "segment", "sign", "start", "stop", "velocity_m_s",
                                           "window_start_s", "window_end_s")}
        for _, row in ok.iterrows():
            plan = case_plan(row)
            drive = None if drives is None else drives.get(str(row["case"]))
            record = record_duration_s(row, durations)
            full = replace(plan, duration_s=record)
            t = drive_times(full, drive)
            last = 0
            for k, sign, i0, i1 in window_ranges(plan, t, spec):
                tw = t[i0:i1]
                y = (triangle_displacement(tw, plan.amplitude_m, plan.period_s, plan.phase_rad) if drive is None
                     else sign * drive.speed(k - 1) * tw)
                cols["case_index"].append(len(plans))
                cols["segment"].append(k)
                cols["sign"].append(sign)
                cols["start"].append(i0)
                cols["stop"].append(i1)
                cols["velocity_m_s"].append(line_slope(tw, y))
                cols["window_start_s"].append(float(tw[0]))
                cols["window_end_s"].append(float(tw[-1]))
                last = max(last, i1 - 1)
            # causal response: simulate up to the last window sample only (same grid)
            plans.append(replace(plan, duration_s=float(t[last])))
            used.append(drive)
        arrays = {k: np.asarray(v, dtype=float if k in ("sign", "velocity_m_s", "window_start_s", "window_end_s")
                                else np.int64) for k, v in cols.items()}
        scales = tuple(float((viscosity_scales or {}).get(p.case, 1.0)) for p in plans)
        return cls(campaign=campaign, spec=spec, plans=tuple(plans), drives=tuple(used),
                   viscosity_scales=scales if any(x != 1.0 for x in scales) else (), **arrays)

    def __len__(self) -> int:
        return int(self.segment.size)

    def forces(self, damper: Damper, effects: Effects = NOMINAL,
               hydraulics: Hydraulics | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(mean force, force std ddof=1) of every window of the noise-free model [N].

        Force = A_p Δp + F_f(piston velocity), Eq. (8), as :func:`isokinetic.physics.responses.true_response`.
        ``hydraulics`` overrides the coefficients (friction and backlash still from ``effects``).
        """
        mean = np.empty(len(self))
        std = np.empty(len(self))
        if not self.plans:
            return mean, std
        hyd = Hydraulics.from_damper(damper, effects) if hydraulics is None else hydraulics
        responses = triangle_responses_at(self.plans, hyd, self.viscosity_scales, effects.backlash_m,
                                          drives=self.drives if any(self.drives) else None)
        a = hyd.piston_area_m2
        for w in range(len(self)):
            _t, dp, vel = responses[self.case_index[w]]
            sl = slice(self.start[w], self.stop[w])
            f = a * dp[sl] + friction_force(vel[sl], effects)
            mean[w] = f.mean()
            std[w] = f.std(ddof=1)
        return mean, std

    def windows(self, damper: Damper, effects: Effects = NOMINAL, label: str | None = None,
                validate: bool = True) -> pd.DataFrame:
        """The model's WINDOWS table (raw_file ``model:<label>``, raw_sha256 '')."""
        mean, std = self.forces(damper, effects)
        cases = [p.case for p in self.plans]
        idx = self.case_index
        speed = np.array([p.velocity_m_s for p in self.plans])[idx] if len(self) else np.empty(0)
        df = pd.DataFrame({
            "campaign": self.campaign,
            "case": np.array(cases, dtype=object)[idx] if len(self) else np.empty(0, dtype=object),
            "segment": self.segment,
            "direction": np.where(self.sign > 0, "+", "-").astype(object),
            "period": (self.segment + 1) // 2,
            "planned_velocity_m_s": self.sign * speed,
            "velocity_m_s": self.velocity_m_s,
            "force_N": mean,
            "force_std_N": std,
            "n_samples": self.stop - self.start,
            "window_start_s": self.window_start_s,
            "window_end_s": self.window_end_s,
            "row_start": self.start,
            "row_stop": self.stop,
            "raw_file": MODEL_PREFIX + (effects_label(effects) if label is None else label),
            "raw_sha256": "",
            "quality": "ok",  # a noise-free model record has nothing to flag
        }, columns=list(tables.WINDOWS.columns))
        df = df.astype(dict.fromkeys(_INT_COLUMNS, "int64"))
        if "missing_samples" in df:  # a model record drops no sample
            df["missing_samples"] = pd.array(np.zeros(len(df), dtype=np.int64), dtype="Int64")
        return tables.validate_table(df, tables.WINDOWS) if validate else df


def model_windows(campaign: str, cases: pd.DataFrame, damper: Damper, effects: Effects = NOMINAL,
                  spec: WindowSpec = WindowSpec(), durations: Mapping[str, float] | None = None,
                  label: str | None = None, validate: bool = True,
                  drives: Mapping[str, Drive] | None = None,
                  viscosity_scales: Mapping[str, float] | None = None) -> pd.DataFrame:
    """Noise-free model windows of every status-ok triangle case of ``cases`` (tables.WINDOWS).

    One-shot form of ``ModelPlan.from_cases(...).windows(...)``; inside a fit prepare the
    ModelPlan once and call :meth:`ModelPlan.forces` (or ``windows(validate=False)``).
    """
    return ModelPlan.from_cases(campaign, cases, spec, durations, drives, viscosity_scales).windows(
        damper, effects, label, validate)


def motion_start(row: Mapping) -> float:
    """Record time at which the plan's t = 0 lies (``motion_start_s`` of cases.parquet; 0 if absent)."""
    value = row.get("motion_start_s", 0.0)
    return float(value) if value is not None and math.isfinite(float(value)) else 0.0


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


def plan_time_ends(cases: pd.DataFrame, load_times) -> dict[str, float]:
    """Plan time of the last sample of every status-ok triangle case: last time stamp - motion start.

    ``load_times(row)`` returns the case's time stamps [s].
    """
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    return {str(row["case"]): float(load_times(row)[-1]) - motion_start(row) for _, row in ok.iterrows()}


def nominal_stage(campaign_root, spec: WindowSpec = WindowSpec()) -> pd.DataFrame:
    """Nominal-model windows of a validated campaign folder ``results/<campaign>/``.

    Reads ``ingest/campaign.json`` (damper block) and ``cases.parquet``; without a damper block
    returns an empty WINDOWS table and logs why. With a viscosity law (format 1.1) and case temperatures,
    each case runs at its own temperature's viscosity. Cases with NaN ``duration_s`` take the last time
    stamp of their measured series as the record length.
    """
    root = Path(campaign_root)
    meta = json.loads((root / "ingest" / "campaign.json").read_text(encoding="utf-8"))
    campaign = str(meta.get("campaign") or root.name)
    if meta.get("damper") is None:
        log.info("campaign %s: no damper block in campaign.json; no nominal model windows", campaign)
        return tables.empty(tables.WINDOWS)
    damper = Damper.from_mapping(meta["damper"])
    cases = pd.read_parquet(root / "cases.parquet")
    windows = pd.read_parquet(root / "windows.parquet") if (root / "windows.parquet").is_file() else None
    drives = case_drives(cases, windows)
    durations = plan_time_ends(cases, lambda row: pd.read_parquet(root / row["timeseries_file"], columns=["time_s"])
                               ["time_s"].to_numpy())
    scales = viscosity_scales(meta, cases)
    if scales:
        log.info("campaign %s: nominal viscosity at each case's temperature (viscosity law): %.4g..%.4g Pa s",
                 campaign, damper.viscosity_Pa_s * min(scales.values()), damper.viscosity_Pa_s * max(scales.values()))
    out = model_windows(campaign, cases, damper, NOMINAL, spec, durations, drives=drives, viscosity_scales=scales)
    log.info("campaign %s: %d nominal model windows from %d triangle case(s)", campaign, len(out),
             out["case"].nunique() if len(out) else 0)
    return out
