"""Provenance of a processed campaign: ``results/<campaign>/provenance.json``.

One file that answers, for a campaign, where its numbers came from:

``raw``
    The evidence. A raw campaign: the manifest and every case file with the sha256 recorded at
    ingest (``ingest/campaign.json``, ``cases.parquet``) and any other file of the raw folder the
    ingest job read (its lineage inputs); for each file on disk, its sha256 now and whether it still
    matches (``unchanged``); a file leading outside the campaign folder (a symlink) is never read
    (``outside``). ``unused_files``: every other entry of the raw folder, which no manifest names,
    by name only (never opened or hashed: isokinetic.audit.raw_folder). A simulated campaign: the
    virtual-rig spec (from the ingest files' lineage: seed, nominal damper, effects, sensors, plan)
    and, per case, the sha256 of the canonical CSV recorded when it was simulated (``python -m
    isokinetic export-virtual`` writes those bytes); nothing to re-hash on disk.
``environment``
    Python and the versions of the packages the numbers depend on (importlib.metadata), the
    isokinetic version, the git commit and dirty flag of the code, and the config hash.
``stages``
    Per rule, in pipeline order, from the lineage records of the campaign's files: last run time
    (latest ``created_utc``), params and params_sha256, config hash, code version and commit, the
    inputs with the sha256 they had then and whether they still have it (``inputs_current``), and the
    outputs with their sha256 now.
``outputs``
    The same by file: path -> {rule, created_utc, params_sha256, git_commit, git_dirty, sha256}.
``checks``
    Changed or missing raw files, raw files leading outside the campaign folder, stages whose inputs
    changed since they ran, files without lineage, and ``ok`` when all of these are empty.
"""

from __future__ import annotations

import datetime as dt
import importlib.metadata
import json
import logging
import os
import platform
from collections.abc import Mapping
from pathlib import Path

import pyarrow.parquet as pq

from isokinetic import __version__
from isokinetic.audit.lineage import git_state, path_sha256, sha256_text
from isokinetic.audit.raw_folder import inside, unused_entries
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import RULE_STAGES, STAGE_OUTPUTS
from isokinetic.io import LINEAGE_SUFFIXES, canonical_json, read_lineage, sha256_file, write_json

log = logging.getLogger("isokinetic.provenance")

FORMAT_VERSION = 1
FILE_NAME = STAGE_OUTPUTS["provenance"]["provenance"]
#: Packages whose versions are recorded (the scientific stack, the workflow engine, the plots).
PACKAGES = ("numpy", "scipy", "pandas", "pyarrow", "pandera", "snakemake", "matplotlib")
#: Pipeline order of the rules (contracts.outputs.RULE_STAGES); any other rule follows, sorted by name.
STAGE_ORDER = tuple(RULE_STAGES)
#: Prefix of a simulated case's raw_file (virtual_rig._cases_table).
VIRTUAL_PREFIX = "virtual_rig:"
#: Note of a raw file that leads outside its campaign folder (never read).
OUTSIDE_NOTE = "leads outside the campaign folder: not read"


def environment() -> dict:
    """Python and package versions of the running interpreter (None for a package not installed)."""
    packages = {}
    for name in PACKAGES:
        try:
            packages[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            packages[name] = None
    try:
        installed = importlib.metadata.version("isokinetic")
    except importlib.metadata.PackageNotFoundError:
        installed = None
    return {"python": platform.python_version(), "python_implementation": platform.python_implementation(),
            "platform": platform.platform(), "packages": packages, "isokinetic": __version__,
            "isokinetic_installed": installed}


def _now_utc() -> str:
    return dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _resolve(path: str, base: Path) -> Path:
    p = Path(path)
    return p if p.is_absolute() else base / p


def check_file(path: str, recorded: str, base: Path, folder: Path | None = None) -> dict:
    """{path, sha256_recorded, exists, sha256_now, unchanged} of one file (paths as recorded). A file that
    resolves outside ``folder`` (the campaign's raw folder, when given: a symlink leading out) is not read:
    it gets ``outside: true`` and no sha256."""
    p = _resolve(path, base)
    if path and folder is not None and (p.is_symlink() or p.exists()) and not inside(p, folder):
        return {"path": path, "sha256_recorded": recorded or None, "exists": True, "sha256_now": None,
                "unchanged": None, "outside": True, "note": OUTSIDE_NOTE}
    exists = bool(path) and p.is_file()
    now = sha256_file(p) if exists else None
    return {"path": path, "sha256_recorded": recorded or None, "exists": exists, "sha256_now": now,
            "unchanged": (now == recorded) if exists and recorded else None}


def _case_rows(root: Path) -> list[dict]:
    """The rows of the campaign's cases table (nulls as None; none without a table), read by pyarrow alone: the
    raw check's job needs no pandas (issue 23)."""
    folder = CampaignFolder.at(root)
    for p in (folder.path("validate", "cases"), folder.ingest_path("cases")):
        if p.is_file():
            return pq.ParquetFile(p).read().to_pylist()  # not read_table: its dataset layer loads pandas
    return []


def raw_sources(root: Path, base: Path = Path(".")) -> dict:
    """The ``raw`` section (module docstring) of the campaign folder ``root``; paths relative to ``base``."""
    campaign = CampaignFolder.at(root)
    meta = campaign.meta if campaign.has_meta() else None
    ingest_lineage = (meta and meta.lineage) or {}
    case_rows = _case_rows(root)
    simulated = ingest_lineage.get("rule") == "virtual_rig" or (
        bool(case_rows) and all(str(r.get("raw_file", "")).startswith(VIRTUAL_PREFIX) for r in case_rows))
    out: dict = {"kind": "simulation" if simulated else "raw", "campaign_json": campaign.ingest_path("meta").as_posix(),
                 "source": meta and meta.source, "files": []}
    if simulated:
        spec = (ingest_lineage.get("params") or {}).get("spec")
        out["virtual_rig"] = {"campaign": meta and meta.campaign, "seed": None if spec is None else spec.get("seed"),
                              "spec": spec, "spec_sha256": None if spec is None else sha256_text(canonical_json(spec)),
                              "generated_by": meta and meta.generated_by}
        if spec is None:
            out["virtual_rig"]["note"] = "no virtual_rig lineage record on ingest/campaign.json: spec unknown"
        for r in case_rows:
            out["files"].append({"role": "case", "case": r["case"], "status": r.get("status"),
                                 "path": r.get("raw_file"), "sha256_recorded": r.get("raw_sha256") or None,
                                 "exists": False, "sha256_now": None, "unchanged": None,
                                 "note": "sha256 of the case's canonical CSV (export-virtual writes these bytes)"})
        return out
    listed = set()
    manifest = (meta and meta.manifest_file) or ""
    folder = _resolve(manifest, base).parent if manifest else None
    if manifest:
        out["files"].append({"role": "manifest", "case": None, "status": None,
                             **check_file(manifest, meta.manifest_sha256 or "", base, folder)})
        listed.add(Path(manifest).as_posix())
    for r in case_rows:
        path = str(r.get("raw_file") or "")
        out["files"].append({"role": "case", "case": r["case"], "status": r.get("status"),
                             **check_file(path, str(r.get("raw_sha256") or ""), base, folder)})
        listed.add(Path(path).as_posix())
    for path, sha in sorted((ingest_lineage.get("inputs") or {}).items()):
        if Path(path).as_posix() not in listed:
            out["files"].append({"role": "other", "case": None, "status": None,
                                 **check_file(path, sha, base, folder)})
    out["unused_files"] = _unused(folder, manifest, listed)
    return out


def _unused(folder: Path | None, manifest: str, listed: set[str]) -> list[dict]:
    """The entries of the campaign's raw folder that no manifest names (listed by name only, never read)."""
    if folder is None or not folder.is_dir():
        return []
    where = Path(manifest).parent
    used = []
    for p in listed:
        try:
            used.append(Path(p).relative_to(where).as_posix())
        except ValueError:
            continue
    return [{**e, "path": (where / e["path"]).as_posix() if e["path"] else ""}
            for e in unused_entries(folder, used)]


def _stage_order(rule: str) -> tuple[int, str]:
    return (STAGE_ORDER.index(rule) if rule in STAGE_ORDER else len(STAGE_ORDER), rule)


def _records(root: Path, exclude: tuple[Path, ...]) -> tuple[dict[str, list[tuple[Path, dict]]], list[str]]:
    """(rule -> [(file, lineage record)], files without lineage) of the Parquet/JSON/PNG files under ``root``."""
    records: dict[str, list[tuple[Path, dict]]] = {}
    unstamped = []
    excluded = {p.resolve() for p in exclude}
    for f in sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in LINEAGE_SUFFIXES):
        if f.name.startswith(".") or f.resolve() in excluded:
            continue
        try:
            rec = read_lineage(f)
        except (ValueError, OSError, json.JSONDecodeError) as exc:
            log.warning("%s: lineage unreadable: %s", f, exc)
            rec = None
        if not rec:
            unstamped.append(f.as_posix())
            continue
        records.setdefault(str(rec.get("rule")), []).append((f, rec))
    return records, unstamped


def stages(root: Path, base: Path = Path("."), exclude: tuple[Path, ...] = ()
           ) -> tuple[list[dict], dict[str, dict], list[str]]:
    """(per-rule stage records, per-file index, files without lineage) of every Parquet/JSON/PNG file
    under ``root`` (the ``stages`` and ``outputs`` sections)."""
    records, unstamped = _records(root, exclude)
    hashes: dict[str, str | None] = {}

    def current(path: str) -> str | None:
        if path not in hashes:
            p = _resolve(path, base)
            hashes[path] = path_sha256(p) if p.exists() else None
        return hashes[path]

    out, index = [], {}
    for rule in sorted(records, key=_stage_order):
        files = records[rule]
        shas = {f.as_posix(): sha256_file(f) for f, _ in files}
        for f, rec in files:
            index[f.as_posix()] = {"rule": rule, "created_utc": rec.get("created_utc"),
                                   "params_sha256": rec.get("params_sha256"), "git_commit": rec.get("git_commit"),
                                   "git_dirty": rec.get("git_dirty"), "sha256": shas[f.as_posix()]}
        runs = {canonical_json({k: v for k, v in rec.items() if k != "created_utc"}) for _, rec in files}
        last = max(files, key=lambda fr: fr[1].get("created_utc") or "")[1]
        inputs = last.get("inputs") or {}
        changed = sorted(p for p, sha in inputs.items() if current(p) != sha)
        out.append({
            "rule": rule, "last_run_utc": last.get("created_utc"), "params": last.get("params"),
            "params_sha256": last.get("params_sha256"), "config_sha256": last.get("config_sha256"),
            "package_version": last.get("package_version"), "git_commit": last.get("git_commit"),
            "git_dirty": last.get("git_dirty"), "python": last.get("python"), "log": last.get("log"),
            "inputs": inputs, "inputs_current": not changed, "changed_inputs": changed,
            "consistent": len(runs) == 1,
            "outputs": shas,
        })
    return out, dict(sorted(index.items())), unstamped


def campaign_provenance(campaign_root: str | os.PathLike, *, base: str | os.PathLike = ".",
                        config_sha256: str | None = None, out_path: str | os.PathLike | None = None) -> dict:
    """The provenance record of ``results/<campaign>/`` (module docstring).

    Paths (raw files, stage inputs) are resolved against ``base``, the workflow's working directory
    where they were recorded. ``out_path`` (the provenance file itself) is left out of the stages.
    """
    root = Path(campaign_root)
    base = Path(base)
    commit, dirty = git_state()
    raw = raw_sources(root, base)
    exclude = (Path(out_path),) if out_path is not None else (root / FILE_NAME,)
    stage_list, index, unstamped = stages(root, base, exclude)
    changed = [f["path"] for f in raw["files"] if f["unchanged"] is False]
    outside = [f["path"] for f in raw["files"] if f.get("outside")]
    missing = [f["path"] for f in raw["files"] if raw["kind"] == "raw" and f["sha256_recorded"] and not f["exists"]]
    stale = [s["rule"] for s in stage_list if not s["inputs_current"]]
    inconsistent = [s["rule"] for s in stage_list if not s["consistent"]]
    return {
        "format_version": FORMAT_VERSION, "campaign": CampaignFolder.at(root).campaign, "created_utc": _now_utc(),
        "git": {"commit": commit, "dirty": dirty}, "config_sha256": config_sha256,
        "environment": environment(), "raw": raw, "stages": stage_list, "outputs": index,
        "checks": {"raw_unchanged": not changed and not missing and not outside, "changed_raw_files": changed,
                   "missing_raw_files": missing, "raw_files_outside": outside, "stale_stages": stale,
                   "inconsistent_stages": inconsistent, "files_without_lineage": unstamped,
                   "ok": not (changed or missing or outside or stale or inconsistent or unstamped)},
    }


def write_provenance(campaign_root: str | os.PathLike, out_path: str | os.PathLike, *,
                     base: str | os.PathLike = ".", config_sha256: str | None = None) -> dict:
    """:func:`campaign_provenance` written to ``out_path`` (io.write_json, with the job's lineage
    record when run by the pipeline); returns it."""
    prov = campaign_provenance(campaign_root, base=base, config_sha256=config_sha256, out_path=out_path)
    write_json(prov, out_path)
    for line in provenance_warnings(prov):
        log.warning("%s", line)
    return prov


def provenance_warnings(prov: Mapping) -> list[str]:
    """Readable lines for every failed check of a provenance record."""
    c, name = prov["checks"], prov["campaign"]
    lines = [f"campaign {name}: raw file {p} differs from its sha256 recorded at ingest" for p in
             c["changed_raw_files"]]
    lines += [f"campaign {name}: raw file {p} is missing" for p in c["missing_raw_files"]]
    lines += [f"campaign {name}: raw file {p} {OUTSIDE_NOTE}" for p in c.get("raw_files_outside", [])]
    lines += [f"campaign {name}: stage {r} ran on inputs that have changed since" for r in c["stale_stages"]]
    lines += [f"campaign {name}: outputs of stage {r} come from different runs" for r in c["inconsistent_stages"]]
    lines += [f"campaign {name}: {p} has no lineage record" for p in c["files_without_lineage"]]
    return lines


def files_without_lineage(results_dir: str | os.PathLike) -> list[str]:
    """Every Parquet, JSON and PNG file under ``results_dir`` that carries no lineage record."""
    out = []
    for f in sorted(p for p in Path(results_dir).rglob("*") if p.is_file() and p.suffix in LINEAGE_SUFFIXES):
        if f.name.startswith("."):
            continue
        try:
            rec = read_lineage(f)
        except (ValueError, OSError, json.JSONDecodeError):
            rec = None
        if not rec:
            out.append(f.as_posix())
    return out


__all__ = ["environment", "check_file", "raw_sources", "stages", "campaign_provenance", "write_provenance",
           "provenance_warnings", "files_without_lineage", "FILE_NAME", "PACKAGES"]
