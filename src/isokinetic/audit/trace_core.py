"""Shared parts of the trace command (:mod:`isokinetic.audit.trace`).

Statuses and their exit codes, the numbered report the steps are printed to, the context of one
trace (project root, config, scratch folders, stage parameters from lineage records or the
config), row selectors, the comparison of stored and re-derived values, and :class:`Kind`, the
spec of a table kind that :data:`isokinetic.audit.trace.KINDS` lists one of per table.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np
import pandas as pd
import yaml

from isokinetic.contracts.settings import (
    CONFIG_KEYS,
    DEFAULTS,
    SCHEMA_FILE,
    Settings,
    flat_settings,
    settings_from_flat,
    with_defaults,
)
from isokinetic.io import read_lineage as read_record
from isokinetic.measurement.windows import WindowSpec

MATCH = "MATCH"
MISMATCH = "MISMATCH"
RAW_CHANGED = "RAW FILE CHANGED"
MISSING = "MISSING FILE"
CANNOT = "CANNOT TRACE"
EXIT_CODES = {MATCH: 0, MISMATCH: 1, RAW_CHANGED: 2, MISSING: 2, CANNOT: 2}

#: Relative tolerance of the comparison (closed-form stages) and of fitted/optimised numbers.
RTOL = 1e-9
FIT_RTOL = 1e-6
#: Keys of diagnosis.json that are not re-derivable (wall-clock time, provenance).
NOT_DERIVED_KEYS = ("seconds", "lineage")
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


def sha_text(sha: str | None) -> str:
    """A hash as shown in the steps: its first 12 characters and '..', '(none)' without one."""
    return (sha[:SHA_SHOWN] + "..") if sha else "(none)"


def value_text(value, unit: str = "") -> str:
    """A stored or re-derived value as shown in the steps (floats to 10 digits, long texts cut), with its unit."""
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
        """The traced project's config, the defaults of its schema (``workflow/schemas/``) filled as a build fills
        them; None without a config."""
        if self._config is None and self.config_path is not None and self.config_path.is_file():
            self._config = yaml.safe_load(self.config_path.read_text(encoding="utf-8")) or {}
            schema = self.root / SCHEMA_FILE
            if schema.is_file():
                self._config = with_defaults(self._config, yaml.safe_load(schema.read_text(encoding="utf-8")))
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
    """The file's lineage record, None when it has none or cannot be read."""
    try:
        rec = read_record(path)
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


def recorded_settings(ctx: Context, files: Sequence[Path]) -> Settings:
    """The settings the traced files were made with: each setting from the lineage params of the first of
    ``files`` that records it, else the config (its schema's defaults filled), else :data:`DEFAULTS` (a project
    without the config schema, whose config leaves it out: the schema's defaults all the same)."""
    values = {}
    for name, ((block, key), factor) in CONFIG_KEYS.items():
        try:
            values[name] = float(param(ctx, [name], files, [block, key], factor)[0])
        except TraceStop:
            values[name] = flat_settings(DEFAULTS)[name]
    return settings_from_flat(values)


def window_spec(ctx: Context, files: Sequence[Path]) -> tuple[WindowSpec, str]:
    """The window fractions (lineage params of ``files``, else the config) and where they came from."""
    a, where_a = param(ctx, ["start_fraction"], files, ["windows", "start_fraction"])
    b, _ = param(ctx, ["end_fraction"], files, ["windows", "end_fraction"])
    return WindowSpec(float(a), float(b)), where_a.removesuffix(".start_fraction")


def ctx_rtol(ctx: Context, default: float = RTOL) -> float:
    """The --rtol given, else the table kind's default."""
    return default if ctx.rtol is None else ctx.rtol


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
    """A numpy scalar as its Python value; pandas' missing value (pd.NA, NaT) of a nullable column as NaN."""
    if isinstance(x, np.generic):
        return x.item()
    if x is pd.NA or x is pd.NaT:
        return math.nan
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



# ----------------------------------------------------------------------------------------------
# table kinds
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Kind:
    """How rows of one kind of table are traced (one entry of :data:`isokinetic.audit.trace.KINDS`).

    ``path``: where the pipeline writes the table, relative to the campaign folder (a glob for the
    time series; from :mod:`isokinetic.contracts.outputs`); ``what``: the row in words;
    ``primary``: the values shown first (and compared even when the stage functions do not make
    them); ``keys``: the columns identifying a row of the re-derived table (``ordinal``: the n-th
    row with those keys); ``intro``: the step explaining the derivation, printed first;
    ``locate``: the folder of the campaign (default: the folder ``path`` is relative to), printing
    any steps it takes; ``source``: the raw evidence of that folder; ``damper``: show the nominal
    damper data; ``rederive``: re-derives the row from the evidence, printing its steps.
    """

    name: str
    path: str
    what: str
    primary: tuple[str, ...] = ()
    keys: tuple[str, ...] = ()
    rederive: Callable | None = None
    intro: Callable | None = None
    locate: Callable | None = None
    source: Callable | None = None
    damper: bool = False
    ordinal: bool = False
    rtol: float = RTOL
    unit_column: str | None = None

    @property
    def depth(self) -> int:
        """Folders from the campaign folder down to the table (1: the table lies in it)."""
        return len(PurePosixPath(self.path).parts)


@dataclass(frozen=True)
class Traced:
    """The traced row: the table's file and kind, its rows, the row's position and values, and the
    campaign folder the row came from."""

    path: Path
    kind: Kind
    df: pd.DataFrame
    pos: int
    row: pd.Series
    root: Path


def match_row(new: pd.DataFrame, t: Traced, what: str) -> pd.Series:
    """The row of a re-derived table with the traced row's keys (the n-th such row for an ``ordinal`` kind)."""
    keys = list(t.kind.keys)
    stored = row_at(t.df, t.pos)
    mask = pd.Series(True, index=new.index)
    for k in keys:
        mask &= new[k].astype(str) == str(stored[k])
    hits = new[mask]
    if t.kind.ordinal:
        same = (t.df[keys].astype(str) == stored[keys].astype(str)).all(axis=1).to_numpy()
        ordinal = int(same[:t.pos].sum())
        hits = hits.iloc[ordinal:ordinal + 1]
    if len(hits) != 1:
        said = ", ".join(f"{k}={stored[k]}" for k in keys)
        raise NotReproduced(f"the re-derived {what} has {len(hits)} row(s) for {said} (stored: 1)")
    return row_at(hits, 0)

