"""The next-test plan as text (issue 37): the manifest fragment ``results/<campaign>/next_tests.yaml`` and the lines
``python -m isokinetic next-test`` prints, both from diagnosis.json's ``next_tests`` block
(:mod:`isokinetic.diagnosis.next_tests`). Standard library only: the command and the report read a finished
diagnosis without the scientific stack.

The fragment is a list of cases in the manifest format of ``docs/raw-campaign-format.md`` (``id``, ``waveform``,
``period_s`` and ``amplitude_mm`` of a triangle, ``frequency_Hz`` and ``amplitude_mm`` of a sine, ``duration_s`` of a
standstill, ``sample_rate_Hz`` and ``file``), each with a comment saying what it resolves: pasted under the
``cases:`` of the campaign's ``campaign.yaml``, with the records the rig writes beside it, it is read as any case.
A load-cell calibration the plan proposes (``calibrations``, contract 1.6) comes before the cases as commented lines:
what to measure, and the declaration of the force column (``columns: force: calibration: {gain, uncertainty_rel}``,
``docs/raw-campaign-format.md``) to uncomment with the measured gain.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

#: The triangle's phase of the raw-campaign format's convention (-π/2: start at -Y moving up), written out.
TRIANGLE_PHASE = "-1.5707963"


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


def calibration_yaml(entry: Mapping, target_se: float) -> list[str]:
    """A proposed calibration as comment lines: what it resolves, what to measure, and the declaration of the force
    column to uncomment (``gain`` the measured reading per unit true force); ``target_se`` the plan's target."""
    groups = ", ".join(f"{g} ({entry['separation_se_by_group'].get(g, 0.0):.1f} SE)" for g in entry["resolves"])
    return ["# Load-cell calibration (next_tests.calibrations): resolves " + groups
            + f"; rig time {entry['rig_time_s']:.0f} s (a group it takes to {target_se:g} SE gets no case below).",
            "# To do: calibrate the load cell against a reference force: a reference load cell in series, load",
            "# steps each way over the campaign's force range; `gain` is the slope of the rig's force reading",
            "# against the reference force, i.e. the load cell's reading per unit true force (1.01: it reads 1 %",
            "# high), the force column's unit and scale not corrected for it. Declare it beside the force column's",
            "# name and unit in campaign.yaml (uncomment, <measured> the slope; uncertainty_rel its relative",
            "# standard uncertainty, 1 sigma):",
            "# columns:",
            "#   force:",
            f"#     calibration: {{gain: <measured>, uncertainty_rel: {entry['uncertainty_rel']:g}}}"]


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
    return f"load cell against a reference force, ±{e['uncertainty_rel'] * 100:.2g} %"


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
        lines.append(f"       declare in campaign.yaml: columns: force: calibration: {{gain: <measured>, "
                     f"uncertainty_rel: {e['uncertainty_rel']:g}}} (gain: reading per unit true force)")
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
