"""``init-campaign --check FOLDER``: a folder's case files against its existing manifest, case by case.

Each case's file is read as ingest reads it (the manifest's dialect, columns, units, ``invert``), then the
same detection as the draft (:mod:`.waveform`, :mod:`.channels`) is compared with the plan: waveform,
period or frequency, amplitude, a triangle's phase, the sample rate, and each column's unit against its
magnitudes (a column declared mm whose values look like m). Only clear disagreements count: a unit only
when the magnitudes make every other unit implausible or far less plausible (``sure``), a period or
frequency beyond :data:`PERIOD_TOLERANCE` and four standard errors, an amplitude beyond
:data:`AMPLITUDE_TOLERANCE`, a sample rate beyond :data:`RATE_TOLERANCE`. Exit status 0 when every case
agrees, 1 otherwise.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from isokinetic.contracts.manifest import MANIFEST_NAME, CaseSpec, load_manifest
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign.sniff import parse_column
from isokinetic.init_campaign.survey import case_files, sample_rate
from isokinetic.init_campaign.waveform import SNAP_FRACTION, Waveform, detect_waveform
from isokinetic.stages.ingest import CaseFileError, canonical_timeseries, read_case_csv

#: A detected period or frequency further than this fraction (and four standard errors) from the plan disagrees:
#: windows are cut from the planned period, and 1e-4 of it is under a sample interval at the end of a record.
PERIOD_TOLERANCE = 1e-4
#: A detected amplitude further than this fraction from the plan disagrees (validation allows 5 % of speed).
AMPLITUDE_TOLERANCE = 0.01
#: A detected sample rate further than this fraction from the plan disagrees (validation allows 5 %).
RATE_TOLERANCE = 0.005


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
    """One case's file as read under the manifest: its raw columns and its time in seconds."""

    spec: CaseSpec
    raw: object                  # the CSV table of strings
    t_s: np.ndarray


def unit_choices(records: list[Record]) -> dict[tuple[str, str, str], ch.UnitChoice]:
    """The most plausible unit of every (channel, column name, declared unit), from the magnitudes of every file
    that has it (a campaign's files share their units: one file's magnitudes may fit two units, all of them
    rarely do)."""
    scores: dict[tuple[str, str, str], list[dict[str, float]]] = {}
    for r in records:
        for channel, column in r.spec.columns.items():
            if channel not in ch.DIMENSION or column.unit == "datetime":
                continue
            data = parse_column(column.name, r.raw[column.name], r.spec.csv.decimal if r.spec.csv else ".")
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
        if choice is not None and choice.unit not in (None, column.unit) and choice.sure == "sure":
            data = parse_column(column.name, record.raw[column.name], record.spec.csv.decimal
                                if record.spec.csv else ".")
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
                               f"({amp.value / plan.amplitude_m - 1.0:+.1%})"))
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


def read_record(folder: Path, spec: CaseSpec) -> tuple[Record | None, list[Finding]]:
    """A case's file read as ingest reads it, or what keeps it from being read."""
    if spec.problems:
        return None, [Finding(p.column, "", f"manifest: {p.message}") for p in spec.problems]
    path = folder / spec.file
    if not path.is_file():
        return None, [Finding("file", spec.file, "file not found")]
    try:
        raw = read_case_csv(path, [], spec.csv)
    except CaseFileError as exc:
        return None, [Finding("file", spec.file, f"ingest refuses it: {exc.problem.message}")]
    df, problems = canonical_timeseries(raw, spec.columns, spec.csv.decimal if spec.csv else ".")
    if problems:
        return None, [Finding(f"column {p.column!r}", "", f"ingest: {p.message}") for p in problems]
    t = df["time_s"].to_numpy()
    if t.size < 2 or not np.all(np.diff(t) > 0):
        return None, [Finding("columns.time", spec.columns["time"].name, "time does not increase")]
    return Record(spec, raw, t), []


def check_case(record: Record, choices: dict[tuple[str, str, str], ch.UnitChoice]) -> CaseCheck:
    """One case of the manifest against its file: sample rate, units, waveform and its plan."""
    spec, t = record.spec, record.t_s
    out = CaseCheck(spec.id, str(spec.file))
    rate = sample_rate(t).value
    if abs(rate / spec.plan.sample_rate_Hz - 1.0) > RATE_TOLERANCE:
        out.findings.append(Finding("sample_rate_Hz", _g(spec.plan.sample_rate_Hz),
                                    f"{_g(rate)} (median time step {_g(1.0 / rate)} s)"))
    out.findings += unit_findings(record, choices)
    df, _ = canonical_timeseries(record.raw, spec.columns, spec.csv.decimal if spec.csv else ".")
    motion = "command" if "command_m" in df else "displacement"
    w = detect_waveform(t, df[f"{motion}_m"].to_numpy())
    out.findings += plan_findings(spec, w, motion)
    out.detected = summary(w, rate)
    return out


def check_folder(folder: str | Path) -> tuple[list[CaseCheck], list[str]]:
    """Every case of ``folder/campaign.yaml`` checked; and the case files the manifest does not name."""
    folder = Path(folder)
    manifest = load_manifest(folder / MANIFEST_NAME)
    read = [(spec, *read_record(folder, spec)) for spec in manifest.cases]
    choices = unit_choices([record for _, record, _ in read if record is not None])
    checks = [check_case(record, choices) if record is not None
              else CaseCheck(spec.id, str(spec.file), findings) for spec, record, findings in read]
    named = {spec.file for spec in manifest.cases}
    return checks, [p.name for p in case_files(folder) if p.name not in named]


def print_check(folder: str | Path, out: TextIO | None = None) -> int:
    """Print the check of a folder, case by case (to ``out``, default stdout); 0 when every case agrees with the
    manifest, 1 otherwise."""
    out = sys.stdout if out is None else out
    checks, unnamed = check_folder(folder)
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

