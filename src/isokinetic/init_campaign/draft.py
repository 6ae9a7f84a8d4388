"""The draft ``campaign.yaml``: every guessed value with a comment saying how it was found and how sure it is.

Values are written as YAML the manifest parser reads back (:func:`isokinetic.contracts.manifest.load_manifest`);
comments never hold a line break. The damper block cannot be inferred from the records: it is written
commented out with the keys to fill in. A file that is not a usable case is listed commented out with
its reason. The draft goes to ``FOLDER/campaign.yaml`` only: never over an existing one without ``force``,
never through a symlink.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import fields
from pathlib import Path

import numpy as np
import yaml

from isokinetic.contracts.manifest import DEFAULT_TRIANGLE_PHASE_RAD, MANIFEST_NAME, CsvDialect
from isokinetic.contracts.settings import DEFAULTS, Settings
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign.survey import RATE_FLOOR, FileSurvey, StepCase, Survey, column_how, survey_folder
from isokinetic.init_campaign.waveform import Estimate, Waveform, round_to_uncertainty
from isokinetic.physics.damper import Damper

#: Comments start at this column when the value leaves room.
COMMENT_COLUMN = 40
#: What each damper key is (SI), for the commented-out block.
DAMPER_HELP = {
    "piston_area_m2": "effective piston area",
    "chamber_volume_1_m3": "volume of chamber 1",
    "chamber_volume_2_m3": "volume of chamber 2",
    "orifice_area_m2": "orifice (or equivalent bypass) area",
    "orifice_length_m": "orifice length",
    "discharge_coefficient": "orifice discharge coefficient",
    "density_kg_m3": "oil density",
    "viscosity_Pa_s": "dynamic viscosity at the test temperature",
    "oil_compressibility_1_Pa": "oil compressibility",
    "charge_pressure_Pa": "optional: absolute chamber pressure at rest (precharge)",
}
_CONTROL = re.compile(r"[\x00-\x1f\x7f\u2028\u2029\x85]")


def scalar(value) -> str:
    """One YAML scalar, quoted when it must be (a column name with ': ' or '#', a file name with a newline)."""
    if isinstance(value, float):
        text = repr(value)
        return text.replace("e", ".0e", 1) if "e" in text and "." not in text else text
    if isinstance(value, str) and _CONTROL.search(value):
        return json.dumps(value)          # a YAML double-quoted scalar, every control character escaped
    return yaml.safe_dump([value], default_flow_style=True, allow_unicode=True, width=1 << 30).strip()[1:-1]


def comment(text: str) -> str:
    """A one-line comment text: control characters (a newline in a file name) shown escaped."""
    return _CONTROL.sub(lambda m: json.dumps(m.group())[1:-1], text)


def line(indent: int, body: str, note: str = "") -> str:
    """``body`` indented, with ``# note`` aligned at COMMENT_COLUMN."""
    text = " " * indent + body
    if note:
        text = f"{text:<{COMMENT_COLUMN - 1}} # {comment(note)}"
    return text


def column_entry(name: str, unit: str | None, invert: bool = False) -> str:
    return f"{{name: {scalar(name)}, unit: {scalar(unit)}" + (", invert: true}" if invert else "}")


def _pm(estimate: Estimate, scale: float, unit: str) -> str:
    """``value ± se unit``, the value to the standard error's first digit (at most 9 significant digits)."""
    value, se = estimate.value * scale, estimate.se * scale
    if not (math.isfinite(se) and se > 0):
        return f"{value:.9g} {unit}"
    cap = 8 - math.floor(math.log10(abs(value))) if value else 9
    return f"{value:.{max(0, min(1 - math.floor(math.log10(se)), cap))}f} ± {se:.1g} {unit}"


def header_lines(survey: Survey) -> list[str]:
    n, bad = len(survey.case_kinds()), len(survey.files) - len(survey.usable)
    out = [f"# {MANIFEST_NAME} drafted by `python -m isokinetic init-campaign` from {len(survey.files)} files "
           f"in {comment(survey.folder.absolute().name)!s}/ ({n} cases" + (f", {bad} set aside below)" if bad else ")"),
           "# (raw campaign format 1.2). Beside every guessed value: how it was found and how sure it is:",
           "#   sure: names and magnitudes agree, or nothing else fits; likely: check it; guess: check it by hand.",
           "# To do by hand: the description, temperature_C, the damper block, every 'likely' and 'guess'. Then run",
           f"#   python -m isokinetic init-campaign --check {comment(survey.folder.as_posix())}"]
    if survey.campaign_note:
        out.append(f"# WARNING: {comment(survey.campaign_note)}")
    if survey.skipped:
        out.append(f"# Passed over ({len(survey.skipped)}), not case files:")
        out += [f"#   {comment(name)}: {comment(why)}" for name, why in survey.skipped]
    return out


def csv_line(fmt: CsvDialect, how: str) -> str:
    """The ``csv:`` block of a file format other than the default (only the keys that differ from it)."""
    default = CsvDialect()
    keys = {k: v for k, v in fmt.to_dict().items() if v != getattr(default, k) or k == "format" and v != "delimited"}
    if fmt.format == "mts793":
        keys.pop("units_row", None)          # an MTS 793 export always has one
        keys.pop("delimiter", None) if fmt.delimiter == "\t" else None
    said = ", ".join(f"{k}: {json.dumps(v) if isinstance(v, str) else scalar(v)}" for k, v in keys.items())
    return line(0, f"csv: {{{said}}}", f"{how}, {'likely' if fmt.encoding == 'cp1252' else 'sure'}")


def campaign_lines(survey: Survey) -> list[str]:
    temps = [ch.temperature_C(f.data[f.roles["temperature"]].numbers, survey.units[("temperature",
                                                                                f.roles["temperature"])].unit)
             for f in survey.usable if "temperature" in f.roles
             and survey.units[("temperature", f.roles["temperature"])].unit is not None]
    out = [line(0, "format_version: 1"),
           line(0, f"campaign: {scalar(survey.campaign)}",
                "the folder name" if not survey.campaign_note else "NOT the folder name: see the warning above"),
           line(0, f"description: {scalar(f'{len(survey.case_kinds())} cases drafted from the case files')}",
                "replace: what was tested, on which damper"),
           line(0, "source: rig", "rig | simulation (informational)")]
    if temps:
        median = float(np.median([np.nanmedian(t) for t in temps]))
        out.append(line(0, f"# temperature_C: {median:.1f}", "the temperature column's median over the files; the "
                                                               "column itself is read per sample"))
    else:
        out.append(line(0, "# temperature_C: 40.0", "damper temperature, C: not in the files, fill in"))
    if survey.sample_rate_Hz is not None:
        out.append(line(0, f"sample_rate_Hz: {scalar(survey.sample_rate_Hz)}", f"{survey.rate_how}, sure"))
    if survey.dialect != CsvDialect():
        out.append(csv_line(survey.dialect, survey.dialect_how))
    out.append("columns:")
    for channel, choice in survey.columns.items():
        if choice.invert:
            out.append(line(2, f"# {channel} inverted: {choice.invert_why}"))
        out.append(line(2, f"{channel}: {column_entry(choice.name, choice.unit, choice.invert)}",
                        f"{choice.how}, {choice.sure}"))
    extras = sorted({e for f in survey.usable for e in f.extras})
    why = {name: said for f in survey.usable for name, said in f.unused.items()}
    plain = [e for e in extras if e not in why]
    if plain:
        out.append(line(2, f"# not used: {', '.join(repr(e) for e in plain)} (extra columns are ignored by ingest)"))
    out += [line(2, f"# not used: {comment(repr(e))}: {comment(why[e])}") for e in extras if e in why]
    refused = sorted({why for f in survey.usable for why in f.refused.values()})
    out += [line(2, f"# REFUSED: {why}") for why in refused]
    return out


def damper_lines() -> list[str]:
    out = ["# damper:   nominal design data in SI units. It cannot be inferred from the records: fill in all nine",
           "#           keys and uncomment the block (without it there is no nominal model to compare against).",
           "#           charge_pressure_Pa is optional: with it, entrained air follows the gas law."]
    for f in fields(Damper):
        out.append(line(0, f"#   {f.name}:", DAMPER_HELP.get(f.name, "")))
    return out


def triangle_lines(w: Waveform, motion: str) -> list[str]:
    period = w.period_s.rounded
    rounded = "" if period == w.period_s.value else f", rounded to {scalar(period)}"
    out = [line(4, f"period_s: {scalar(period)}", f"mid-stroke crossings every T/2: {_pm(w.period_s, 1.0, 's')}"
                                                  f"{rounded}, {w.period_s.sure}")]
    amp = w.amplitude_m
    amp_mm = Estimate(amp.value * 1e3, amp.se * 1e3).rounded_amplitude
    speed = 4.0 * amp.value / period * 1e3
    sure = "sure" if motion == "command" else "likely"
    out.append(line(4, f"amplitude_mm: {scalar(amp_mm)}",
                    f"speed {speed:.4g} mm/s x T/4 = {_pm(amp, 1e3, 'mm')} from the {motion}, {sure}"))
    snapped = abs(w.phase_rad) == -DEFAULT_TRIANGLE_PHASE_RAD
    said = ("-pi/2, the spec's default" if w.phase_rad == DEFAULT_TRIANGLE_PHASE_RAD else "+pi/2" if snapped
            else "CHECK: the fitted phase")
    out.append(line(4, f"phase_rad: {scalar(w.phase_rad if snapped else round(w.phase_rad, 6))}",
                    f"{said}: {w.phase_note}, {w.phase_sure}"))
    if w.periods < 2.0 * (1 - 1e-6):
        out.append(line(4, f"# the record holds {w.periods:.2f} periods; the pipeline needs 2 (four half-periods)"))
    return out


def plan_lines(w: Waveform, motion: str) -> list[str]:
    """The waveform's plan keys: a triangle's period, amplitude and phase, a sine's frequency and amplitude."""
    if w.kind == "triangle":
        return triangle_lines(w, motion)
    if w.kind != "sine":
        return []
    freq, amp = w.frequency_Hz, w.amplitude_m
    sure = "sure" if motion == "command" else "likely"
    return [line(4, f"frequency_Hz: {scalar(freq.rounded)}", f"{_pm(freq, 1.0, 'Hz')}, {freq.sure}"),
            line(4, f"amplitude_mm: {scalar(Estimate(amp.value * 1e3, amp.se * 1e3).rounded_amplitude)}",
                 f"{_pm(amp, 1e3, 'mm')} from the {motion}" + (f"; {w.phase_note}" if w.phase_note else "")
                 + f", {sure}")]


def step_lines(f: FileSurvey, step: StepCase) -> list[str]:
    """The entry of one step of a stepped record: id, file, its slice, waveform and plan."""
    source = f.roles[f.motion]
    return [line(2, f"- id: {scalar(step.case_id)}", f"{step.how}"),
            line(4, f"file: {scalar(f.file)}"),
            line(4, f"time_range_s: [{scalar(step.start_s)}, {scalar(step.end_s)}]",
                 "the step's slice of the file's own time axis, transitions and settling cycles left out"),
            line(4, f"waveform: {step.waveform.kind}",
                 f"from {source!r} ({f.motion}): {step.waveform.how}, {step.waveform.sure}"),
            *plan_lines(step.waveform, f.motion)]


def case_lines(f: FileSurvey, survey: Survey) -> list[str]:
    """A file's case entries (one, or one per step of a stepped record): id, file, waveform and its keys,
    overrides (sample rate, columns)."""
    own = round_to_uncertainty(f.rate.value, f.rate.se, floor=RATE_FLOOR)
    common = []
    if own != survey.sample_rate_Hz:
        common.append(line(4, f"sample_rate_Hz: {scalar(own)}", f"time step {1.0 / own:.6g} s, sure"))
    common += override_lines(f, survey)
    notes = [line(4, f"# NOTE: {w_}") for w_ in f.warnings]
    if f.steps:
        said = ("a record with ramps, one case: its steady part" if f.steps[0].case_id == f.case_id else
                f"a stepped record, {len(f.steps)} cases")
        out = [line(2, f"# {comment(f.file)}: {said} (the whole record: {f.waveform.kind}; "
                       f"{comment(f.waveform.how)})")]
        for step in f.steps:
            out += step_lines(f, step) + common
        return out + notes
    w = f.waveform
    source = f.roles[f.motion]
    out = [line(2, f"- id: {scalar(f.case_id)}", f.id_note), line(4, f"file: {scalar(f.file)}")]
    out.append(line(4, f"waveform: {w.kind}", f"from {source!r} ({f.motion}): {w.how}, {w.sure}"))
    return out + plan_lines(w, f.motion) + common + notes


def override_lines(f: FileSurvey, survey: Survey) -> list[str]:
    """The case's ``columns:`` where its file differs from the campaign's columns."""
    entries = []
    for channel in dict.fromkeys([*survey.columns, *f.roles]):
        name, choice = f.roles.get(channel), survey.columns.get(channel)
        if name is None:
            if choice is not None and channel not in ("time", "displacement", "force"):
                entries.append(line(6, f"{channel}: null", f"this file has no {channel} column, sure"))
            continue
        unit = survey.units[(channel, name)]
        invert = channel == "force" and bool(f.invert)
        if choice is None or (name, unit.unit, invert) != (choice.name, choice.unit, choice.invert):
            how, sure = f.role_how[channel]
            sure = max(sure, unit.sure, key=["sure", "likely", "guess"].index)
            if invert:
                entries.append(line(6, f"# {channel} inverted: {f.invert}"))
            entries.append(line(6, f"{channel}: {column_entry(name, unit.unit, invert)}",
                                f"{column_how(how, unit)}, {sure}"))
    return [line(4, "columns:")] + entries if entries else []


def set_aside_lines(f: FileSurvey) -> list[str]:
    return [line(2, f"# - id: {scalar(f.case_id)}", f"NOT A CASE: {f.problem}"), line(2, f"#   file: {scalar(f.file)}")]


def draft_text(survey: Survey) -> str:
    """The draft manifest's text."""
    out = header_lines(survey) + campaign_lines(survey) + damper_lines() + ["cases:"]
    for f in survey.files:
        out += case_lines(f, survey) if f.ok else set_aside_lines(f)
    return "\n".join(out) + "\n"


def write_draft(folder: str | Path, force: bool = False, settings: Settings = DEFAULTS) -> tuple[Path, Survey]:
    """Survey ``folder`` and write its draft ``campaign.yaml`` (an existing one only with ``force``; ``settings``:
    the project's, :func:`isokinetic.contracts.settings.project_settings`)."""
    folder = Path(folder)
    path = folder / MANIFEST_NAME
    if path.is_symlink():
        raise FileExistsError(f"{path} is a symlink: not written through (remove it first)")
    if path.exists() and not force:
        raise FileExistsError(f"{path} exists: not overwritten (--force replaces it)")
    survey = survey_folder(folder, settings)
    if not survey.usable:
        reasons = "; ".join(f"{f.file}: {f.problem}" for f in survey.files)
        raise ValueError(f"{folder}: no usable case file, nothing drafted ({comment(reasons)})")
    text = draft_text(survey)
    with open(path, "w" if force else "x", encoding="utf-8", newline="\n") as fh:
        fh.write(text)
    return path, survey
