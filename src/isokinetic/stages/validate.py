"""Input checks: bad cases are quarantined one by one, every other case carries on.

A :class:`Problem` says what is wrong with one case (column or manifest key, first bad data
row, message); :func:`reason` turns it into the quarantine text, which names campaign, case,
column and row, e.g. ``campaign demo, case T03, column 'force_kN', row 17: non-numeric value 'abc'``.

:func:`validate_campaign` checks every case an ingest left ``ok`` (raw or simulated alike):
the canonical time-series schema (NaN/inf, time not strictly increasing), too few samples,
a record shorter than the plan needs, a sample interval far from the manifest's; then
dropped samples, saturated (flat-topped) force or displacement, and implausible magnitudes (a unit
mix-up, checked against the plan and the nominal damper model). Saturation inside the analysed data
(the windows of a triangle case; the whole record of a sine or free case) quarantines; a flat top
outside the windows is *flagged but usable*: warnings carried into the ``quality`` column of
``cases.parquet`` ('ok' when there are none).

Dropped samples (a busy logger's singles and bursts, :mod:`isokinetic.measurement.sampling`): the
later stages use the real time stamps, so a few missing samples cost only precision. A case is set
aside only when, in one of its analysed spans (a triangle case's four windows and the line fits of its
measured motion, :func:`gap_spans`; a sine or free record as a whole), the missing fraction exceeds
``GapTolerance.max_missing_fraction`` (5 %), or one gap lasts longer than ``GapTolerance.limit_s``
(the larger of ``max_gap_s``, 0.1 s, and 2 % of the half-period); both are the config's
``validation`` keys. Other gaps are flagged; every case's ``missing_samples``, ``missing_fraction``
and ``longest_gap_s`` go into ``cases.parquet`` (:data:`SAMPLING_COLUMNS`).

Timing from the record: the motion of a triangle case is measured from its displacement channel
(:func:`motion.estimate_motion`) and its windows are placed at the measured motion start, not at
the plan's t = 0 (``motion_start_s``, ``delay_s``, ``velocity_ratio``, ``motion_rms_m`` in
``cases.parquet``). A motion that departs from its plan beyond the tolerances below, windows that
no longer fit the record at the measured start, or a force against the measured velocity in all
four windows (a forgotten ``invert: true``) quarantine; a time axis offset from the motion start
or one half-period off its planned speed is flagged.

Physics any damper obeys, with or without a damper block (:func:`physics_problems`, method in
:mod:`isokinetic.measurement.plausibility`, rules and limits in docs/real-world-input.md): a force too small
for any damper or for its declared ``full_scale`` (kN declared as N), force over velocity outside any damper's
damping, a record that gives energy back over its cycles (``invert``, or played backwards), a force that leads
its motion at every reversal (time reversed or channels shifted), a temperature that follows the command or
the displacement.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import case_plan
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.campaign_meta import CampaignMeta
from isokinetic.contracts.problem import Problem
from isokinetic.contracts.settings import DEFAULTS, GapTolerance
from isokinetic.io import write_parquet
from isokinetic.measurement import plausibility as pl
from isokinetic.measurement.motion import Motion, ends_early, estimate_motion, line_spans_s
from isokinetic.measurement.sampling import find_gaps, sample_interval_s, span_sampling
from isokinetic.measurement.windows import WindowSpec, case_windows, missing_windows_note, windowed_half_periods
from isokinetic.physics.damper import Damper, nominal_force
from isokinetic.physics.plan import CasePlan

log = logging.getLogger("isokinetic")

#: Fewer samples than this cannot describe a record (and leave no sample interval to check).
MIN_SAMPLES = 10
QUARANTINE_COLUMNS = tuple(tables.QUARANTINE.columns)
#: This many consecutive identical samples at a channel's maximum or minimum are a flat top.
SATURATION_MIN_RUN = 10
#: Median |force| of a triangle record against the nominal force (Eq. 31) at its planned
#: velocity: outside [FORCE_RATIO_MIN, FORCE_RATIO_MAX] is implausible. Measured records of the
#: shipped and simulated campaigns lie within 0.02 .. 11 (friction dominates slow cases).
FORCE_RATIO_MIN, FORCE_RATIO_MAX = 1e-3, 100.0
#: Physical limit of the force: piston area times this pressure difference.
MAX_PRESSURE_PA = 50e6
#: Measured displacement (or command) amplitude against the planned one: beyond this factor either
#: way is implausible (shipped and simulated records: 0.91 .. 1.01).
AMPLITUDE_RATIO = 5.0
#: Measured piston speed against the planned W = 4Y/T (Eq. 26): the mean |v| of the four half-periods
#: off by more than this quarantines (the steady points would not lie at the planned speeds: a wrong
#: period or amplitude in the manifest, or a wrong LVDT scale); one half-period off by more than this
#: while the mean holds is flagged. Rig and simulated records lie within 0.1 %, a manifest amplitude
#: rounded to 4 significant digits adds 0.05 %.
MAX_VELOCITY_ERROR = 0.05
#: rms departure of the measured displacement from the planned triangle at the measured motion start,
#: beyond the LVDT noise (sqrt(rms² - noise²)), as a fraction of the planned amplitude: above this the
#: record does not follow its plan (wrong waveform, period or phase) and is quarantined. A speed 5 %
#: off gives 2.9 %; servo lag, corner rounding and noise give well under 1 %.
MAX_MOTION_RMS_FRACTION = 0.05
#: A motion start further than this from t = 0 of the record's time axis is flagged (and aligned).
TIME_OFFSET_NOTE_S = 0.1
#: A window's mean force counts as against the velocity only when this many standard errors from 0.
FORCE_SIGN_SIGMAS = 3.0
#: The hint a record with the opposite sign convention gets.
INVERT_HINT = "the rig's sign convention looks opposite: add `invert: true`"
#: The hint a record whose force leads its motion gets (:mod:`isokinetic.measurement.plausibility`).
REVERSED_HINT = ("time reversed (rows in reverse order, the time column left ascending) or channels shifted: "
                 "export the record in time order")
#: cases.parquet columns of the measured motion (NaN unless a triangle case reached the motion check).
MOTION_COLUMNS = ("motion_start_s", "delay_s", "velocity_ratio", "motion_rms_m")
#: cases.parquet columns of the dropped samples (NA unless the case reached the gap check).
SAMPLING_COLUMNS = ("missing_samples", "missing_fraction", "longest_gap_s")


def reason(campaign: str, case: str, problem: Problem) -> str:
    """The quarantine text: ``campaign C, case K, column 'x', row N: message``."""
    where = [f"campaign {campaign}", f"case {case}", f"{problem.kind} {problem.column!r}"]
    if problem.row is not None:
        where.append(f"row {problem.row}")
    return ", ".join(where) + ": " + problem.message


def quarantine_rows(campaign: str, case: str, stage: str, problems: Iterable[Problem]) -> list[dict]:
    """QUARANTINE rows for one case's problems; each reason is also logged."""
    rows = []
    for problem in problems:
        text = reason(campaign, case, problem)
        log.warning("quarantined at %s: %s", stage, text)
        rows.append({"campaign": campaign, "case": case, "stage": stage, "column": problem.column,
                     "row": problem.row, "reason": text})
    return rows


def quarantine_frame(rows: list[dict]) -> pd.DataFrame:
    """A QUARANTINE table from rows (empty rows give the empty table)."""
    if not rows:
        return tables.empty(tables.QUARANTINE)
    return pd.DataFrame(rows, columns=list(QUARANTINE_COLUMNS)).astype({"row": "Int64"})


def _failure_message(check: str, value, previous) -> str:
    if check == "not_nullable":
        return "missing value (NaN)"
    if check == "finite":
        return f"non-finite value {value}"
    if check == "time_increasing":
        return f"time {value} s is not above the previous row's {previous} s"
    if check == "column_in_dataframe":
        return "column missing"
    return f"failed {check}: {value}"


def timeseries_problems(df: pd.DataFrame) -> list[Problem]:
    """TIMESERIES schema failures, one per column, at the first bad data row (``row`` value)."""
    failures = tables.failure_cases(df, tables.TIMESERIES)
    if failures is None:
        return []
    data_rows = df["row"] if "row" in df else pd.Series(np.arange(len(df)), index=df.index)
    found: dict[str, Problem] = {}
    for f in failures.itertuples(index=False):
        column = f.failure_case if f.check == "column_in_dataframe" else f.column
        row, previous = None, None
        if not pd.isna(f.index):
            position = df.index.get_loc(f.index)
            row = int(data_rows.iloc[position])
            previous = df[column].iloc[position - 1] if position > 0 else None
        known = found.get(column)
        if known is None or (row is not None and (known.row is None or row < known.row)):
            found[column] = Problem(column, _failure_message(str(f.check), f.failure_case, previous), row=row)
    return list(found.values())


def record_problems(time_s: np.ndarray, plan: CasePlan, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                    min_samples: int = MIN_SAMPLES) -> list[Problem]:
    """Too few samples, a sine or free record shorter than the plan needs (one sample interval of slack,
    :func:`motion.ends_early`), or a sample interval (:func:`isokinetic.measurement.sampling.sample_interval_s`)
    off 1/sample_rate_Hz by more than the tolerance. A triangle record that ends early is judged by its windows
    (:func:`window_problems`: it keeps those that lie complete inside it). Time must be valid already."""
    n = len(time_s)
    if n < min_samples:
        return [Problem("time_s", f"only {n} samples, at least {min_samples} needed")]
    problems = []
    dt_s = 1.0 / plan.sample_rate_Hz
    duration_s = float(time_s[-1] - time_s[0])
    need_s = plan.required_duration_s
    if plan.waveform != "triangle" and ends_early(time_s, plan):
        problems.append(Problem("time_s", f"record lasts {duration_s:.6g} s, the {plan.waveform} plan needs "
                                          f"{need_s:.6g} s (less one sample interval, {dt_s:.6g} s)"))
    interval_s = sample_interval_s(time_s)       # the one rule init-campaign's draft and --check use too
    off = interval_s / dt_s - 1.0
    if abs(off) > sample_rate_tolerance:
        problems.append(Problem("time_s", f"sample interval {interval_s:.6g} s is {off:+.1%} off "
                                          f"1/sample_rate_Hz = {dt_s:.6g} s (tolerance {sample_rate_tolerance:.1%})"))
    return problems


def analysed_spans(plan: CasePlan, time_s: np.ndarray, spec: WindowSpec,
                   motion_start_s: float = 0.0) -> list[tuple[str, float, float]]:
    """(label, start, end) of the time spans whose samples the later stages use: the windows of a
    triangle case at the motion start (windows.window_ranges), the whole record of a sine or free case."""
    if plan.waveform != "triangle":
        return [(f"the record (a {plan.waveform} record is used whole)", float(time_s[0]), float(time_s[-1]))]
    half = plan.period_s / 2.0
    out = []
    for k, (t0, _t1, _sign) in enumerate(windowed_half_periods(plan, float(time_s[-1]), spec, motion_start_s), 1):
        a, b = t0 + spec.start_fraction * half, t0 + spec.end_fraction * half
        out.append((f"the window of segment {k} (t = {a:.6g} .. {b:.6g} s)", a, b))
    return out


def _inside(spans, a: float, b: float) -> str | None:
    """The label of the first span that [a, b] overlaps."""
    return next((label for label, s0, s1 in spans if a <= s1 and b >= s0), None)


def gap_spans(plan: CasePlan, time_s: np.ndarray, spec: WindowSpec,
              motion: Motion | None = None) -> list[tuple[str, float, float]]:
    """(label, start, end) of the spans whose dropped samples are judged: the analysed spans
    (:func:`analysed_spans`), and for a triangle case with a measured motion the line fits of its four
    half-periods (motion.line_spans_s), on which its speed and motion start rest."""
    start_s = motion.motion_start_s if motion is not None else 0.0
    spans = analysed_spans(plan, time_s, spec, start_s)
    if motion is not None:
        spans += [(f"the motion fit of half-period {k} (t = {a:.6g} .. {b:.6g} s)", float(a), float(b))
                  for k, (a, b) in enumerate(line_spans_s(plan, start_s), 1)]
    return spans


def _pct(x: float) -> str:
    return f"{x:+.1%}"


def gap_problems(df: pd.DataFrame, plan: CasePlan, spans, tolerance: GapTolerance = DEFAULTS.gap
                 ) -> tuple[list[Problem], list[str], dict[str, float]]:
    """Dropped samples (:func:`sampling.find_gaps` on the median interval): (problems, warnings, the
    SAMPLING_COLUMNS values).

    A span missing more than ``tolerance.max_missing_fraction`` of its samples (the first such span, at
    the row after its first gap), else a gap longer than ``tolerance.limit_s`` whose missing samples
    lie in a span (the first one, at the row after it), is a problem; any other missing samples are
    one warning giving their count, share and the longest gap.
    """
    t = df["time_s"].to_numpy()
    rows = df["row"].to_numpy()
    dt_s = sample_interval_s(t)
    gaps = find_gaps(t, dt_s)
    missing = gaps.total_missing
    summary = {"missing_samples": missing, "missing_fraction": missing / (t.size + missing),
               "longest_gap_s": gaps.longest_s}
    if missing == 0:
        return [], [], summary
    share = 0.0
    for label, a, b in spans:
        span = span_sampling(t, a, b, dt_s, gaps)
        share = max(share, span.missing_fraction)
        if span.missing_fraction > tolerance.max_missing_fraction:
            return [Problem("time_s", f"{span.missing} of the {span.expected} samples ({span.missing_fraction:.1%}) "
                                      f"missing inside {label}, more than the {tolerance.max_missing_fraction:.1%} "
                                      "tolerated (validation.max_missing_fraction)",
                            row=int(rows[span.first_after_gap]))], [], summary
    limit_s = tolerance.limit_s(plan)
    for j, m, interval in zip(gaps.before, gaps.missing, gaps.interval_s):
        ta, tb = float(t[j]), float(t[j + 1])
        where = _inside(spans, ta + dt_s, tb - dt_s) if interval > limit_s else None
        if where is not None:
            return [Problem("time_s", f"gap in time: {m} sample(s) missing between t = {ta:.6g} s and {tb:.6g} s "
                                      f"(interval {interval:.6g} s, sample interval {dt_s:.6g} s), inside {where}: "
                                      f"longer than the {limit_s:.6g} s tolerated (validation.max_gap_s, or "
                                      f"{tolerance.max_gap_half_period_fraction:.0%} of the half-period)",
                            row=int(rows[j + 1]))], [], summary
    j = int(np.argmax(gaps.interval_s))
    warning = (f"{missing} sample(s) missing in {gaps.missing.size} gap(s), {summary['missing_fraction']:.2%} of the "
               f"record; longest gap {gaps.longest_s:.4g} s at t = {t[gaps.before[j]]:.6g} s; at most "
               f"{share:.1%} of an analysed span (tolerance {tolerance.max_missing_fraction:.1%})")
    return [], [warning], summary


def clipped(t: np.ndarray, x: np.ndarray, i0: int, i1: int, extreme: float, top: bool) -> bool:
    """Whether the run x[i0:i1] at the record's ``extreme`` (``top``: a maximum) is a channel's end of range rather
    than a smooth crest read at the channel's resolution (a slow sine sampled fast stays within one step of its
    peak for many samples). A smooth crest is reached from the samples beside it within a few resolution steps,
    and a parabola through the samples flanking it (as many on each side as the run is long) peaks within 3 steps
    (the smallest step the record makes) or 3 noise σ (from the flanks' second differences) of it; anything else
    (the signal heading beyond, or jumping onto the plateau) is clipped, and so is a run with fewer than 3
    flanking samples."""
    n = i1 - i0
    left, right = np.arange(max(i0 - n, 0), i0), np.arange(i1, min(i1 + n, x.size))
    flank = np.concatenate([left, right])
    if flank.size < 3 or not left.size or not right.size:
        return True
    steps = np.abs(np.diff(x))
    step = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
    curvature = [np.diff(x[side], 2) for side in (left, right) if side.size > 2]
    noise = float(np.std(np.concatenate(curvature))) / math.sqrt(6.0) if curvature else 0.0
    tolerance = 3.0 * max(step, noise)
    if max(abs(x[i0 - 1] - extreme), abs(x[i1] - extreme)) > tolerance:
        return True
    tc = t[flank] - 0.5 * (t[i0] + t[i1 - 1])
    coef = np.polyfit(tc, x[flank], 2)
    if coef[0] == 0.0:
        return True
    vertex = float(np.polyval(coef, float(np.clip(-coef[1] / (2.0 * coef[0]), tc.min(), tc.max()))))
    return (vertex - extreme if top else extreme - vertex) > tolerance


def saturation_problems(df: pd.DataFrame, spans, min_run: int = SATURATION_MIN_RUN
                        ) -> tuple[list[Problem], list[str]]:
    """Flat tops: ``min_run`` or more consecutive identical samples at the maximum or minimum of the
    force or displacement channel (a load cell or LVDT at the end of its range), the signal heading beyond them
    (:func:`clipped`; a smooth crest read at the channel's resolution is none). Inside an analysed
    span a problem (first run, its first row), outside a warning."""
    t = df["time_s"].to_numpy()
    rows = df["row"].to_numpy()
    problems, warnings = [], []
    for column, unit in (("force_N", "N"), ("displacement_m", "m")):
        x = df[column].to_numpy()
        runs = []
        for side, extreme in (("maximum", x.max()), ("minimum", x.min())):
            at = np.concatenate([[False], x == extreme, [False]])
            edges = np.flatnonzero(np.diff(at.astype(np.int8)))
            runs += [(i0, i1, side, extreme) for i0, i1 in zip(edges[::2], edges[1::2])
                     if i1 - i0 >= min_run and clipped(t, x, i0, i1, extreme, side == "maximum")]
        for i0, i1, side, extreme in sorted(runs, key=lambda r: r[0]):
            ta, tb = float(t[i0]), float(t[i1 - 1])
            what = (f"saturated: {i1 - i0} consecutive samples at the {side} {extreme:.6g} {unit} "
                    f"(t = {ta:.6g} .. {tb:.6g} s)")
            where = _inside(spans, ta, tb)
            if where is not None:
                problems.append(Problem(column, f"{what}, inside {where}", row=int(rows[i0])))
                break
            warnings.append(f"{column} {what}, outside windows")
    return problems, warnings


def _times(ratio: float) -> str:
    return f"{ratio:.3g}" if ratio < 100 else f"{ratio:.0f}"


def _first_row(df: pd.DataFrame, mask: np.ndarray) -> int | None:
    return int(df["row"].iloc[int(np.argmax(mask))]) if mask.any() else None


def plausibility_problems(df: pd.DataFrame, plan: CasePlan, damper: Damper | None) -> list[Problem]:
    """Magnitudes that betray a wrong declared unit (values are never rescaled).

    Force: the median |force| against the nominal model (Eq. 31) at the planned velocity of a
    triangle case (both ways) or the peak velocity of a sine case (too large only: compressibility
    makes a loop's force small), and against the piston area times MAX_PRESSURE_PA. Displacement
    and command: the amplitude (max - min)/2 against the planned amplitude. The row is the first
    sample beyond the plausible bound (None for too small values).
    """
    problems = []
    f = np.abs(df["force_N"].to_numpy())
    median = float(np.median(f))
    if damper is not None:
        limit = damper.piston_area_m2 * MAX_PRESSURE_PA
        v = {"triangle": plan.velocity_m_s, "sine": 2 * np.pi * plan.frequency_Hz * plan.amplitude_m}.get(
            plan.waveform, np.nan)
        nominal = abs(float(nominal_force(v, damper))) if np.isfinite(v) and v != 0 else np.nan
        ratio = median / nominal if nominal > 0 else np.nan
        said = (f"median |force| {median:.4g} N is {_times(ratio)} x the nominal model's {nominal:.4g} N at the "
                f"planned {abs(v) * 1e3:.4g} mm/s (Eq. 31)") if np.isfinite(ratio) else f"median |force| {median:.4g} N"
        bounds = []
        if ratio > FORCE_RATIO_MAX:
            bounds.append(FORCE_RATIO_MAX * nominal)
        if median > limit:
            bounds.append(limit)
            said += f"{' and' if np.isfinite(ratio) else ''} above the physical limit {limit:.4g} N " \
                    f"(piston area x {MAX_PRESSURE_PA / 1e6:g} MPa)"
        if bounds:
            problems.append(Problem("force_N", f"{said}: implausibly large, a unit mix-up "
                                               "(e.g. values in N declared as kN)?",
                                    row=_first_row(df, f > min(bounds))))
        elif plan.waveform == "triangle" and ratio < FORCE_RATIO_MIN:
            problems.append(Problem("force_N", f"{said}: implausibly small, a unit mix-up "
                                               "(e.g. values in kN declared as N)?"))
    amplitude = plan.amplitude_m
    if np.isfinite(amplitude) and amplitude > 0:
        for column in ("displacement_m", "command_m"):
            if column not in df:
                continue
            y = df[column].to_numpy()
            amp = (y.max() - y.min()) / 2.0
            ratio = amp / amplitude
            said = f"amplitude {amp * 1e3:.4g} mm is {_times(ratio)} x the planned {amplitude * 1e3:.4g} mm"
            if ratio > AMPLITUDE_RATIO:
                # the row beyond the bound around the median position: one wild sample moves (max + min)/2 with
                # it, and every row would lie 'beyond' (row 0 named for a bad value at row 500)
                centre = float(np.median(y))
                problems.append(Problem(column, f"{said}: implausibly large, a unit mix-up (e.g. values in um "
                                                "declared as mm, or in mm declared as m)?",
                                        row=_first_row(df, np.abs(y - centre) > AMPLITUDE_RATIO * amplitude)))
            elif ratio < 1.0 / AMPLITUDE_RATIO:
                problems.append(Problem(column, f"{said}: implausibly small, a unit mix-up (e.g. values in m "
                                                "declared as mm, or in mm declared as um)?"))
    return problems


def motion_problems(motion: Motion, plan: CasePlan) -> tuple[list[Problem], list[str]]:
    """The measured motion against the plan (Eq. 26): (problems, flagged-but-usable warnings).

    Displacement against the plan in every half-period (an inverted LVDT), the mean speed off the
    plan by more than MAX_VELOCITY_ERROR, or an rms departure beyond MAX_MOTION_RMS_FRACTION of the
    amplitude (noise removed) quarantine, in that order (one problem for the column). One
    half-period off its speed while the mean holds, and a motion start more than TIME_OFFSET_NOTE_S
    from t = 0, are warnings.
    """
    problems, warnings = [], []
    w_mm_s = plan.velocity_m_s * 1e3
    ratios = motion.velocity_ratios
    measured = np.isfinite(ratios)
    speeds = ", ".join(f"{v * 1e3:+.4g}" for v in motion.velocities_m_s)
    planned = ", ".join(f"{v * 1e3:+.4g}" for v in motion.planned_velocities_m_s)
    if measured.any() and (ratios[measured] < 0).all():
        problems.append(Problem("displacement_m", f"the displacement moves against the plan in every half-period "
                                                  f"(measured {speeds} mm/s, planned {planned} mm/s): {INVERT_HINT} "
                                                  "to the manifest's `displacement` column"))
    elif abs(motion.velocity_ratio - 1.0) > MAX_VELOCITY_ERROR:
        problems.append(Problem("displacement_m", f"measured piston speed {motion.velocity_ratio * w_mm_s:.4g} mm/s "
                                                  f"(mean |v| of the half-periods: {speeds} mm/s) is "
                                                  f"{_pct(motion.velocity_ratio - 1.0)} off the planned 4Y/T = "
                                                  f"{w_mm_s:.4g} mm/s (Eq. 26; tolerance {MAX_VELOCITY_ERROR:.0%}): a "
                                                  "wrong period_s or amplitude in the manifest, or a wrong LVDT "
                                                  "scale?"))
    elif motion.excess_rms_m > MAX_MOTION_RMS_FRACTION * plan.amplitude_m:
        problems.append(Problem("displacement_m", f"the displacement departs from the planned triangle (Eq. 26, "
                                                  f"shifted to the measured motion start t = "
                                                  f"{motion.motion_start_s:.6g} s) by {motion.rms_m * 1e3:.4g} mm "
                                                  f"rms, {motion.excess_rms_m / plan.amplitude_m:.1%} of the "
                                                  f"{plan.amplitude_m * 1e3:.4g} mm amplitude beyond the LVDT "
                                                  f"noise {motion.noise_m * 1e3:.2g} mm (tolerance "
                                                  f"{MAX_MOTION_RMS_FRACTION:.0%})"))
    else:
        for k in np.flatnonzero(measured & (np.abs(np.abs(ratios) - 1.0) > MAX_VELOCITY_ERROR)):
            warnings.append(f"half-period {k + 1} moves at {motion.velocities_m_s[k] * 1e3:+.4g} mm/s, "
                            f"{_pct(abs(ratios[k]) - 1.0)} off the planned {w_mm_s:.4g} mm/s")
    if abs(motion.motion_start_s) > TIME_OFFSET_NOTE_S:
        first = motion.motion_start_s - motion.delay_s
        warnings.append(f"time axis offset: the motion starts at t = {motion.motion_start_s:.6g} s of the record "
                        f"(first sample at t = {first:.6g} s, delay {motion.delay_s * 1e3:.3g} ms); windows "
                        "aligned to the measured motion")
    return problems, warnings


def window_problems(df: pd.DataFrame, plan: CasePlan, motion: Motion, spec: WindowSpec
                    ) -> tuple[list[Problem], list[str]]:
    """The windows at the measured motion start: that they fit the record, and the force's sign:
    (problems, flagged-but-usable warnings).

    A record that does not hold its first window at the motion start (a delay too large, a record cut
    short before it), or that ends early before the middle of its second half-period (its motion start rests on
    one ramp: motion module doc), is a ``time_s`` problem; one that ends before its last windows keeps those it
    holds complete, the others named in a warning (:func:`windows.missing_windows_note`). A mean force against the
    measured velocity in every window, each mean FORCE_SIGN_SIGMAS standard errors from zero, is a ``force_N``
    problem with the INVERT_HINT (Force resists positive velocity: raw-campaign spec, "Waveforms and signs").
    """
    t_end_s = float(df["time_s"].iloc[-1])
    velocities = np.asarray(motion.velocities_m_s)
    if ends_early(df["time_s"].to_numpy(), plan) and not ((velocities > 0).any() and (velocities < 0).any()):
        middle_s = float(line_spans_s(plan, 0.0)[1].mean())
        return [Problem("time_s", f"record ends at {t_end_s:.6g} s, before the middle of its second half-period "
                                  f"({middle_s:.6g} s after the motion start in the plan): the motion start, on "
                                  "which the windows are placed, needs the line of a rising and of a falling "
                                  "half-period (at least the first window and the middle of the second "
                                  "half-period)")], []
    try:
        rows = case_windows(plan, df, spec, motion.motion_start_s)
    except ValueError as exc:
        said = str(exc).removeprefix(f"case {plan.case}: ")
        return [Problem("time_s", f"the windows do not fit the record at the measured motion start, "
                                  f"{motion.delay_s * 1e3:.4g} ms after the first sample: {said}")], []
    missing = missing_windows_note(plan, t_end_s, [r["segment"] for r in rows], motion.motion_start_s)
    warnings = [missing] if missing else []
    forces = np.array([r["force_N"] for r in rows])
    velocities = np.array([r["velocity_m_s"] for r in rows])
    se = np.array([r["force_std_N"] / math.sqrt(r["n_samples"]) for r in rows])
    if np.all(forces * velocities < 0) and np.all(np.abs(forces) > FORCE_SIGN_SIGMAS * se):
        pairs = ", ".join(f"{f:+.4g} N at {v * 1e3:+.4g} mm/s" for f, v in zip(forces, velocities))
        row = int(rows[0]["row_start"])
        every = "all four" if len(rows) == 4 else f"all {len(rows)} of its"
        return [Problem("force_N", f"the mean force opposes the measured velocity in {every} windows ({pairs}): "
                                   f"{INVERT_HINT} to the manifest's `force` column", row=row)], warnings
    return [], warnings


def temperature_problems(df: pd.DataFrame) -> list[Problem]:
    """A temperature channel that follows the command or the displacement (|correlation| >=
    pl.FOLLOW_CORRELATION) is that channel, not an oil temperature (a short header drafted as a temperature)."""
    if "temperature_C" not in df:
        return []
    temperature = df["temperature_C"].to_numpy()
    for column in ("command_m", "displacement_m"):
        r = pl.follows(temperature, df[column].to_numpy()) if column in df else 0.0
        if r >= pl.FOLLOW_CORRELATION:
            return [Problem("temperature_C", f"the temperature follows the {column.split('_')[0]} (|correlation| "
                                             f"{r:.3f}, at least {pl.FOLLOW_CORRELATION:g}): an oil temperature "
                                             f"drifts, it does not repeat the motion; is the column the "
                                             f"{column.split('_')[0]}?")]
    return []


def energy_problems(df: pd.DataFrame, dt_s: float) -> list[Problem]:
    """Dissipation and causality (:mod:`isokinetic.measurement.plausibility`): a record whose cycles give
    energy back runs backwards when its negated force leads the motion (REVERSED_HINT), else has the opposite sign
    convention (INVERT_HINT) where its cycles are slow enough to tell that from a channel's lag
    (pl.energy_decides; a faster one is flagged by :func:`energy_warnings`); a record whose force leads the
    motion at every reversal (the lead beyond pl.lead_bound_s and three standard errors) is time reversed or
    shifted (REVERSED_HINT)."""
    t, x, f = (df[c].to_numpy() for c in ("time_s", "displacement_m", "force_N"))
    net, absolute = pl.cycle_energies(t, x, f)
    back = pl.gives_energy_back(net, absolute)   # a lag can make a fast record do it, never make a force lead
    lead = pl.causality(t, x, -f if back else f, dt_s)
    gave = (f"over its {net.size} complete cycle(s) the record gives back {-net.sum():.4g} J, "
            f"{-net.sum() / absolute.sum():.0%} of the work |F v| dt; a damper absorbs energy") if back else ""
    if lead.leads_everywhere:
        said = f"{gave}, and with the force negated {lead.said()}" if back else lead.said()
        return [Problem("force_N", f"{said}: {REVERSED_HINT}")]
    if back and pl.energy_decides(t, x):
        return [Problem("force_N", f"{gave}: {INVERT_HINT} to the manifest's `force` column (or the record runs "
                                   "backwards in time: then the force leads its motion, not measured here)")]
    return []


def magnitude_problems(df: pd.DataFrame, full_scale_N: float | None, campaign_peaks_N=None) -> list[Problem]:
    """Force magnitudes without design data (pl.force_magnitude_problem: against a declared full scale, or a
    damper's forces over the cases sharing the force column), and force over velocity against any damper's
    damping (pl.DAMPING_RANGE_N_S_M)."""
    f = df["force_N"].to_numpy()
    said = pl.force_magnitude_problem(f, full_scale_N, campaign_peaks_N)
    if said:
        return [Problem("force_N", said)]
    damping = pl.implied_damping_N_s_m(df["time_s"].to_numpy(), df["displacement_m"].to_numpy(), f)
    if not pl.plausible_damping(damping):
        low, high = pl.DAMPING_RANGE_N_S_M
        return [Problem("force_N", f"force over velocity {damping:.3g} N s/m lies outside a damper's {low:g} to "
                                   f"{high:g} N s/m: a unit mix-up in the force or the displacement?")]
    return []


def velocity_column_problem(df: pd.DataFrame, problem: Problem) -> Problem | None:
    """A triangle case's displacement problem restated when the column is a velocity (pl.two_level_fraction: two
    levels, not a ramp), which no `invert` or scale fixes; None otherwise."""
    if problem.column != "displacement_m":
        return None
    y = df["displacement_m"].to_numpy()
    share = pl.two_level_fraction(y)
    if share < pl.TWO_LEVEL_FRACTION:
        return None
    return Problem("displacement_m", f"the displacement column looks like a velocity: {share:.0%} of its samples "
                                     f"sit on two levels, as a triangle test's piecewise constant velocity does, "
                                     f"where a displacement ramps between them; name the displacement column in "
                                     f"the manifest (`invert` or a scale would not fix this)")


def energy_warnings(df: pd.DataFrame, plan: CasePlan) -> list[str]:
    """A kept moving record whose cycles give back more than pl.ENERGY_NOTE_FRACTION of their work (but not
    pl.ENERGY_FRACTION, which sets it aside): flagged, as a force channel's lag on a mostly elastic force or a
    sign error could both show it."""
    if plan.waveform == "standstill":
        return []
    t, x = df["time_s"].to_numpy(), df["displacement_m"].to_numpy()
    back = pl.energy_given_back(*pl.cycle_energies(t, x, df["force_N"].to_numpy()))
    if back <= pl.ENERGY_NOTE_FRACTION:
        return []
    decides = pl.energy_decides(t, x)
    if back > pl.ENERGY_FRACTION and decides:
        return []   # set aside (energy_problems)
    kept = (f"kept below {pl.ENERGY_FRACTION:.0%}" if decides else
            f"kept: its cycles are shorter than {pl.ENERGY_PERIODS_PER_LAG:g} x {pl.FORCE_LAG_MAX_S:g} s, where a "
            "channel's lag alone can turn the force past a quarter period")
    return [f"the cycles give back {back:.0%} of the work |F v| dt (a damper absorbs energy): a force channel's lag "
            f"past a quarter period on a mostly elastic force shows this, and so does a force of the wrong sign; "
            f"{kept}: check the force channel's filter and sign"]


def physics_problems(df: pd.DataFrame, plan: CasePlan, full_scale_N: float | None = None,
                     campaign_peaks_N=None) -> list[Problem]:
    """The checks that need no damper block: a temperature that follows the motion, and for a moving case
    (triangle, sine, free) the force's magnitude (``campaign_peaks_N``: the 99th percentile |F| of the cases
    sharing its force column, None: this case alone) and damping, dissipation and causality."""
    problems = temperature_problems(df)
    if plan.waveform == "standstill":
        return problems
    return problems + magnitude_problems(df, full_scale_N, campaign_peaks_N) + energy_problems(df, sample_interval_s(
        df["time_s"].to_numpy()))


@dataclass(frozen=True)
class CaseCheck:
    """What the checks of one case found: problems, flagged-but-usable warnings, the measured motion
    (None unless a triangle case got as far as the motion check), the SAMPLING_COLUMNS values (None
    unless the case got as far as the gap check)."""

    problems: list[Problem]
    warnings: list[str]
    motion: Motion | None = None
    sampling: dict[str, float] | None = None


def check_case(df: pd.DataFrame, plan: CasePlan, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
               min_samples: int = MIN_SAMPLES, damper: Damper | None = None,
               window_spec: WindowSpec = DEFAULTS.window, gap_tolerance: GapTolerance = DEFAULTS.gap,
               full_scale_N: float | None = None, campaign_peaks_N=None) -> CaseCheck:
    """All checks of one canonical time series.

    The schema first, then the record (length, sample rate); then the measured motion of a triangle
    case, whose start places the windows; then gaps, saturation, plausibility, the motion against
    the plan and the windows (fit, force sign), the physics any damper obeys (:func:`physics_problems`; a
    time-reversed record's reason before the windows' sign hint); each step only once the previous ones hold
    (at most one problem per column, the first found).
    """
    problems = timeseries_problems(df) or record_problems(df["time_s"].to_numpy(), plan, sample_rate_tolerance,
                                                          min_samples)
    if problems:
        return CaseCheck(problems, [])
    t = df["time_s"].to_numpy()
    motion, start_s = None, 0.0
    if plan.waveform == "triangle":
        motion = estimate_motion(t, df["displacement_m"].to_numpy(), plan)
        start_s = motion.motion_start_s
    spans = analysed_spans(plan, t, window_spec, start_s)
    gaps, warnings, sampling = gap_problems(df, plan, gap_spans(plan, t, window_spec, motion), gap_tolerance)
    flat, flat_warnings = saturation_problems(df, spans)
    if plan.waveform == "standstill":   # (manifest 1.2) a rod at rest: a flat displacement is the point, not an LVDT
        flat = [p for p in flat if p.column != "displacement_m"]   # at the end of its range
    found: dict[str, Problem] = {}
    later, motion_warnings = [], []
    if motion is not None:
        later, motion_warnings = motion_problems(motion, plan)
        windows, window_warnings = window_problems(df, plan, motion, window_spec)
        motion_warnings += window_warnings
        # with the displacement inverted, the force is checked against a velocity of the wrong sign
        inverted = any(INVERT_HINT in p.message for p in later)
        later += [p for p in windows if not (inverted and p.column == "force_N")]
    physics = physics_problems(df, plan, full_scale_N, campaign_peaks_N)
    later = [velocity_column_problem(df, p) or p for p in later]
    if any(INVERT_HINT in p.message and p.column == "displacement_m" for p in later):
        physics = [p for p in physics if p.column != "force_N"]    # judged against a velocity of the wrong sign
    reversed_first = [p for p in physics if REVERSED_HINT in p.message]
    for problem in gaps + flat + plausibility_problems(df, plan, damper) + reversed_first + later + physics:
        found.setdefault(problem.column, problem)
    energy = energy_warnings(df, plan) if not found else []
    return CaseCheck(list(found.values()), warnings + flat_warnings + motion_warnings + energy, motion, sampling)


def case_checks(df: pd.DataFrame, plan: CasePlan, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                min_samples: int = MIN_SAMPLES, damper: Damper | None = None,
                window_spec: WindowSpec = DEFAULTS.window, gap_tolerance: GapTolerance = DEFAULTS.gap
                ) -> tuple[list[Problem], list[str]]:
    """(problems, flagged-but-usable warnings) of :func:`check_case`."""
    found = check_case(df, plan, sample_rate_tolerance, min_samples, damper, window_spec, gap_tolerance)
    return found.problems, found.warnings


def case_problems(df: pd.DataFrame, plan: CasePlan, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                  min_samples: int = MIN_SAMPLES, damper: Damper | None = None,
                  window_spec: WindowSpec = DEFAULTS.window) -> list[Problem]:
    """The problems of :func:`check_case` (warnings dropped)."""
    return check_case(df, plan, sample_rate_tolerance, min_samples, damper, window_spec).problems


def motion_columns(motion: Motion | None, plan: CasePlan) -> dict[str, float]:
    """The MOTION_COLUMNS of cases.parquet: motion_start_s (record time of the plan's t = 0),
    delay_s (motion start - first time stamp), velocity_ratio (mean measured |v| / planned 4Y/T),
    motion_rms_m (rms departure of the displacement from the planned triangle at the motion start,
    noise included); NaN without a measured motion."""
    if motion is None:
        return dict.fromkeys(MOTION_COLUMNS, math.nan)
    return {"motion_start_s": motion.motion_start_s, "delay_s": motion.delay_s,
            "velocity_ratio": motion.velocity_ratio, "motion_rms_m": motion.rms_m}


def force_columns(meta: CampaignMeta) -> dict[str, tuple[tuple[str, str, float], float | None]]:
    """case -> ((name, unit, scale) of its force column, its declared ``full_scale`` in N or None), from the
    campaign's manifest (campaign.json ``manifest_file``); empty for a simulated campaign or a manifest that no
    longer reads (every case then shares one column, without a full scale)."""
    path = meta.manifest_file
    if not path or not Path(path).is_file():
        return {}
    from isokinetic.contracts.manifest import ManifestError, channel_unit, load_manifest  # pint: lazy
    try:
        manifest = load_manifest(path)
    except (ManifestError, OSError, ValueError):
        return {}
    out = {}
    for spec in manifest.cases:
        column = spec.columns.get("force")
        if column is None:
            continue
        try:
            to_n = abs(column.scale * channel_unit("force", column.unit).scale)
        except ValueError:
            continue
        full = None if column.full_scale is None else abs(column.full_scale) * to_n
        out[spec.plan.case] = ((column.name, column.unit, column.scale), full)
    return out


def peaks_by_column(ingested: CampaignFolder, moving: pd.DataFrame, columns: dict) -> dict[str, list[float]]:
    """case -> the 99th percentile |F| of every moving case that shares its force column (pl.peak_magnitude)."""
    peaks = {row["case"]: pl.peak_magnitude(ingested.timeseries(row, ["force_N"])["force_N"].to_numpy())
             for _, row in moving.iterrows()}
    key = {case: columns.get(case, (None, None))[0] for case in peaks}
    return {case: [p for other, p in peaks.items() if key[other] == key[case]] for case in peaks}


def validate_campaign(campaign_root: str | Path, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                      min_samples: int = MIN_SAMPLES, window_spec: WindowSpec = DEFAULTS.window,
                      gap_tolerance: GapTolerance = DEFAULTS.gap) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Check every ``ok`` case of ``<campaign_root>/ingest``.

    Returns (cases, quarantine): all cases with their final status and ``quality`` (the ingest's
    warnings followed by this stage's, 'ok' when none, 'quarantined') and the measured motion of
    each triangle case (MOTION_COLUMNS, :func:`motion_columns`) and the dropped samples of each
    checked case (SAMPLING_COLUMNS, :func:`gap_problems`), and the ingest's quarantine rows followed
    by this stage's (``stage="validate"``). Each warning is logged.
    """
    ingested = CampaignFolder.at(campaign_root)
    campaign = ingested.meta.campaign
    damper = ingested.damper
    cases = ingested.ingested_cases()
    if "quality" not in cases:
        cases["quality"] = np.where(cases["status"] == "ok", "ok", "quarantined")
    cases["quality"] = cases["quality"].fillna("ok").astype(str)
    for column in MOTION_COLUMNS:
        cases[column] = math.nan
    cases["missing_samples"] = pd.array([pd.NA] * len(cases), dtype="Int64")
    for column in SAMPLING_COLUMNS[1:]:
        cases[column] = math.nan
    rows = []
    columns = force_columns(ingested.meta)
    ok = cases[cases["status"] == "ok"]
    peaks = peaks_by_column(ingested, ok[ok["waveform"] != "standstill"], columns)
    for i, row in ok.iterrows():
        df = ingested.timeseries(row)
        plan = case_plan(row)
        found = check_case(df, plan, sample_rate_tolerance, min_samples, damper, window_spec, gap_tolerance,
                           columns.get(plan.case, (None, None))[1], peaks.get(plan.case))
        problems, warnings = found.problems, found.warnings
        for column, value in motion_columns(found.motion, plan).items():
            cases.loc[i, column] = value
        for column, value in (found.sampling or {}).items():
            cases.loc[i, column] = value
        if problems:
            cases.loc[i, ["status", "quality"]] = ["quarantined", "quarantined"]
            rows += quarantine_rows(campaign, row["case"], "validate", problems)
        elif warnings:
            earlier = [] if row["quality"] == "ok" else [row["quality"]]
            cases.loc[i, "quality"] = "; ".join(earlier + warnings)
        if not problems and cases.loc[i, "quality"] != "ok":
            # usable: no action needed, so not a WARNING (the cases table and the report show it)
            log.info("flagged (usable) at validate: campaign %s, case %s: %s", campaign, row["case"],
                     cases.loc[i, "quality"])
    quarantine = ingested.ingested_quarantine()
    if rows:
        new = quarantine_frame(rows)
        quarantine = new if quarantine.empty else pd.concat([quarantine, new], ignore_index=True)
    return cases, quarantine


def write_validated(campaign_root: str | Path, sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance,
                    min_samples: int = MIN_SAMPLES, window_spec: WindowSpec = DEFAULTS.window,
                    gap_tolerance: GapTolerance = DEFAULTS.gap) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Validate and write ``<campaign_root>/cases.parquet`` and ``quarantine.parquet``."""
    folder = CampaignFolder.at(campaign_root)
    cases, quarantine = validate_campaign(folder.root, sample_rate_tolerance, min_samples, window_spec, gap_tolerance)
    write_parquet(tables.validate_table(quarantine, tables.QUARANTINE), folder.path("validate", "quarantine"))
    write_parquet(tables.validate_table(cases, tables.CASES), folder.path("validate", "cases"))
    return cases, quarantine
