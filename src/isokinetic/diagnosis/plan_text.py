"""The next-test plan as text (issue 37): the manifest fragment ``results/<campaign>/next_tests.yaml`` and the lines
``python -m isokinetic next-test`` prints, both from diagnosis.json's ``next_tests`` block
(:mod:`isokinetic.diagnosis.next_tests`). Standard library only: the command and the report read a finished
diagnosis without the scientific stack.

The fragment is a list of cases in the manifest format of ``docs/raw-campaign-format.md`` (``id``, ``waveform``,
``period_s`` and ``amplitude_mm`` of a triangle, ``frequency_Hz`` and ``amplitude_mm`` of a sine, ``duration_s`` of a
standstill, ``sample_rate_Hz`` and ``file``), each with a comment saying what it resolves: pasted under the
``cases:`` of the campaign's ``campaign.yaml``, with the records the rig writes beside it, it is read as any case.
A calibration the plan proposes (``calibrations``, contract 1.6) comes before the cases as commented lines: what to
measure, and the declaration to uncomment with the measured value (``docs/raw-campaign-format.md``): of a load cell's,
the force column's ``calibration: {gain, uncertainty_rel}``; of an LVDT's, the displacement column's
``calibration: {scale, uncertainty_rel}``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

#: The triangle's phase of the raw-campaign format's convention (-π/2: start at -Y moving up), written out.
TRIANGLE_PHASE = "-1.5707963"


@dataclass(frozen=True)
class CalibrationText:
    """A calibration ``check``'s text: its name, what it calibrates against what, the column it declares, the
    declared key, what that key is, the comment lines saying what to do."""

    name: str
    what: str
    column: str
    key: str
    means: str
    todo: tuple[str, ...]

    @property
    def title(self) -> str:
        return self.name[:1].upper() + self.name[1:]


CALIBRATIONS = {
    "load_cell_gain": CalibrationText(
        "load-cell calibration", "load cell against a reference force", "force", "gain", "reading per unit true force",
        ("# To do: calibrate the load cell against a reference force: a reference load cell in series, load",
         "# steps each way over the campaign's force range; `gain` is the slope of the rig's force reading",
         "# against the reference force, i.e. the load cell's reading per unit true force (1.01: it reads 1 %",
         "# high), the force column's unit and scale not corrected for it. Declare it beside the force column's")),
    "lvdt_scale": CalibrationText(
        "LVDT calibration", "LVDT against a reference displacement", "displacement", "scale",
        "reading per unit true displacement",
        ("# To do: calibrate the LVDT against a reference displacement: a micrometer calibrator or gauge blocks",
         "# against the actuator's rod, steps each way over the campaign's stroke; `scale` is the slope of the",
         "# LVDT's reading against the reference displacement, i.e. its reading per unit true displacement (1.01:",
         "# it reads 1 % long), the displacement column's unit and scale not corrected for it; declared, the",
         "# diagnosis takes the scale as measured and lists no displacement_scale group. Declare it beside the",
         "# displacement column's")),
}


def _number(x: float) -> str:
    """A number as the fragment writes it: 7 significant digits, no exponent for ordinary values."""
    return f"{float(x):.7g}"


def case_yaml(entry: Mapping) -> list[str]:
    """The manifest lines of one plan entry (a list item, indented as under ``cases:``), its comment first."""
    groups = ", ".join(f"{g} ({entry.get('separation_se_by_group', {}).get(g, 0.0):.1f} SE)"
                       for g in entry.get("resolves") or []) or "adds to the separation below 1 SE"
    lines = [f"  # {entry['case']}: {entry.get('label', entry['waveform'])}; resolves {groups}; "
             f"rig time {entry['rig_time_s']:.0f} s",
             f"  - id: {entry['case']}", f"    waveform: {entry['waveform']}"]
    if entry["waveform"] == "triangle":
        lines += [f"    period_s: {_number(entry['period_s'])}",
                  f"    amplitude_mm: {_number(entry['amplitude_m'] * 1e3)}",
                  f"    phase_rad: {TRIANGLE_PHASE}"]
    elif entry["waveform"] == "sine":
        lines += [f"    frequency_Hz: {_number(entry['frequency_Hz'])}",
                  f"    amplitude_mm: {_number(entry['amplitude_m'] * 1e3)}"]
    if entry.get("duration_s") is not None and entry["waveform"] != "triangle":
        lines.append(f"    duration_s: {_number(entry['duration_s'])}")
    lines += [f"    sample_rate_Hz: {_number(entry['sample_rate_Hz'])}", f"    file: {entry['case']}.csv"]
    return lines


def declaration(entry: Mapping) -> str:
    """The declaration of a proposed calibration in campaign.yaml, on one line (``<measured>`` to fill in)."""
    t = CALIBRATIONS[entry["check"]]
    return f"columns: {t.column}: calibration: {{{t.key}: <measured>, uncertainty_rel: {entry['uncertainty_rel']:g}}}"


def calibration_yaml(entry: Mapping, target_se: float) -> list[str]:
    """A proposed calibration as comment lines: what it resolves, what to measure, and the declaration of its column
    to uncomment (the force column's ``gain``, the displacement column's ``scale``: the measured reading per unit
    true force or displacement); ``target_se`` the plan's target."""
    t = CALIBRATIONS[entry["check"]]
    groups = ", ".join(f"{g} ({entry['separation_se_by_group'].get(g, 0.0):.1f} SE)" for g in entry["resolves"])
    return [f"# {t.title} (next_tests.calibrations): resolves " + groups
            + f"; rig time {entry['rig_time_s']:.0f} s (a group it takes to {target_se:g} SE gets no case below).",
            *t.todo,
            "# name and unit in campaign.yaml (uncomment, <measured> the slope; uncertainty_rel its relative",
            "# standard uncertainty, 1 sigma):",
            "# columns:",
            f"#   {t.column}:",
            f"#     calibration: {{{t.key}: <measured>, uncertainty_rel: {entry['uncertainty_rel']:g}}}"]


def plan_yaml(block: Mapping | None, campaign: str) -> str:
    """``next_tests.yaml``: the plan's calibration as commented lines and its cases as a manifest fragment
    (``cases: []`` with the note where there is none)."""
    block = block or {"needed": False, "note": "no next_tests block in diagnosis.json", "plan": []}
    head = [f"# Next tests of campaign {campaign} (diagnosis.json, next_tests): {block['note']}",
            *[line for entry in block.get("calibrations") or []
              for line in calibration_yaml(entry, block.get("target_se", 0.0))],
            "# Paste the cases below under `cases:` of the campaign's campaign.yaml and run them after its cases, in",
            "# this order (a drift's reading depends on when a case runs); each `file` is the record the rig writes."]
    plan = block.get("plan") or []
    if not plan:
        return "\n".join([*head, "cases: []", ""])
    body = [line for entry in plan for line in case_yaml(entry)]
    total = block.get("total_rig_time_s") or 0.0
    return "\n".join([*head, f"# total rig time {total:.0f} s ({total / 60.0:.1f} min)", "cases:", *body, ""])


def case_text(e: Mapping) -> str:
    """A plan entry in a few words: waveform, speed or frequency, amplitude, period or duration."""
    if e["waveform"] == "triangle":
        return (f"triangle {e['velocity_m_s'] * 1e3:.4g} mm/s, Y {e['amplitude_m'] * 1e3:.4g} mm, "
                f"T {e['period_s']:.4g} s")
    if e["waveform"] == "sine":
        return f"sine {e['frequency_Hz']:.4g} Hz, Y {e['amplitude_m'] * 1e3:.4g} mm"
    return f"standstill {e.get('duration_s') or 0.0:.0f} s"


def calibration_label(e: Mapping) -> str:
    """A calibration entry in a few words."""
    return f"{CALIBRATIONS[e['check']].what}, ±{e['uncertainty_rel'] * 100:.2g} %"


def plan_lines(block: Mapping | None) -> list[str]:
    """What ``next-test`` prints: one line where no plan is needed, else the note, the rivals, one line per case
    and each group's separation."""
    if not block:
        return ["no next_tests block in diagnosis.json (diagnosed before contract 1.5)"]
    if not block.get("needed"):
        return [block["note"]]
    lines = [block["note"]]
    for r in block.get("rivals") or []:
        lines.append(f"  rival {r['group']}: {r['label']}")
    for e in block.get("calibrations") or []:
        lines.append(f"  CAL  {calibration_label(e):<44} {e['rig_time_s']:7.0f} s  {e['separation_se']:6.1f} SE  "
                     f"resolves {', '.join(e['resolves'])}")
        t = CALIBRATIONS[e["check"]]
        lines.append(f"       declare in campaign.yaml: {declaration(e)} ({t.key}: {t.means})")
    for e in block.get("plan") or []:
        lines.append(f"  {e['case']}  {case_text(e):<44} {e['rig_time_s']:7.0f} s  {e['separation_se']:6.1f} SE  "
                     f"resolves {', '.join(e['resolves']) or '-'}")
    if block.get("plan") or block.get("calibrations"):
        lines.append(f"  total rig time {block['total_rig_time_s']:.0f} s; separation "
                     + ", ".join(f"{g} {se:.1f} SE" for g, se in (block.get("separation_se") or {}).items()))
    return lines


def separation_text(se: float | None) -> str:
    """A separation in standard errors for the page (— where unknown)."""
    return "—" if se is None or not math.isfinite(se) else f"{se:.1f} SE"
