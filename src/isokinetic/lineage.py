"""Lineage: which rule, code, parameters and inputs made a derived file.

Every Parquet file a rule writes carries, in its schema metadata under the key
``isokinetic.lineage``, a JSON record (:func:`stage_lineage`):

    {"rule": "windows", "campaign": "paper-lag-damper",
     "package_version": "0.1.0", "git_commit": "d1bfcc8…", "git_dirty": false,
     "python": "3.11.7", "params": {...}, "params_sha256": "…", "config_sha256": "…",
     "inputs": {"results/x/cases.parquet": "<sha256>", ...}, "created_utc": "2026-11-21T08:20:00Z"}

JSON outputs carry the same record under their top-level key ``lineage``. Row-level lineage
lives in the tables themselves (raw file, sha256, row range and time window of each window;
the keys of the rows an aggregate was computed from).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import platform
from collections.abc import Iterable, Mapping
from pathlib import Path

import pyarrow.parquet as pq

from . import __version__
from .io import sha256_file

METADATA_KEY = b"isokinetic.lineage"
REPO_ROOT = Path(__file__).resolve().parents[2]


def canonical_json(obj) -> str:
    """Stable JSON text (sorted keys, no spaces) for hashing."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def sha256_text(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def git_state(root: Path = REPO_ROOT) -> tuple[str | None, bool | None]:
    """(commit, dirty) of the code's git checkout.

    Pipeline jobs get both from the environment (ISOKINETIC_GIT_COMMIT, ISOKINETIC_GIT_DIRTY), set
    once by the workflow (workflow/rules/common.smk) in Snakemake's own process: a job never spawns
    git, because a subprocess in a process holding pyarrow's thread pools intermittently aborted it
    at exit. Elsewhere the commit is read from .git directly and ``dirty`` is None (unknown).
    """
    if "ISOKINETIC_GIT_COMMIT" in os.environ:
        dirty = {"1": True, "0": False}.get(os.environ.get("ISOKINETIC_GIT_DIRTY", ""))
        return os.environ["ISOKINETIC_GIT_COMMIT"] or None, dirty
    return read_head(root), None


def read_head(root: Path = REPO_ROOT) -> str | None:
    """The commit .git/HEAD points to, read from the files (None outside a checkout)."""
    git = root / ".git"
    try:
        head = (git / "HEAD").read_text(encoding="utf-8").strip()
        if not head.startswith("ref: "):
            return head or None
        ref = head[5:]
        if (git / ref).is_file():
            return (git / ref).read_text(encoding="utf-8").strip()
        for line in (git / "packed-refs").read_text(encoding="utf-8").splitlines():
            if line.endswith(" " + ref):
                return line.split()[0]
    except OSError:
        return None
    return None


def path_sha256(path: str | os.PathLike) -> str:
    """sha256 of a file, or of a folder's sorted (relative path, file sha256) listing."""
    path = Path(path)
    if path.is_dir():
        listing = [(str(p.relative_to(path)), sha256_file(p)) for p in sorted(path.rglob("*")) if p.is_file()]
        return sha256_text(canonical_json(listing))
    return sha256_file(path)


def stage_lineage(rule: str, params: Mapping, inputs: Iterable[str | os.PathLike], campaign: str | None = None,
                  config_sha256: str | None = None) -> dict:
    """The lineage record of one run of a rule (see the module docstring)."""
    commit, dirty = git_state()
    plain = json.loads(canonical_json(dict(params)))
    return {"rule": rule, "campaign": campaign, "package_version": __version__, "git_commit": commit,
            "git_dirty": dirty, "python": platform.python_version(), "params": plain,
            "params_sha256": sha256_text(canonical_json(plain)), "config_sha256": config_sha256,
            "inputs": {str(p): path_sha256(p) for p in inputs if Path(p).exists()},
            "created_utc": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}


def stamp_parquet(path: str | os.PathLike, lineage: Mapping) -> None:
    """Attach the lineage record to a Parquet file's schema metadata (rewritten atomically)."""
    from .io import _atomic

    table = pq.read_table(path)
    meta = dict(table.schema.metadata or {})
    meta[METADATA_KEY] = canonical_json(lineage).encode("utf-8")
    table = table.replace_schema_metadata(meta)
    _atomic(path, lambda tmp: pq.write_table(table, tmp))


def stamp_json(path: str | os.PathLike, lineage: Mapping) -> None:
    """Add the lineage record to a JSON object file under the key 'lineage' (rewritten atomically)."""
    from .io import write_json

    data = json.loads(Path(path).read_text(encoding="utf-8"))
    data["lineage"] = dict(lineage)
    write_json(data, path)


def read_lineage(path: str | os.PathLike) -> dict | None:
    """The lineage record of a Parquet or JSON file written by the pipeline (None when absent)."""
    path = Path(path)
    if path.suffix == ".json":
        return json.loads(path.read_text(encoding="utf-8")).get("lineage")
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(METADATA_KEY)
    return None if raw is None else json.loads(raw.decode("utf-8"))


def stamp_outputs(outputs: Iterable[str | os.PathLike], lineage: Mapping) -> list[Path]:
    """Stamp every Parquet and JSON file among the outputs (folders: every such file inside)."""
    stamped = []
    for out in outputs:
        out = Path(out)
        files = sorted(out.rglob("*")) if out.is_dir() else [out]
        for f in files:
            if f.suffix == ".parquet":
                stamp_parquet(f, lineage)
            elif f.suffix == ".json":
                try:
                    stamp_json(f, lineage)
                except (json.JSONDecodeError, AttributeError, TypeError):
                    continue
            else:
                continue
            stamped.append(f)
    return stamped


def from_snakemake(smk, config_path: str = "config/config.yaml") -> dict:
    """The lineage record of the running Snakemake job (rule, params, inputs, config hash)."""
    params = {k: v for k, v in smk.params.items()}
    campaign = getattr(smk.wildcards, "campaign", None) if hasattr(smk, "wildcards") else None
    config_sha = sha256_text(canonical_json(smk.config)) if getattr(smk, "config", None) is not None else None
    return stage_lineage(smk.rule, params, list(smk.input), campaign=campaign, config_sha256=config_sha)
