"""The campaign manifest, ``campaign.yaml`` (docs/raw-campaign-format.md, version 1).

:func:`load_manifest` separates two kinds of trouble:

* a *broken manifest* (unparseable, wrong shape, bad campaign-level key) raises
  :class:`ManifestError` naming the file and the key: the campaign fails alone;
* a problem that concerns one case (a missing period, a missing file key, an unknown
  unit on a column the case uses, ...) is recorded in that case's ``problems``: ingest
  quarantines the case and carries on with the others.

Hostile input is refused as a broken manifest, before any case file is opened and before the
YAML is turned into Python objects (:func:`check_yaml_events` walks the parser's events first; the YAML side
lives in :mod:`isokinetic.contracts.manifest_yaml`, whose names this module re-exports):

* a manifest larger than :data:`MAX_MANIFEST_BYTES` (1 MB) or not a regular file;
* YAML anchors and aliases (``&a`` / ``*a``: the "billion laughs" expansion bomb), merge keys
  (``<<``), duplicate mapping keys (PyYAML would silently keep the last one), tags other than the
  plain YAML types (``!!python/object:...``, ``!!binary``, local ``!tags``: nothing constructs
  objects), complex (non-scalar) mapping keys, nesting deeper than :data:`MAX_DEPTH`, more than
  :data:`MAX_NODES` values;
* a case ``file`` that is not a bare name or a relative path into a subfolder of the campaign folder
  (``..``, absolute path, backslash, drive letter, NUL), or a symlink (the file, or a folder on its way)
  whose target lies outside the campaign folder;
* sizes that make no physical sense or would allocate gigabytes (:data:`BOUNDS`, per key, and
  :data:`MAX_PLANNED_SAMPLES` samples per planned record; at most :data:`MAX_CASES` cases);
* a ``csv`` block (format 1.1; 1.2: ``format``, ``encoding``, ``units_row``) that is not one of the
  formats ingest can read (:func:`csv_dialect`);
* a ``damper.viscosity_law`` (format 1.1) that is not a valid law (:func:`viscosity_law`), a campaign
  ``temperature_C`` outside :data:`TEMPERATURE_RANGE_C` (a case's is that case's problem).

Keys the spec does not define are kept in ``metadata``, mirroring the manifest's structure
(top-level keys, unknown ``columns`` channels, extra ``damper`` keys, per-case keys under
``metadata["cases"][<id>]``); one that lies close to a known key (``gas_force_n``) is also warned about in
``Manifest.warnings`` (1.2, :func:`near_miss_warnings`).

Format 1.2 additions (docs/raw-campaign-format.md, "1.2 additions"): the ``csv`` block's ``format``
(``mts793``), ``encoding`` and ``units_row``; units ``in``, ``lbf``, ``kgf``, ``F`` and ``Sec``; a case's
slice of its file (``time_range_s`` or ``rows``), its own ``gas_force_N`` and the ``standstill`` waveform;
case files in subfolders; a channel's ``full_scale`` (issue 20: ingest refuses samples beyond
:data:`FULL_SCALE_FACTOR` times it).

Format 1.4 additions (docs/raw-campaign-format.md, "1.4 additions"): a unit is any unit of the channel's
dimension that :mod:`isokinetic.units` reads (pint: ``kip``, ``cm``, ``daN``, ``ozf``, ``µm``, ``Sec``,
``degC``; :data:`CHANNEL_DIMENSIONS`), an unknown one named with the nearest known ones; a column's ``scale``
and ``offset`` (a logger writing volts: value = raw x scale + offset, in the column's unit); a headerless
file's columns named by 1-based position (``name: 4`` or ``col4``, with ``csv: {header: none}``); the csv block's
``header`` and, for ``format: xlsx``, ``sheet`` (:mod:`isokinetic.contracts.manifest_csv`).

Format 1.6 additions (docs/raw-campaign-format.md, "1.6 additions"): the campaign's force column may declare the
load cell's calibration against a reference force, ``calibration: {gain, uncertainty_rel}``
(:func:`force_calibration`), and its displacement column the LVDT's against a reference displacement,
``calibration: {scale, uncertainty_rel}`` (:func:`displacement_calibration`); campaign level only: a case's
columns may not declare one.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path

from isokinetic.contracts.manifest_csv import (  # noqa: F401  (re-exported: the manifest's public names)
    CSV_DECIMALS,
    CSV_DELIMITERS,
    CSV_KEYS,
    CSV_TAB_SPELLINGS,
    HEADER_KINDS,
    NEAR_MISS_RATIO,
    CsvDialect,
    csv_dialect,
    near_miss,
    near_miss_warnings,
)
from isokinetic.contracts.manifest_yaml import (  # noqa: F401  (re-exported: the manifest's public names)
    MAX_DEPTH,
    MAX_MANIFEST_BYTES,
    MAX_NODES,
    SAFE_TAGS,
    ManifestError,
    _inside,
    check_yaml_events,
    parse_yaml,
    read_manifest_bytes,
)
from isokinetic.contracts.problem import Problem
from isokinetic.physics.damper import Damper
from isokinetic.physics.plan import WAVEFORMS, CasePlan
from isokinetic.physics.viscosity import ViscosityLaw, law_from_mapping
from isokinetic.timestamps import TIME_STAMPS, TIME_TEXT_UNITS  # noqa: F401  (TIME_STAMPS: re-exported)
from isokinetic.units import Unit, UnitError, parse_unit

FORMAT_VERSION = 1
MANIFEST_NAME = "campaign.yaml"
CAMPAIGN_RULE = "[a-z0-9][a-z0-9_-]*"
CAMPAIGN_PATTERN = re.compile(CAMPAIGN_RULE)
#: Case ids name files (``timeseries/<id>.parquet``), so they are restricted to safe characters.
CASE_ID_RULE = "[A-Za-z0-9][A-Za-z0-9_.-]*"
CASE_ID_PATTERN = re.compile(CASE_ID_RULE)
#: Longest case id: ids name the case's result files, and file names are limited (255 bytes).
MAX_CASE_ID_LENGTH = 64

#: Channel -> the dimension of its unit (format 1.4: any unit of it that :mod:`isokinetic.units` reads: ``kip``,
#: ``cm``, ``daN``, ``Sec``, ``degC``, ...). The temperature channel is kept in degrees Celsius.
CHANNEL_DIMENSIONS = {"time": "time", "displacement": "length", "force": "force", "command": "length",
                      "temperature": "temperature"}
#: The time units that are no pint unit (seconds from the first sample, :mod:`isokinetic.timestamps`): ISO 8601
#: stamps (``datetime``, TIME_STAMPS), clock times (``hms``) and Excel serial dates (``excel_serial``), format 1.5.
#: Plausible temperatures of a damper under test [C] (cold tests to beyond any oil's flash point); a value
#: outside is a unit error: any temperature above -73 C written in K and declared as C lies above it.
TEMPERATURE_RANGE_C = (-60.0, 200.0)
CHANNELS = tuple(CHANNEL_DIMENSIONS)
REQUIRED_CHANNELS = ("time", "displacement", "force")

TOP_KEYS = frozenset({"format_version", "campaign", "description", "source", "temperature_C",
                      "sample_rate_Hz", "columns", "damper", "cases", "gas_force_N", "csv"})
CASE_KEYS = frozenset({"id", "waveform", "file", "sample_rate_Hz", "columns", "period_s",
                       "amplitude_mm", "phase_rad", "frequency_Hz", "duration_s", "temperature_C",
                       "time_range_s", "rows", "gas_force_N"})     # the last three: 1.2
#: Case-file suffixes (1.2: .txt and .dat for vendor exports); a manifest may name any, init-campaign looks
#: for these.
CASE_FILE_SUFFIXES = (".csv", ".tsv", ".txt", ".dat")
#: Largest data-row number a case's ``rows`` slice may name (1.2): far beyond any record.
MAX_ROW = 1_000_000_000
COLUMN_KEYS = ("name", "unit", "invert", "full_scale", "scale", "offset",    # full_scale: 1.2; scale, offset: 1.4
               "calibration")                                        # calibration: 1.6, force and displacement
#: The columns that may declare a calibration (1.6, campaign level only): channel -> (the key of the instrument's
#: reading per unit true quantity, what that reading is). The reading defaults to DEFAULT_CALIBRATION_READING.
CALIBRATED_CHANNELS = {"force": ("gain", "the load cell's reading per unit true force"),
                       "displacement": ("scale", "the LVDT's reading per unit true displacement")}
DEFAULT_CALIBRATION_READING = 1.0
#: Range of a declared gain or LVDT scale: beyond 10 % the sensor is no calibrated instrument (or the column's
#: unit is wrong), which a conversion, not a calibration, corrects.
CALIBRATION_RANGE = (0.9, 1.1)
#: Largest declared relative standard uncertainty of either: the diagnosis' own gain bound (2 %): a looser load-cell
#: calibration tells the diagnosis nothing it does not assume, and a looser LVDT one leaves the scale as free as
#: that gain, which a scale error mimics (gain 1/k plus C_D·√k).
MAX_CALIBRATION_UNCERTAINTY_REL = 0.02
#: Largest 1-based column position a headerless file's column may be named by (1.4).
MAX_COLUMN_POSITION = 10_000
#: A headerless file's column names (1.4): ``col1``, ``col2``, ... (what :mod:`isokinetic.rawfile` names them).
POSITION_NAME = re.compile(r"col([1-9][0-9]*)")
#: A sample beyond this many times its channel's declared ``full_scale`` is no reading of the sensor (ingest
#: sets the case aside, naming the row).
FULL_SCALE_FACTOR = 100.0
#: Channels that may declare a ``full_scale`` (the temperature channel has its own plausible range).
FULL_SCALE_CHANNELS = ("displacement", "force", "command")
DEFAULT_TRIANGLE_PHASE_RAD = -math.pi / 2

#: Most cases in one campaign.
MAX_CASES = 1_000
#: Largest |gas_force_N| (format 1.1) a manifest may declare: 1 MN, far above any damper's gas force; a
#: larger value is a unit error (kN written as N?) and refuses the campaign.
MAX_GAS_FORCE_N = 1.0e6
#: Upper bounds (inclusive) of positive sizes, campaign-level or per case. A value above its bound
#: is a unit or typing error, or hostile: the campaign is refused. Lower bounds: > 0 as before.
BOUNDS = {
    "sample_rate_Hz": 1.0e6,     # 1 MHz: far above any damper rig's acquisition rate
    "period_s": 1.0e5,           # about 28 h per triangle period
    "frequency_Hz": 1.0e4,       # 10 kHz excitation
    "amplitude_mm": 1.0e3,       # 1 m of piston amplitude
    "duration_s": 1.0e6,         # about 11.6 days of record
}
#: Most samples a planned record may need (sample rate x the longer of the plan's required
#: duration and ``duration_s``): 1e7 samples = 80 MB per float64 channel. Stages that simulate the
#: plan (nominal model, diagnosis) allocate this many samples.
MAX_PLANNED_SAMPLES = 10_000_000


@dataclass(frozen=True)
class Column:
    """Where one channel lives in a case CSV: column name (``col4`` for a headerless file's 4th column, 1.4),
    unit (its canonical symbol, :mod:`isokinetic.units`), sign flip, and the sensor's full scale in that unit
    (1.2, ``full_scale``; None: not declared): ingest refuses a sample beyond ``FULL_SCALE_FACTOR`` times it.
    ``scale`` and ``offset`` (1.4, a logger writing volts): the value in ``unit`` is raw x scale + offset."""

    name: str
    unit: str
    invert: bool = False
    full_scale: float | None = None
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class CaseSpec:
    """One case of the manifest: its plan in SI, its file and columns, and its own problems."""

    plan: CasePlan
    file: str | None                 # bare file name; None when missing or invalid (see problems)
    columns: dict[str, Column]       # effective channels: campaign columns merged with the case's
    keys: dict                       # the case entry exactly as written
    metadata: dict                   # the entry's keys the spec does not define
    problems: tuple[Problem, ...] = ()
    gas_force_N: float | None = None  # the case's gas_force_N (1.2), else the campaign's (1.1); subtracted at ingest
    csv: CsvDialect | None = None    # the campaign's csv block (1.1); None: none declared, ',' and '.'
    temperature_C: float | None = None  # the case's temperature_C (1.1); None: not given on the case
    time_range_s: tuple[float, float] | None = None  # (1.2) the case's slice [start, end) on the file's time axis
    rows: tuple[int, int] | None = None  # (1.2) the case's slice [first, stop) of 0-based data rows
    case_gas_force_N: float | None = None  # (1.2) the gas_force_N written on the case itself, None when not

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
    #: Known static force (gas force) subtracted from every force sample at ingest (format 1.1), N, in
    #: the force channel's sign convention after ``invert``; None when the manifest declares none.
    gas_force_N: float | None = None
    #: The case files' dialect (format 1.1 ``csv`` block); None when the manifest declares none: the
    #: format's ',' between fields and '.' as the decimal mark, read exactly as before 1.1.
    csv: CsvDialect | None = None
    #: The oil's viscosity-temperature law (format 1.1 ``damper.viscosity_law``); None when not given.
    viscosity_law: ViscosityLaw | None = None
    #: Keys the format does not know but that lie close to one it does (1.2): "key 'x' is not a key of the
    #: format; did you mean 'y'?" (:func:`near_miss_warnings`).
    warnings: tuple[str, ...] = ()
    #: The load cell's calibration (1.6, ``columns.force.calibration``): {"gain", "uncertainty_rel"}; None when
    #: none is declared (:func:`force_calibration`).
    force_calibration: dict[str, float] | None = None
    #: The LVDT's calibration (1.6, ``columns.displacement.calibration``): {"scale", "uncertainty_rel"}; None when
    #: none is declared (:func:`displacement_calibration`).
    displacement_calibration: dict[str, float] | None = None


def number(value) -> float | None:
    """``value`` as a finite float, or None. Accepts numeric strings: PyYAML reads ``1e-3``
    (no decimal point) as a string."""
    if isinstance(value, bool):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError, OverflowError):
        return None
    return out if math.isfinite(out) else None


def bare_file_name(name) -> bool:
    """True for a plain file name: no path separator, no ``..``, not absolute, not empty."""
    return (isinstance(name, str) and name.strip() not in ("", ".") and "/" not in name
            and "\\" not in name and ".." not in name and ":" not in name and "\0" not in name)


def relative_file_name(name) -> bool:
    """True for a relative path inside the campaign folder (1.2): ``T01.csv`` or ``run1/T01.csv``, parts
    separated by '/', each a :func:`bare_file_name` (no ``..``, not absolute, no backslash or drive)."""
    return isinstance(name, str) and all(bare_file_name(part) for part in name.split("/"))


def channel_unit(channel: str, unit: str) -> Unit:
    """The :class:`isokinetic.units.Unit` of a channel's unit text (of the channel's dimension,
    :data:`CHANNEL_DIMENSIONS`); raises :class:`isokinetic.units.UnitError` naming the nearest known units."""
    return parse_unit(unit, CHANNEL_DIMENSIONS[channel])


def si_conversion(channel: str, column: Column) -> tuple[float, float] | None:
    """(factor, offset) taking a column's raw numbers to the channel's internal unit (SI; temperatures in C):
    the column's ``scale``/``offset`` (1.4) then its unit's; None for time stamps, clock times, serial dates."""
    if column.unit in TIME_TEXT_UNITS:
        return None
    unit = channel_unit(channel, column.unit)
    return column.scale * unit.scale, column.offset * unit.scale + unit.offset


def unit_from_text(text: str) -> str | None:
    """The canonical symbol (:func:`isokinetic.units.parse_unit`) of a units-row cell (``Sec`` -> s, ``[mm]`` ->
    mm, ``°C`` -> degC, ``lbs`` -> lbf, ``kip``), None for a text that names no unit. (Kept for
    init_campaign until it reads units through :mod:`isokinetic.units` itself.)"""
    try:
        return parse_unit(text).symbol
    except UnitError:
        return None


def column_name(name, headerless: bool = False) -> str | None:
    """The frame column a manifest's ``name`` means: the header's name (stripped), or with ``headerless`` (1.4,
    ``csv: {header: none}``) a 1-based position, ``4`` or ``col4`` -> ``col4``; None when it means none."""
    if isinstance(name, int) and not isinstance(name, bool):
        return f"col{name}" if headerless and 1 <= name <= MAX_COLUMN_POSITION else None
    if not isinstance(name, str) or not name.strip():
        return None
    if headerless:
        match = POSITION_NAME.fullmatch(name.strip())
        return name.strip() if match and int(match.group(1)) <= MAX_COLUMN_POSITION else None
    return name.strip()


def _name_problem(key: str, name, headerless: bool) -> Problem:
    if name is None:
        return Problem(f"{key}.name", "missing", kind="key")
    if headerless:
        return Problem(f"{key}.name", f"a headerless file's columns are named by 1-based position (4 or col4, at most "
                                      f"{MAX_COLUMN_POSITION}), got {name!r}", kind="key")
    if isinstance(name, int) and not isinstance(name, bool):
        return Problem(f"{key}.name", f"a position ({name!r}) names a column of a headerless file only (csv: {{header: "
                                      "none}}); give the header's name", kind="key")
    return Problem(f"{key}.name", f"must be a column name, got {name!r}", kind="key")


def _scale_problems(key: str, spec: Mapping) -> list[Problem]:
    """A scaled channel's ``scale`` (finite, non-zero) and ``offset`` (finite) (1.4); not on ISO 8601 stamps."""
    problems = []
    for field_name, zero_ok in (("scale", False), ("offset", True)):
        if spec.get(field_name) is None:
            continue
        value = number(spec[field_name])
        if spec.get("unit") in TIME_TEXT_UNITS:
            problems.append(Problem(f"{key}.{field_name}", f"{spec['unit']} time is not scaled", kind="key"))
        elif value is None or (value == 0 and not zero_ok):
            what = "a finite, non-zero number" if not zero_ok else "a finite number"
            problems.append(Problem(f"{key}.{field_name}", f"must be {what} (value = raw x scale + offset, in the "
                                                           f"column's unit), got {spec[field_name]!r}", kind="key"))
    return problems


def column_problems(channel: str, spec, headerless: bool = False) -> list[Problem]:
    """Problems of one channel's ``{name, unit, invert, full_scale, scale, offset}`` mapping (``headerless``:
    the file has no header, columns are named by position).

    Structural problems name the manifest key (``kind="key"``); an unknown unit names the
    CSV column (``kind="column"``), with the nearest known units (:mod:`isokinetic.units`).
    """
    key = f"columns.{channel}"
    if not isinstance(spec, Mapping):
        return [Problem(key, f"expected a mapping with keys {', '.join(COLUMN_KEYS)}, got {spec!r}", kind="key")]
    name, unit = column_name(spec.get("name"), headerless), spec.get("unit")
    if name is None:
        return [_name_problem(key, spec.get("name"), headerless)]
    problems = []
    if "unit" not in spec:
        problems.append(Problem(f"{key}.unit", "missing", kind="key"))
    elif not (channel == "time" and unit in TIME_TEXT_UNITS):
        try:
            channel_unit(channel, unit)
        except UnitError as exc:
            problems.append(Problem(name, str(exc)))
    if not isinstance(spec.get("invert", False), bool):
        problems.append(Problem(f"{key}.invert", f"must be true or false, got {spec['invert']!r}", kind="key"))
    if spec.get("full_scale") is not None:
        value = number(spec["full_scale"])
        if channel not in FULL_SCALE_CHANNELS:
            problems.append(Problem(f"{key}.full_scale", f"applies to {', '.join(FULL_SCALE_CHANNELS)} only",
                                    kind="key"))
        elif value is None or value <= 0:
            problems.append(Problem(f"{key}.full_scale", f"must be a positive number (the sensor's full scale in the "
                                                         f"column's unit), got {spec['full_scale']!r}", kind="key"))
    return problems + _scale_problems(key, spec)


def _column_of(channel: str, spec: Mapping, headerless: bool = False) -> Column:
    """A channel's Column (its problems checked already), its unit spelled by its canonical symbol (``Sec`` ->
    ``s``, ``lbs`` -> ``lbf``, ``°C`` -> ``degC``)."""
    unit = spec.get("unit")
    if unit not in TIME_TEXT_UNITS:
        try:
            unit = channel_unit(channel, unit).symbol
        except UnitError:       # the manifest's columns as written: each case using it reports the unit
            pass
    return Column(name=column_name(spec["name"], headerless), invert=bool(spec.get("invert", False)), unit=unit,
                  full_scale=number(spec.get("full_scale")),
                  scale=1.0 if spec.get("scale") is None else number(spec["scale"]),
                  offset=0.0 if spec.get("offset") is None else number(spec["offset"]))


def _bounded(value: float, key: str, where: str, name: str | None = None) -> float:
    """``value`` unless it exceeds ``BOUNDS[name]`` (name defaults to the key's last part)."""
    bound = BOUNDS[name or key.rsplit(".", 1)[-1]]
    if value > bound:
        raise ManifestError(where, key, f"{value:g} is above the bound {bound:g} (a unit error? "
                                        "bounds: isokinetic.contracts.manifest.BOUNDS)")
    return value


def _campaign_columns(block, where: str, headerless: bool = False) -> tuple[dict[str, Mapping], dict]:
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
        structural = [p for p in column_problems(channel, spec, headerless) if p.kind == "key"]
        if structural:
            raise ManifestError(where, structural[0].column, structural[0].message)
    return specs, {k: v for k, v in block.items() if k not in CHANNEL_DIMENSIONS}


def force_calibration(block, where: str) -> dict[str, float] | None:
    """The campaign force column's ``calibration`` (1.6): ``{gain, uncertainty_rel}``, the load cell's reading per
    unit true force as a calibration against a reference force found it (:func:`column_calibration`)."""
    return column_calibration(block, where, "force")


def displacement_calibration(block, where: str) -> dict[str, float] | None:
    """The campaign displacement column's ``calibration`` (1.6): ``{scale, uncertainty_rel}``, the LVDT's reading
    per unit true displacement as a calibration against a reference displacement (gauge blocks, a micrometer
    calibrator) found it (:func:`column_calibration`)."""
    return column_calibration(block, where, "displacement")


def column_calibration(block, where: str, channel: str) -> dict[str, float] | None:
    """The campaign ``channel`` column's ``calibration`` (1.6, a channel of :data:`CALIBRATED_CHANNELS`): the
    instrument's reading per unit true quantity (``gain`` or ``scale``, default 1, within
    :data:`CALIBRATION_RANGE`; the column's unit and scale not corrected for it) and its relative standard
    uncertainty (``uncertainty_rel``, 1 sigma, > 0 and <= :data:`MAX_CALIBRATION_UNCERTAINTY_REL`); None when not
    declared. A ``calibration`` on any other channel, or a malformed one, refuses the campaign naming the key."""
    columns = block if isinstance(block, Mapping) else {}
    for other in CHANNELS:
        if other not in CALIBRATED_CHANNELS and isinstance(columns.get(other), Mapping) \
                and "calibration" in columns[other]:
            raise ManifestError(where, f"columns.{other}.calibration", "only the force and displacement columns "
                                "declare a calibration (the load cell's gain, the LVDT's scale)")
    spec = columns.get(channel)
    if not isinstance(spec, Mapping) or spec.get("calibration") is None:
        return None
    (reading, what), key, cal = CALIBRATED_CHANNELS[channel], f"columns.{channel}.calibration", spec["calibration"]
    keys = (reading, "uncertainty_rel")
    if not isinstance(cal, Mapping):
        raise ManifestError(where, key, f"expected a mapping {{{', '.join(keys)}}}, got {cal!r}")
    unknown = sorted(str(k) for k in cal if k not in keys)
    if unknown:
        raise ManifestError(where, f"{key}.{unknown[0]}", f"not a key of the calibration (keys: {', '.join(keys)})")
    if cal.get("uncertainty_rel") is None:
        raise ManifestError(where, f"{key}.uncertainty_rel", f"missing (the {reading}'s relative standard uncertainty)")
    value = DEFAULT_CALIBRATION_READING if cal.get(reading) is None else number(cal[reading])
    lo, hi = CALIBRATION_RANGE
    if value is None or not lo <= value <= hi:
        raise ManifestError(where, f"{key}.{reading}", f"must be a number within [{lo:g}, {hi:g}] ({what}), "
                                                       f"got {cal[reading]!r}")
    rel = number(cal["uncertainty_rel"])
    if rel is None or not 0.0 < rel <= MAX_CALIBRATION_UNCERTAINTY_REL:
        raise ManifestError(where, f"{key}.uncertainty_rel", f"must be a number > 0 and <= "
                            f"{MAX_CALIBRATION_UNCERTAINTY_REL:g} (the {reading}'s relative standard uncertainty, "
                            f"1 sigma), got {cal['uncertainty_rel']!r}")
    return {reading: value, "uncertainty_rel": rel}


def _damper(block, where: str) -> tuple[Damper | None, dict]:
    """The optional ``damper`` block (SI design data) and its extra keys."""
    if block is None:
        return None, {}
    if not isinstance(block, Mapping):
        raise ManifestError(where, "damper", f"expected a mapping of design data, got {block!r}")
    values = {}
    for f in fields(Damper):
        if f.name not in block:
            if f.name in Damper.OPTIONAL:
                continue
            raise ManifestError(where, f"damper.{f.name}", "missing")
        value = number(block[f.name])
        if value is None or value <= 0:
            raise ManifestError(where, f"damper.{f.name}", f"must be a positive number, got {block[f.name]!r}")
        values[f.name] = value
    return Damper.from_mapping(values), {k: v for k, v in block.items() if k not in values and k != "viscosity_law"}


def viscosity_law(block, damper: Damper | None, where: str) -> ViscosityLaw | None:
    """The optional ``damper.viscosity_law`` (format 1.1), e.g. ``{kind: walther, points: [[40.0, 0.030],
    [100.0, 0.006]]}`` ([C, Pa s]; :mod:`isokinetic.physics.viscosity`); a malformed law refuses the campaign,
    naming the key."""
    if not isinstance(block, Mapping) or block.get("viscosity_law") is None:
        return None
    try:
        return law_from_mapping(dict(block["viscosity_law"]) if isinstance(block["viscosity_law"], Mapping)
                                else block["viscosity_law"], damper.density_kg_m3)
    except ValueError as exc:
        raise ManifestError(where, "damper.viscosity_law", str(exc)) from None


def temperature_value(value, key: str) -> tuple[float | None, Problem | None]:
    """A temperature [C] within :data:`TEMPERATURE_RANGE_C`, or the problem (None and None when absent)."""
    if value is None:
        return None, None
    out = number(value)
    lo, hi = TEMPERATURE_RANGE_C
    if out is None:
        return None, Problem(key, f"must be a number (C), got {value!r}", kind="key")
    if not lo <= out <= hi:
        return None, Problem(key, f"{out:g} C lies outside {lo:g}..{hi:g} C (a temperature in K written as C?)",
                             kind="key")
    return out, None


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


def _gas_force(doc: Mapping, where: str) -> float | None:
    """The optional ``gas_force_N`` (format 1.1): a finite number of at most :data:`MAX_GAS_FORCE_N` in
    magnitude, either sign (None when absent)."""
    value = _optional(doc, "gas_force_N", float, where)
    if value is not None and abs(value) > MAX_GAS_FORCE_N:
        raise ManifestError(where, "gas_force_N", f"|{value:g}| N is above the bound {MAX_GAS_FORCE_N:g} N "
                                                  "(a unit error?)")
    return value


def _campaign_temperature(doc: Mapping, where: str) -> float | None:
    """The campaign's ``temperature_C`` within :data:`TEMPERATURE_RANGE_C` (None when absent)."""
    value, problem = temperature_value(doc.get("temperature_C"), "temperature_C")
    if problem is not None:
        raise ManifestError(where, "temperature_C", problem.message)
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
    if len(case) > MAX_CASE_ID_LENGTH:
        raise ManifestError(where, f"cases[{index}].id", f"{len(case)} characters, more than the "
                            f"{MAX_CASE_ID_LENGTH} a case id may have (it names the case's files)")
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


def _case_columns(base: dict[str, Mapping], override, headerless: bool = False) -> tuple[dict[str, Column],
                                                                                        list[Problem]]:
    """Campaign columns merged field by field with a case's ``columns``; ``command: null`` drops it."""
    if override is not None and not isinstance(override, Mapping):
        return {}, [Problem("columns", f"expected a mapping of channels, got {override!r}", kind="key")]
    merged, problems = dict(base), []
    for channel, spec in (override or {}).items():
        if channel not in CHANNEL_DIMENSIONS:
            continue
        if spec is None:
            if channel in REQUIRED_CHANNELS:
                problems.append(Problem(f"columns.{channel}", "a required channel cannot be removed", kind="key"))
            merged.pop(channel, None)
        else:
            merged[channel] = {**base.get(channel, {}), **spec} if isinstance(spec, Mapping) else spec
    problems += [p for channel, spec in merged.items() for p in column_problems(channel, spec, headerless)]
    if problems:
        return {}, problems
    return {channel: _column_of(channel, spec, headerless) for channel, spec in merged.items()}, []


def _case(entry: Mapping, case: str, sample_rate_Hz: float, base_columns: dict[str, Mapping],
          where: str, folder: Path, headerless: bool = False) -> CaseSpec:
    """Parse one case entry; problems that concern only this case go to ``problems``."""
    waveform = entry.get("waveform")
    if waveform not in WAVEFORMS:
        said = "missing" if waveform is None else f"must be one of {', '.join(WAVEFORMS)}, got {waveform!r}"
        raise ManifestError(where, f"cases.{case}.waveform", said)
    problems: list[Problem] = []
    rate = _positive(entry, "sample_rate_Hz", problems, required=False)
    file = entry.get("file")
    if file is None:
        problems.append(Problem("file", "missing", kind="key"))
    elif not relative_file_name(file):
        raise ManifestError(where, f"cases.{case}.file",
                            f"must be a bare file name inside the campaign folder, got {file!r} (or a path into a "
                            "subfolder: run1/T01.csv, with '/' and no '..')")
    elif _escapes(folder, file):
        raise ManifestError(where, f"cases.{case}.file", f"{file!r} is a symlink to "
                            f"{(folder / file).resolve().as_posix()}, outside the campaign folder")
    override = entry.get("columns")
    for channel in CHANNELS:
        if isinstance(override, Mapping) and isinstance(override.get(channel), Mapping) \
                and "calibration" in override[channel]:
            raise ManifestError(where, f"cases.{case}.columns.{channel}.calibration", "a calibration is the "
                                f"sensor's, declared once on the campaign's {channel} column "
                                f"(columns.{channel}.calibration), not on a case")
    columns, column_issues = _case_columns(base_columns, override, headerless)
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
    elif waveform == "standstill":
        problems += [Problem(key, "a standstill case has no motion: leave the key out", kind="key")
                     for key in ("amplitude_mm", "period_s", "frequency_Hz", "phase_rad") if key in entry]
    duration = _positive(entry, "duration_s", problems, required=False)
    time_range, rows = _case_slice(entry, problems)
    gas_force_N, problem = _case_gas_force(entry)
    if problem is not None:
        problems.append(problem)
    case_temperature, problem = temperature_value(entry.get("temperature_C"), "temperature_C")
    if problem is not None:
        problems.append(problem)
    for key, value in (("sample_rate_Hz", rate), ("period_s", plan["period_s"]),
                       ("frequency_Hz", plan["frequency_Hz"]), ("amplitude_mm", plan["amplitude_m"] * 1e3),
                       ("duration_s", duration)):
        if not math.isnan(value):
            _bounded(value, f"cases.{case}.{key}", where)
    plan_ = CasePlan(case=case, waveform=waveform, sample_rate_Hz=sample_rate_Hz if math.isnan(rate) else rate,
                     duration_s=duration, **plan)
    for key, seconds in (("duration_s", duration), ("period_s" if waveform == "triangle" else "frequency_Hz",
                                                     plan_.required_duration_s)):
        samples = plan_.sample_rate_Hz * seconds
        if not math.isnan(samples) and samples > MAX_PLANNED_SAMPLES:
            raise ManifestError(where, f"cases.{case}.{key}",
                                f"the record would need {samples:.3g} samples ({seconds:g} s at "
                                f"{plan_.sample_rate_Hz:g} Hz), more than the {MAX_PLANNED_SAMPLES:.0e} "
                                "a case may have")
    return CaseSpec(
        plan=plan_,
        file=file, columns=columns, keys=dict(entry),
        metadata={k: v for k, v in entry.items() if k not in CASE_KEYS}, problems=tuple(problems),
        temperature_C=case_temperature, time_range_s=time_range, rows=rows, case_gas_force_N=gas_force_N)


def _escapes(folder: Path, file: str) -> bool:
    """True when the case file, or a folder on its way, is a symlink leading out of the campaign folder."""
    path = folder
    for part in file.split("/"):
        path = path / part
        if path.is_symlink() and not _inside(path, folder):
            return True
    return False


def _case_slice(entry: Mapping, problems: list[Problem]) -> tuple[tuple[float, float] | None,
                                                                  tuple[int, int] | None]:
    """The case's slice of its file (1.2): ``time_range_s: [start, end)`` (seconds on the file's own time
    axis, 0 <= start < end <= the duration bound) or ``rows: [first, stop)`` (0-based data rows, integers,
    0 <= first < stop <= :data:`MAX_ROW`); not both. A malformed slice is the case's problem."""
    if entry.get("time_range_s") is not None and entry.get("rows") is not None:
        problems.append(Problem("rows", "give time_range_s or rows, not both", kind="key"))
        return None, None
    value = entry.get("time_range_s")
    if value is not None:
        pair = [number(v) for v in value] if isinstance(value, list) and len(value) == 2 else None
        if pair is None or None in pair or not 0.0 <= pair[0] < pair[1] <= BOUNDS["duration_s"]:
            problems.append(Problem("time_range_s", f"must be [start, end) in seconds, 0 <= start < end <= "
                                                    f"{BOUNDS['duration_s']:g}, got {value!r}", kind="key"))
            return None, None
        return (pair[0], pair[1]), None
    value = entry.get("rows")
    if value is not None:
        ok = (isinstance(value, list) and len(value) == 2
              and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
              and 0 <= value[0] < value[1] <= MAX_ROW)
        if not ok:
            problems.append(Problem("rows", f"must be [first, stop) of 0-based data rows, integers, 0 <= first < "
                                            f"stop <= {MAX_ROW}, got {value!r}", kind="key"))
            return None, None
        return None, (value[0], value[1])
    return None, None


def _case_gas_force(entry: Mapping) -> tuple[float | None, Problem | None]:
    """A case's own ``gas_force_N`` (1.2; overrides the campaign's): a finite number within
    :data:`MAX_GAS_FORCE_N` (None when absent)."""
    value = entry.get("gas_force_N")
    if value is None:
        return None, None
    out = number(value)
    if out is None:
        return None, Problem("gas_force_N", f"must be a number (N), got {value!r}", kind="key")
    if abs(out) > MAX_GAS_FORCE_N:
        return None, Problem("gas_force_N", f"|{out:g}| N is above the bound {MAX_GAS_FORCE_N:g} N (a unit error?)",
                             kind="key")
    return out, None


def load_manifest(path: str | Path) -> Manifest:
    """Read and check ``campaign.yaml``; raises :class:`ManifestError` for a broken manifest."""
    where = str(path)
    data = read_manifest_bytes(path)
    doc = parse_yaml(data, where)
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
    _bounded(rate, "sample_rate_Hz", where)
    dialect = csv_dialect(doc.get("csv"), where)
    headerless = dialect is not None and dialect.header == "none"
    base_columns, extra_columns = _campaign_columns(doc.get("columns"), where, headerless)
    calibrations = {"force_calibration": force_calibration(doc.get("columns"), where),
                    "displacement_calibration": displacement_calibration(doc.get("columns"), where)}
    damper, extra_damper = _damper(doc.get("damper"), where)
    law = viscosity_law(doc.get("damper"), damper, where)
    entries = doc.get("cases")
    if not isinstance(entries, list) or not entries:
        raise ManifestError(where, "cases", "missing" if entries is None else "must be a non-empty list of cases")
    if len(entries) > MAX_CASES:
        raise ManifestError(where, "cases", f"{len(entries)} cases, more than the {MAX_CASES} a campaign may have")
    cases, seen = [], set()
    for index, entry in enumerate(entries):
        case = _case_id(entry, index, where)
        if case in seen:
            raise ManifestError(where, f"cases[{index}].id", f"duplicate case id {case!r}")
        seen.add(case)
        cases.append(_case(entry, case, rate, base_columns, where, Path(path).parent, headerless))
    gas_force_N = _gas_force(doc, where)
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
        temperature_C=_campaign_temperature(doc, where), sample_rate_Hz=rate,
        gas_force_N=gas_force_N, csv=dialect, viscosity_law=law,
        columns={ch: _column_of(ch, spec, headerless) for ch, spec in base_columns.items()}, damper=damper,
        cases=tuple(replace(c, gas_force_N=gas_force_N if c.case_gas_force_N is None else c.case_gas_force_N,
                            csv=dialect) for c in cases), metadata=metadata,
        sha256=hashlib.sha256(data).hexdigest(), warnings=tuple(_near_misses(doc, where)),
        **calibrations)


def _near_misses(doc: Mapping, where: str) -> list[str]:
    """Warnings for keys that look like slips of known ones: top level, columns, csv, damper, each case."""
    out = near_miss_warnings(where, doc, TOP_KEYS)
    if isinstance(doc.get("columns"), Mapping):
        out += near_miss_warnings(where, doc["columns"], CHANNEL_DIMENSIONS, "columns.")
    if isinstance(doc.get("damper"), Mapping):
        out += near_miss_warnings(where, doc["damper"], {f.name for f in fields(Damper)} | {"viscosity_law"},
                                  "damper.")
    for entry in doc.get("cases") or ():
        if isinstance(entry, Mapping):
            prefix = f"cases.{entry.get('id')}."
            out += near_miss_warnings(where, entry, CASE_KEYS, prefix)
            if isinstance(entry.get("columns"), Mapping):
                out += near_miss_warnings(where, entry["columns"], CHANNEL_DIMENSIONS, prefix + "columns.")
    return out
