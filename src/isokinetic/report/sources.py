"""Where each number of a page comes from: file, rule, commit, parameters, and how to audit it.

A :class:`Source` is one file a page reads, with its lineage: the record the file carries
(:func:`isokinetic.io.read_lineage`), else the file's entry in the campaign's
``provenance.json``, else (a figure) the record of the table its job wrote, else the rule the
workflow names for it (:func:`isokinetic.contracts.outputs.rule_of`) and "not recorded". Each
number cell's ``title`` (:meth:`Source.title`) and each table's lineage line (:func:`lineage_of`)
say these facts, with the command that audits the row
(``python -m isokinetic trace <table> <selector>``, :func:`trace_command`).
"""

from __future__ import annotations

import contextlib
import json
import os
import shlex
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from isokinetic.contracts.outputs import STAGE_OUTPUTS, rule_of, sibling_table
from isokinetic.io import read_lineage, sha256_file
from isokinetic.report.numbers import missing, short


def read_parquet(path: Path) -> pd.DataFrame | None:
    """A table of the results, None when it is missing or unreadable (the page says so)."""
    try:
        return pd.read_parquet(path) if path.is_file() else None
    except (OSError, ValueError):
        return None


def read_json(path: Path) -> dict | None:
    """A JSON object of the results, None when it is missing, unreadable or not an object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


TRACE = "python -m isokinetic trace"

#: Tables ``python -m isokinetic trace`` re-derives, by file name (the names of
#: :data:`isokinetic.audit.trace.KINDS`, which a test compares; not imported: trace loads every stage).
TRACEABLE = frozenset(Path(STAGE_OUTPUTS[stage][name]).name for stage, name in (
    ("validate", "cases"), ("windows", "windows"), ("characteristic", "characteristic"),
    ("repeatability", "repeatability"), ("nominal", "nominal"), ("design", "plan_check"), ("models", "models"),
    ("models", "residuals"), ("harmonic", "table"), ("diagnosis", "json"), ("blind_score", "scores")))
_QUARANTINE, _CASES = (Path(STAGE_OUTPUTS["validate"][name]).name for name in ("quarantine", "cases"))


def trace_command(table: str, selector: str) -> str:
    """The command a reader runs to audit one row (or JSON key) of a table."""
    return f"{TRACE} {shlex.quote(table)} {shlex.quote(selector)}" if selector else f"{TRACE} {shlex.quote(table)}"


def audit_command(path: Path, label: str, selector: str) -> str | None:
    """The trace command auditing one row (or JSON key path) of a file, None where trace has none:
    a quarantined case is audited through cases.parquet; a Parquet table needs a one-row selector."""
    if path.name == _QUARANTINE:
        case = dict(p.split("=", 1) for p in selector.split(",") if "=" in p).get("case")
        return trace_command(str(Path(label).with_name(_CASES).as_posix()), f"case={case}") if case else None
    if path.name not in TRACEABLE or (path.suffix == ".parquet" and not selector):
        return None
    return trace_command(label, selector)


def selector_of(row: Mapping, keys: Sequence[str]) -> str:
    """``case=T05,direction=+,period=1``: the row's values of the key columns."""
    return ",".join(f"{k}={row[k]}" for k in keys if k in row and not missing(row[k]))


def display_path(path: Path) -> str:
    """Path as the reader types it: relative to the working directory (the project root) if below it."""
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path.cwd().resolve())).as_posix() \
            if Path(path).resolve().is_relative_to(Path.cwd().resolve()) else Path(path).as_posix()
    except (OSError, ValueError):
        return Path(path).as_posix()


def _provenance_record(provenance: Mapping | None, keys: Sequence[str]) -> dict | None:
    """The record of one file in a campaign's provenance.json, whatever its container's shape
    (a mapping path -> record, under 'files'/'outputs'/'lineage' or at the top, or a list of
    records with 'path'/'file')."""
    if not isinstance(provenance, Mapping):
        return None
    for container in (provenance.get("files"), provenance.get("outputs"), provenance.get("lineage"),
                      provenance.get("records"), provenance):
        if isinstance(container, Mapping):
            for key in keys:
                rec = container.get(key)
                if isinstance(rec, Mapping):
                    inner = rec.get("lineage")
                    return dict(inner if isinstance(inner, Mapping) else rec)
        elif isinstance(container, list):
            for rec in container:
                if isinstance(rec, Mapping) and (rec.get("path") in keys or rec.get("file") in keys):
                    inner = rec.get("lineage")
                    return dict(inner if isinstance(inner, Mapping) else rec)
    return None


@dataclass
class Source:
    """A file a page shows numbers from, with its lineage."""

    path: Path
    label: str                   # the path as shown (relative to the project root)
    exists: bool
    rule: str | None = None      # from the record, else from the workflow (outputs.rule_of)
    record: dict | None = None   # the lineage record (file metadata or provenance.json)
    origin: str = "none"         # 'file', 'provenance', 'same job as <file>' or 'none'
    sha256: str | None = None    # of the file as the report read it

    @property
    def commit(self) -> str | None:
        return (self.record or {}).get("git_commit")

    def facts(self) -> list[str]:
        """Short lineage facts for titles: rule, commit, params hash (or 'not recorded')."""
        out = [f"rule {self.rule or '?'}"]
        if self.record:
            commit = short(self.commit, 10) if self.commit else "unknown (not a git checkout)"
            dirty = (self.record or {}).get("git_dirty")
            out.append(f"commit {commit}{' (dirty)' if dirty else ''}")
            out.append(f"params {short(self.record.get('params_sha256'), 10)}")
        else:
            out.append("lineage not recorded")
        if self.sha256:
            out.append(f"sha256 {short(self.sha256)}")
        return out

    def title(self, selector: str = "", column: str | None = None, extra: Sequence[str] = ()) -> str:
        """A cell's title: which value of which row of which file, made how, and how to audit it."""
        what = f"{column} of " if column else ""
        where = f"{what}{self.label}" + (f" [{selector}]" if selector else "")
        cmd = self.audit(selector)
        parts = [where, *extra, *self.facts()] + ([f"audit: {cmd}"] if cmd else [])
        return " | ".join(parts)

    def audit(self, selector: str = "") -> str | None:
        return audit_command(self.path, self.label, selector)


def _own_record(path: Path) -> dict | None:
    """The lineage record a Parquet, JSON or PNG file carries, None if none or unreadable."""
    if path.suffix not in (".parquet", ".json", ".png"):
        return None
    try:
        record = read_lineage(path)
    except Exception:  # noqa: BLE001 - an unreadable record is reported as absent
        return None
    return dict(record) if isinstance(record, Mapping) and record else None


class Sources:
    """Lineage lookups for one page (cached; one sha256 per file)."""

    def __init__(self, root: Path, provenance: Mapping | None = None):
        self.root = Path(root)
        self.provenance = provenance
        self._cache: dict[str, Source] = {}

    def __call__(self, rel: str) -> Source:
        """The file ``rel`` (relative to the root) with its lineage, looked up once."""
        if rel in self._cache:
            return self._cache[rel]
        path = self.root / rel
        src = Source(path=path, label=display_path(path), exists=path.is_file(), rule=rule_of(rel))
        if src.exists:
            with contextlib.suppress(OSError):
                src.sha256 = sha256_file(path)
            src.record = _own_record(path)
            if src.record:
                src.origin = "file"
        if src.record is None:
            src.record = _provenance_record(self.provenance, [src.label, rel, path.as_posix()])
            if src.record:
                src.origin = "provenance"
        if src.record is None and path.suffix == ".png":
            self._borrow_from_sibling(src, rel)
        if src.record and src.record.get("rule"):
            src.rule = src.record["rule"]
        self._cache[rel] = src
        return src

    def _borrow_from_sibling(self, src: Source, rel: str) -> None:
        """A figure without a record of its own shares the record of the table its job wrote."""
        sibling = sibling_table(rel)
        if sibling and sibling != rel:
            sib = self(sibling)
            if sib.record:
                src.record, src.origin = sib.record, f"same job as {sib.label}"

    def all(self) -> list[Source]:
        return list(self._cache.values())


@dataclass(frozen=True)
class Lineage:
    """What a page's lineage line under a table or figure says (see the ``lineage`` macro)."""

    exists: bool
    label: str
    rule: str
    recorded: bool
    commit: str | None = None
    dirty: bool | None = None
    params: str = "-"
    made: str | None = None
    origin: str | None = None    # where the record came from, when not from the file itself
    sha256: str | None = None
    audit: str | None = None


def lineage_of(src: Source, selector: str = "") -> Lineage:
    """The lineage line of a file, with the audit command of the row ``selector``."""
    rec = src.record or {}
    return Lineage(exists=src.exists, label=src.label, rule=src.rule or "?", recorded=bool(rec),
                   commit=short(rec["git_commit"], 12) if rec.get("git_commit") else None,
                   dirty=rec.get("git_dirty"), params=short(rec.get("params_sha256"), 12),
                   made=rec.get("created_utc") or None, origin=None if src.origin == "file" else src.origin,
                   sha256=short(src.sha256, 16) if src.sha256 else None, audit=src.audit(selector))


def lineage_rows(sources: Iterable[Source]) -> list[dict]:
    """The lineage section's rows: every file a page read, with its record, by path."""
    rows = []
    for s in sorted(sources, key=lambda s: s.label):
        rec = s.record or {}
        rows.append({"label": s.label, "rule": s.rule or "?", "commit": short(rec.get("git_commit"), 12),
                     "dirty": bool(rec.get("git_dirty")), "params": short(rec.get("params_sha256"), 12),
                     "config": short(rec.get("config_sha256"), 12), "made": rec.get("created_utc", "-"),
                     "record": s.origin if s.record else "not recorded",
                     "sha256": short(s.sha256, 16) if s.exists else "missing",
                     "inputs": [(k, short(v, 12)) for k, v in (rec.get("inputs") or {}).items()],
                     "logs": rec.get("log") or []})
    return rows
