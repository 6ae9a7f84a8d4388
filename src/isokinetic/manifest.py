"""The campaign manifest, ``campaign.yaml`` (shared/spec/raw-campaign-format.md, version 1).

:func:`load_manifest` separates two kinds of trouble:

* a *broken manifest* (unparseable, wrong shape, bad campaign-level key) raises
  :class:`ManifestError` naming the file and the key: the campaign fails alone;
* a problem that concerns one case (a missing period, a file name with a path, an unknown
  unit on a column the case uses, ...) is recorded in that case's ``problems``: ingest
  quarantines the case and carries on with the others.

Keys the spec does not define are kept in ``metadata``, mirroring the manifest's structure
(top-level keys, unknown ``columns`` channels, extra ``damper`` keys, per-case keys under
``metadata["cases"][<id>]``).
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from .damper import Damper
from .plan import WAVEFORMS, CasePlan
from .validate import Problem

FORMAT_VERSION = 1
MANIFEST_NAME = "campaign.yaml"
CAMPAIGN_RULE = "[a-z0-9][a-z0-9_-]*"
CAMPAIGN_PATTERN = re.compile(CAMPAIGN_RULE)
#: Case ids name files (``timeseries/<id>.parquet``), so they are restricted to safe characters.
CASE_ID_RULE = "[A-Za-z0-9][A-Za-z0-9_.-]*"
CASE_ID_PATTERN = re.compile(CASE_ID_RULE)

#: Channel -> unit -> factor to SI; ``None`` marks ISO 8601 stamps (seconds from the first sample).
UNITS: dict[str, dict[str, float | None]] = {
    "time": {"s": 1.0, "ms": 1e-3, "datetime": None},
    "displacement": {"m": 1.0, "mm": 1e-3, "um": 1e-6},
    "force": {"N": 1.0, "kN": 1e3},
    "command": {"m": 1.0, "mm": 1e-3, "um": 1e-6},
}
CHANNELS = tuple(UNITS)
REQUIRED_CHANNELS = ("time", "displacement", "force")

TOP_KEYS = frozenset({"format_version", "campaign", "description", "source", "temperature_C",
                      "sample_rate_Hz", "columns", "damper", "cases"})
CASE_KEYS = frozenset({"id", "waveform", "file", "sample_rate_Hz", "columns", "period_s",
                       "amplitude_mm", "phase_rad", "frequency_Hz", "duration_s"})
COLUMN_KEYS = ("name", "unit", "invert")
DEFAULT_TRIANGLE_PHASE_RAD = -math.pi / 2


class ManifestError(ValueError):
    """A broken manifest: the whole campaign is rejected. The message names file and key."""

    def __init__(self, path: str, key: str | None, problem: str):
        self.path, self.key, self.problem = path, key, problem
        super().__init__(f"{path}: key {key!r}: {problem}" if key else f"{path}: {problem}")


@dataclass(frozen=True)
class Column:
    """Where one channel lives in a case CSV: column name, unit as written, sign flip."""

    name: str
    unit: str
    invert: bool = False


@dataclass(frozen=True)
class CaseSpec:
    """One case of the manifest: its plan in SI, its file and columns, and its own problems."""

    plan: CasePlan
    file: str | None                 # bare file name; None when missing or invalid (see problems)
    columns: dict[str, Column]       # effective channels: campaign columns merged with the case's
    keys: dict                       # the case entry exactly as written
    metadata: dict                   # the entry's keys the spec does not define
    problems: tuple[Problem, ...] = ()

    @property
    def id(self) -> str:
        return self.plan.case

    @property
    def waveform(self) -> str:
        return self.plan.waveform


@dataclass(frozen=True)
class Manifest:
    """A parsed ``campaign.yaml``."""

    path: str
    format_version: int
    campaign: str
    description: str | None
    source: str | None
    temperature_C: float | None
    sample_rate_Hz: float
    columns: dict[str, Column]
    damper: Damper | None
    cases: tuple[CaseSpec, ...]
    metadata: dict = field(default_factory=dict)
    sha256: str = ""


def number(value) -> float | None:
    """``value`` as a finite float, or None. Accepts numeric strings: PyYAML reads ``1e-3``
    (no decimal point) as a string."""
    if isinstance(value, bool):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def bare_file_name(name) -> bool:
    """True for a plain file name: no path separator, no ``..``, not absolute, not empty."""
    return (isinstance(name, str) and name.strip() not in ("", ".") and "/" not in name
            and "\\" not in name and ".." not in name and ":" not in name and "\0" not in name)


def column_problems(channel: str, spec) -> list[Problem]:
    """Problems of one channel's ``{name, unit, invert}`` mapping.

    Structural problems name the manifest key (``kind="key"``); an unknown unit names the
    CSV column (``kind="column"``).
    """
    key = f"columns.{channel}"
    if not isinstance(spec, Mapping):
        return [Problem(key, f"expected a mapping with keys {', '.join(COLUMN_KEYS)}, got {spec!r}", kind="key")]
    name, unit = spec.get("name"), spec.get("unit")
    if not isinstance(name, str) or not name.strip():
        return [Problem(f"{key}.name", "missing" if name is None else f"must be a column name, got {name!r}",
                        kind="key")]
    problems = []
    if "unit" not in spec:
        problems.append(Problem(f"{key}.unit", "missing", kind="key"))
    elif unit not in UNITS[channel]:
        problems.append(Problem(name.strip(), f"unknown unit {unit!r} for {channel}; expected one of "
                                              f"{', '.join(UNITS[channel])}"))
    if not isinstance(spec.get("invert", False), bool):
        problems.append(Problem(f"{key}.invert", f"must be true or false, got {spec['invert']!r}", kind="key"))
    return problems


def _column(spec: Mapping) -> Column:
    return Column(name=spec["name"].strip(), unit=spec.get("unit"), invert=bool(spec.get("invert", False)))


def _parse_yaml(data: bytes, where: str):
    """yaml.safe_load, with syntax errors turned into a ManifestError giving line and column."""
    try:
        return yaml.safe_load(data)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ManifestError(where, None, f"invalid YAML{at}: {problem}") from None


def _campaign_columns(block, where: str) -> tuple[dict[str, Mapping], dict]:
    """The campaign-level ``columns`` mappings, structure checked; unknown channels as metadata.

    Unknown units are left for each case to report (every case using the column is quarantined).
    """
    if not isinstance(block, Mapping):
        raise ManifestError(where, "columns", "missing" if block is None else "expected a mapping of channels")
    for channel in REQUIRED_CHANNELS:
        if block.get(channel) is None:
            raise ManifestError(where, f"columns.{channel}", "missing")
    specs = {ch: block[ch] for ch in CHANNELS if block.get(ch) is not None}
    for channel, spec in specs.items():
        structural = [p for p in column_problems(channel, spec) if p.kind == "key"]
        if structural:
            raise ManifestError(where, structural[0].column, structural[0].message)
    return specs, {k: v for k, v in block.items() if k not in UNITS}


def _damper(block, where: str) -> tuple[Damper | None, dict]:
    """The optional ``damper`` block (SI design data) and its extra keys."""
    if block is None:
        return None, {}
    if not isinstance(block, Mapping):
        raise ManifestError(where, "damper", f"expected a mapping of design data, got {block!r}")
    values = {}
    for f in fields(Damper):
        if f.name not in block:
            raise ManifestError(where, f"damper.{f.name}", "missing")
        value = number(block[f.name])
        if value is None or value <= 0:
            raise ManifestError(where, f"damper.{f.name}", f"must be a positive number, got {block[f.name]!r}")
        values[f.name] = value
    return Damper.from_mapping(values), {k: v for k, v in block.items() if k not in values}


def _optional(doc: Mapping, key: str, kind: type, where: str):
    """An optional campaign-level key of a given type (None when absent)."""
    value = doc.get(key)
    if value is None:
        return None
    if kind is float:
        out = number(value)
        if out is None:
            raise ManifestError(where, key, f"must be a number, got {value!r}")
        return out
    if not isinstance(value, kind):
        raise ManifestError(where, key, f"must be a {kind.__name__}, got {value!r}")
    return value


def _case_id(entry, index: int, where: str) -> str:
    if not isinstance(entry, Mapping):
        raise ManifestError(where, f"cases[{index}]", f"expected a mapping, got {entry!r}")
    case = entry.get("id")
    if case is None:
        raise ManifestError(where, f"cases[{index}].id", "missing")
    if not isinstance(case, str) or not CASE_ID_PATTERN.fullmatch(case):
        raise ManifestError(where, f"cases[{index}].id",
                            f"must be a string matching {CASE_ID_RULE}, got {case!r}")
    return case


def _positive(entry: Mapping, key: str, problems: list[Problem], required: bool = True) -> float:
    """A positive number from a case entry; NaN and a problem when missing or invalid."""
    if entry.get(key) is None:
        if required:
            problems.append(Problem(key, "missing", kind="key"))
        return math.nan
    value = number(entry[key])
    if value is None or value <= 0:
        problems.append(Problem(key, f"must be a positive number, got {entry[key]!r}", kind="key"))
        return math.nan
    return value


def _case_columns(base: dict[str, Mapping], override) -> tuple[dict[str, Column], list[Problem]]:
    """Campaign columns merged field by field with a case's ``columns``; ``command: null`` drops it."""
    if override is not None and not isinstance(override, Mapping):
        return {}, [Problem("columns", f"expected a mapping of channels, got {override!r}", kind="key")]
    merged, problems = dict(base), []
    for channel, spec in (override or {}).items():
        if channel not in UNITS:
            continue
        if spec is None:
            if channel in REQUIRED_CHANNELS:
                problems.append(Problem(f"columns.{channel}", "a required channel cannot be removed", kind="key"))
            merged.pop(channel, None)
        else:
            merged[channel] = {**base.get(channel, {}), **spec} if isinstance(spec, Mapping) else spec
    problems += [p for channel, spec in merged.items() for p in column_problems(channel, spec)]
    if problems:
        return {}, problems
    return {channel: _column(spec) for channel, spec in merged.items()}, []


def _case(entry: Mapping, case: str, sample_rate_Hz: float, base_columns: dict[str, Mapping],
          where: str) -> CaseSpec:
    """Parse one case entry; problems that concern only this case go to ``problems``."""
    waveform = entry.get("waveform")
    if waveform not in WAVEFORMS:
        raise ManifestError(where, f"cases.{case}.waveform",
                            "missing" if waveform is None else f"must be one of {', '.join(WAVEFORMS)}, got {waveform!r}")
    problems: list[Problem] = []
    rate = _positive(entry, "sample_rate_Hz", problems, required=False)
    file = entry.get("file")
    if file is None:
        problems.append(Problem("file", "missing", kind="key"))
    elif not bare_file_name(file):
        problems.append(Problem("file", f"must be a bare file name inside the campaign folder, got {file!r}",
                                kind="key"))
        file = None
    columns, column_issues = _case_columns(base_columns, entry.get("columns"))
    problems += column_issues
    plan = dict(amplitude_m=math.nan, period_s=math.nan, frequency_Hz=math.nan, phase_rad=math.nan)
    if waveform in ("triangle", "sine"):
        plan["amplitude_m"] = _positive(entry, "amplitude_mm", problems) * 1e-3
    if waveform == "triangle":
        plan["period_s"] = _positive(entry, "period_s", problems)
        phase = entry.get("phase_rad")
        plan["phase_rad"] = DEFAULT_TRIANGLE_PHASE_RAD if phase is None else number(phase)
        if plan["phase_rad"] is None:
            problems.append(Problem("phase_rad", f"must be a number, got {entry['phase_rad']!r}", kind="key"))
            plan["phase_rad"] = math.nan
    elif waveform == "sine":
        plan["frequency_Hz"] = _positive(entry, "frequency_Hz", problems)
        plan["phase_rad"] = 0.0
    duration = _positive(entry, "duration_s", problems, required=False)
    return CaseSpec(
        plan=CasePlan(case=case, waveform=waveform, sample_rate_Hz=sample_rate_Hz if math.isnan(rate) else rate,
                      duration_s=duration, **plan),
        file=file, columns=columns, keys=dict(entry),
        metadata={k: v for k, v in entry.items() if k not in CASE_KEYS}, problems=tuple(problems))


def load_manifest(path: str | Path) -> Manifest:
    """Read and check ``campaign.yaml``; raises :class:`ManifestError` for a broken manifest."""
    where = str(path)
    data = Path(path).read_bytes()
    doc = _parse_yaml(data, where)
    if not isinstance(doc, Mapping):
        raise ManifestError(where, None, "expected a mapping at the top level, got "
                                         + ("an empty file" if doc is None else type(doc).__name__))
    version = doc.get("format_version")
    if version is None:
        raise ManifestError(where, "format_version", "missing")
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise ManifestError(where, "format_version", f"unknown version {version!r}; this reader knows {FORMAT_VERSION}")
    campaign = doc.get("campaign")
    folder = Path(path).absolute().parent.name
    if campaign is None:
        raise ManifestError(where, "campaign", "missing")
    if not isinstance(campaign, str) or not CAMPAIGN_PATTERN.fullmatch(campaign):
        raise ManifestError(where, "campaign", f"must match {CAMPAIGN_RULE}, got {campaign!r}")
    if campaign != folder:
        raise ManifestError(where, "campaign", f"{campaign!r} differs from the folder name {folder!r}")
    rate = number(doc.get("sample_rate_Hz"))
    if rate is None or rate <= 0:
        raise ManifestError(where, "sample_rate_Hz", "missing" if doc.get("sample_rate_Hz") is None
                            else f"must be a positive number, got {doc['sample_rate_Hz']!r}")
    base_columns, extra_columns = _campaign_columns(doc.get("columns"), where)
    damper, extra_damper = _damper(doc.get("damper"), where)
    entries = doc.get("cases")
    if not isinstance(entries, list) or not entries:
        raise ManifestError(where, "cases", "missing" if entries is None else "must be a non-empty list of cases")
    cases, seen = [], set()
    for index, entry in enumerate(entries):
        case = _case_id(entry, index, where)
        if case in seen:
            raise ManifestError(where, f"cases[{index}].id", f"duplicate case id {case!r}")
        seen.add(case)
        cases.append(_case(entry, case, rate, base_columns, where))
    metadata = {k: v for k, v in doc.items() if k not in TOP_KEYS}
    for key, extra in (("columns", extra_columns), ("damper", extra_damper)):
        if extra:
            metadata[key] = extra
    case_metadata = {c.id: c.metadata for c in cases if c.metadata}
    if case_metadata:
        metadata["cases"] = case_metadata
    return Manifest(
        path=where, format_version=FORMAT_VERSION, campaign=campaign,
        description=_optional(doc, "description", str, where), source=_optional(doc, "source", str, where),
        temperature_C=_optional(doc, "temperature_C", float, where), sample_rate_Hz=rate,
        columns={ch: _column(spec) for ch, spec in base_columns.items()}, damper=damper,
        cases=tuple(cases), metadata=metadata, sha256=hashlib.sha256(data).hexdigest())
