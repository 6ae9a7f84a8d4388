"""The method's settings as one frozen record, built from the validated config (issue 36, part 1).

One source: the config (``config/config.yaml``) validated against its schema
(``workflow/schemas/config.schema.yaml``), whose ``default:`` values fill what the config leaves out. Those
defaults are this module's (:data:`DEFAULTS`, the record's own field defaults: what a stage applies when it is
called outside a build; ``tests/contracts/test_settings.py`` checks every one against the schema's, key by key,
:data:`CONFIG_KEYS`). No stage or method signature holds a literal default of a setting: it takes
:data:`DEFAULTS`' value or the setting itself (a test walks the signatures). The workflow builds
:data:`Settings` once (``workflow/rules/common.smk``) and every rule's script, the blind suite, ``trace`` and
``init-campaign`` read the same record (:func:`load_settings`, :func:`project_settings` outside Snakemake), so
that no stage applies its own literal default. Each rule takes as a param the part of the record its stages
read (:func:`rule_settings`): a change reruns that rule's jobs and no other.
"""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:   # annotations only: the settings import nothing heavy (common.smk reads them)
    from isokinetic.physics.plan import CasePlan

#: The config and its schema, relative to a project's root.
CONFIG_FILE = Path("config") / "config.yaml"
SCHEMA_FILE = Path("workflow") / "schemas" / "config.schema.yaml"


@dataclass(frozen=True)
class WindowSpec:
    """Window as fractions of the half-period T/2 (paper: [0.45, 0.95]; config ``windows``)."""

    start_fraction: float = 0.45
    end_fraction: float = 0.95

    def __post_init__(self):
        if not 0.0 <= self.start_fraction < self.end_fraction <= 1.0:
            raise ValueError(f"window fractions must satisfy 0 <= start < end <= 1, got "
                             f"[{self.start_fraction}, {self.end_fraction}]")


@dataclass(frozen=True)
class GapTolerance:
    """How many dropped samples a case may miss (config ``validation``).

    In any analysed span (:func:`isokinetic.stages.validate.gap_spans`) at most ``max_missing_fraction`` of the
    samples (5 %: the window mean then rests on 95 % of its samples, its standard error up by under 3 %), and no
    single gap longer than :meth:`limit_s`: the larger of ``max_gap_s`` (0.1 s) and
    ``max_gap_half_period_fraction`` (2 %) of the half-period. The fraction guards short windows, the
    duration long ones (2 % of T/2 is 4 % of a [0.45, 0.95] window): a longer hole in a steady
    window could hide a transient the window mean would not show.
    """

    max_missing_fraction: float = 0.05
    max_gap_s: float = 0.1
    max_gap_half_period_fraction: float = 0.02

    def __post_init__(self):
        if not 0.0 <= self.max_missing_fraction < 1.0:
            raise ValueError(f"max_missing_fraction must lie in [0, 1), got {self.max_missing_fraction}")
        if not self.max_gap_s > 0.0 or not self.max_gap_half_period_fraction >= 0.0:
            raise ValueError(f"max_gap_s must be > 0 and max_gap_half_period_fraction >= 0, got "
                             f"{self.max_gap_s}, {self.max_gap_half_period_fraction}")

    def limit_s(self, plan: CasePlan) -> float:
        """The longest gap tolerated in an analysed span of this case [s]: max(max_gap_s, fraction·T/2);
        a free record (no period) max_gap_s."""
        half = {"triangle": plan.period_s / 2.0, "sine": 0.5 / plan.frequency_Hz}.get(plan.waveform, math.nan)
        return max(self.max_gap_s, self.max_gap_half_period_fraction * half) if math.isfinite(half) else \
            self.max_gap_s


@dataclass(frozen=True)
class DesignLimits:
    """Test-design limits of the plan check (config ``design``), SI."""

    convergence_fraction: float = 0.999
    max_amplitude_m: float = 10.0e-3
    min_amplitude_m: float = 0.1e-3


@dataclass(frozen=True)
class Settings:
    """Every setting a campaign's chain reads (config keys in brackets).

    window: the steady window as fractions of T/2 [windows]; repeatability_tolerance: period 1 against period 2
    [repeatability.tolerance]; sample_rate_tolerance, gap: what validate accepts [validation]; max_case_file_MB:
    the largest raw case file read [ingest.max_case_file_MB]; design: the plan check's limits, SI [design]."""

    window: WindowSpec = WindowSpec()
    repeatability_tolerance: float = 0.05
    sample_rate_tolerance: float = 0.05
    gap: GapTolerance = GapTolerance()
    max_case_file_MB: float = 256.0
    design: DesignLimits = DesignLimits()

    @classmethod
    def from_config(cls, config: Mapping) -> Settings:
        """The settings of a config already validated with its defaults filled (:func:`with_defaults`;
        Snakemake's ``validate`` fills them too): each setting at its config key, in SI (CONFIG_KEYS)."""
        return settings_from_flat({name: float(config[block][key]) * factor
                                   for name, ((block, key), factor) in CONFIG_KEYS.items()})


#: The settings' defaults: what every stage applies where it is called without settings (outside a build).
DEFAULTS = Settings()


def settings_from_flat(values: Mapping[str, float]) -> Settings:
    """The settings of flat names and values (every name of FLAT; :func:`flat_settings` inverted): what a job's
    params and lineage record keep, back as the record (``trace`` rebuilds with it)."""
    v = {name: float(values[name]) for name in FLAT}
    return Settings(window=WindowSpec(v["start_fraction"], v["end_fraction"]),
                    repeatability_tolerance=v["repeatability_tolerance"],
                    sample_rate_tolerance=v["sample_rate_tolerance"],
                    gap=GapTolerance(v["max_missing_fraction"], v["max_gap_s"]), max_case_file_MB=v["max_case_file_MB"],
                    design=DesignLimits(v["phi"], v["max_amplitude_m"], v["min_amplitude_m"]))


#: The settings each rule's stages read (its params: a change reruns its jobs).
RULE_SETTINGS = {"ingest": ("max_case_file_MB",),
                 "characteristic": ("window", "repeatability_tolerance", "sample_rate_tolerance", "gap"),
                 "analysis": ("window", "design"),
                 "diagnosis": ("window", "design"),   # design: the next tests' limits (Fig. 21, next_tests)
                 "blind_generate": ("window",),
                 "blind_diagnose": ("window", "repeatability_tolerance", "sample_rate_tolerance", "gap",
                                    "max_case_file_MB", "design")}


#: Every setting by the flat name a job's params and lineage record keep (``trace`` reads them): (its field of
#: :class:`Settings`, its value).
FLAT: dict[str, tuple[str, Callable[[Settings], float]]] = {
    "start_fraction": ("window", lambda s: s.window.start_fraction),
    "end_fraction": ("window", lambda s: s.window.end_fraction),
    "repeatability_tolerance": ("repeatability_tolerance", lambda s: s.repeatability_tolerance),
    "sample_rate_tolerance": ("sample_rate_tolerance", lambda s: s.sample_rate_tolerance),
    "max_missing_fraction": ("gap", lambda s: s.gap.max_missing_fraction),
    "max_gap_s": ("gap", lambda s: s.gap.max_gap_s),
    "max_case_file_MB": ("max_case_file_MB", lambda s: s.max_case_file_MB),
    "phi": ("design", lambda s: s.design.convergence_fraction),
    "max_amplitude_m": ("design", lambda s: s.design.max_amplitude_m),
    "min_amplitude_m": ("design", lambda s: s.design.min_amplitude_m)}


#: Every flat setting's config keys (the path to it in ``config/config.yaml``) and the factor from the config's
#: unit to the record's SI one.
CONFIG_KEYS: dict[str, tuple[tuple[str, str], float]] = {
    "start_fraction": (("windows", "start_fraction"), 1.0), "end_fraction": (("windows", "end_fraction"), 1.0),
    "repeatability_tolerance": (("repeatability", "tolerance"), 1.0),
    "sample_rate_tolerance": (("validation", "sample_rate_tolerance"), 1.0),
    "max_missing_fraction": (("validation", "max_missing_fraction"), 1.0),
    "max_gap_s": (("validation", "max_gap_s"), 1.0), "max_case_file_MB": (("ingest", "max_case_file_MB"), 1.0),
    "phi": (("design", "convergence_fraction"), 1.0), "max_amplitude_m": (("design", "max_amplitude_mm"), 1e-3),
    "min_amplitude_m": (("design", "min_amplitude_mm"), 1e-3)}


def flat_settings(settings: Settings) -> dict[str, float]:
    """Every setting as one flat name -> value (FLAT)."""
    return {name: value(settings) for name, (_field, value) in FLAT.items()}


def rule_settings(settings: Settings, rule: str) -> dict[str, float]:
    """The flat settings a rule's stages read (RULE_SETTINGS, FLAT), for its params."""
    return {name: value(settings) for name, (field, value) in FLAT.items() if field in RULE_SETTINGS[rule]}


def with_defaults(config: Mapping, schema: Mapping) -> dict:
    """A copy of ``config`` with every ``default`` of ``schema`` filled where the config leaves it out, as
    Snakemake's ``validate`` fills them; an object the config omits is created where a property below it has a
    default and it requires none (``ingest``: its file-size limit), never where it requires keys (``blind``:
    the block's presence asks for the blind suite)."""
    out = copy.deepcopy(dict(config))
    _fill(out, schema)
    return out


def _fill(node: dict, schema: Mapping) -> None:
    for key, sub in (schema.get("properties") or {}).items():
        if key not in node and "default" in sub:
            node[key] = copy.deepcopy(sub["default"])
        elif sub.get("type") == "object" and (key in node or (_has_defaults(sub) and not sub.get("required"))):
            node.setdefault(key, {})
            if isinstance(node[key], dict):
                _fill(node[key], sub)


def _has_defaults(schema: Mapping) -> bool:
    return any("default" in s or _has_defaults(s) for s in (schema.get("properties") or {}).values())


def load_settings(root: str | Path | None = None, config: str | Path | None = None) -> Settings:
    """The settings of the project at ``root`` (None: the working directory or the nearest folder above it that
    holds ``config/config.yaml`` and ``workflow/schemas/config.schema.yaml``): its config (default
    ``config/config.yaml``) validated against the schema, defaults filled (what a build of it applies). Read
    once per process and config file version."""
    root = Path(root).resolve() if root is not None else project_root()
    path = Path(config).resolve() if config is not None else root / CONFIG_FILE
    stat = path.stat()
    return _load(str(root / SCHEMA_FILE), str(path), stat.st_mtime_ns, stat.st_size)


def project_settings(*starts: str | Path) -> Settings:
    """The settings of the project around the first of ``starts`` inside one (a raw campaign folder, say), else
    around the working directory (:func:`load_settings`); :data:`DEFAULTS` outside any project (what
    ``init-campaign`` applies to a folder checked on its own)."""
    for start in (*starts, "."):
        try:
            return load_settings(project_root(start))
        except FileNotFoundError:
            continue
    return DEFAULTS


def project_root(start: str | Path = ".") -> Path:
    """The nearest folder from ``start`` up that holds a project's config and its schema; FileNotFoundError
    naming what is missing where there is none."""
    here = Path(start).resolve()
    for folder in (here, *here.parents):
        if (folder / CONFIG_FILE).is_file() and (folder / SCHEMA_FILE).is_file():
            return folder
    raise FileNotFoundError(f"no project (a folder with {CONFIG_FILE} and {SCHEMA_FILE}) at {here} or above it: "
                            "pass the settings, or run from the project")


@functools.lru_cache(maxsize=8)
def _load(schema_file: str, config_file: str, _mtime_ns: int, _size: int) -> Settings:
    import jsonschema
    import yaml

    schema = yaml.safe_load(Path(schema_file).read_text(encoding="utf-8"))
    raw = yaml.safe_load(Path(config_file).read_text(encoding="utf-8")) or {}
    filled = with_defaults(raw, schema)
    jsonschema.validate(filled, schema)
    return Settings.from_config(filled)
