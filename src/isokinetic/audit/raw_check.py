"""Raw data is never touched: re-hash every raw file a processed campaign read.

:func:`raw_changes` compares, for a processed campaign folder ``results/<campaign>/``, the sha256
recorded at ingest (``ingest/campaign.json`` ``manifest_sha256``; ``raw_sha256`` of every case in
``cases.parquet``; any other file in the ingest job's lineage inputs) with the bytes on disk now.
The comparison is :func:`isokinetic.audit.provenance.raw_sources`, which the provenance rule uses too:
one implementation of the hashes, two callers. A simulated campaign has nothing on disk to check.

The stage runs first in the campaign's report job (rule ``campaign_report``: a raw file changed since
ingest fails that job, before the provenance and the page are written) and writes ``raw_check.json``
for every campaign (``kind`` ``raw`` or ``simulation``); the workflow's ``onsuccess``/``onerror`` handlers
check every raw campaign again at the end of each run.

``python -m isokinetic raw-check results/<campaign> [...]`` prints one line per changed or missing
file and exits 1 when there is any (0 otherwise).
"""

from __future__ import annotations

import os
from pathlib import Path

from isokinetic.audit.provenance import raw_sources
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_json

FILE_NAME = STAGE_OUTPUTS["raw_check"]["raw_check"]


class RawDataChanged(RuntimeError):
    """A raw file differs from, or is missing against, the sha256 recorded at ingest."""


def raw_changes(campaign_root: str | os.PathLike, base: str | os.PathLike = ".") -> list[dict]:
    """The raw files of a processed campaign that changed or went missing since ingest.

    Each item: ``{"path", "role" ('manifest'|'case'|'other'), "case", "problem" ('changed'|'missing'|'outside'),
    "sha256_recorded", "sha256_now"}``, paths as recorded (resolved against ``base``, the workflow's
    working directory). Files recorded without a hash (a case quarantined because its file was
    missing) are not checked. Empty for a simulated campaign.
    """
    return _changes(raw_sources(Path(campaign_root), Path(base)))


def _changes(raw: dict) -> list[dict]:
    """The changed, missing or outside files of a ``raw`` section (:func:`isokinetic.audit.provenance.raw_sources`)."""
    if raw["kind"] != "raw":
        return []
    out = []
    for f in raw["files"]:
        if not f["sha256_recorded"]:
            continue
        if f.get("outside"):
            problem = "outside"
        elif not f["exists"]:
            problem = "missing"
        elif f["unchanged"] is False:
            problem = "changed"
        else:
            continue
        out.append({"path": f["path"], "role": f["role"], "case": f["case"], "problem": problem,
                    "sha256_recorded": f["sha256_recorded"], "sha256_now": f["sha256_now"]})
    return out


def describe(campaign: str, change: dict) -> str:
    """One readable line for a change."""
    if change["problem"] == "outside":
        return (f"campaign {campaign}: raw file {change['path']} now leads outside the campaign folder: not read "
                f"(sha256 {change['sha256_recorded'][:12]}.. recorded at ingest)")
    if change["problem"] == "missing":
        return (f"campaign {campaign}: raw file {change['path']} is missing "
                f"(sha256 {change['sha256_recorded'][:12]}.. recorded at ingest)")
    return (f"campaign {campaign}: raw file {change['path']} has sha256 {change['sha256_now'][:12]}.. now, "
            f"{change['sha256_recorded'][:12]}.. recorded at ingest")


def check_raw(campaign_root: str | os.PathLike, out_path: str | os.PathLike | None = None, *,
              base: str | os.PathLike = ".") -> list[dict]:
    """:func:`raw_changes`, written to ``out_path`` as JSON (``campaign``, ``kind``: ``raw`` or ``simulation``
    (nothing on disk to check), ``ok``, ``changes``) when given; raises :class:`RawDataChanged` listing every
    change when there is any."""
    root = Path(campaign_root)
    raw = raw_sources(root, Path(base))
    changes = _changes(raw)
    if out_path is not None:
        write_json({"campaign": root.name, "kind": raw["kind"], "ok": not changes, "changes": changes}, out_path)
    if changes:
        raise RawDataChanged("; ".join(describe(root.name, c) for c in changes))
    return changes


def print_changes(campaign_roots, base: str | os.PathLike = ".") -> int:
    """Print one line per changed or missing raw file of the processed campaigns; how many."""
    n = 0
    for root in campaign_roots:
        for change in raw_changes(root, base):
            print(describe(Path(root).name, change))
            n += 1
    return n


__all__ = ["raw_changes", "check_raw", "describe", "print_changes", "RawDataChanged", "FILE_NAME"]
