"""Proof of the diagnosis' next tests on the independent reference rig (issue 37, part 3).

A blind scenario (its raw campaign, written by :func:`isokinetic.reference.campaign.write_campaign`, and its truth
record, :meth:`isokinetic.blind.generate.Scenario.truth_record`) whose verdict lists a ``confounded`` group gets
a plan of extra cases (``next_tests.plan`` of diagnosis.json, or any list of entries in that shape). The plan is
run on the same rig as the campaign:

Same rig, same nuisances
    The truth record's damper, true effects (:class:`~isokinetic.reference.rig.TrueEffects`), rig and sensor chain
    (:class:`~isokinetic.reference.rig.RigImperfections`), the servo's distortion of a sine and the noise seed.
    The plan's cases are appended after the campaign's, as the rig would run them next: case i (0-based, counted
    on from the campaign's last) draws its noise from stream ``[seed, i]`` (fresh, deterministic), its slow
    viscosity drift continues by case index, its load-cell zero drift by campaign time (the cases back to back),
    and its samples drop out by stream ``[seed, i, 11]``, exactly as :func:`write_campaign` treats case i. A
    standstill (:class:`Standstill`, its record the entry's ``duration_s``) holds the actuator at mid-stroke and
    records through the same measurement chain (:func:`isokinetic.reference.campaign.measure`). A campaign
    without a command channel gets none in its new cases either.

A calibration
    A plan's ``calibrations`` entry is run as the calibration reads the scenario's rig: the load cell against a
    reference force, its true gain times (1 + u ε), u the entry's relative standard uncertainty and ε standard
    normal from the stream ``[seed, CALIBRATION_STREAM]``; the LVDT against a reference displacement, its true
    scale times (1 + u ε), ε from ``[seed, CALIBRATION_STREAM, 1]`` (:func:`calibrated_value`). The copy's
    campaign.yaml then declares it (``columns.force.calibration: {gain, uncertainty_rel}``,
    ``columns.displacement.calibration: {scale, uncertainty_rel}``, the format's 1.6 additions), as the engineer
    would after calibrating. Its rig time counts in the plan's.

A copy, never the original
    The raw folder is copied (:func:`extend_campaign`) and only the copy gets the new case files and manifest
    entries (and a calibration's declaration); the copy is diagnosed through the build's chain (a ``diagnose``
    callable: the layer that runs stages passes :func:`isokinetic.stages.blind_diagnose.diagnose_raw_campaign`).

The judge (:func:`judge`)
    The confounding *resolves to the truth* when no group of the first verdict's ``confounded`` remains and none
    appears, and the new verdict is the truth as target (e) of the blind score judges it: the verdict's effects
    equal the truth's (an out-of-catalogue truth: ``explained: false``), their sizes within 15 % or 3 reported
    standard errors, the delay within 2 ms, the load-cell offset within 2 N (at the extended campaign's middle),
    a force-channel lag within 5 ms (a lag of zero where the truth has none), the LVDT scale within 0.3 %, the
    load-cell gain within 0.3 % (the LVDT's tolerance; the diagnosis reports no standard error of the gain) and
    the zero drift as reported (none where the diagnosis reports none: the drift test's estimate of a drift it
    dropped is not a claim) within what moves the zero by 2 N at the extended campaign's ends (the offset's
    tolerance).

The uniform plan (:func:`uniform_plan`)
    The baseline a proposed plan must beat: as many cases and the same rig time, spread over the campaign's own
    range (a plan's calibration is no case: its rig time goes to the uniform cases' records, at least one case).
    Triangle campaigns: speeds log-spaced over the campaign's speeds, amplitudes following the campaign's (log-log
    interpolated over speed), all periods scaled by one factor so that the rig time is the plan's.
    Sine campaigns: frequencies log-spaced over the campaign's, amplitudes following the campaign's (over
    frequency), each case a equal share of the rig time in whole cycles (at least :data:`MIN_SINE_CYCLES`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from isokinetic.blind.score import (
    TARGET_DELAY_ERROR_S,
    TARGET_LAG_ERROR_S,
    TARGET_OFFSET_ERROR_N,
    TARGET_PARAM_ERROR,
    TARGET_PARAM_Z,
    TARGET_SCALE_ERROR,
    score_row,
)
from isokinetic.diagnosis.next_tests import TARGET_SE
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

#: The load-cell gain's tolerance in the judge (target (e)'s tolerance of the LVDT's gain).
TARGET_GAIN_ERROR = TARGET_SCALE_ERROR
#: Fewest cycles of a uniform plan's sine case (the diagnosis skips the first and needs steady ones after it).
MIN_SINE_CYCLES = 4
#: Relative mismatch allowed between a triangle entry's amplitude and W T / 4 (the manifest rounds to 4 digits).
AMPLITUDE_RTOL = 1e-3
#: The integrator's tolerance of an appended case (write_campaign's default: the campaign's own).
EXPORT_RTOL = 1e-10

#: The spawn key's last entry of a calibration's error draw (``[seed, CALIBRATION_STREAM]``: apart from every case's).
CALIBRATION_STREAM = 0xCA1

#: A plan's or the original verdict's confounded group, as a set.
Group = frozenset


# --------------------------------------------------------------------------------------------
# The scenario's rig
# --------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class ScenarioRig:
    """Everything the reference rig needs to run more cases of one blind scenario, from its truth record."""

    damper: rr.DamperDesign
    effects: rr.TrueEffects
    rig: rr.RigImperfections
    harmonics: tuple[tuple[int, float, float], ...]
    seed: int

    @classmethod
    def from_truth(cls, truth: Mapping) -> ScenarioRig:
        rig = dict(truth["rig"])
        harmonics = tuple((int(k), float(h), float(p)) for k, h, p in rig.pop("sine_harmonics", ()))
        return cls(rr.DamperDesign.from_mapping(truth["damper"]), rr.TrueEffects(**truth["effects"]),
                   rr.RigImperfections(**rig), harmonics, int(truth["noise_seed"]))


def read_manifest(raw_dir: str | os.PathLike) -> dict:
    """campaign.yaml of a raw campaign folder."""
    with open(Path(raw_dir) / "campaign.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


def write_manifest(raw_dir: str | os.PathLike, manifest: Mapping) -> None:
    """campaign.yaml as :func:`isokinetic.reference.campaign.write_campaign` writes it."""
    with open(Path(raw_dir) / "campaign.yaml", "w", encoding="utf-8", newline="\n") as fh:
        yaml.safe_dump(dict(manifest), fh, sort_keys=False, default_flow_style=False, allow_unicode=True, width=100)


def case_spans_s(raw_dir: str | os.PathLike, manifest: Mapping) -> list[float]:
    """Each case's share of campaign time as the rig counts it (its record plus one sample interval), from the
    record's first and last time stamps (the rig never drops those)."""
    column = manifest["columns"]["time"]
    scale = {"ms": 1e-3, "s": 1.0}[column["unit"]]
    spans = []
    for entry in manifest["cases"]:
        t = pd.read_csv(Path(raw_dir) / entry["file"], usecols=[column["name"]])[column["name"]].to_numpy()
        rate = float(entry.get("sample_rate_Hz", manifest["sample_rate_Hz"]))
        spans.append(float(t[-1] - t[0]) * scale + 1.0 / rate)
    return spans


@dataclasses.dataclass(frozen=True)
class Standstill:
    """A stretch with no motion: the actuator held at mid-stroke (the damper at rest, so its true force is zero:
    no flow, no friction, a gas spring at its zero) while the rig's measurement chain records."""

    case_id: str
    duration_s: float
    sample_rate_Hz: float

    def sample_times_s(self) -> np.ndarray:
        """t = k / fs, k = 0 .. round(duration fs)."""
        return np.arange(int(round(self.duration_s * self.sample_rate_Hz)) + 1, dtype=float) / self.sample_rate_Hz

    def true_series(self) -> pd.DataFrame:
        """The true channels the rig's measurement reads (:func:`isokinetic.reference.campaign.measure`)."""
        t = self.sample_times_s()
        return pd.DataFrame({"time_s": t, "force_N": np.zeros_like(t), "actuator_m": np.zeros_like(t),
                             "command_m": np.zeros_like(t)})


Case = rr.TriangleCase | rr.SineCase | Standstill


def rig_case(entry: Mapping, harmonics: tuple = ()) -> Case:
    """The reference rig's case of one plan entry (the ``next_tests.plan`` shape; a standstill's record from its
    ``duration_s``). ValueError where the rig cannot run it as planned: a triangle of other than two periods (it
    records 2T) or whose amplitude is not W T / 4, an unknown waveform."""
    case, waveform = str(entry["case"]), entry["waveform"]
    rate = float(entry["sample_rate_Hz"])
    if waveform == "standstill":
        return Standstill(case, float(entry["duration_s"]), rate)
    if waveform == "triangle":
        v, period = float(entry["velocity_m_s"]), float(entry["period_s"])
        if int(entry.get("periods", 2)) != 2:
            raise ValueError(f"plan case {case}: the reference rig records two periods of a triangle, "
                             f"not {entry['periods']}")
        if abs(float(entry["amplitude_m"]) - v * period / 4.0) > AMPLITUDE_RTOL * v * period / 4.0:
            raise ValueError(f"plan case {case}: amplitude {entry['amplitude_m']} m is not W T / 4 = "
                             f"{v * period / 4.0:.6g} m")
        return rr.TriangleCase(case, v, period, rate)
    if waveform == "sine":
        return rr.SineCase(case, float(entry["frequency_Hz"]), float(entry["amplitude_m"]), float(entry["periods"]),
                           rate, tuple(harmonics))
    raise ValueError(f"plan case {case}: the reference rig cannot run a {waveform!r} case")


def rig_time_s(case: Case) -> float:
    """A case's rig time: its record."""
    return float(case.duration_s)


# --------------------------------------------------------------------------------------------
# The campaign's copy, extended
# --------------------------------------------------------------------------------------------

def drop_csv_column(text: str, name: str) -> str:
    """CSV text without its column ``name``."""
    lines = text.split("\n")
    k = lines[0].split(",").index(name)
    return "\n".join(",".join(f for j, f in enumerate(line.split(",")) if j != k) if line else line
                     for line in lines)


def manifest_entries(cases: Sequence[Case], manifest: Mapping) -> list[dict]:
    """The manifest entries of appended cases, written as the rig writes its campaign's (phase where the campaign
    writes one, a sample rate where it differs from the campaign's; a standstill's id, waveform and file)."""
    phase = any("phase_rad" in e for e in manifest["cases"])
    moving = [c for c in cases if not isinstance(c, Standstill)]
    written = iter(rrc.campaign_manifest(manifest["campaign"], moving, rr.TABLE1, write_phase=phase)["cases"]
                   if moving else [])
    entries = [{"id": c.case_id, "waveform": "standstill", "file": f"{c.case_id}.csv"} if isinstance(c, Standstill)
               else next(written) for c in cases]
    for entry, case in zip(entries, cases, strict=True):
        file = entry.pop("file")
        entry.pop("sample_rate_Hz", None)
        if case.sample_rate_Hz != float(manifest["sample_rate_Hz"]):
            entry["sample_rate_Hz"] = float(case.sample_rate_Hz)
        entry["file"] = file
    return entries


def case_file_text(srig: ScenarioRig, case, index: int, n_cases: int, start_s: float, span_s: float,
                   temperature_C: float, command: bool) -> str:
    """CSV text of case ``index`` of the campaign, simulated as :func:`write_campaign` simulates its case
    ``index`` of ``n_cases`` (the viscosity drift's count) starting at campaign time ``start_s``, the wear and
    warm-up at its middle's fraction of the original campaign's span ``span_s`` (beyond 1: after it)."""
    if isinstance(case, Standstill):
        measured = rrc.measure(case.true_series(), case, srig.rig, srig.seed, index, start_s)
    else:
        warm, area = rr.campaign_drift(srig.effects, (start_s + 0.5 * case.duration_s) / span_s, temperature_C)
        measured = rrc.simulate_case(case, srig.damper, srig.effects, srig.rig, srig.seed, index, n_cases,
                                     EXPORT_RTOL, warm, start_s, area)
    series = rrc.dropped(measured, srig.rig, srig.seed, index)
    text = rrc.case_csv(series, case, srig.rig)
    return text if command else drop_csv_column(text, rrc.EXPORT_COLUMNS["command"][0])


#: Per calibration check: (the channel of campaign.yaml it declares, the declaration's key of the value, the rig's
#: true value's field of RigImperfections, the spawn key's tail of its error draw).
CALIBRATED = {"load_cell_gain": ("force", "gain", "force_gain", ()),
              "lvdt_scale": ("displacement", "scale", "displacement_gain", (1,))}


def calibrated_value(srig: ScenarioRig, check: str, uncertainty_rel: float) -> float:
    """The value a calibration ``check`` of relative standard uncertainty ``uncertainty_rel`` reads on the scenario's
    rig: the true load-cell gain or LVDT scale times (1 + u ε), ε standard normal from its stream
    ``[seed, CALIBRATION_STREAM, *tail]`` (:data:`CALIBRATED`)."""
    _channel, _key, field, tail = CALIBRATED[check]
    rng = np.random.default_rng(np.random.SeedSequence([srig.seed, CALIBRATION_STREAM, *tail]))
    return float(getattr(srig.rig, field)) * (1.0 + uncertainty_rel * float(rng.standard_normal()))


def calibration_declarations(srig: ScenarioRig, calibrations: Sequence[Mapping]) -> dict[str, dict]:
    """{channel: campaign.yaml's ``columns.<channel>.calibration``} after a plan's calibrations (of each check the
    tightest uncertainty; :func:`calibrated_value`)."""
    out = {}
    for check, (channel, key, _field, _tail) in CALIBRATED.items():
        u = [float(c["uncertainty_rel"]) for c in calibrations if c.get("check") == check]
        if u:
            out[channel] = {key: round(calibrated_value(srig, check, min(u)), 7), "uncertainty_rel": min(u)}
    return out


def extend_campaign(raw_dir: str | os.PathLike, truth: Mapping, plan: Sequence[Mapping],
                    out_root: str | os.PathLike, calibrations: Sequence[Mapping] = ()) -> Path:
    """A copy of the raw campaign ``raw_dir`` as ``out_root/<campaign>/`` (replaced if it exists) with the plan's
    cases simulated on the scenario's own rig (module doc) and appended: their case files and manifest entries;
    with ``calibrations`` (a plan's), the calibrations read on the rig declared in its manifest
    (:func:`calibration_declarations`). Nothing under ``raw_dir`` is written. Returns the copy's folder."""
    raw_dir = Path(raw_dir)
    out = Path(out_root) / raw_dir.name
    if out.resolve() == raw_dir.resolve():
        raise ValueError(f"{raw_dir}: the extended copy must not be the original folder")
    manifest = read_manifest(raw_dir)
    if set(manifest["columns"]) - {"time", "displacement", "force", "command"}:
        raise ValueError(f"{raw_dir}: channels {sorted(manifest['columns'])}: the proof runs campaigns of the "
                         f"blind export's channels only")
    srig = ScenarioRig.from_truth(truth)
    cases = [rig_case(e, srig.harmonics) for e in plan]
    taken = {e["id"] for e in manifest["cases"]}
    if clash := sorted(taken & {c.case_id for c in cases}):
        raise ValueError(f"{raw_dir}: plan cases {clash} already in the campaign")
    spans = case_spans_s(raw_dir, manifest)
    n, start, span = len(spans), float(sum(spans)), float(sum(spans))
    if out.exists():
        shutil.rmtree(out)
    shutil.copytree(raw_dir, out)
    command = "command" in manifest["columns"]
    for j, case in enumerate(cases):
        text = case_file_text(srig, case, n + j, n, start, span, float(manifest["temperature_C"]), command)
        (out / f"{case.case_id}.csv").write_text(text, encoding="utf-8", newline="\n")
        start += case.duration_s + 1.0 / case.sample_rate_Hz
    columns = dict(manifest["columns"])
    for channel, declared in calibration_declarations(srig, calibrations).items():
        columns[channel] = {**columns[channel], "calibration": declared}
    write_manifest(out, {**manifest, "columns": columns,
                         "cases": [*manifest["cases"], *manifest_entries(cases, manifest)]})
    return out


# --------------------------------------------------------------------------------------------
# The judge
# --------------------------------------------------------------------------------------------

def groups_of(diagnosis: Mapping | None) -> list[Group]:
    """The ``confounded`` groups of a diagnosis, as sets (none for a failed one)."""
    if diagnosis is None:
        return []
    return [Group(g) for g in diagnosis.get("confounded") or [] if isinstance(g, (list, tuple))]


def group_text(group: Sequence[str]) -> str:
    """A group as diagnosis.json lists it, joined by '+'."""
    return "+".join(group)


def extended_truth(truth: Mapping, campaign_span_s: float) -> dict:
    """The truth record with its load-cell offset at the middle of a campaign of ``campaign_span_s`` (the
    diagnosis reports the offset at its campaign's middle, and a zero drift moves it)."""
    inst = dict(truth.get("instrument") or {})
    if "force_offset_at_start_N" in inst:
        inst["force_offset_N"] = inst["force_offset_at_start_N"] + inst.get("force_drift_N_s", 0.0) * 0.5 * \
            campaign_span_s
    return {**truth, "instrument": inst}


def verdict_misses(truth: Mapping, diagnosis: Mapping | None, campaign_span_s: float) -> list[str]:
    """What keeps a diagnosis from being the truth as target (e) judges it (module doc); [] where it is."""
    if diagnosis is None or diagnosis.get("status") not in ("ok", None):
        return ["diagnosis failed"]
    expected = truth.get("expected") or {}
    verdict, explained = set(diagnosis.get("verdict") or []), bool(diagnosis.get("explained", True))
    if expected.get("explained") is False:
        return [] if not explained else [f"explained: true ({'+'.join(sorted(verdict)) or 'none'})"]
    want = set(expected.get("verdict") or truth.get("truth") or [])
    if verdict != want:
        return [f"verdict {'+'.join(sorted(verdict)) or 'none'} (truth {'+'.join(sorted(want)) or 'none'})"]
    t = extended_truth(truth, campaign_span_s)
    row = score_row({**t, "out_of_catalogue": ""}, diagnosis)
    misses = []
    if want and not (row["param_error_max"] <= TARGET_PARAM_ERROR or row["param_z_max"] <= TARGET_PARAM_Z):
        misses.append(f"sizes {100 * row['param_error_max']:.1f} % off ({row['param_z_max']:.2g} SE)")
    drift_tolerance = TARGET_OFFSET_ERROR_N / (0.5 * campaign_span_s)
    reported = (diagnosis.get("instrument") or {}).get("force_drift_N_s")
    row["drift_error_N_s"] = abs((reported or 0.0) - float(t["instrument"].get("force_drift_N_s", 0.0)))
    for key, tolerance, unit, scale in (("delay_error_s", TARGET_DELAY_ERROR_S, "ms", 1e3),
                                        ("offset_error_N", TARGET_OFFSET_ERROR_N, "N", 1.0),
                                        ("lag_error_s", TARGET_LAG_ERROR_S, "ms", 1e3),
                                        ("scale_error", TARGET_SCALE_ERROR, "%", 1e2),
                                        ("gain_error", TARGET_GAIN_ERROR, "%", 1e2),
                                        ("drift_error_N_s", drift_tolerance, "mN/s", 1e3)):
        value = row[key]
        if not math.isnan(value) and not value <= tolerance:
            misses.append(f"{key.split('_error')[0]} {scale * value:.3g} {unit}")
    return misses


def judge(truth: Mapping, before: Mapping | None, after: Mapping | None, campaign_span_s: float) -> dict:
    """Whether the extra cases resolved ``before``'s confounding to the truth (module doc): ``remaining`` groups
    of ``before`` still in ``after``, ``new`` groups of ``after``, ``misses`` of its verdict against the truth
    (:func:`verdict_misses`; ``campaign_span_s``: the extended campaign's time), and ``resolved``."""
    first, then = groups_of(before), groups_of(after)
    remaining = [g for g in first if g in then]
    new = [g for g in then if g not in first]
    misses = verdict_misses(truth, after, campaign_span_s)
    listed = (after or {}).get("confounded") or []
    order = {Group(g): group_text(g) for g in listed if isinstance(g, (list, tuple))}
    return {"verdict": "+".join((after or {}).get("verdict") or []) if after else "error",
            "explained": bool((after or {}).get("explained", False)),
            "remaining": [order[g] for g in remaining], "new": [order[g] for g in new], "misses": misses,
            "resolved": bool(after is not None and not remaining and not new and not misses)}


# --------------------------------------------------------------------------------------------
# The uniform plan
# --------------------------------------------------------------------------------------------

def _sig(x: float, digits: int = 3) -> float:
    return float(f"{x:.{digits}g}")


def _log_interp(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    order = np.argsort(xp)
    return np.exp(np.interp(np.log(x), np.log(xp[order]), np.log(fp[order])))


def plan_entry(case: rr.TriangleCase | rr.SineCase) -> dict:
    """A plan entry (the ``next_tests.plan`` shape, nothing resolved, with its record's ``duration_s``) of a rig
    case."""
    sine = isinstance(case, rr.SineCase)
    return {"duration_s": rig_time_s(case), "case": case.case_id, "waveform": "sine" if sine else "triangle",
            "velocity_m_s": None if sine else case.velocity_m_s, "amplitude_m": case.amplitude_m,
            "period_s": None if sine else case.period_s, "frequency_Hz": case.frequency_Hz if sine else None,
            "periods": int(round(case.n_cycles)) if sine else 2, "sample_rate_Hz": case.sample_rate_Hz,
            "rig_time_s": rig_time_s(case), "resolves": [], "separation_se": None}


def uniform_triangles(manifest: Mapping, n: int, total_s: float) -> list[dict]:
    """``n`` triangle cases U01.. at speeds log-spaced over the campaign's triangles' (3 digits), amplitudes
    following the campaign's, the periods scaled by one factor to ``total_s`` of records."""
    tri = [e for e in manifest["cases"] if e.get("waveform", "triangle") == "triangle"]
    amp = np.array([float(e["amplitude_mm"]) * 1e-3 for e in tri])
    speed = 4.0 * amp / np.array([float(e["period_s"]) for e in tri])
    v = np.array([_sig(x) for x in np.geomspace(speed.min(), speed.max(), n)]) if n > 1 else \
        np.array([_sig(math.sqrt(speed.min() * speed.max()))])
    period = 4.0 * _log_interp(v, speed, amp) / v
    period = period * total_s / float(np.sum(2.0 * period))
    rate = float(tri[0].get("sample_rate_Hz", manifest["sample_rate_Hz"]))
    return [plan_entry(rr.TriangleCase(f"U{i:02d}", float(w), _sig(float(t), 4), rate))
            for i, (w, t) in enumerate(zip(v, period, strict=True), start=1)]


def uniform_sines(manifest: Mapping, n: int, total_s: float, harmonics: tuple = ()) -> list[dict]:
    """``n`` sine cases U01.. at frequencies log-spaced over the campaign's (3 digits), amplitudes following the
    campaign's, each an equal share of ``total_s`` in whole cycles (at least MIN_SINE_CYCLES)."""
    freq = np.array([float(e["frequency_Hz"]) for e in manifest["cases"]])
    amp = np.array([float(e["amplitude_mm"]) * 1e-3 for e in manifest["cases"]])
    f = np.array([_sig(x) for x in np.geomspace(freq.min(), freq.max(), n)]) if n > 1 else \
        np.array([_sig(math.sqrt(freq.min() * freq.max()))])
    rate = float(manifest["cases"][0].get("sample_rate_Hz", manifest["sample_rate_Hz"]))
    return [plan_entry(rr.SineCase(f"U{i:02d}", float(fi), _sig(float(y), 4),
                                   float(max(MIN_SINE_CYCLES, round(fi * total_s / n))), rate, tuple(harmonics)))
            for i, (fi, y) in enumerate(zip(f, _log_interp(f, freq, amp), strict=True), start=1)]


def uniform_plan(manifest: Mapping, plan: Sequence[Mapping], harmonics: tuple = (), extra_s: float = 0.0
                 ) -> list[dict]:
    """The uniform plan beside ``plan`` (module doc): as many cases, the same rig time (its records, as
    :func:`rig_time_s` counts them, plus ``extra_s``: a calibration's rig time, in at least one case), spread over
    the campaign's range (sines for a sine-only campaign)."""
    total = float(sum(rig_time_s(rig_case(e, harmonics)) for e in plan)) + extra_s
    n = max(len(plan), 1) if extra_s > 0 else len(plan)
    if not n:
        return []
    sine_only = all(e.get("waveform") == "sine" for e in manifest["cases"])
    return uniform_sines(manifest, n, total, harmonics) if sine_only else uniform_triangles(manifest, n, total)


# --------------------------------------------------------------------------------------------
# The proof of one scenario
# --------------------------------------------------------------------------------------------

#: A diagnosis run: (raw campaign folder, work root) -> diagnosis.json's content (raises on failure).
Diagnose = Callable[[Path, Path], dict]


def run_plan(raw_dir: str | os.PathLike, truth: Mapping, before: Mapping, plan: Sequence[Mapping],
             work_root: str | os.PathLike, diagnose: Diagnose, calibrations: Sequence[Mapping] = ()) -> dict:
    """The plan's cases appended to a copy of the campaign (``work_root/raw/``; its ``calibrations`` declared
    there), diagnosed (``work_root/work/``) and judged (:func:`judge`); a plan the rig cannot run or a diagnosis
    that fails is not resolved, and says why (``error``)."""
    work_root = Path(work_root)
    try:
        out = extend_campaign(raw_dir, truth, plan, work_root / "raw", calibrations)
    except ValueError as exc:
        return {**judge(truth, before, None, math.nan), "error": str(exc), "rig_time_s": None}
    span = float(sum(case_spans_s(out, read_manifest(out))))
    rig_time = float(sum(rig_time_s(rig_case(e)) for e in plan)) + calibration_time_s(calibrations)
    try:
        after = diagnose(out, work_root / "work")
    except Exception as exc:  # noqa: BLE001 - a failed diagnosis is a plan that did not resolve
        return {**judge(truth, before, None, span), "error": f"{type(exc).__name__}: {exc}", "rig_time_s": rig_time}
    return {**judge(truth, before, after, span), "error": "", "rig_time_s": rig_time}


def calibration_time_s(calibrations: Sequence[Mapping]) -> float:
    """The rig time of a plan's calibrations [s]."""
    return float(sum(float(c["rig_time_s"]) for c in calibrations))


def prove_scenario(raw_dir: str | os.PathLike, truth: Mapping, before: Mapping, plan: Sequence[Mapping],
                   work_root: str | os.PathLike, diagnose: Diagnose, calibrations: Sequence[Mapping] = ()) -> dict:
    """One row of the proof: the scenario's confounding, the plan's size (cases and calibrations) and rig time, and
    the proposed and the uniform plan each run (:func:`run_plan`, in ``work_root/proposed`` and
    ``work_root/uniform``) and judged."""
    work_root = Path(work_root)
    srig = ScenarioRig.from_truth(truth)
    extra = calibration_time_s(calibrations)
    row = {"scenario": str(truth["scenario"]),
           "confounded": ";".join(group_text(g) for g in before.get("confounded") or []),
           "n_cases": len(plan), "n_calibrations": len(calibrations),
           "plan_rig_time_s": float(sum(float(e["rig_time_s"]) for e in plan)) + extra}
    if not plan and not calibrations:
        return {**row, "proposed": None, "uniform": None, "resolved": False, "uniform_resolved": False}
    proposed = run_plan(raw_dir, truth, before, plan, work_root / "proposed", diagnose, calibrations)
    try:
        uniform = run_plan(raw_dir, truth, before, uniform_plan(read_manifest(raw_dir), plan, srig.harmonics, extra),
                           work_root / "uniform", diagnose)
    except ValueError as exc:   # a proposed plan the rig cannot run has no rig time to spread
        uniform = {**judge(truth, before, None, math.nan), "error": str(exc), "rig_time_s": None}
    return {**row, "proposed": proposed, "uniform": uniform, "resolved": proposed["resolved"],
            "uniform_resolved": uniform["resolved"]}


# --------------------------------------------------------------------------------------------
# The proof over scenarios
# --------------------------------------------------------------------------------------------

#: The proof's target: the share of confounded scenarios whose proposed plan resolves to the truth.
TARGET_RESOLVED_RATE = 0.90


def proof_row(raw_dir: str | os.PathLike, truth: Mapping, work_root: str | os.PathLike, diagnose: Diagnose) -> dict:
    """A scenario's row of the proof: its campaign diagnosed (``work_root/before``); where the verdict has a
    confounding or ``next_tests`` says a test is needed, the proposed plan (``next_tests.plan``: none where the
    diagnosis proposes none) and the uniform one run and judged (:func:`prove_scenario`). ``in_proof`` False for
    a scenario with nothing to resolve; ``expected``: the group a scenario built to be confounded was built for."""
    work_root = Path(work_root)
    kind = str(truth.get("out_of_catalogue") or "")
    base = {"scenario": str(truth["scenario"]),
            "truth": "+".join([*(truth.get("truth") or []), *([f"({kind})"] if kind else [])]),
            "expected": group_text((truth.get("confounding") or {}).get("expected") or [])}
    try:
        before = diagnose(Path(raw_dir), work_root / "before")
    except Exception as exc:  # noqa: BLE001 - the scenario is reported, the proof goes on
        return {**base, "in_proof": False, "confounded": "", "note": f"diagnosis failed: {exc}"}
    block = before.get("next_tests") or {}
    needed = bool(before.get("confounded")) or bool(block.get("needed"))
    if not needed:
        return {**base, "in_proof": False, "confounded": "", "note": block.get("note", "not confounded"),
                "verdict": "+".join(before.get("verdict") or []), "explained": bool(before.get("explained"))}
    row = prove_scenario(raw_dir, truth, before, block.get("plan") or [], work_root, diagnose,
                         block.get("calibrations") or [])
    separations = [float(v) for v in (block.get("separation_se") or {}).values()]
    planned = row["n_cases"] or row["n_calibrations"]
    return {**base, **row, "in_proof": True, "note": str(block.get("note", "no next_tests block")),
            "predicted_se": min(separations) if separations and planned else None,
            "verdict_before": "+".join(before.get("verdict") or []), "explained_before": bool(before.get("explained"))}


def proof_summary(rows: Sequence[Mapping]) -> dict:
    """The two rates over the scenarios in the proof (every one with a confounding counts; one without a plan
    counts as not resolved by either plan), the target TARGET_RESOLVED_RATE and whether the proposed plans beat
    the uniform ones; and how many plans the diagnosis expected to separate every group by TARGET_SE
    (``predicted_se``) and how many of those resolved."""
    proof = [r for r in rows if r.get("in_proof")]
    n = len(proof)
    resolved = sum(bool(r["resolved"]) for r in proof)
    uniform = sum(bool(r["uniform_resolved"]) for r in proof)
    rate = resolved / n if n else None
    return {"n": n, "with_plan": sum(bool(r.get("n_cases") or r.get("n_calibrations")) for r in proof),
            "resolved": resolved,
            "uniform_resolved": uniform, "rate": rate, "uniform_rate": uniform / n if n else None,
            "target": TARGET_RESOLVED_RATE,
            "predicted_to_separate": sum((r.get("predicted_se") or 0.0) >= TARGET_SE for r in proof),
            "resolved_predicted": sum(bool(r["resolved"]) and (r.get("predicted_se") or 0.0) >= TARGET_SE
                                      for r in proof),
            "pass": None if rate is None else bool(rate >= TARGET_RESOLVED_RATE and resolved > uniform),
            "not_in_proof": [r["scenario"] for r in rows if not r.get("in_proof")]}


def _se(value: float | None) -> str:
    return "—" if value is None else f"{value:.1f}"


def _yes(value: bool | None) -> str:
    return "—" if value is None else ("yes" if value else "no")


def proof_table(rows: Sequence[Mapping]) -> str:
    """The proof as a Markdown table (scenario, confounding, plan size and rig time, resolved by the proposed
    plan, by the uniform one, what kept either from it) and its two rates."""
    lines = ["| scenario | truth | confounded | plan | rig time [min] | expected [SE] | proposed | uniform | why not |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r.get("in_proof"):
            continue
        why = "; ".join(f"{k}: {v}" for k, v in (("proposed", _why(r.get("proposed"))),
                                                 ("uniform", _why(r.get("uniform")))) if v)
        size = f"{r['n_cases']}" + (" + calibration" if r.get("n_calibrations") else "")
        lines.append(f"| {r['scenario']} | {r['truth'] or 'none'} | {r['confounded'] or '(rivals)'} | {size} "
                     f"| {r['plan_rig_time_s'] / 60.0:.1f} | {_se(r.get('predicted_se'))} | {_yes(r['resolved'])} "
                     f"| {_yes(r['uniform_resolved'])} "
                     f"| {why or (r['note'] if not (r['n_cases'] or r.get('n_calibrations')) else '')} |")
    s = proof_summary(rows)
    if s["n"]:
        lines.append("")
        lines.append(f"resolved to the truth: proposed {s['resolved']}/{s['n']} = {100 * s['rate']:.0f} %, uniform "
                     f"{s['uniform_resolved']}/{s['n']} = {100 * s['uniform_rate']:.0f} % (target >= "
                     f"{100 * s['target']:.0f} % and proposed > uniform: {'PASS' if s['pass'] else 'FAIL'}); plans "
                     f"expected to separate every group by {TARGET_SE:g} SE: {s['predicted_to_separate']}, of which "
                     f"{s['resolved_predicted']} resolved")
    return "\n".join(lines)


def _why(result: Mapping | None) -> str:
    """What kept a plan's run from resolving: its error, the groups left or new, the verdict's misses."""
    if not result or result.get("resolved"):
        return ""
    if result.get("error"):
        return result["error"][:80]
    parts = [f"still {', '.join(result['remaining'])}" if result["remaining"] else "",
             f"new {', '.join(result['new'])}" if result["new"] else "", ", ".join(result["misses"])]
    return "; ".join(p for p in parts if p)
