"""``init-campaign --check FOLDER``: a folder's case files against its existing manifest, case by case.

Each case's file is read as ingest reads it (the manifest's file format, its slice ``time_range_s`` /
``rows``, columns, units, ``invert``), then the same detection as the draft (:mod:`.waveform`,
:mod:`.channels`, :mod:`.survey`) is compared with the plan: waveform (a standstill: no motion), period or
frequency, amplitude, a triangle's phase, the sample rate, each column's unit against its magnitudes (a
column declared mm whose values look like m), and the column choice itself: a column in volts declared as
a force, displacement or temperature, a column other than the one the role choice takes (when that choice
is not a guess), and the physics of the roles (the force follows the velocity as a damper's does, with the
right sign after ``invert``; a plausible oil temperature; the displacement's range against the plan's
amplitude). Only clear disagreements count: a unit only when the magnitudes make every other unit
implausible or far less plausible (``sure``), a period or frequency beyond :data:`PERIOD_TOLERANCE` and
four standard errors, an amplitude beyond :data:`AMPLITUDE_TOLERANCE`, a sample interval off the plan's
by ingest's own rule (:func:`isokinetic.measurement.sampling.rate_offset` beyond the project's
``validation.sample_rate_tolerance``: a rate --check accepts is one validate accepts), a file above the project's
``ingest.max_case_file_MB`` not read, as ingest does not read it. The settings are the project's
(:func:`isokinetic.contracts.settings.project_settings`: the config of the project around the folder, else around
the working directory, else the defaults). Exit status 0 when every case agrees, 1 otherwise.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from isokinetic.contracts.manifest import MANIFEST_NAME, CaseSpec, load_manifest
from isokinetic.contracts.settings import DEFAULTS, Settings, project_settings
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign import survey as sv
from isokinetic.init_campaign.sniff import parse_column
from isokinetic.init_campaign.survey import case_files, relative_name, sample_rate
from isokinetic.init_campaign.waveform import SNAP_FRACTION, Waveform, detect_waveform
from isokinetic.measurement.motion import noise_level
from isokinetic.measurement.sampling import rate_offset
from isokinetic.stages.ingest import CaseFileError, FileCache, case_series, size_problem, slice_rows
from isokinetic.timestamps import TIME_TEXT_UNITS

#: A detected period or frequency further than this fraction (and four standard errors) from the plan disagrees:
#: windows are cut from the planned period, and 1e-4 of it is under a sample interval at the end of a record.
PERIOD_TOLERANCE = 1e-4
#: A detected amplitude further than this fraction from the plan disagrees: a commanded amplitude lies a percent or
#: two above the measured one (servo error, compliance), and ingest quarantines a speed 5 % off the plan's
#: (:data:`isokinetic.stages.validate.MAX_VELOCITY_ERROR`).
AMPLITUDE_TOLERANCE = 0.03
#: A standstill moves less than this [m] (or a few noise levels, :data:`STANDSTILL_SIGMAS`).
STANDSTILL_RANGE_M, STANDSTILL_SIGMAS = 1.0e-4, 16.0


@dataclass(frozen=True)
class Finding:
    """One disagreement: the manifest key, what it plans, what the file shows."""

    key: str
    planned: str
    detected: str
    planned_word: str = "planned"


@dataclass
class CaseCheck:
    """One case's check: its disagreements (none: it agrees) and what was detected."""

    case: str
    file: str
    findings: list[Finding] = field(default_factory=list)
    detected: str = ""

    @property
    def agrees(self) -> bool:
        return not self.findings


def _g(x: float) -> str:
    return f"{x:.6g}"


@dataclass
class Record:
    """One case's file as read under the manifest: its raw columns (the case's slice), the file's units row,
    the decimal mark, its time in seconds, and the canonical SI series (``invert`` applied)."""

    spec: CaseSpec
    raw: object                  # the table of strings
    t_s: np.ndarray
    units: dict = field(default_factory=dict)
    decimal: str = "."
    df: object = None


def unit_choices(records: list[Record]) -> dict[tuple[str, str, str], ch.UnitChoice]:
    """The most plausible unit of every (channel, column name, declared unit), from the magnitudes of every file
    that has it (a campaign's files share their units: one file's magnitudes may fit two units, all of them
    rarely do)."""
    scores: dict[tuple[str, str, str], list[dict[str, float]]] = {}
    for r in records:
        for channel, column in r.spec.columns.items():
            if channel not in ch.DIMENSION or column.unit in TIME_TEXT_UNITS:
                continue
            data = parse_column(column.name, r.raw[column.name], r.decimal)
            if data.numbers is None:
                continue
            key = (channel, column.name, column.unit)
            scores.setdefault(key, []).append(ch.unit_scores(channel, data.numbers, r.t_s))
    return {key: ch.choose_unit(per_file) for key, per_file in scores.items()}


def unit_findings(record: Record, choices: dict[tuple[str, str, str], ch.UnitChoice]) -> list[Finding]:
    """Columns whose declared unit the campaign's magnitudes clearly contradict."""
    out = []
    for channel, column in record.spec.columns.items():
        choice = choices.get((channel, column.name, column.unit))
        scored = channel in ch.DIMENSION and column.unit in ch.SCORED[ch.DIMENSION[channel]]
        if scored and choice is not None and choice.unit not in (None, column.unit) and choice.sure == "sure":
            data = parse_column(column.name, record.raw[column.name], record.decimal)
            shown = ch.describe(channel, data.numbers[np.isfinite(data.numbers)], record.t_s)
            out.append(Finding(f"columns.{channel}", f"{column.name!r} in {column.unit}",
                               f"magnitudes that look like {choice.unit} ({shown}; {choice.why})", "declared"))
    return out


def plan_findings(spec: CaseSpec, w: Waveform, motion: str) -> list[Finding]:
    """Planned against detected waveform, period or frequency, amplitude and a triangle's phase."""
    plan = spec.plan
    if w.kind != plan.waveform:
        return [Finding("waveform", plan.waveform, f"{w.kind} ({w.how})")]
    out, pairs = [], []
    if w.kind == "triangle":
        pairs.append(("period_s", plan.period_s, w.period_s, "s"))
    elif w.kind == "sine":
        pairs.append(("frequency_Hz", plan.frequency_Hz, w.frequency_Hz, "Hz"))
    for key, planned, found, unit in pairs:
        if abs(found.value - planned) > max(4.0 * found.se, PERIOD_TOLERANCE * planned):
            out.append(Finding(key, _g(planned), f"{_g(found.value)} ± {found.se:.1g} {unit}"))
    if w.kind in ("triangle", "sine"):
        amp = w.amplitude_m
        if abs(amp.value / plan.amplitude_m - 1.0) > AMPLITUDE_TOLERANCE:
            out.append(Finding("amplitude_mm", _g(plan.amplitude_m * 1e3),
                               f"{_g(amp.value * 1e3)} mm from the {motion} "
                               f"({amp.value / plan.amplitude_m - 1.0:+.1%}, tolerance {AMPLITUDE_TOLERANCE:.0%})"))
    if w.kind == "triangle" and not out:
        delta = math.remainder(w.phase_rad - plan.phase_rad, 2.0 * math.pi)
        if abs(delta) > 2.0 * math.pi * SNAP_FRACTION:
            hint = "; half a period off: a wrong phase, or a displacement of the opposite sign (`invert: true`)?" \
                if abs(abs(delta) - math.pi) < 2.0 * math.pi * SNAP_FRACTION else ""
            out.append(Finding("phase_rad", _g(plan.phase_rad), f"{_g(w.phase_rad)} ({w.phase_note}){hint}"))
    return out


def summary(w: Waveform, rate: float) -> str:
    if w.kind == "triangle":
        said = f"triangle, period {_g(w.period_s.value)} s, amplitude {_g(w.amplitude_m.value * 1e3)} mm"
    elif w.kind == "sine":
        said = f"sine, {_g(w.frequency_Hz.value)} Hz, amplitude {_g(w.amplitude_m.value * 1e3)} mm"
    else:
        said = "free"
    return f"{said}, {_g(rate)} Hz"


def read_record(folder: Path, spec: CaseSpec, cache: FileCache | None = None,
                max_file_MB: float = DEFAULTS.max_case_file_MB) -> tuple[Record | None, list[Finding]]:
    """A case's file read as ingest reads it (its format, its slice; not above ``max_file_MB``), or what keeps it
    from being read."""
    if spec.problems:
        return None, [Finding(p.column, "", f"manifest: {p.message}") for p in spec.problems]
    cache = cache or FileCache()
    path = folder / spec.file
    if not path.is_file():
        return None, [Finding("file", spec.file, "file not found")]
    too_large = size_problem(path, max_file_MB)
    if too_large is not None:
        return None, [Finding("file", spec.file, f"ingest refuses it: {too_large.message}")]
    try:
        table = cache.table(path, spec.csv)
    except CaseFileError as exc:
        return None, [Finding("file", spec.file, f"ingest refuses it: {exc.problem.message}")]
    span, _, problem = slice_rows(spec, table, cache, path)
    if problem is not None:
        return None, [Finding(problem.column, "", f"ingest: {problem.message}")]
    df, problems, _, _ = case_series(table, span, spec)      # a partial record's damaged rows left out, as ingest
    if problems:
        return None, [Finding(f"column {p.column!r}", "", f"ingest: {p.message}") for p in problems]
    t = df["time_s"].to_numpy()
    if t.size < 2 or not np.all(np.diff(t) > 0):
        return None, [Finding("columns.time", spec.columns["time"].name, "time does not increase")]
    raw = table.frame.iloc[np.searchsorted(table.rows, df["row"].to_numpy())].reset_index(drop=True)
    return Record(spec, raw, t, dict(table.units), table.decimal, df), []


def role_choice(record: Record) -> sv.FileSurvey:
    """The draft's role choice re-run on a case's columns (names, a units row, magnitudes)."""
    data = {str(n): parse_column(str(n), record.raw[n], record.decimal) for n in record.raw.columns}
    fs = sv.FileSurvey(str(record.spec.file), record.spec.id, data=data,
                       units_row={k: v for k, v in record.units.items() if v})
    sv.assign_by_name(fs)
    sv.assign_by_magnitude(fs)
    return fs


def column_findings(record: Record) -> list[Finding]:
    """The manifest's column choice against the draft's: a column in volts as a force, displacement, command or
    temperature (its scaled twin named when there is one), and a column other than the one the role choice takes
    by name or magnitudes (unless that choice is only a guess)."""
    fs, out = role_choice(record), []
    for channel, column in record.spec.columns.items():
        chosen = fs.roles.get(channel)
        if channel != "time" and ch.says_volts(column.name, record.units.get(column.name)):
            twin = f"its scaled twin {chosen!r} is the {channel}" if chosen else "no scaled twin: scale it first"
            out.append(Finding(f"columns.{channel}", f"{column.name!r} in {column.unit}",
                               f"a column in volts, not in {column.unit} ({twin})", "declared"))
        elif chosen is not None and chosen != column.name and fs.role_how[channel][1] != "guess":
            out.append(Finding(f"columns.{channel}", repr(column.name),
                               f"the role choice takes {chosen!r} ({fs.role_how[channel][0]})", "declared"))
    return out


def velocity_findings(record: Record) -> list[Finding]:
    """A declared force that is the displacement's derivative times a unit ratio (:func:`channels.derivative_fit`):
    a velocity, never a force; a declared displacement that is the command's: a velocity, never a displacement
    (``invert`` would not fix it)."""
    columns = record.spec.columns
    pairs = [("displacement", "force", "a force (a damper's force is no function of the velocity alone)")]
    pairs += [("command", "displacement", "a displacement (`invert` would not fix it)")] if "command" in columns else []
    out = []
    for of, channel, what in pairs:
        raw = [parse_column(c.name, record.raw[c.name], record.decimal).numbers
               for c in (columns[of], columns[channel])]
        fit = ch.derivative_fit(record.t_s, *raw) if all(r is not None for r in raw) else None
        if fit is not None and fit.is_velocity:
            out.append(Finding(f"columns.{channel}", repr(columns[channel].name),
                               f"a column that {ch.velocity_note(fit, f'the {of}')}, not {what}", "declared"))
    return out


def force_findings(record: Record, disp: np.ndarray) -> list[Finding]:
    """A declared force that does not follow the velocity as a damper's does: opposing it in every cycle (a wrong
    ``invert``), uncorrelated, or with an implausible damping."""
    column = record.spec.columns["force"]
    verdict = ch.force_follows_velocity(record.t_s, disp, record.df["force_N"].to_numpy())
    force = repr(column.name) + (" inverted" if column.invert else "")
    if verdict.opposed_everywhere:
        return [Finding("columns.force", force, f"a force opposing the velocity in all {verdict.cycles} cycles "
                                                f"(correlation {verdict.correlation:.2f}): `invert` is wrong, "
                                                "or the column", "declared")]
    if verdict.problem:
        return [Finding("columns.force", force, verdict.problem, "declared")]
    if not ch.plausible_damping(verdict.damping_N_s_m):
        return [Finding("columns.force", force, f"force over velocity {verdict.damping_N_s_m:.3g} N s/m, outside "
                                                f"a damper's {ch.DAMPING_RANGE_N_S_M[0]:g} to "
                                                f"{ch.DAMPING_RANGE_N_S_M[1]:g} N s/m", "declared")]
    return []


def physics_findings(record: Record, motion: str) -> list[Finding]:
    """The roles' physics under the manifest: a moving case's force follows its velocity as a damper's does
    (positive correlation after ``invert``, a plausible damping), the temperature is plausible for oil, the
    displacement's range is the plan's amplitude."""
    spec, df, out = record.spec, record.df, []
    plan = spec.plan
    if "temperature_C" in df:
        median = float(np.nanmedian(df["temperature_C"].to_numpy()))
        if not sv.OIL_RANGE_C[0] <= median <= sv.OIL_RANGE_C[1]:
            out.append(Finding("columns.temperature", repr(spec.columns["temperature"].name),
                               f"a median of {median:.4g} C, not plausible for oil ({sv.OIL_RANGE_C[0]:g} to "
                               f"{sv.OIL_RANGE_C[1]:g} C)", "declared"))
    if plan.waveform == "standstill":
        return out
    out += velocity_findings(record)
    if plan.waveform not in ("triangle", "sine"):
        return out
    disp = df["displacement_m"].to_numpy()
    if not any(f.key in ("columns.force", "columns.displacement") for f in out):     # a velocity: no sign to judge
        out += force_findings(record, disp)
    if motion == "command":
        amplitude = ch.robust_range(disp) / 2.0
        if abs(amplitude / plan.amplitude_m - 1.0) > sv.RANGE_TOLERANCE:
            out.append(Finding("columns.displacement", repr(spec.columns["displacement"].name),
                               f"a range of ±{amplitude * 1e3:.4g} mm against the plan's ±{plan.amplitude_m * 1e3:.4g} "
                               "mm", "declared"))
    return out


def standstill_findings(record: Record, motion: str) -> list[Finding]:
    """A standstill case whose motion channel moves (more than :data:`STANDSTILL_RANGE_M` and the noise)."""
    y = record.df[f"{motion}_m"].to_numpy()
    spread = ch.robust_range(y)
    if spread > max(STANDSTILL_RANGE_M, STANDSTILL_SIGMAS * noise_level(y)):
        return [Finding("waveform", "standstill", f"a {motion} that moves {spread * 1e3:.4g} mm")]
    return []


def check_case(record: Record, choices: dict[tuple[str, str, str], ch.UnitChoice],
               sample_rate_tolerance: float = DEFAULTS.sample_rate_tolerance) -> CaseCheck:
    """One case of the manifest against its file: sample rate (validate's ``sample_rate_tolerance``), units,
    columns, waveform and its plan."""
    spec, t = record.spec, record.t_s
    out = CaseCheck(spec.id, str(spec.file))
    rate = sample_rate(t).value
    off = rate_offset(t, spec.plan.sample_rate_Hz)
    if abs(off) > sample_rate_tolerance:
        out.findings.append(Finding("sample_rate_Hz", _g(spec.plan.sample_rate_Hz),
                                    f"{_g(rate)} (time step {_g(1.0 / rate)} s, {off:+.1%} off the plan's: ingest "
                                    f"allows {sample_rate_tolerance:.0%})"))
    out.findings += unit_findings(record, choices)
    out.findings += column_findings(record)
    df = record.df
    motion = "command" if "command_m" in df else "displacement"
    out.findings += physics_findings(record, motion)
    if spec.plan.waveform == "standstill":
        out.findings += standstill_findings(record, motion)
        out.detected = f"standstill, {_g(rate)} Hz" if not out.findings else f"{_g(rate)} Hz"
        return out
    w = detect_waveform(t, df[f"{motion}_m"].to_numpy())
    out.findings += plan_findings(spec, w, motion)
    out.detected = summary(w, rate)
    return out


def check_folder(folder: str | Path, settings: Settings | None = None) -> tuple[list[CaseCheck], list[str]]:
    """Every case of ``folder/campaign.yaml`` checked with ``settings`` (None: the project's,
    :func:`isokinetic.contracts.settings.project_settings`); and the case files the manifest does not name."""
    folder = Path(folder)
    settings = project_settings(folder) if settings is None else settings
    manifest = load_manifest(folder / MANIFEST_NAME)
    cache = FileCache()
    read = [(spec, *read_record(folder, spec, cache, settings.max_case_file_MB)) for spec in manifest.cases]
    choices = unit_choices([record for _, record, _ in read if record is not None])
    checks = [check_case(record, choices, settings.sample_rate_tolerance) if record is not None
              else CaseCheck(spec.id, str(spec.file), findings) for spec, record, findings in read]
    named = {str(spec.file) for spec in manifest.cases}
    return checks, [relative_name(p, folder) for p in case_files(folder) if relative_name(p, folder) not in named]


def print_check(folder: str | Path, out: TextIO | None = None, settings: Settings | None = None) -> int:
    """Print the check of a folder, case by case (to ``out``, default stdout; ``settings`` as
    :func:`check_folder`); 0 when every case agrees with the manifest, 1 otherwise."""
    out = sys.stdout if out is None else out
    checks, unnamed = check_folder(folder, settings)
    for c in checks:
        if c.agrees:
            print(f"{c.case} ({c.file}): agrees: {c.detected}", file=out)
            continue
        print(f"{c.case} ({c.file}): DISAGREES" + (f" (detected: {c.detected})" if c.detected else ""), file=out)
        for f in c.findings:
            planned = f"{f.planned_word} {f.planned}, detected " if f.planned else ""
            print(f"  {f.key}: {planned}{f.detected}", file=out)
    if unnamed:
        print(f"note: case files the manifest does not name: {', '.join(unnamed)}", file=out)
    agree = sum(c.agrees for c in checks)
    print(f"{agree} of {len(checks)} cases agree with {Path(folder) / MANIFEST_NAME}", file=out)
    return 0 if agree == len(checks) else 1

