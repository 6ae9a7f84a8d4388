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

CSV exports
    ``characteristic.csv`` and ``models/models.csv`` (names row, units row, then the rows;
    :mod:`isokinetic.stages.exports`) are traced through their Parquet source: the names and units rows
    and the selected line, field by field, must be what the export writes for the same row of the
    source (else ``MISMATCH``, naming line and fields); then that row is traced like the Parquet's.

Selectors
    ``col=value,col=value`` must pick exactly one row (``case=T12,segment=3``); ``row=N`` picks
    the N-th row (0-based) of a table without a ``row`` column. For ``diagnosis.json`` the
    selector is a key path (``gap_before``, ``params.coulomb_force_N``, ``where.0.v_min_m_s``,
    ``.`` for every key); without one, ``gap_before``, ``gap_after`` and ``verdict``.

Layout
    This module: :data:`KINDS`, one :class:`~isokinetic.audit.trace_core.Kind` per table (where
    the pipeline writes it, from :mod:`isokinetic.contracts.outputs`; its primary values; the keys
    of a row; the derivation in words; its re-derivation), and the one procedure every row follows
    (:func:`trace_row`). :mod:`isokinetic.audit.trace_core`: statuses, the numbered report,
    selectors, comparisons. :mod:`isokinetic.audit.trace_evidence`: the raw evidence and its hash
    checks. :mod:`isokinetic.audit.trace_steps`: the re-derivation of each kind.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import sys
import tempfile
from collections.abc import Sequence
from fnmatch import fnmatchcase
from pathlib import Path, PurePosixPath

import pandas as pd

from isokinetic.audit import trace_steps as steps
from isokinetic.audit.lineage import path_sha256
from isokinetic.audit.trace_core import (
    CANNOT,
    FIT_RTOL,
    MATCH,
    MISMATCH,
    MISSING,
    RAW_CHANGED,
    Comparison,
    Context,
    Kind,
    MissingFile,
    NotReproduced,
    Report,
    Traced,
    TraceResult,
    TraceStop,
    compare_rows,
    ctx_rtol,
    parse_selector,
    project_root,
    read_lineage,
    select_row,
    sha_text,
    unit_of,
    value_text,
)
from isokinetic.audit.trace_evidence import describe_source, open_source
from isokinetic.contracts.campaign import timeseries_relpath
from isokinetic.contracts.outputs import ingest_path, outputs_of, rule_of
from isokinetic.stages.exports import EXPORTS, csv_text

__all__ = ["KINDS", "trace", "trace_row", "table_kind", "TraceResult", "TraceStop", "MATCH", "MISMATCH",
           "RAW_CHANGED", "MISSING", "CANNOT"]


#: Every kind of table trace knows, by name.
KINDS = {k.name: k for k in (
    Kind("cases", outputs_of("validate")["cases"], "validated cases (raw file, hash, status)",
         primary=("raw_sha256", "n_samples", "status", "motion_start_s", "delay_s"), keys=("case",),
         intro=steps.intro_cases, rederive=steps.rederive_cases),
    Kind("ingest_cases", ingest_path("cases"), "ingested cases (raw file, hash)",
         primary=("raw_sha256", "n_samples", "status"), keys=("case",),
         intro=steps.intro_cases, rederive=steps.rederive_cases),
    Kind("timeseries", timeseries_relpath("*"), "canonical SI time series of one case",
         primary=("time_s", "displacement_m", "force_N", "command_m"), keys=("row",),
         rederive=steps.rederive_timeseries),
    Kind("windows", outputs_of("windows")["windows"], "steady window of one half-period",
         primary=("force_N", "force_std_N", "velocity_m_s", "n_samples"), keys=("case", "segment"),
         intro=steps.intro_windows, rederive=steps.rederive_windows),
    Kind("characteristic", outputs_of("characteristic")["characteristic"], "steady characteristic point",
         primary=("force_N", "force_std_N", "velocity_m_s", "n_samples", "repeatability_flagged"),
         keys=("case", "segment"), intro=steps.intro_windows, rederive=steps.rederive_characteristic),
    Kind("repeatability", outputs_of("repeatability")["repeatability"], "period 2 against period 1",
         primary=("rel_diff", "force_period1_N", "force_period2_N", "velocity_m_s", "flagged"),
         keys=("case", "direction"), intro=steps.intro_repeatability, rederive=steps.rederive_repeatability),
    Kind("nominal", outputs_of("nominal")["nominal"], "nominal model through the plan",
         primary=("force_N", "force_std_N", "velocity_m_s"), keys=("case", "segment"), damper=True,
         intro=steps.intro_nominal, rederive=steps.rederive_nominal),
    Kind("plan_check", outputs_of("design")["plan_check"], "test-design plan check",
         primary=("G1", "G2", "G3", "stroke_to_converge_m", "window_start_stroke_m", "flagged", "reasons"),
         keys=("case",), damper=True, locate=steps.locate_plan_check, rederive=steps.rederive_plan_check),
    Kind("models", outputs_of("models")["models"], "fitted model parameter",
         primary=("estimate", "ci_low", "ci_high", "std_error", "plausible"), keys=("model", "direction", "parameter"),
         damper=True, unit_column="unit", intro=steps.intro_models, rederive=steps.rederive_models),
    Kind("residuals", outputs_of("models")["residuals"], "fitted model residual",
         primary=("predicted_N", "residual_N", "normalized_residual"), keys=("model", "case", "segment"),
         damper=True, intro=steps.intro_residuals, rederive=steps.rederive_residuals),
    Kind("harmonic", outputs_of("harmonic")["table"], "harmonic / free-record point",
         primary=("velocity_m_s", "force_N", "lag_s"), keys=("case", "kind", "direction"), ordinal=True,
         intro=steps.intro_harmonic, rederive=steps.rederive_harmonic),
    Kind("diagnosis", outputs_of("diagnosis")["json"], "sim-to-real gap diagnosis", rtol=FIT_RTOL),
    Kind("scores", outputs_of("blind_score")["scores"], "blind-test score",
         primary=("verdict", "exact", "gap_before", "gap_after", "shrink"), keys=("scenario",), rtol=FIT_RTOL,
         locate=steps.locate_scores, source=steps.source_scores, rederive=steps.rederive_scores),
)}


def csv_export_of(path: Path) -> tuple[Path, Sequence[str]] | None:
    """(Parquet source, columns in their row's unit) of a CSV export (``characteristic.csv``,
    ``models/models.csv``; :data:`isokinetic.stages.exports.EXPORTS`), None for any other file."""
    for source, target, row_unit in EXPORTS.values():
        n = len(PurePosixPath(target).parts)
        if len(path.parts) > n and PurePosixPath(*path.parts[-n:]).as_posix() == target:
            return path.parents[n - 1] / source, row_unit
    return None


def _csv_rows(text: str) -> list[list[str]]:
    return list(csv.reader(io.StringIO(text)))


def check_export(ctx: Context, path: Path, source: Path, row_unit: Sequence[str], selector: str | None) -> str:
    """A CSV export against its Parquet source: the names and units rows, then the selected row field by
    field against the source's row written the way the export writes it (:func:`exports.csv_text`). Returns
    the selector of the same row in the source (``row=N``); a differing field stops the trace (MISMATCH)."""
    if not source.is_file():
        raise MissingFile(f"{ctx.rel(source)}: the Parquet source of {ctx.rel(path)} is missing")
    try:
        got = _csv_rows(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise NotReproduced(f"{ctx.rel(path)}: not the CSV the export writes ({exc})") from None
    table = pd.read_parquet(source)
    want = _csv_rows(csv_text(table, row_unit))
    if len(got) < 2 or got[0] != want[0] or got[1] != want[1]:
        raise NotReproduced(f"{ctx.rel(path)}: its column names or units row differ from those of "
                            f"{ctx.rel(source)} (names: {', '.join(want[0])})")
    frame = pd.DataFrame(got[2:], columns=got[0])
    pos, _ = select_row(frame, parse_selector(selector))
    line = pos + 3  # 1-based line of the file: names, units, then the rows
    ctx.report.step(f"CSV export: data row {pos} (0-based, line {line} of the file, under the names and "
                    f"units rows) of {ctx.rel(path)}, a view of {ctx.rel(source)} written by the stage exports",
                    "units row: " + ", ".join(f"{n} [{u}]" for n, u in zip(got[0], got[1], strict=True) if u))
    if len(got) != len(want):
        raise NotReproduced(f"{ctx.rel(path)} has {len(got) - 2} rows, its source {ctx.rel(source)} {len(want) - 2}")
    diff = [f"{n}: CSV {a!r}, Parquet {b!r}" for n, a, b in zip(want[0], got[line - 1], want[line - 1], strict=True)
            if a != b]
    if diff:
        raise NotReproduced(f"line {line} of {ctx.rel(path)} differs from row {pos} of {ctx.rel(source)}: "
                            + "; ".join(diff[:6]))
    ctx.report.line(f"      every field of line {line} is the field of row {pos} of {ctx.rel(source)} as the "
                    "export writes it (floats in their round-trip form): the row is traced there")
    others = [i + 1 for i, (a, b) in enumerate(zip(got, want, strict=True)) if a != b and i != line - 1]
    if others:
        ctx.report.line(f"      note: {len(others)} other line(s) of the file differ from their source rows "
                        f"(lines {', '.join(map(str, others[:8]))}{', ...' if len(others) > 8 else ''})")
    if "row" in table.columns:
        raise TraceStop(f"{ctx.rel(source)} has a 'row' column: its CSV rows cannot be traced by position")
    return f"row={pos}"


def table_kind(path: Path) -> Kind:
    """The kind of a results file: the rule that writes it (:func:`isokinetic.contracts.outputs.rule_of`
    of its path below the campaign folder, the longest such path first), then the kind at that path."""
    depth = max(k.depth for k in KINDS.values())
    for n in range(depth, 0, -1):
        rel = PurePosixPath(*path.parts[-n:]).as_posix()
        if rule_of(rel) is None:
            continue
        for kind in KINDS.values():
            if kind.depth == n and fnmatchcase(rel, kind.path):
                return kind
    names = sorted({PurePosixPath(k.path).name for k in KINDS.values() if "*" not in k.path})
    patterns = [k.path.replace("*", "<case>") for k in KINDS.values() if "*" in k.path]
    exports = ", ".join(target for _, target, _ in EXPORTS.values())
    raise TraceStop(f"{path}: not a table trace knows; it traces {', '.join(names)}, {', '.join(patterns)} "
                    f"and the CSV exports {exports}")


# ----------------------------------------------------------------------------------------------
# the steps every trace shows
# ----------------------------------------------------------------------------------------------

def show_lineage(ctx: Context, path: Path) -> None:
    """The file's lineage record, each input checked against its recorded sha256."""
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
            state = "unchanged" if path_sha256(here) == sha else "CHANGED since (rebuilt or edited)"
        rep.line(f"  input {p}: sha256 {sha_text(sha)} - {state}")


def _stored_step(ctx: Context, kind: Kind, df: pd.DataFrame, pos: int, row: pd.Series) -> None:
    keys = [k for k in ["campaign", *kind.keys] if k in row.index]
    ident = ", ".join(f"{k} {row[k]}" for k in keys)

    def unit(c):
        return str(row["unit"]) if c in ("estimate", "ci_low", "ci_high", "std_error") and "unit" in row else unit_of(c)

    vals = ", ".join(f"{c} = {value_text(row[c], unit(c))}" for c in kind.primary if c in row.index)
    ctx.report.step(f"Stored: row {pos} (0-based) of {len(df)} in {ctx.rel(ctx.table)} ({kind.what}): {ident}", vals)


def trace_row(ctx: Context, kind: Kind, path: Path, selector: str | None) -> tuple[list[Comparison], Sequence[str]]:
    """One row of a table, the same way for every kind: the stored row, the derivation in words, the
    raw evidence, the kind's re-derivation; returns (comparisons, primary value names)."""
    df = pd.read_parquet(path)
    pos, row = select_row(df, parse_selector(selector))
    _stored_step(ctx, kind, df, pos, row)
    root = kind.locate(ctx, path, row) if kind.locate else path.parents[kind.depth - 1]
    t = Traced(path=path, kind=kind, df=df, pos=pos, row=row, root=root)
    if kind.intro:
        ctx.report.step(kind.intro(ctx, t))
    src = (kind.source or open_source)(ctx, root)
    describe_source(ctx, src)
    if kind.damper:
        steps.damper_step(ctx, src)
    new = kind.rederive(ctx, t, src)
    rtol = ctx_rtol(ctx, kind.rtol)
    return compare_rows(row, new, rtol, unit_column=kind.unit_column, primary=kind.primary), kind.primary


def show_comparisons(ctx: Context, comps: list[Comparison], primary: Sequence[str], rtol: float) -> str:
    """The table of stored against re-derived values; the status (MATCH or MISMATCH)."""
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
        stored, new = value_text(c.stored, c.unit), value_text(c.recomputed, c.unit)
        rep.line(f"  {c.name:<{width}}  stored {stored:<24}  re-derived {new:<24}  {verdict}")
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
# entry point
# ----------------------------------------------------------------------------------------------


def what_is_there(path: Path) -> str:
    """Why ``path`` is no table file trace can read: nothing there, a directory, a FIFO, a socket or a device."""
    if path.is_dir():
        return "a directory, not a table file (name a .parquet, .json or .csv file inside it)"
    if not path.exists():
        return "no such file"
    import stat

    mode = path.stat().st_mode
    kinds = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a device"),
             (stat.S_ISBLK, "a device"))
    kind = next((name for test, name in kinds if test(mode)), "not a regular file")
    return f"{kind}, not a table file: trace reads regular files only"

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
                raise MissingFile(f"{path}: {what_is_there(path)}")
            export = csv_export_of(path)
            if export is not None:  # a CSV export: checked against its Parquet source, which is traced
                selector = check_export(ctx, path, *export, selector)
                path = ctx.table = export[0]
            kind = table_kind(path)
            show_lineage(ctx, path)
            if kind.rederive is None:  # a JSON document: a key path instead of a row
                comps, primary = steps.trace_diagnosis(ctx, path, selector)
            else:
                comps, primary = trace_row(ctx, kind, path, selector)
            status = show_comparisons(ctx, comps, primary, ctx_rtol(ctx, kind.rtol))
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
