"""Audit one number: how it was derived, and the same number re-derived from the raw data.

``python -m isokinetic trace <table> [<selector>]`` prints, as numbered steps, where one row (or
one diagnosis key) of a results table came from - the stage, its parameters, the raw file and
the rows of it that were used - then re-derives the row from the raw evidence with the package's
own stage functions and compares every value with the stored one.

Raw evidence
    A raw campaign (``cases.raw_file`` a path): the manifest named in ``ingest/campaign.json``
    and the case CSVs, re-read with :func:`ingest.ingest_case`. A simulated campaign
    (``raw_file`` = ``virtual_rig:<campaign>/<case>``): the virtual-rig spec, from the lineage
    params of ``ingest/cases.parquet`` when present, else ``virtual_campaigns.<campaign>`` of the
    config; the case is re-simulated and its exported CSV (:func:`virtual_rig.case_csv`) hashed.
    Before anything is recomputed, every raw file used is hashed and compared with the sha256
    recorded in the cases table (and in the traced row's ``raw_sha256`` when it has one); the
    manifest with ``campaign.json``'s ``manifest_sha256``. A difference stops the trace with
    ``RAW FILE CHANGED``: a changed file is never used silently.

Re-derivation
    The raw evidence is re-processed into a scratch folder (deleted afterwards) by the stage
    functions themselves (ingest, validate, windows, repeatability, characteristic, nominal,
    design.plan_check, harmonic, models.fit_models, diagnosis.diagnose, blind.score): only the
    cases the row needs for per-case tables, every case for fits and the diagnosis. Stage
    parameters (window fractions, tolerances, design limits) come from the lineage record of the
    traced file or of the stage's own output when present, else from the config.

Result
    Every column of the row is compared (floats with ``rtol``, default 1e-9; 1e-6 for the
    diagnosis and the blind scores, whose optimiser stops at a relative tolerance of 1e-6; a
    force spread ``*_std_N`` also accepts an absolute difference of rtol·|force_N|, as a
    noise-free model window has a spread of rounding size). The last line of the output is the
    status: ``MATCH`` (exit 0), ``MISMATCH`` (exit 1), ``RAW FILE CHANGED`` or ``MISSING FILE``
    (exit 2), or ``CANNOT TRACE`` (exit 2: unsupported table, bad selector, no spec to
    re-simulate from).

Selectors
    ``col=value,col=value`` must pick exactly one row (``case=T12,segment=3``); ``row=N`` picks
    the N-th row (0-based) of a table without a ``row`` column. For ``diagnosis.json`` the
    selector is a key path (``gap_before``, ``params.coulomb_force_N``, ``where.0.v_min_m_s``,
    ``.`` for every key); without one, ``gap_before``, ``gap_after`` and ``verdict``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from . import lineage as lineage_mod
from .io import sha256_file, write_parquet

MATCH = "MATCH"
MISMATCH = "MISMATCH"
RAW_CHANGED = "RAW FILE CHANGED"
MISSING = "MISSING FILE"
CANNOT = "CANNOT TRACE"
EXIT_CODES = {MATCH: 0, MISMATCH: 1, RAW_CHANGED: 2, MISSING: 2, CANNOT: 2}

#: Relative tolerance of the comparison (closed-form stages) and of fitted/optimised numbers.
RTOL = 1e-9
FIT_RTOL = 1e-6
VIRTUAL_PREFIX = "virtual_rig:"
#: Keys of diagnosis.json that are not re-derivable (wall-clock time, provenance).
NOT_DERIVED_KEYS = ("seconds", "lineage")
DIAGNOSIS_DEFAULT_KEYS = ("gap_before", "gap_after", "verdict")
SHA_SHOWN = 12


class TraceStop(Exception):
    """The trace cannot compare: ``status`` says why (the message says what)."""

    status = CANNOT


class MissingFile(TraceStop):
    status = MISSING


class RawFileChanged(TraceStop):
    status = RAW_CHANGED


class NotReproduced(TraceStop):
    """The re-derivation does not even produce the stored row (a mismatch)."""

    status = MISMATCH


@dataclass
class Comparison:
    """One stored value against its re-derived value."""

    name: str
    stored: object
    recomputed: object
    ok: bool
    unit: str = ""
    rel_diff: float = 0.0
    derived: bool = True    # False: the stage functions do not produce this column (not compared)


@dataclass
class TraceResult:
    status: str
    comparisons: list[Comparison]
    text: str

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.status]


# ----------------------------------------------------------------------------------------------
# output
# ----------------------------------------------------------------------------------------------

class Report:
    """Numbered steps, printed as they happen (a diagnosis re-run takes a while) and kept."""

    def __init__(self, stream=None):
        self.stream = stream
        self.lines: list[str] = []
        self.n = 0

    def line(self, text: str = "") -> None:
        self.lines.append(text)
        if self.stream is not None:
            print(text, file=self.stream, flush=True)

    def step(self, title: str, *details: str) -> None:
        self.n += 1
        self.line(f"{self.n:>2}. {title}")
        for d in details:
            if d:
                self.line(f"      {d}")

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


_UNITS = (("_m3_s_Pa", "m^3/(s Pa)"), ("_m_s", "m/s"), ("_m2", "m^2"), ("_m3", "m^3"), ("_Hz", "Hz"),
          ("_rad", "rad"), ("_Pa_s", "Pa s"), ("_kg_m3", "kg/m^3"), ("_1_Pa", "1/Pa"), ("_N", "N"), ("_s", "s"),
          ("_m", "m"), ("_C", "degC"))


def unit_of(name: str) -> str:
    """SI unit of a column named with its unit suffix (force_N -> N), '' if none."""
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return unit
    return ""


def short(sha: str | None) -> str:
    return (sha[:SHA_SHOWN] + "..") if sha else "(none)"


def fmt(value, unit: str = "") -> str:
    if isinstance(value, (bool, np.bool_)):
        text = str(bool(value))
    elif isinstance(value, (float, np.floating)):
        text = f"{float(value):.10g}"
    elif isinstance(value, (int, np.integer)):
        text = str(int(value))
    elif value is None:
        text = "null"
    elif isinstance(value, str):
        text = repr(value) if value == "" or len(value) > 70 else value
        if len(text) > 72:
            text = text[:69] + "..."
    else:
        text = json.dumps(value, default=str)
        if len(text) > 72:
            text = text[:69] + "..."
    return f"{text} {unit}" if unit and isinstance(value, (float, int, np.floating, np.integer)) \
        and not isinstance(value, (bool, np.bool_)) else text


# ----------------------------------------------------------------------------------------------
# context: project root, config, parameters, scratch folders
# ----------------------------------------------------------------------------------------------

def project_root(table: Path) -> Path:
    """The folder holding ``results/`` above the table (relative paths in tables are relative to
    it: the pipeline runs there), else the working directory."""
    for parent in table.resolve().parents:
        if parent.name == "results":
            return parent.parent
    return Path.cwd()


@dataclass
class Context:
    table: Path
    root: Path
    config_path: Path | None
    report: Report
    scratch: Path
    rtol: float | None = None          # overrides the per-table default
    _config: dict | None = None
    _n_scratch: int = 0

    def config(self) -> dict | None:
        if self._config is None and self.config_path is not None and self.config_path.is_file():
            self._config = yaml.safe_load(self.config_path.read_text(encoding="utf-8")) or {}
        return self._config

    def rel(self, path) -> str:
        p = Path(path)
        try:
            return p.resolve().relative_to(self.root.resolve()).as_posix()
        except ValueError:
            return p.as_posix()

    def resolve(self, recorded: str | os.PathLike) -> Path:
        """A path as recorded by the pipeline (relative to the project root), made usable here."""
        p = Path(recorded)
        if p.is_absolute():
            return p
        for base in (self.root, Path.cwd()):
            if (base / p).exists():
                return base / p
        return self.root / p

    def new_scratch(self, name: str) -> Path:
        self._n_scratch += 1
        return self.scratch / f"{self._n_scratch}" / name


def read_lineage(path: Path) -> dict | None:
    try:
        rec = lineage_mod.read_lineage(path)
    except (OSError, ValueError, json.JSONDecodeError, AttributeError):
        return None
    return rec if isinstance(rec, dict) else None


def param(ctx: Context, keys: Sequence[str], files: Sequence[Path], config_keys: Sequence[str],
          scale: float = 1.0):
    """(value, where it came from) of a stage parameter: lineage params of the first of ``files``
    that records one of ``keys``, else the config (times ``scale``)."""
    for f in files:
        rec = read_lineage(f) if Path(f).is_file() else None
        params = (rec or {}).get("params") or {}
        for k in keys:
            if k in params:
                return params[k], f"lineage params of {ctx.rel(f)}"
    cfg = ctx.config()
    value = cfg
    for k in config_keys:
        value = value.get(k) if isinstance(value, Mapping) else None
    if value is None:
        where = ctx.rel(ctx.config_path) if ctx.config_path else "no config"
        raise TraceStop(f"stage parameter {keys[0]!r}: no lineage record of it and no "
                        f"{'.'.join(config_keys)} in {where}; pass --config")
    return float(value) * scale if scale != 1.0 else value, f"{ctx.rel(ctx.config_path)} {'.'.join(config_keys)}"


def window_spec(ctx: Context, files: Sequence[Path]):
    from .windows import WindowSpec

    a, where_a = param(ctx, ["start_fraction"], files, ["windows", "start_fraction"])
    b, _ = param(ctx, ["end_fraction"], files, ["windows", "end_fraction"])
    return WindowSpec(float(a), float(b)), where_a.removesuffix(".start_fraction")


def show_lineage(ctx: Context, path: Path) -> None:
    rec = read_lineage(path)
    rep = ctx.report
    if rec is None:
        rep.line("lineage: no lineage record in this file (not stamped); provenance is taken from the "
                 "tables' own columns")
        return
    dirty = {True: "dirty", False: "clean"}.get(rec.get("git_dirty"), "dirty: unknown")
    rep.line(f"lineage: rule {rec.get('rule')}, campaign {rec.get('campaign')}, isokinetic "
             f"{rec.get('package_version')}, commit {(rec.get('git_commit') or '?')[:10]} ({dirty}), "
             f"python {rec.get('python')}, written {rec.get('created_utc')}")
    params = json.dumps(rec.get("params") or {}, sort_keys=True, default=str)
    rep.line(f"  params: {params if len(params) <= 160 else params[:157] + '...'}")
    for p, sha in (rec.get("inputs") or {}).items():
        here = ctx.resolve(p)
        if not here.exists():
            state = "missing now"
        else:
            state = "unchanged" if lineage_mod.path_sha256(here) == sha else "CHANGED since (rebuilt or edited)"
        rep.line(f"  input {p}: sha256 {short(sha)} - {state}")


# ----------------------------------------------------------------------------------------------
# selectors
# ----------------------------------------------------------------------------------------------

def parse_selector(text: str | None) -> dict[str, str]:
    """'case=T12,segment=3' -> {'case': 'T12', 'segment': '3'}."""
    if text is None or not text.strip():
        return {}
    out = {}
    for part in text.split(","):
        if not part.strip():
            continue
        if "=" not in part:
            raise TraceStop(f"selector part {part!r} is not column=value (e.g. case=T12,segment=3 or row=5)")
        k, v = part.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _matches(series: pd.Series, value: str) -> pd.Series:
    dtype = series.dtype
    try:
        if pd.api.types.is_bool_dtype(dtype):
            want = value.strip().lower() in ("true", "1", "yes")
            return series.astype(bool) == want
        if pd.api.types.is_integer_dtype(dtype):
            return series == int(value)
        if pd.api.types.is_float_dtype(dtype):
            x = float(value)
            return pd.Series(np.isclose(series.to_numpy(float), x, rtol=1e-12, atol=0.0) |
                             (np.isnan(series.to_numpy(float)) & math.isnan(x)), index=series.index)
    except ValueError:
        raise TraceStop(f"selector value {value!r} does not fit column {series.name!r} ({dtype})") from None
    return series.astype(str) == value


def row_at(df: pd.DataFrame, pos: int) -> pd.Series:
    """Row ``pos`` with each column's own type (``df.iloc[pos]`` would turn ints to floats)."""
    return pd.Series({c: df[c].iloc[pos] for c in df.columns}, dtype=object, name=pos)


def select_row(df: pd.DataFrame, selector: Mapping[str, str]) -> tuple[int, pd.Series]:
    """(position, row) of the one row the selector picks; TraceStop explains otherwise."""
    if not selector:
        if len(df) == 1:
            return 0, row_at(df, 0)
        raise TraceStop(f"the table has {len(df)} rows: give a selector such as "
                        f"{_suggest(df, df.index)} or row=N")
    if "row" in selector and "row" not in df.columns:
        if len(selector) > 1:
            raise TraceStop("row=N selects by position and cannot be combined with other columns")
        try:
            pos = int(selector["row"])
        except ValueError:
            raise TraceStop(f"row={selector['row']!r}: not an integer") from None
        if not 0 <= pos < len(df):
            raise TraceStop(f"row={pos}: the table has rows 0..{len(df) - 1}")
        return pos, row_at(df, pos)
    mask = pd.Series(True, index=df.index)
    for col, value in selector.items():
        if col not in df.columns:
            raise TraceStop(f"no column {col!r}; columns: {', '.join(map(str, df.columns))}")
        mask &= _matches(df[col], value)
    hits = np.flatnonzero(mask.to_numpy())
    if len(hits) == 1:
        return int(hits[0]), row_at(df, int(hits[0]))
    said = ",".join(f"{k}={v}" for k, v in selector.items())
    if not len(hits):
        last = list(selector)[-1]
        values = sorted(map(str, pd.unique(df[last])))[:12]
        raise TraceStop(f"no row matches {said}; values of {last}: {', '.join(values)}")
    raise TraceStop(f"{len(hits)} rows match {said}; narrow it with {_suggest(df.iloc[hits], hits)}")


def _suggest(df: pd.DataFrame, positions) -> str:
    keys = []
    for col in df.columns:
        if pd.api.types.is_float_dtype(df[col].dtype):
            continue
        values = pd.unique(df[col].astype(str))
        if 1 < len(values) <= 8:
            keys.append(f"{col} ({', '.join(sorted(values))})")
        if len(keys) == 3:
            break
    pos = ", ".join(str(int(p)) for p in list(positions)[:8])
    more = "..." if len(positions) > 8 else ""
    return (("one of " + "; ".join(keys) + " or ") if keys else "") + f"row=N (rows {pos}{more})"


def json_get(obj, path: str):
    """Value at a dotted key path ('params.coulomb_force_N', 'where.0.v_min_m_s')."""
    value = obj
    for part in path.split("."):
        if isinstance(value, Mapping) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.lstrip("-").isdigit() and -len(value) <= int(part) < len(value):
            value = value[int(part)]
        else:
            keys = sorted(value) if isinstance(value, Mapping) else f"list of {len(value)}" \
                if isinstance(value, list) else type(value).__name__
            raise TraceStop(f"key path {path!r}: no {part!r} (there: {keys})")
    return value


# ----------------------------------------------------------------------------------------------
# comparison
# ----------------------------------------------------------------------------------------------

def _is_number(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _plain(x):
    if isinstance(x, np.generic):
        return x.item()
    return x


def compare_value(name: str, stored, new, rtol: float, atol: float = 0.0, unit: str = "") -> list[Comparison]:
    """Comparisons of two values (recursing into dicts and lists)."""
    stored, new = _plain(stored), _plain(new)
    if isinstance(stored, Mapping) and isinstance(new, Mapping):
        out = []
        for k in list(stored) + [k for k in new if k not in stored]:
            if k in NOT_DERIVED_KEYS:
                continue
            out += compare_value(f"{name}.{k}" if name else str(k), stored.get(k, "<absent>"), new.get(k, "<absent>"),
                                 rtol)
        return out
    if isinstance(stored, (list, tuple)) and isinstance(new, (list, tuple)) and len(stored) == len(new) and \
            any(isinstance(x, (Mapping, list, tuple)) for x in list(stored) + list(new)):
        out = []
        for i, (a, b) in enumerate(zip(stored, new)):
            out += compare_value(f"{name}.{i}", a, b, rtol)
        return out
    if _is_number(stored) and _is_number(new):
        a, b = float(stored), float(new)
        if math.isnan(a) or math.isnan(b):
            ok = math.isnan(a) and math.isnan(b)
            rel = 0.0 if ok else math.inf
        elif a == b:
            ok, rel = True, 0.0
        else:
            scale = max(abs(a), abs(b))
            rel = abs(a - b) / scale if scale > 0 else math.inf
            ok = abs(a - b) <= rtol * scale or abs(a - b) <= atol
        return [Comparison(name, stored, new, ok, unit, rel)]
    if isinstance(stored, (list, tuple)) or isinstance(new, (list, tuple)):
        both = isinstance(stored, (list, tuple)) and isinstance(new, (list, tuple))
        ok = both and list(stored) == list(new)
        return [Comparison(name, stored, new, ok, unit, 0.0 if ok else math.inf)]
    ok = stored == new or (stored is None and new is None)
    return [Comparison(name, stored, new, bool(ok), unit, 0.0 if ok else math.inf)]


def compare_rows(stored: pd.Series, new: pd.Series, rtol: float, unit_column: str | None = None,
                 primary: Sequence[str] = ()) -> list[Comparison]:
    """Every column of the stored row against the re-derived row. A column the stage functions do
    not produce (a provenance column a pipeline script adds) is listed, not compared, unless it is
    one of the ``primary`` values."""
    out = []
    for col in stored.index:
        if col not in new.index:
            out.append(Comparison(str(col), stored[col], "<absent>", col not in primary, rel_diff=math.inf,
                                  derived=False))
            continue
        unit = unit_of(str(col))
        if unit_column is not None and col in ("estimate", "ci_low", "ci_high", "std_error"):
            unit = str(stored.get(unit_column, ""))
        atol = 0.0
        if str(col).endswith("_std_N") and "force_N" in stored.index and _is_number(stored["force_N"]) \
                and math.isfinite(float(stored["force_N"])):
            atol = rtol * abs(float(stored["force_N"]))
        out += compare_value(str(col), stored[col], new[col], rtol, atol, unit)
    return out


def show_comparisons(ctx: Context, comps: list[Comparison], primary: Sequence[str], rtol: float) -> str:
    rep = ctx.report
    rep.line("")
    rep.line(f"Stored against re-derived (floats: rtol {rtol:g}):")
    shown = [c for c in comps if (c.name in primary or not c.ok) and (c.derived or not c.ok)]
    skipped = [c for c in comps if not c.derived and c.ok]
    shown.sort(key=lambda c: (list(primary).index(c.name) if c.name in primary else len(primary)))
    width = max([len(c.name) for c in shown] + [8])
    for c in shown:
        if c.ok:
            verdict = "identical" if c.rel_diff == 0.0 else f"agree (rel. diff {c.rel_diff:.1e})"
        else:
            verdict = "DIFFER" + (f" (rel. diff {c.rel_diff:.2e})" if math.isfinite(c.rel_diff) else "")
        rep.line(f"  {c.name:<{width}}  stored {fmt(c.stored, c.unit):<24}  re-derived {fmt(c.recomputed, c.unit):<24}"
                 f"  {verdict}")
    rest = [c for c in comps if c not in shown and c not in skipped]
    if skipped:
        rep.line(f"  not produced by the stage functions, not compared: {', '.join(c.name for c in skipped)}")
    if rest:
        names = ", ".join(c.name for c in rest)
        rep.line(f"  {len(rest)} other value(s) agree: {names if len(names) <= 150 else names[:147] + '...'}")
    status = MATCH if comps and all(c.ok for c in comps) else MISMATCH
    if not comps:
        rep.line("  nothing to compare")
    return status


# ----------------------------------------------------------------------------------------------
# raw evidence of a campaign
# ----------------------------------------------------------------------------------------------

@dataclass
class RawSource:
    """Where a processed campaign's numbers came from: a raw folder or a virtual-rig spec."""

    name: str
    kind: str                           # "raw" | "virtual"
    recorded: pd.DataFrame | None       # the processed cases table (recorded hashes), None if unknown
    recorded_path: Path | None
    vc: object = None                   # VirtualCampaign
    spec_where: str = ""
    manifest: object = None             # Manifest
    manifest_path: Path | None = None
    manifest_recorded: str = ""         # manifest_file as the pipeline recorded it
    campaign_dir: Path | None = None
    extra: dict = field(default_factory=dict)

    @property
    def damper(self):
        return self.vc.damper if self.kind == "virtual" else self.manifest.damper

    def case_ids(self) -> list[str]:
        if self.recorded is not None:
            return [str(c) for c in self.recorded["case"]]
        if self.kind == "virtual":
            return [c.case for c in self.vc.cases]
        return [s.id for s in self.manifest.cases]

    def recorded_row(self, case: str) -> pd.Series | None:
        if self.recorded is None:
            return None
        hit = self.recorded[self.recorded["case"].astype(str) == case]
        return None if hit.empty else hit.iloc[0]


def _recorded_cases(root: Path) -> tuple[pd.DataFrame, Path]:
    for p in (root / "cases.parquet", root / "ingest" / "cases.parquet"):
        if p.is_file():
            return pd.read_parquet(p), p
    raise MissingFile(f"{root}: no cases.parquet or ingest/cases.parquet to take the recorded raw files from")


def open_source(ctx: Context, root: Path) -> RawSource:
    """The raw evidence of the processed campaign folder ``root`` (results/<campaign>)."""
    from .manifest import MANIFEST_NAME

    recorded, recorded_path = _recorded_cases(root)
    raw_files = recorded["raw_file"].astype(str)
    if len(recorded) and raw_files.str.startswith(VIRTUAL_PREFIX).all():
        name = raw_files.iloc[0][len(VIRTUAL_PREFIX):].split("/")[0]
        return _virtual_source(ctx, root, name, recorded, recorded_path)
    meta_path = root / "ingest" / "campaign.json"
    meta = json.loads(meta_path.read_text(encoding="utf-8")) if meta_path.is_file() else {}
    manifest_file = meta.get("manifest_file") or ""
    if not manifest_file:
        ing = read_lineage(root / "ingest" / "cases.parquet") or {}
        folder = (ing.get("params") or {}).get("campaign_dir")
        if folder:
            manifest_file = f"{folder}/{MANIFEST_NAME}"
        else:
            with_file = [f for f in raw_files if f]
            if not with_file:
                raise TraceStop(f"{ctx.rel(root)}: no raw file recorded for any case")
            manifest_file = (Path(with_file[0]).parent / MANIFEST_NAME).as_posix()
    return _raw_source(ctx, ctx.resolve(manifest_file), manifest_file, meta.get("manifest_sha256") or "",
                       recorded, recorded_path, where=ctx.rel(meta_path) if meta else "")


def _virtual_source(ctx: Context, root: Path, name: str, recorded, recorded_path) -> RawSource:
    from .virtual_rig import VirtualCampaign

    ing = root / "ingest" / "cases.parquet"
    rec = read_lineage(ing) if ing.is_file() else None
    spec = ((rec or {}).get("params") or {}).get("spec")
    if isinstance(spec, Mapping):
        where = f"lineage params of {ctx.rel(ing)} (rule {rec.get('rule')})"
    else:
        cfg = ctx.config() or {}
        spec = (cfg.get("virtual_campaigns") or {}).get(name)
        if spec is None:
            where = ctx.rel(ctx.config_path) if ctx.config_path else "no config found"
            raise TraceStop(f"campaign {name} was simulated, but {ctx.rel(ing)} has no lineage record and "
                            f"{where} has no virtual_campaigns.{name}: nothing to re-simulate from (pass --config)")
        where = f"{ctx.rel(ctx.config_path)} virtual_campaigns.{name} (no lineage record in {ctx.rel(ing)})"
    vc = VirtualCampaign.from_config(name, spec)
    return RawSource(name=name, kind="virtual", recorded=recorded, recorded_path=recorded_path, vc=vc,
                     spec_where=where)


def _raw_source(ctx: Context, manifest_path: Path, manifest_recorded: str, manifest_sha: str, recorded,
                recorded_path, where: str = "") -> RawSource:
    from .manifest import load_manifest

    if not manifest_path.is_file():
        raise MissingFile(f"manifest {manifest_recorded or manifest_path} not found (looked in {ctx.root})")
    sha = sha256_file(manifest_path)
    if manifest_sha and sha != manifest_sha:
        raise RawFileChanged(f"manifest {ctx.rel(manifest_path)}: sha256 is now {short(sha)}, recorded "
                             f"{short(manifest_sha)} in {where or 'campaign.json'}: it changed after processing")
    manifest = load_manifest(manifest_path)
    src = RawSource(name=manifest.campaign, kind="raw", recorded=recorded, recorded_path=recorded_path,
                    manifest=manifest, manifest_path=manifest_path, manifest_recorded=manifest_recorded or
                    manifest_path.as_posix(), campaign_dir=manifest_path.parent)
    src.extra["manifest_sha"] = sha
    src.extra["manifest_sha_recorded"] = manifest_sha
    return src


def describe_source(ctx: Context, src: RawSource) -> None:
    if src.kind == "virtual":
        vc = src.vc
        effects = ", ".join(vc.effects.active()) or "none"
        ctx.report.step(f"Raw source: simulated campaign {src.name!r} (virtual rig)",
                        f"spec from {src.spec_where}",
                        f"seed {vc.seed}, {len(vc.cases)} planned cases, hidden effects: {effects}; "
                        f"noise: force {vc.measurement.force_noise_N:g} N + {vc.measurement.force_noise_rel:g}|F|, "
                        f"LVDT {vc.measurement.displacement_noise_m:g} m",
                        "raw_sha256 of a simulated case = sha256 of its exported CSV (virtual_rig.case_csv)")
    else:
        rec = src.extra.get("manifest_sha_recorded")
        check = (f"= recorded {short(rec)} (campaign.json) - unchanged" if rec else "(no recorded hash to check)")
        ctx.report.step(f"Raw source: campaign folder {ctx.rel(src.campaign_dir)}",
                        f"manifest {ctx.rel(src.manifest_path)}: sha256 {short(src.extra['manifest_sha'])} {check}",
                        f"campaign {src.name!r}, {len(src.manifest.cases)} cases in the manifest")


def rebuild(ctx: Context, src: RawSource, cases: Sequence[str] | None = None,
            expected: Mapping[str, str] | None = None, validate: bool = True,
            sample_rate_tolerance: float | None = None) -> Path:
    """Re-process ``cases`` (default: every recorded case) from the raw evidence into a scratch
    campaign folder (ingest/ and, with ``validate``, cases.parquet); raw hashes checked first."""
    from .campaign import write_ingested
    from .ingest import campaign_meta, ingest_case
    from .validate import quarantine_frame, quarantine_rows, write_validated

    wanted = list(cases) if cases is not None else src.case_ids()
    scratch = ctx.new_scratch(src.name)
    if src.kind == "virtual":
        from .virtual_rig import write_campaign

        known = {c.case: c for c in src.vc.cases}
        missing = [c for c in wanted if c not in known]
        if missing:
            raise RawFileChanged(f"case(s) {', '.join(missing)} are not in the virtual-rig spec ({src.spec_where}): "
                                 "the spec changed after processing")
        write_campaign(dataclasses.replace(src.vc, cases=tuple(known[c] for c in wanted)), scratch)
    else:
        specs = {s.id: s for s in src.manifest.cases}
        rows, quarantined, series = [], [], {}
        for case in wanted:
            spec = specs.get(case)
            if spec is None:
                raise RawFileChanged(f"case {case} is no longer in {ctx.rel(src.manifest_path)}")
            row, problems, df = ingest_case(src.campaign_dir, src.manifest.campaign, spec)
            rec = src.recorded_row(case)
            if rec is not None and rec["raw_file"] and row["raw_file"] and \
                    ctx.resolve(str(rec["raw_file"])).resolve() == Path(row["raw_file"]).resolve():
                row["raw_file"] = str(rec["raw_file"])  # the same file, named as the pipeline named it
            rows.append(row)
            quarantined += quarantine_rows(src.manifest.campaign, case, "ingest", problems)
            if df is not None:
                series[case] = df
        write_ingested(scratch / "ingest", campaign_meta(src.manifest, src.manifest_recorded), pd.DataFrame(rows),
                       quarantine_frame(quarantined), series)
    check_hashes(ctx, src, pd.read_parquet(scratch / "ingest" / "cases.parquet"), expected or {})
    if validate:
        tol = 0.05 if sample_rate_tolerance is None else sample_rate_tolerance
        write_validated(scratch, sample_rate_tolerance=tol)
    return scratch


def check_hashes(ctx: Context, src: RawSource, new_cases: pd.DataFrame, expected: Mapping[str, str]) -> None:
    """Every re-derived raw hash against the recorded ones; RawFileChanged / MissingFile on a difference."""
    lines, changed, files = [], [], []
    for row in new_cases.itertuples(index=False):
        case, sha = str(row.case), str(row.raw_sha256)
        label = str(row.raw_file) if src.kind == "raw" else f"{VIRTUAL_PREFIX}{src.name}/{case} (re-simulated CSV)"
        records = []
        rec = src.recorded_row(case)
        if rec is not None:
            records.append((str(rec["raw_sha256"]), ctx.rel(src.recorded_path)))
        if case in expected:
            records.append((str(expected[case]), f"the traced row ({ctx.rel(ctx.table)})"))
        if src.kind == "raw" and not sha and any(r for r, _ in records):
            raise MissingFile(f"case {case}: raw file {label} not found (recorded sha256 "
                              f"{short(records[0][0])} in {records[0][1]})")
        for want, where in records:
            if want != sha:
                changed.append(f"case {case}: {label} has sha256 {short(sha)} now, {short(want)} recorded in {where}")
                if label not in files:
                    files.append(label)
        if records:
            lines.append(f"{case}: {label}  sha256 {short(sha)} = recorded ({', '.join(w for _, w in records)})")
        else:
            lines.append(f"{case}: {label}  sha256 {short(sha)} (nothing recorded to check against)")
    verb = "Re-read" if src.kind == "raw" else "Re-simulated"
    if changed:
        ctx.report.step(f"{verb} {len(new_cases)} case(s): raw sha256 DIFFERS from the record", *changed)
        if src.kind == "raw":
            what = f"{', '.join(files)} changed after processing"
        else:
            what = (f"the re-simulated CSV of {', '.join(files)} differs from the recorded one: the virtual-rig spec "
                    f"({src.spec_where}) or the simulator changed after processing")
        raise RawFileChanged(f"{what}; nothing was recomputed from the changed data")
    if len(lines) > 3:
        lines = lines[:2] + [f"... {len(lines) - 2} more case file(s), every hash equal to the recorded one"]
    ctx.report.step(f"{verb} {len(new_cases)} case(s) and checked their raw sha256", *lines)


# ----------------------------------------------------------------------------------------------
# raw text lines (for the audit trail)
# ----------------------------------------------------------------------------------------------

class RawText:
    """The raw CSV text of a case (the file, or the exported CSV of a simulated case)."""

    def __init__(self, ctx: Context, src: RawSource, scratch: Path, case: str):
        if src.kind == "virtual":
            from .virtual_rig import case_csv

            series = pd.read_parquet(scratch / "ingest" / "timeseries" / f"{case}.parquet")
            self.lines = case_csv(series, src.vc.measurement).splitlines()
            self.label = f"exported CSV of {VIRTUAL_PREFIX}{src.name}/{case}"
        else:
            cases = pd.read_parquet(scratch / "ingest" / "cases.parquet").set_index("case")
            path = ctx.resolve(str(cases.loc[case, "raw_file"]))
            self.lines = path.read_text(encoding="utf-8-sig").splitlines()
            self.label = ctx.rel(path)
        self.header = 0
        while self.header < len(self.lines) and (not self.lines[self.header].strip()
                                                 or self.lines[self.header].startswith("#")):
            self.header += 1

    def line(self, row: int) -> str:
        i = self.header + 1 + int(row)
        text = self.lines[i] if i < len(self.lines) else "(beyond the end)"
        return f"line {i + 1}: {text}"

    def header_text(self) -> str:
        return f"line {self.header + 1}: {self.lines[self.header] if self.header < len(self.lines) else ''}"


def column_mapping(src: RawSource, case: str) -> list[str]:
    """How each CSV column becomes a canonical SI column."""
    from .ingest import CANONICAL
    from .manifest import UNITS

    if src.kind == "virtual":
        from .virtual_rig import RAW_COLUMNS

        lines = [f"{name} [{unit}] x {factor:g} -> {CANONICAL[ch]}" for ch, (name, unit, factor) in RAW_COLUMNS.items()]
        return lines + ["(the pipeline used the simulated SI series; the CSV holds the same quantised values)"]
    spec = next(s for s in src.manifest.cases if s.id == case)
    out = []
    for ch, col in spec.columns.items():
        factor = UNITS[ch][col.unit]
        how = "ISO 8601 -> seconds from the first sample" if factor is None else f"x {factor:g}"
        out.append(f"{col.name} [{col.unit}] {how}{' x (-1) (invert)' if col.invert else ''} -> {CANONICAL[ch]}")
    return out


# ----------------------------------------------------------------------------------------------
# table kinds
# ----------------------------------------------------------------------------------------------

TABLE_KINDS = {
    "cases": "validated cases (raw file, hash, status)",
    "ingest_cases": "ingested cases (raw file, hash)",
    "timeseries": "canonical SI time series of one case",
    "windows": "steady window of one half-period",
    "characteristic": "steady characteristic point",
    "repeatability": "period 2 against period 1",
    "nominal": "nominal model through the plan",
    "plan_check": "test-design plan check",
    "models": "fitted model parameter",
    "residuals": "fitted model residual",
    "harmonic": "harmonic / free-record point",
    "diagnosis": "sim-to-real gap diagnosis",
    "scores": "blind-test score",
}

PRIMARY = {
    "cases": ["raw_sha256", "n_samples", "status", "motion_start_s", "delay_s"],
    "ingest_cases": ["raw_sha256", "n_samples", "status"],
    "timeseries": ["time_s", "displacement_m", "force_N", "command_m"],
    "windows": ["force_N", "force_std_N", "velocity_m_s", "n_samples"],
    "characteristic": ["force_N", "force_std_N", "velocity_m_s", "n_samples", "repeatability_flagged"],
    "repeatability": ["rel_diff", "force_period1_N", "force_period2_N", "velocity_m_s", "flagged"],
    "nominal": ["force_N", "force_std_N", "velocity_m_s"],
    "plan_check": ["G1", "G2", "G3", "stroke_to_converge_m", "window_start_stroke_m", "flagged", "reasons"],
    "models": ["estimate", "ci_low", "ci_high", "std_error"],
    "residuals": ["predicted_N", "residual_N", "normalized_residual"],
    "harmonic": ["velocity_m_s", "force_N", "lag_s"],
    "scores": ["verdict", "exact", "gap_before", "gap_after", "shrink"],
}

#: Columns that identify a row of a re-derived table (plus the ordinal within them for harmonic).
KEYS = {
    "cases": ["case"], "ingest_cases": ["case"], "timeseries": ["row"],
    "windows": ["case", "segment"], "characteristic": ["case", "segment"], "nominal": ["case", "segment"],
    "repeatability": ["case", "direction"], "plan_check": ["case"],
    "models": ["model", "direction", "parameter"], "residuals": ["model", "case", "segment"],
    "harmonic": ["case", "kind", "direction"], "scores": ["scenario"],
}


def table_kind(path: Path) -> str:
    name, parent = path.name, path.parent.name
    if parent == "timeseries" and path.suffix == ".parquet":
        return "timeseries"
    kinds = {"cases.parquet": "ingest_cases" if parent == "ingest" else "cases", "windows.parquet": "windows",
             "characteristic.parquet": "characteristic", "repeatability.parquet": "repeatability",
             "nominal_windows.parquet": "nominal", "plan_check.parquet": "plan_check",
             "models.parquet": "models", "model_residuals.parquet": "residuals", "harmonic.parquet": "harmonic",
             "diagnosis.json": "diagnosis", "scores.parquet": "scores"}
    if name not in kinds:
        raise TraceStop(f"{path}: not a table trace knows; it traces {', '.join(sorted(kinds))} and "
                        "ingest/timeseries/<case>.parquet")
    return kinds[name]


def campaign_root(path: Path, kind: str) -> Path:
    """results/<campaign> of a table of that kind."""
    if kind == "timeseries":
        return path.parent.parent.parent
    if kind in ("ingest_cases", "models", "residuals", "harmonic", "plan_check"):
        return path.parent.parent
    return path.parent


def match_row(new: pd.DataFrame, stored_df: pd.DataFrame, pos: int, kind: str, what: str) -> pd.Series:
    """The row of a re-derived table with the stored row's keys (ordinal within them for harmonic)."""
    keys = KEYS[kind]
    stored = row_at(stored_df, pos)
    mask = pd.Series(True, index=new.index)
    for k in keys:
        mask &= new[k].astype(str) == str(stored[k])
    hits = new[mask]
    if kind == "harmonic":
        same = (stored_df[keys].astype(str) == stored[keys].astype(str)).all(axis=1).to_numpy()
        ordinal = int(same[:pos].sum())
        hits = hits.iloc[ordinal:ordinal + 1]
    if len(hits) != 1:
        said = ", ".join(f"{k}={stored[k]}" for k in keys)
        raise NotReproduced(f"the re-derived {what} has {len(hits)} row(s) for {said} (stored: 1)")
    return row_at(hits, 0)


# ----------------------------------------------------------------------------------------------
# handlers: each prints its steps and returns (comparisons, primary names, rtol)
# ----------------------------------------------------------------------------------------------

def _stored_step(ctx: Context, kind: str, df: pd.DataFrame, pos: int, row: pd.Series) -> None:
    keys = [k for k in ["campaign", *KEYS.get(kind, [])] if k in row.index]
    ident = ", ".join(f"{k} {row[k]}" for k in keys)
    def unit(c):
        return str(row["unit"]) if c in ("estimate", "ci_low", "ci_high", "std_error") and "unit" in row else unit_of(c)

    vals = ", ".join(f"{c} = {fmt(row[c], unit(c))}" for c in PRIMARY.get(kind, []) if c in row.index)
    ctx.report.step(f"Stored: row {pos} (0-based) of {len(df)} in {ctx.rel(ctx.table)} ({TABLE_KINDS[kind]}): {ident}",
                    vals)


def _rep_tolerance(ctx: Context, root: Path, files: Sequence[Path]) -> tuple[float, str]:
    tol, where = param(ctx, ["tolerance", "repeatability_tolerance"], [*files, root / "repeatability.parquet"],
                       ["repeatability", "tolerance"])
    return float(tol), where


def _rate_tolerance(ctx: Context, root: Path, files: Sequence[Path]) -> float:
    tol, _ = param(ctx, ["sample_rate_tolerance"], [root / "cases.parquet", *files],
                   ["validation", "sample_rate_tolerance"])
    return float(tol)


def _series_step(ctx: Context, src: RawSource, scratch: Path, case: str) -> pd.DataFrame:
    series = pd.read_parquet(scratch / "ingest" / "timeseries" / f"{case}.parquet")
    cases = pd.read_parquet(scratch / "cases.parquet").set_index("case")
    status = cases.loc[case, "status"]
    if status != "ok":
        q = pd.read_parquet(scratch / "quarantine.parquet")
        reasons = "; ".join(q[q["case"] == case]["reason"]) or "?"
        ctx.report.step(f"Validation (validate.case_problems): case {case} is quarantined now: {reasons}")
    raw = RawText(ctx, src, scratch, case)
    how = "ingest.ingest_case" if src.kind == "raw" else "virtual_rig.simulate_cases"
    ctx.report.step(f"Canonical SI series of {case} ({how}; validation: status {status}): {len(series)} samples, "
                    f"t = {series['time_s'].iloc[0]:g} .. "
                    f"{series['time_s'].iloc[-1]:g} s",
                    *column_mapping(src, case), f"{raw.label} {raw.header_text()}")
    return series


def _window_steps(ctx: Context, src: RawSource, scratch: Path, row: pd.Series, spec, spec_where: str,
                  series: pd.DataFrame) -> None:
    from .campaign import case_plan
    from .windows import motion_start_of, windowed_half_periods

    cases = pd.read_parquet(scratch / "cases.parquet").set_index("case", drop=False)
    case_row = cases.loc[str(row["case"])]
    plan = case_plan(case_row)
    start = motion_start_of(case_row)
    k = int(row["segment"])
    t = series["time_s"].to_numpy()
    segs = windowed_half_periods(plan, float(t[-1]), spec, start)
    half = plan.period_s / 2.0
    raw = RawText(ctx, src, scratch, str(row["case"]))
    delay = case_row.get("delay_s", math.nan)
    delay_text = f", delay {float(delay) * 1e3:.4g} ms after the first sample" if pd.notna(delay) else ""
    motion = (f"motion start (validate, motion.estimate_motion from the displacement): plan t = 0 at record "
              f"t = {start:.6g} s{delay_text}; windows at motion start + plan times")
    if len(segs) >= k:
        t0, t1, sign = segs[k - 1]
        geometry = (f"half-period {k}: t = {t0:g} .. {t1:g} s, direction {'+' if sign > 0 else '-'} "
                    f"(triangle T = {plan.period_s:g} s, Y = {plan.amplitude_m:g} m, phase {plan.phase_rad:.6g} rad, "
                    f"planned |v| = 4Y/T = {plan.velocity_m_s:.6g} m/s)")
        window = (f"window [{spec.start_fraction:g}, {spec.end_fraction:g}] x T/2 = "
                  f"{t0 + spec.start_fraction * half:g} .. {t0 + spec.end_fraction * half:g} s "
                  f"(fractions from {spec_where})")
    else:
        geometry, window = f"half-period {k}: not in the re-derived record", ""
    ctx.report.step("Window selection (windows.window_ranges)", motion, geometry, window,
                    f"stored rows [{int(row['row_start'])}, {int(row['row_stop'])}), t = {row['window_start_s']:g} .. "
                    f"{row['window_end_s']:g} s, n = {int(row['n_samples'])}",
                    f"first sample, {raw.label} {raw.line(int(row['row_start']))}",
                    f"last sample,  {raw.label} {raw.line(int(row['row_stop']) - 1)}")


def _stats_step(ctx: Context, new: pd.Series) -> None:
    ctx.report.step("Window statistics (windows.case_windows) on the re-derived samples",
                    f"force_N     = mean of force_N over the {int(new['n_samples'])} samples = {new['force_N']:.10g} N",
                    f"force_std_N = standard deviation (ddof = 1) = {new['force_std_N']:.10g} N",
                    "velocity_m_s = least-squares slope of displacement_m against time_s = "
                    f"{new['velocity_m_s']:.10g} m/s",
                    f"window t = {new['window_start_s']:g} .. {new['window_end_s']:g} s, rows "
                    f"[{int(new['row_start'])}, {int(new['row_stop'])})")


def handle_windows(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .characteristic import assemble
    from .repeatability import repeatability
    from .windows import windows_stage

    root = campaign_root(path, kind)
    case = str(row["case"])
    ctx.report.step(f"Provenance in the row: raw file {row['raw_file']}, sha256 {short(row['raw_sha256'])}, "
                    f"rows [{int(row['row_start'])}, {int(row['row_stop'])}) (t = {row['window_start_s']:g} .. "
                    f"{row['window_end_s']:g} s)")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    spec, spec_where = window_spec(ctx, [path, root / "windows.parquet"])
    tol, tol_where = _rep_tolerance(ctx, root, [path])
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], expected={case: str(row["raw_sha256"])}, sample_rate_tolerance=srt)
    series = _series_step(ctx, src, scratch, case)
    _window_steps(ctx, src, scratch, row, spec, spec_where, series)
    win = windows_stage(scratch, spec)
    new = match_row(win, df, pos, "windows", "windows of the case")
    _stats_step(ctx, new)
    if kind == "characteristic":
        rep = repeatability(win, tol)
        char = assemble(win, rep)
        new = match_row(char, df, pos, kind, "characteristic of the case")
        r = rep[rep["direction"] == new["direction"]].iloc[0]
        ctx.report.step(f"Repeatability flag (repeatability.repeatability, tolerance {tol:g} from {tol_where})",
                        f"case {case}, direction {new['direction']}: rel_diff = (F2 - F1)/mean(|F1|, |F2|) = "
                        f"{r['rel_diff']:.6g} -> repeatability_flagged = {bool(new['repeatability_flagged'])}")
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def handle_repeatability(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .repeatability import relative_difference, repeatability
    from .windows import windows_stage

    root = campaign_root(path, kind)
    case, direction = str(row["case"]), str(row["direction"])
    ctx.report.step(f"Derivation: rel_diff = (F2 - F1) / mean(|F1|, |F2|) of the windows of case {case}, direction "
                    f"{direction}, period 1 (F1) and period 2 (F2), from {ctx.rel(root / 'windows.parquet')}")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    spec, spec_where = window_spec(ctx, [root / "windows.parquet"])
    tol, tol_where = _rep_tolerance(ctx, root, [path])
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], sample_rate_tolerance=srt)
    series = _series_step(ctx, src, scratch, case)
    win = windows_stage(scratch, spec)
    mine = win[win["direction"] == direction].sort_values("period")
    for _, w in mine.iterrows():
        _window_steps(ctx, src, scratch, w, spec, spec_where, series)
        ctx.report.step(f"Period {int(w['period'])} window (windows.case_windows): force_N = {w['force_N']:.10g} N "
                        f"over {int(w['n_samples'])} samples, velocity_m_s = {w['velocity_m_s']:.10g} m/s")
    f1, f2 = float(mine.iloc[0]["force_N"]), float(mine.iloc[-1]["force_N"])
    rel = float(relative_difference(f1, f2))
    ctx.report.step(f"repeatability.relative_difference: ({f2:.10g} - {f1:.10g}) / mean(|{f1:.10g}|, |{f2:.10g}|) = "
                    f"{rel:.10g}", f"flagged = |rel_diff| > {tol:g} (tolerance from {tol_where}) = {abs(rel) > tol}")
    new = match_row(repeatability(win, tol), df, pos, kind, "repeatability of the case")
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def plan_text(c: Mapping) -> str:
    """A case plan in words (cases-table row)."""
    wf = str(c["waveform"])
    rate = f"{float(c['sample_rate_Hz']):g} Hz"
    record = f", record {float(c['duration_s']):g} s" if pd.notna(c.get("duration_s")) else ""
    if wf == "triangle":
        period, amp = float(c["period_s"]), float(c["amplitude_m"])
        return (f"triangle T = {period:g} s, Y = {amp:g} m (|v| = 4Y/T = {4 * amp / period:.6g} m/s), "
                f"phase {float(c['phase_rad']):.6g} rad, {rate}{record}")
    if wf == "sine":
        return f"sine f = {float(c['frequency_Hz']):g} Hz, Y = {float(c['amplitude_m']):g} m, {rate}{record}"
    return f"{wf}, {rate}{record}"


def _damper_step(ctx: Context, src: RawSource) -> None:
    d = src.damper
    where = (f"damper block of {ctx.rel(src.manifest_path)}" if src.kind == "raw" else
             f"damper of the virtual-rig spec ({src.spec_where})")
    if d is None:
        ctx.report.step(f"Damper data: none ({where} missing)")
        return
    ctx.report.step(f"Nominal damper data from the {where}",
                    f"A_p = {d.piston_area_m2:g} m^2, V1 = {d.chamber_volume_1_m3:g} m^3, "
                    f"V2 = {d.chamber_volume_2_m3:g} m^3, A_O = {d.orifice_area_m2:g} m^2, "
                    f"l_O = {d.orifice_length_m:g} m, C_D = {d.discharge_coefficient:g}, "
                    f"rho = {d.density_kg_m3:g} kg/m^3, mu = {d.viscosity_Pa_s:g} Pa s, "
                    f"beta = {d.oil_compressibility_1_Pa:g} 1/Pa")


def handle_nominal(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .nominal import nominal_stage

    root = campaign_root(path, kind)
    case = str(row["case"])
    ctx.report.step(f"Derivation: the noise-free nominal model (no added effects) simulated through case {case}'s "
                    f"plan and reduced over the same window (nominal.nominal_stage -> nominal.model_windows)")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    _damper_step(ctx, src)
    spec, spec_where = window_spec(ctx, [path])
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], sample_rate_tolerance=srt)
    cases = pd.read_parquet(scratch / "cases.parquet").set_index("case")
    c = cases.loc[case]
    ctx.report.step(f"Case plan of {case} (from the raw manifest / spec; status after validation {c['status']})",
                    plan_text(c),
                    f"window fractions [{spec.start_fraction:g}, {spec.end_fraction:g}] from {spec_where}")
    from .io import write_parquet
    from .windows import windows_stage

    measured = windows_stage(scratch, spec)
    write_parquet(measured, scratch / "windows.parquet")
    speeds = ", ".join(f"{abs(v) * 1e3:.6g}" for v in measured.sort_values("segment")["velocity_m_s"])
    ctx.report.step(f"Measured kinematics that drive the model (windows of {case}, re-derived)",
                    f"half-period speeds [mm/s]: {speeds}; motion start {c.get('motion_start_s', 0.0):g} s "
                    "(the model runs each half-period at its measured speed, nominal.case_drives)")
    new = match_row(nominal_stage(scratch, spec), df, pos, kind, "nominal model windows of the case")
    ctx.report.step(f"Model window {int(new['segment'])} (direction {new['direction']}): rows "
                    f"[{int(new['row_start'])}, {int(new['row_stop'])}) of the model's sample grid k/fs, "
                    f"t = {new['window_start_s']:g} .. {new['window_end_s']:g} s",
                    f"force_N = mean of A_p dp (Eq. 8; the nominal model has no friction) = {new['force_N']:.10g} N, "
                    f"velocity_m_s = slope of the actuator displacement = {new['velocity_m_s']:.10g} m/s")
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def handle_plan_check(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .design import plan_check

    root = campaign_root(path, kind)
    own = root / "design" / "plan_check.parquet"
    if not (root / "ingest").is_dir():  # the all-campaigns summary results/design/plan_check.parquet
        root = path.parent.parent / str(row["campaign"])
        own = root / "design" / "plan_check.parquet"
        ctx.report.step(f"Summary row: copied by rule design_summary from {ctx.rel(own)} (campaign {row['campaign']})")
        if not root.is_dir():
            raise MissingFile(f"campaign folder {ctx.rel(root)} of this summary row not found")
    case = str(row["case"])
    src = open_source(ctx, root)
    describe_source(ctx, src)
    _damper_step(ctx, src)
    files = [path, own]
    phi, phi_where = param(ctx, ["phi"], files, ["design", "convergence_fraction"])
    max_a, _ = param(ctx, ["max_amplitude_m"], files, ["design", "max_amplitude_mm"], scale=1e-3)
    min_a, _ = param(ctx, ["min_amplitude_m"], files, ["design", "min_amplitude_mm"], scale=1e-3)
    start, start_where = param(ctx, ["start_fraction"], files, ["windows", "start_fraction"])
    srt = _rate_tolerance(ctx, root, files)
    scratch = rebuild(ctx, src, [case], sample_rate_tolerance=srt)
    cases = pd.read_parquet(scratch / "cases.parquet")
    c = cases.set_index("case").loc[case]
    ctx.report.step(f"Planned case {case} from the raw manifest / spec (status after validation {c['status']})",
                    plan_text(c),
                    f"design limits: phi = {phi:g} ({phi_where}), max amplitude {max_a:g} m, "
                    f"min amplitude {min_a:g} m, window start fraction {start:g} ({start_where})")
    name = str(pd.read_parquet(scratch / "cases.parquet")["campaign"].iloc[0])
    new_df = plan_check(name, cases[cases["case"] == case], src.damper, phi=float(phi), max_amplitude_m=float(max_a),
                        min_amplitude_m=float(min_a), start_fraction=float(start))
    new = match_row(new_df, df, pos, kind, "plan check of the case")
    g = f"G1 = {new['G1']:.6g}, G2 = {new['G2']:.6g}, G3 = {new['G3']:.6g} (Eq. 19-22)"
    if new["waveform"] == "triangle":
        detail = [f"W = 4Y/T = {new['velocity_m_s']:.6g} m/s; {g}",
                  f"stroke to converge (mixed flow, Eq. 28) = {new['stroke_to_converge_m']:.6g} m; the window starts "
                  f"after {new['window_start_stroke_m']:.6g} m of stroke"]
    elif new["waveform"] == "sine":
        detail = [f"peak velocity 2 pi f Y = {new['velocity_m_s']:.6g} m/s; {g}; travel and noise floor checked only"]
    else:
        detail = ["free waveform: nothing planned to check"]
    ctx.report.step("design.plan_check", *detail,
                    f"flagged = {bool(new['flagged'])}; reasons: {new['reasons'] or '(none)'}")
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def handle_harmonic(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .harmonic import harmonic_stage

    root = campaign_root(path, kind)
    case = str(row["case"])
    ctx.report.step(f"Derivation: {row['kind']} point of {row['waveform']} case {case}: velocity from a Savitzky-Golay "
                    f"derivative of the displacement (window {row['window_s']:g} s), settled loop, extremes per "
                    "direction (harmonic.harmonic_stage)")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], sample_rate_tolerance=srt)
    _series_step(ctx, src, scratch, case)
    table, loops = harmonic_stage(scratch)
    new = match_row(table, df, pos, kind, "harmonic table of the case")
    lp = loops.get(case)
    if "row_start" in new.index and int(new["row_start"]) >= 0:
        raw = RawText(ctx, src, scratch, case)
        ctx.report.step(f"Samples used: rows [{int(new['row_start'])}, {int(new['row_stop'])}) of the raw record",
                        f"first sample, {raw.label} {raw.line(int(new['row_start']))}",
                        f"last sample,  {raw.label} {raw.line(int(new['row_stop']) - 1)}")
    ctx.report.step(f"harmonic.harmonic_stage on the re-derived series: loop of {0 if lp is None else len(lp)} "
                    f"samples, f = {new['frequency_Hz']:g} Hz, derivative window {new['window_s']:g} s",
                    f"direction {new['direction']}: velocity_m_s = {new['velocity_m_s']:.10g} m/s, force_N = "
                    f"{new['force_N']:.10g} N, lag_s = {new['lag_s']:.6g} s over {int(new['n_points'])} half-cycles")
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def _characteristic_chain(ctx: Context, src: RawSource, root: Path, files: Sequence[Path]) -> tuple[Path, object]:
    """Every case re-derived, windows -> repeatability -> characteristic written in the scratch folder."""
    from .characteristic import assemble
    from .repeatability import repeatability
    from .windows import windows_stage

    spec, spec_where = window_spec(ctx, [*files, root / "windows.parquet"])
    tol, tol_where = _rep_tolerance(ctx, root, files)
    srt = _rate_tolerance(ctx, root, files)
    scratch = rebuild(ctx, src, sample_rate_tolerance=srt)
    cases = pd.read_parquet(scratch / "cases.parquet")
    win = windows_stage(scratch, spec)
    rep = repeatability(win, tol)
    char = assemble(win, rep)
    write_parquet(win, scratch / "windows.parquet")
    write_parquet(rep, scratch / "repeatability.parquet")
    write_parquet(char, scratch / "characteristic.parquet")
    n_ok = int((cases["status"] == "ok").sum())
    ctx.report.step(f"Characteristic re-derived from the raw data: {n_ok} of {len(cases)} cases ok after validation, "
                    f"{len(win)} windows (fractions [{spec.start_fraction:g}, {spec.end_fraction:g}] from "
                    f"{spec_where}), repeatability tolerance {tol:g} ({tol_where})",
                    "stages: ingest -> validate -> windows.windows_stage -> repeatability.repeatability -> "
                    "characteristic.assemble")
    return scratch, spec


def handle_models(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .models import fit_models

    root = campaign_root(path, kind)
    if kind == "models":
        what = (f"{row['model']} model, direction {row['direction']}, parameter {row['parameter']} "
                f"({row['kind']}{', from ' + str(row['derived_from']) if row.get('derived_from') else ''})")
    else:
        what = f"{row['model']} model residual at case {row['case']}, segment {row['segment']}"
    ctx.report.step(f"Derivation: {what}: weighted least squares (weights 1/(window standard error)^2) over "
                    f"the whole characteristic {ctx.rel(root / 'characteristic.parquet')} (models.fit_models)")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    _damper_step(ctx, src)
    scratch, _spec = _characteristic_chain(ctx, src, root, [path])
    char = pd.read_parquet(scratch / "characteristic.parquet")
    models_df, residuals = fit_models(char, src.damper)
    new = match_row(models_df if kind == "models" else residuals, df, pos, kind, f"{kind} table")
    if kind == "models":
        ctx.report.step(f"models.fit_models on {len(char)} points: {new['parameter']} = {new['estimate']:.10g} "
                        f"{new['unit']} (95 % interval {new['ci_low']:.6g} .. {new['ci_high']:.6g}), "
                        f"{int(new['n_points'])} points, residual scale {new['residual_scale']:.6g}",
                        f"{new['description']}" + (f"; assumes {new['assumption']}" if new['assumption'] else ""))
    else:
        ctx.report.step(f"models.fit_models on {len(char)} points: predicted {new['predicted_N']:.10g} N, "
                        f"residual {new['residual_N']:.10g} N")
    return compare_rows(row, new, ctx_rtol(ctx), unit_column="unit" if kind == "models" else None,
                        primary=PRIMARY[kind]), PRIMARY[kind]


def handle_cases(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    root = campaign_root(path, kind)
    case = str(row["case"])
    ctx.report.step(f"Provenance in the row: raw file {row['raw_file']}, sha256 {short(row['raw_sha256'])}, "
                    f"{int(row['n_samples'])} samples, status {row['status']}")
    src = open_source(ctx, root)
    describe_source(ctx, src)
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], expected={case: str(row["raw_sha256"])}, sample_rate_tolerance=srt)
    new_path = scratch / ("ingest/cases.parquet" if kind == "ingest_cases" else "cases.parquet")
    new = match_row(pd.read_parquet(new_path), df, pos, kind, "cases table")
    if new["status"] == "ok":
        _series_step(ctx, src, scratch, case)
    else:
        q = pd.read_parquet(scratch / "quarantine.parquet")
        ctx.report.step(f"Case {case} is quarantined: " + ("; ".join(q[q["case"] == case]["reason"]) or "?"))
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def handle_timeseries(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    root = campaign_root(path, kind)
    case = path.stem
    src = open_source(ctx, root)
    describe_source(ctx, src)
    srt = _rate_tolerance(ctx, root, [path])
    scratch = rebuild(ctx, src, [case], validate=False, sample_rate_tolerance=srt)
    new_path = scratch / "ingest" / "timeseries" / f"{case}.parquet"
    if not new_path.is_file():
        raise TraceStop(f"case {case} no longer ingests (quarantined now): no time series to compare")
    new_df = pd.read_parquet(new_path)
    raw = RawText(ctx, src, scratch, case)
    new = match_row(new_df, df, pos, kind, "time series")
    ctx.report.step(f"Row {int(row['row'])} of {case} in the raw CSV and its conversion to SI",
                    f"{raw.label} {raw.header_text()}", f"{raw.label} {raw.line(int(row['row']))}",
                    *column_mapping(src, case))
    return compare_rows(row, new, ctx_rtol(ctx), primary=PRIMARY[kind]), PRIMARY[kind]


def _diagnosis_run(ctx: Context, src: RawSource, root: Path, files: Sequence[Path]) -> dict:
    from .diagnosis import diagnose

    scratch, spec = _characteristic_chain(ctx, src, root, files)
    ctx.report.step("Running diagnosis.diagnose on the re-derived campaign (windows + transient bins, candidate fits; "
                    "this takes a few seconds per campaign)")
    result, _obs, _pred = diagnose(scratch, spec)
    return result


def handle_diagnosis(ctx: Context, path: Path, selector: str | None):
    stored = json.loads(path.read_text(encoding="utf-8"))
    keys = [selector] if selector else list(DIAGNOSIS_DEFAULT_KEYS)
    if keys == ["."]:
        keys = [k for k in stored if k not in NOT_DERIVED_KEYS]
    for k in keys:
        if k.split(".")[0] in NOT_DERIVED_KEYS:
            raise TraceStop(f"{k!r} is not re-derivable (wall-clock time / provenance)")
    values = {k: json_get(stored, k) for k in keys}
    ctx.report.step(f"Stored in {ctx.rel(path)}: " + "; ".join(f"{k} = {fmt(v)}" for k, v in values.items()),
                    f"campaign {stored.get('campaign')}, status {stored.get('status')}, metric {stored.get('metric')} "
                    "(rms over the characteristic windows of z = (F_meas - F_model)/sigma)")
    root = path.parent
    src = open_source(ctx, root)
    describe_source(ctx, src)
    _damper_step(ctx, src)
    result = _diagnosis_run(ctx, src, root, [path])
    noise = result.get("noise") or {}
    ctx.report.step(f"Re-derived: verdict {result.get('verdict')}, gap_before {fmt(result.get('gap_before'))} -> "
                    f"gap_after {fmt(result.get('gap_after'))}, shrink {fmt(result.get('shrink'))}",
                    f"sigma^2 = (window force std)^2/n + (r F)^2 with r = {fmt(noise.get('repeatability_rel'))} "
                    f"(period-to-period scatter); {noise.get('n_windows')} windows, {noise.get('n_transient_bins')} "
                    f"transient bins; {len(result.get('candidates') or [])} candidate effect sets fitted")
    comps = []
    for k in keys:
        try:
            new = json_get(result, k)
        except TraceStop:
            new = "<absent>"
        comps += compare_value(k, values[k], new, ctx_rtol(ctx, FIT_RTOL))
    return comps, keys


def handle_scores(ctx: Context, kind: str, path: Path, df: pd.DataFrame, pos: int, row: pd.Series):
    from .blind import score

    blind_root = path.parent
    name = str(row["scenario"])
    # row-level provenance columns when the scores carry them (blind.write_scores), else the layout
    truth_path = ctx.resolve(str(row["truth_file"])) if row.get("truth_file") else blind_root / "truth" / f"{name}.json"
    raw_dir = ctx.resolve(str(row["raw_dir"])) if row.get("raw_dir") else blind_root / "raw" / name
    if not truth_path.is_file():
        raise MissingFile(f"truth file {ctx.rel(truth_path)} not found")
    truth = json.loads(truth_path.read_text(encoding="utf-8"))
    ctx.report.step(f"Truth of {name}: {ctx.rel(truth_path)} (sha256 {short(sha256_file(truth_path))}): effects "
                    f"{truth.get('truth') or '[]'}, magnitude {fmt(truth.get('magnitude_x_detection'))} x "
                    "detection level",
                    "the diagnosis never sees this file; blind.score compares its verdict with it")
    processed = sorted(p for p in blind_root.glob(f"diagnosis/*/{name}") if (p / "cases.parquet").is_file())
    if row.get("diagnosis_file"):
        named = ctx.resolve(str(row["diagnosis_file"])).parent
        processed = [named] if (named / "cases.parquet").is_file() else processed
    if processed:
        root = processed[0]
        ctx.report.step(f"Diagnosed (rule blind_diagnose) in {ctx.rel(root)} from the raw campaign {ctx.rel(raw_dir)}")
        src = open_source(ctx, root)
        files = [root / "diagnosis.json", root / "cases.parquet"]
    else:
        if not (raw_dir / "campaign.yaml").is_file():
            raise MissingFile(f"raw scenario {ctx.rel(raw_dir)} not found")
        ctx.report.step(f"No processed folder of {name} under {ctx.rel(blind_root / 'diagnosis')}: the raw hashes "
                        "cannot be checked against a record")
        root = raw_dir
        src = _raw_source(ctx, raw_dir / "campaign.yaml", "", "", None, None)
        files = []
    describe_source(ctx, src)
    result = _diagnosis_run(ctx, src, root, files)
    ctx.report.step(f"Re-derived diagnosis: verdict {result.get('verdict')}, "
                    f"gap_before {fmt(result.get('gap_before'))} -> gap_after {fmt(result.get('gap_after'))}")
    new = match_row(score([truth], {name: result}), df, pos, kind, "score")
    ctx.report.step(f"blind.score: truth {new['truth'] or '(none)'} against verdict {new['verdict'] or '(none)'} -> "
                    f"exact = {bool(new['exact'])}, shrink = {fmt(new['shrink'])}")
    return compare_rows(row, new, ctx_rtol(ctx, FIT_RTOL), primary=PRIMARY[kind]), PRIMARY[kind]


HANDLERS: dict[str, Callable] = {
    "cases": handle_cases, "ingest_cases": handle_cases, "timeseries": handle_timeseries,
    "windows": handle_windows, "characteristic": handle_windows, "repeatability": handle_repeatability,
    "nominal": handle_nominal, "plan_check": handle_plan_check, "models": handle_models,
    "residuals": handle_models, "harmonic": handle_harmonic, "scores": handle_scores,
}

def ctx_rtol(ctx: Context, default: float = RTOL) -> float:
    return default if ctx.rtol is None else ctx.rtol


# ----------------------------------------------------------------------------------------------
# entry point
# ----------------------------------------------------------------------------------------------

def trace(table: str | os.PathLike, selector: str | None = None, *, root: str | os.PathLike | None = None,
          config: str | os.PathLike | None = None, rtol: float | None = None, stream="stdout") -> TraceResult:
    """Trace one row (or diagnosis key) of ``table`` back to the raw data and re-derive it.

    ``root``: the project folder relative paths in the tables refer to (default: the folder above
    ``results/``, else the working directory); ``config``: the config YAML for stage parameters and
    virtual-rig specs when no lineage record gives them (default ``<root>/config/config.yaml``);
    ``stream``: where the steps are printed as they happen (default sys.stdout; None: only kept in the
    result's ``text``). The result's ``status`` is MATCH, MISMATCH, RAW FILE CHANGED, MISSING FILE or
    CANNOT TRACE; ``exit_code`` 0, 1, 2, 2, 2.
    """
    report = Report(sys.stdout if stream == "stdout" else stream)
    path = Path(table)
    base = Path(root) if root is not None else project_root(path)
    cfg = Path(config) if config is not None else base / "config" / "config.yaml"
    report.line(f"trace {path.as_posix()}" + (f" [{selector}]" if selector else ""))
    comps: list[Comparison] = []
    with tempfile.TemporaryDirectory(prefix="isokinetic-trace-") as tmp:
        ctx = Context(table=path, root=base, config_path=cfg if cfg.is_file() else None, report=report,
                      scratch=Path(tmp), rtol=None if rtol is None else float(rtol))
        try:
            if not path.is_file():
                raise MissingFile(f"{path}: no such file")
            kind = table_kind(path)
            show_lineage(ctx, path)
            if kind == "diagnosis":
                comps, primary = handle_diagnosis(ctx, path, selector)
                used_rtol = ctx_rtol(ctx, FIT_RTOL)
            else:
                df = pd.read_parquet(path)
                pos, row = select_row(df, parse_selector(selector))
                _stored_step(ctx, kind, df, pos, row)
                comps, primary = HANDLERS[kind](ctx, kind, path, df, pos, row)
                used_rtol = ctx_rtol(ctx, FIT_RTOL if kind == "scores" else RTOL)
            status = show_comparisons(ctx, comps, primary, used_rtol)
        except TraceStop as exc:
            status = exc.status
            report.line("")
            report.line(f"{status}: {exc}")
        except (ValueError, KeyError, OSError) as exc:  # a manifest/spec/table the stages refuse
            status = CANNOT
            report.line("")
            report.line(f"{status}: {type(exc).__name__}: {exc.args[0] if exc.args else exc}")
    report.line(status)
    return TraceResult(status, comps, report.text())
