"""Window extraction (Sec. 4.4): one steady point per constant-velocity half-period.

For each triangle case the four complete half-periods of its two-period record are found
from the plan (Eq. 26; a record that ends early, a rig that crashed while writing, keeps the windows that
lie complete inside it, at least :data:`MIN_WINDOWS`, the others named by :func:`missing_windows_note`),
placed on the record's own time axis at the measured motion start (``motion_start_s`` of cases.parquet,
:mod:`isokinetic.measurement.motion`; 0 when absent), and the samples in [start_fraction, end_fraction]·T/2
of each are reduced to the mean force, its standard deviation, and the velocity of a least-squares line
through the displacement.

Windows are placed by time, and every statistic uses the real time stamps, so a record that
dropped samples (:mod:`isokinetic.measurement.sampling`) is reduced without bias: the velocity is
the least-squares slope against the real times, and the mean force of a window that misses samples
is the value of the least-squares line through its force at the window's time centre
(:func:`window_mean_force`). Whether a window misses too much is the validate stage's decision.

Spikes (:mod:`isokinetic.measurement.spikes`): the force samples of a window that are isolated spikes (a Hampel
filter, a run of at most three samples beyond 6 robust sigmas of the running median) are left out of its mean, its
spread and its sample count, as dropped samples are (the mean is then the line at the time centre), and counted
(``spikes_excluded``); a window with more than max(1, 1 %) of its samples spikes is set aside
(:func:`extract_windows`, its reason in ``notes``). A window without a spike is reduced exactly as before.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import case_plan
from isokinetic.contracts.settings import DEFAULTS, WindowSpec  # noqa: F401 - the window's spec, imported from here too
from isokinetic.measurement.sampling import find_gaps, sample_interval_s, span_sampling
from isokinetic.measurement.spikes import spike_mask, too_many, too_many_note
from isokinetic.physics.plan import CasePlan, half_periods

#: Minimum samples a window must hold for a mean, a standard deviation and a line fit.
MIN_WINDOW_SAMPLES = 3
#: Windows a triangle record must hold complete (the first ones of the plan's four). A record cut short (a rig
#: that crashed while writing) keeps the windows that lie complete inside it: one is enough for a point; the
#: motion start that places it needs the record to reach the middle of the second half-period too (a rising and a
#: falling line, :mod:`isokinetic.measurement.motion`; validate checks it). Shorter records are set aside.
MIN_WINDOWS = 1
#: The plan's windows of a triangle record: two periods, both directions (Sec. 4.3).
PLAN_WINDOWS = 4


def line_slope(t, y) -> float:
    """The least-squares slope of y against t, in y's unit per t's (the window's piston velocity [m/s])."""
    tc = t - t.mean()
    return float(np.dot(tc, y - y.mean()) / np.dot(tc, tc))


def window_mean_force(t, f, centre_s: float, complete: bool) -> float:
    """The mean force of a window (time t [s], force f [N]) on its real time axis [N].

    A complete window (no sample missing): the plain mean over its samples (the paper's window mean).
    A window with gaps: the least-squares line through (t, f) evaluated at the window's time centre.
    In a steady window the force is constant, or drifts slowly (temperature, settling); the line's
    value at the centre is then the time mean over the whole window whatever samples are missing,
    while a plain mean would lean toward the part of the window that kept more samples. It is the
    plain mean when the samples' mean time is the centre (a complete window), and adds only
    (centre - mean time)²·var(slope) to the variance, far less than weighting each sample by its
    interval (a trapezoid mean), which gives the two neighbours of a burst of m missing samples
    1 + m/2 times the weight of the others and inflates the noise of the mean.
    """
    if complete:
        return float(f.mean())
    tm = t.mean()
    return float(f.mean() + line_slope(t, f) * (centre_s - tm))


def windowed_half_periods(plan: CasePlan, t_end_s: float, spec: WindowSpec,
                          motion_start_s: float = 0.0):
    """The half-periods, of the plan's first four, (rows t_start, t_end, sign) whose window ends within the record.

    Times are on the record's axis: the plan's (Eq. 26) plus ``motion_start_s``, the record time at
    which the plan's t = 0 lies (0: plan time is record time). A turning point within one sample
    interval of the plan's t = 0 counts (a rounded phase such as -1.5707963 loses no half-period).
    A half-period counts when its window [start, end]·T/2 lies before the record's last sample
    ``t_end_s``; the rest of it need not be recorded (a record ending one sample before 2T still
    holds four windows).
    """
    half = plan.period_s / 2.0
    rows = half_periods(plan.period_s, plan.phase_rad, t_end_s - motion_start_s + (1.0 - spec.end_fraction) * half,
                        tolerance_s=1.0 / plan.sample_rate_Hz, max_count=4)     # bounded: 1e308 s ends no loop
    rows[:, :2] += motion_start_s
    return rows


def first_window_end_s(plan: CasePlan, spec: WindowSpec) -> float:
    """The end of the plan's first window in plan time [s] (Eq. 26)."""
    rows = windowed_half_periods(plan, math.inf, spec)
    return float(rows[0, 0] + spec.end_fraction * plan.period_s / 2.0)


def missing_windows_note(plan: CasePlan, t_end_s: float, segments, motion_start_s: float = 0.0) -> str:
    """What a triangle record that ends early lost: '' when it holds all PLAN_WINDOWS windows, else e.g.
    'record ends at 14.72 s, before the plan's 16 s: windows 4 missing' (the plan's end at the motion start)."""
    missing = [k for k in range(1, PLAN_WINDOWS + 1) if k not in {int(s) for s in segments}]
    if not missing:
        return ""
    plan_end_s = motion_start_s + plan.required_duration_s
    return (f"record ends at {t_end_s:.6g} s, before the plan's {plan_end_s:.6g} s: "
            f"window{'s' if len(missing) > 1 else ''} {', '.join(map(str, missing))} missing")


def time_tolerance_s(plan: CasePlan) -> float:
    """A sample this close to a window edge is on it (float rounding of shifted time axes) [s]."""
    return 1e-6 / plan.sample_rate_Hz


def window_ranges(plan: CasePlan, t, spec: WindowSpec,
                  motion_start_s: float = 0.0) -> list[tuple[int, float, int, int]]:
    """(segment 1-4, sign, i0, i1) of the four windows of a triangle record with sample times ``t`` [s].

    The samples [i0, i1) lie in motion_start_s + [t0 + start_fraction·T/2, t0 + end_fraction·T/2]
    of each of the first four half-periods (t0 its start in plan time, Eq. 26;
    :func:`windowed_half_periods`); ``motion_start_s`` is the record time of the plan's t = 0
    (0, the default: ``t`` is plan time, as on a model grid). Raises ValueError when the record does
    not hold four windows, a window starts before the first sample, or a window holds fewer than
    MIN_WINDOW_SAMPLES samples. Shared by the measured windows and the model run through the plan,
    so both use the same samples. A record that ends early gives the windows that lie complete inside it (at
    least MIN_WINDOWS, else ValueError; :func:`missing_windows_note` names the others).
    """
    segments = windowed_half_periods(plan, float(t[-1]), spec, motion_start_s)
    if len(segments) < MIN_WINDOWS:
        aligned = f" (motion start at t = {motion_start_s:.6g} s)" if motion_start_s != 0.0 else ""
        first_end = motion_start_s + first_window_end_s(plan, spec)
        raise ValueError(f"case {plan.case}: record of {t[-1]:.6g} s holds the windows of {len(segments)} "
                         f"half-periods of T = {plan.period_s:.6g} s{aligned}, {MIN_WINDOWS} needed (the first "
                         f"window ends at t = {first_end:.6g} s)")
    half = plan.period_s / 2.0
    eps = time_tolerance_s(plan)
    out = []
    for k, (t0, _t1, sign) in enumerate(segments, start=1):
        a, b = t0 + spec.start_fraction * half, t0 + spec.end_fraction * half
        if a < t[0] - eps:
            raise ValueError(f"case {plan.case}: window of segment {k} starts at t = {a:.6g} s, before the "
                             f"record's first sample at {t[0]:.6g} s (motion start at t = {motion_start_s:.6g} s)")
        i0 = int(np.searchsorted(t, a - eps, side="left"))
        i1 = int(np.searchsorted(t, b + eps, side="right"))
        if i1 - i0 < MIN_WINDOW_SAMPLES:
            raise ValueError(f"case {plan.case}: window of segment {k} holds {i1 - i0} samples, "
                             f"{MIN_WINDOW_SAMPLES} needed")
        out.append((k, float(sign), i0, i1))
    return out


def case_windows(plan: CasePlan, series: pd.DataFrame, spec: WindowSpec = DEFAULTS.window,
                 motion_start_s: float = 0.0) -> list[dict]:
    """The windows of one triangle case as rows (segment, direction, period, statistics): four, or those a record
    that ends early holds complete (:func:`window_ranges`).

    Cut at ``motion_start_s`` + the plan's window times (:func:`window_ranges`); window_start_s and
    window_end_s are on the record's time axis, velocity_m_s is the measured slope in the window,
    force_N its mean force on the real time axis and force_std_N, n_samples its spread and samples, spikes left out
    (:func:`window_statistics`; ``set_aside``: why the window has too many), missing_samples the
    samples of the record's grid in the window that are missing (:func:`sampling.span_sampling`).
    Raises ValueError as :func:`window_ranges` does.
    """
    t = series["time_s"].to_numpy()
    y = series["displacement_m"].to_numpy()
    f = series["force_N"].to_numpy()
    rows = series["row"].to_numpy()
    dt_s = sample_interval_s(t)
    gaps = find_gaps(t, dt_s)
    half = plan.period_s / 2.0
    segments = windowed_half_periods(plan, float(t[-1]), spec, motion_start_s)
    out = []
    for k, sign, i0, i1 in window_ranges(plan, t, spec, motion_start_s):
        a, b = segments[k - 1, 0] + spec.start_fraction * half, segments[k - 1, 0] + spec.end_fraction * half
        missing = span_sampling(t, a, b, dt_s, gaps).missing
        out.append({
            "case": plan.case,
            "segment": k,
            "direction": "+" if sign > 0 else "-",
            "period": (k + 1) // 2,
            "planned_velocity_m_s": sign * plan.velocity_m_s,
            "velocity_m_s": line_slope(t[i0:i1], y[i0:i1]),
            **window_statistics(t, f, i0, i1, 0.5 * (a + b), missing),
            "window_start_s": float(t[i0]),
            "window_end_s": float(t[i1 - 1]),
            "row_start": int(rows[i0]),
            "row_stop": int(rows[i1 - 1]) + 1,
            "missing_samples": missing,
        })
    return out


def window_statistics(t, f, i0: int, i1: int, centre_s: float, missing: int = 0) -> dict:
    """The force_N, force_std_N, n_samples, spikes_excluded, set_aside ('' or the reason) of the window [i0, i1)
    of a record's force ``f`` (module doc): its spikes (:func:`isokinetic.measurement.spikes.spike_mask`) left out,
    the mean on the real time axis (:func:`window_mean_force`; complete when no sample is missing or excluded)."""
    spikes = spike_mask(f, i0, i1)
    n_spikes = int(spikes.sum())
    tw, fw = t[i0:i1], f[i0:i1]
    if n_spikes:
        tw, fw = tw[~spikes], fw[~spikes]
    return {"force_N": window_mean_force(tw, fw, centre_s, complete=missing == 0 and n_spikes == 0),
            "force_std_N": float(fw.std(ddof=1)), "n_samples": int(fw.size), "spikes_excluded": n_spikes,
            "set_aside": too_many_note(n_spikes, i1 - i0) if too_many(n_spikes, i1 - i0) else ""}


def motion_start(case) -> float:
    """``motion_start_s`` of a cases-table row: the record time of the plan's t = 0 (0 when the
    column is absent or NaN, as in tables written before it existed)."""
    value = case.get("motion_start_s") if hasattr(case, "get") else None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return 0.0
    return value if math.isfinite(value) else 0.0


def extract_windows(cases: pd.DataFrame, load_series, spec: WindowSpec, notes: dict[str, str] | None = None
                    ) -> pd.DataFrame:
    """Windows of every status-ok triangle case of a cases table (tables.WINDOWS), cut at each case's
    ``motion_start_s`` (0 when the table has no such column).

    ``load_series(case_row)`` returns the case's canonical time series. A window with too many spikes is left
    out; ``notes`` (when given) receives, per case, what its spikes did ({case: text}, only cases with a spike).
    """
    rows = []
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    for _, case in ok.iterrows():
        found = case_windows(case_plan(case), load_series(case), spec, motion_start(case))
        if notes is not None and (said := spike_note(found)):
            notes[str(case["case"])] = said
        for row in found:
            if row["set_aside"]:
                continue
            row.update(campaign=case["campaign"], raw_file=case["raw_file"], raw_sha256=case["raw_sha256"],
                       quality=case.get("quality", "ok") if isinstance(case.get("quality"), str) else "ok")
            rows.append(row)
    columns = list(tables.WINDOWS.columns)
    df = pd.DataFrame(rows, columns=columns) if rows else tables.empty(tables.WINDOWS).reindex(columns=columns)
    df = df.astype({"segment": "int64", "period": "int64", "n_samples": "int64",
                    "row_start": "int64", "row_stop": "int64", "missing_samples": "Int64", "spikes_excluded": "Int64"})
    return tables.validate_table(df[columns], tables.WINDOWS)


def spike_note(rows: list[dict]) -> str:
    """What the spikes of one case's windows (:func:`case_windows` rows) did, '' when it has none."""
    said = [f"window {r['segment']} ({r['direction']}, period {r['period']}): {r['set_aside']}" for r in rows
            if r["set_aside"]]
    kept = [r for r in rows if r["spikes_excluded"] and not r["set_aside"]]
    if kept:
        n = sum(int(r["spikes_excluded"]) for r in kept)
        where = ", ".join(f"{r['segment']}: {r['spikes_excluded']}" for r in kept)
        said.append(f"{n} spike sample{'s' if n > 1 else ''} excluded from the window means (window: count {where}; "
                    f"Hampel filter, docs/method.md)")
    return "; ".join(said)
