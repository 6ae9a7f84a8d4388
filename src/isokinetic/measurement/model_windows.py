"""The damper model run "on equal terms" with the rig (paper Sec. 4.5, Fig. 13-14).

The incompressible formula Eq. (31)/(32) is what a steady window would read after an infinitely
long settling. A measured window, however, sits at [0.45, 0.95] T/2 of a half-period that starts
from the previous half-period's force, so a short fast case may not have converged (Eq. 28-29).
To compare like with like, this module simulates the noise-free compressible model (Eq. 1-3, 7, 8;
:mod:`isokinetic.physics.responses`) through the campaign's *own* triangle plan - same period, amplitude,
phase, sample rate and record length as measured - and reduces it with the *same* windows
(:mod:`isokinetic.measurement.windows`): one WINDOWS row per measured window, ``raw_file`` ``model:<label>``.

Record length
    The windows only use the first four complete half-periods and the response is causal, so the
    simulated record only needs to reach the last window sample. Whether the four half-periods are
    *complete* depends on the measured record length, taken (first found) from ``durations[case]``
    (e.g. the measured record's last time stamp), the case's ``duration_s``, ``(n_samples - 1) /
    sample_rate_Hz`` of the cases table, else the plan's two periods 2T. :func:`isokinetic.stages.nominal.nominal_stage`
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

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import case_plan
from isokinetic.measurement.windows import WindowSpec, line_slope, motion_start, window_ranges
from isokinetic.physics.damper import NOMINAL, Damper, Effects, friction_force
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.plan import CasePlan, triangle_displacement
from isokinetic.physics.responses import Drive, drive_times, triangle_responses_at

#: ``raw_file`` prefix of model windows (the rest is the label: 'nominal' or the active effects).
MODEL_PREFIX = "model:"
_INT_COLUMNS = ("segment", "period", "n_samples", "row_start", "row_stop")


def effects_label(effects: Effects) -> str:
    """'nominal' for the nominal model, else the active effect groups joined by '+'."""
    active = effects.active()
    return "nominal" if not active else "+".join(active)


def record_duration_s(row: Mapping, durations: Mapping[str, float] | None = None) -> float:
    """The measured record length [s] of a case row: durations[case], duration_s, (n - 1)/fs, else 2T."""
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
    def from_cases(cls, campaign: str, cases: pd.DataFrame, spec: WindowSpec,
                   durations: Mapping[str, float] | None = None,
                   drives: Mapping[str, Drive] | None = None,
                   viscosity_scales: Mapping[str, float] | None = None) -> ModelPlan:
        """The plan of the status-ok triangle cases of a cases table (tables.CASES).

        ``drives`` (case -> :class:`isokinetic.physics.responses.Drive`,
        :func:`isokinetic.measurement.drive.case_drives`) runs a case with its measured half-period speeds
        on its measured sample grid; a case without one runs the plan.
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
        for column in ("missing_samples", "spikes_excluded"):  # a model record drops no sample and has no spike
            if column in df:
                df[column] = pd.array(np.zeros(len(df), dtype=np.int64), dtype="Int64")
        return tables.validate_table(df, tables.WINDOWS) if validate else df


def model_windows(campaign: str, cases: pd.DataFrame, damper: Damper, effects: Effects,
                  spec: WindowSpec, durations: Mapping[str, float] | None = None,
                  label: str | None = None, validate: bool = True,
                  drives: Mapping[str, Drive] | None = None,
                  viscosity_scales: Mapping[str, float] | None = None) -> pd.DataFrame:
    """The noise-free model windows of every status-ok triangle case of ``cases`` (tables.WINDOWS).

    One-shot form of ``ModelPlan.from_cases(...).windows(...)``; inside a fit prepare the
    ModelPlan once and call :meth:`ModelPlan.forces` (or ``windows(validate=False)``).
    """
    return ModelPlan.from_cases(campaign, cases, spec, durations, drives, viscosity_scales).windows(
        damper, effects, label, validate)


def plan_time_ends(cases: pd.DataFrame, load_times) -> dict[str, float]:
    """Plan time of the last sample of every status-ok triangle case: last time stamp - motion start.

    ``load_times(row)`` returns the case's time stamps [s].
    """
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    return {str(row["case"]): float(load_times(row)[-1]) - motion_start(row) for _, row in ok.iterrows()}
