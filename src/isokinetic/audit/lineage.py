"""Lineage: which rule, code, parameters and inputs made a derived file.

A job's lineage record (:func:`stage_lineage`, from a Snakemake job :func:`from_snakemake`):

    {"rule": "windows", "campaign": "paper-lag-damper",
     "package_version": "0.1.0", "git_commit": "d1bfcc8…", "git_dirty": false,
     "python": "3.11.7", "params": {...}, "params_sha256": "…", "config_sha256": "…",
     "inputs": {"results/x/cases.parquet": "<sha256>", ...}, "created_utc": "2026-11-21T08:20:00Z",
     "wildcards": {"campaign": "paper-lag-damper"}, "log": ["logs/paper-lag-damper/windows.log"]}

This module builds the record; :mod:`isokinetic.io` attaches it to every Parquet, JSON and PNG file
as the file is written (and reads it back, :func:`isokinetic.io.read_lineage`): a job enters
``isokinetic.io.lineage_context(record)`` through :func:`isokinetic.job.job`, once. Row-level
lineage lives in the tables themselves (raw file, sha256, row range and time window of each
window; the keys of the rows an aggregate was computed from, written by :func:`row_keys`).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import platform
from collections.abc import Iterable, Mapping
from pathlib import Path

from isokinetic import __version__
from isokinetic.io import canonical_json, sha256_file

__all__ = ["sha256_text", "git_state", "read_head", "path_sha256", "stage_lineage", "from_snakemake"]


def sha256_text(text: str) -> str:
    """Hex sha256 of a text's UTF-8 bytes."""
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def git_state() -> tuple[str | None, bool | None]:
    """(commit, dirty) of the code's git checkout.

    Pipeline jobs get both from the environment (ISOKINETIC_GIT_COMMIT, ISOKINETIC_GIT_DIRTY), set
    once by the workflow (workflow/rules/common.smk) in Snakemake's own process: a job never spawns
    git, because a subprocess in a process holding pyarrow's thread pools intermittently aborted it
    at exit. Elsewhere the commit is read from the .git of the working directory's checkout (not
    the package's install location: an installed package has none) and ``dirty`` is None (unknown).
    """
    if "ISOKINETIC_GIT_COMMIT" in os.environ:
        dirty = {"1": True, "0": False}.get(os.environ.get("ISOKINETIC_GIT_DIRTY", ""))
        return os.environ["ISOKINETIC_GIT_COMMIT"] or None, dirty
    return read_head(), None


def _git_dir(start: Path) -> Path | None:
    """The git folder of the checkout holding ``start`` (a worktree's ``.git`` file followed)."""
    for folder in (start, *start.parents):
        git = folder / ".git"
        if git.is_dir():
            return git
        if git.is_file():
            text = git.read_text(encoding="utf-8").strip()
            if text.startswith("gitdir: "):
                return (folder / text[len("gitdir: "):]).resolve()
    return None


def read_head(start: str | os.PathLike | None = None) -> str | None:
    """The commit HEAD points to in the checkout holding ``start`` (default: the working
    directory), read from the files; None outside a checkout."""
    try:
        git = _git_dir(Path(start if start is not None else Path.cwd()).resolve())
        if git is None:
            return None
        head = (git / "HEAD").read_text(encoding="utf-8").strip()
        if not head.startswith("ref: "):
            return head or None
        ref = head[5:]
        common = git / "commondir"  # a worktree keeps its branches in the main checkout's git folder
        places = [git] + ([(git / common.read_text(encoding="utf-8").strip()).resolve()] if common.is_file() else [])
        for place in places:
            if (place / ref).is_file():
                return (place / ref).read_text(encoding="utf-8").strip()
            packed = place / "packed-refs"
            if packed.is_file():
                for line in packed.read_text(encoding="utf-8").splitlines():
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
    """The lineage record of one run of a rule (see the module docstring); every input hashed once."""
    commit, dirty = git_state()
    plain = json.loads(canonical_json(dict(params)))
    return {"rule": rule, "campaign": campaign, "package_version": __version__, "git_commit": commit,
            "git_dirty": dirty, "python": platform.python_version(), "params": plain,
            "params_sha256": sha256_text(canonical_json(plain)), "config_sha256": config_sha256,
            "inputs": {str(p): path_sha256(p) for p in inputs if Path(p).exists()},
            "created_utc": dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")}


def from_snakemake(smk) -> dict:
    """The lineage record of the running Snakemake job (rule, params, inputs, config hash).

    Besides :func:`stage_lineage`'s keys: ``wildcards`` (all of the job's wildcards) and ``log``
    (the job's log files), so a record leads to the log of the run that made the file.
    """
    params = dict(smk.params.items())
    wildcards = dict(smk.wildcards.items()) if hasattr(smk, "wildcards") else {}
    campaign = wildcards.get("campaign")
    config_sha = sha256_text(canonical_json(smk.config)) if getattr(smk, "config", None) is not None else None
    record = stage_lineage(smk.rule, params, list(smk.input), campaign=campaign, config_sha256=config_sha)
    record["wildcards"] = {str(k): str(v) for k, v in wildcards.items()}
    record["log"] = [str(p) for p in getattr(smk, "log", [])]
    return record


# ----------------------------------------------------------------------------------------------
# row-level lineage: keys of the rows an aggregate was computed from
# ----------------------------------------------------------------------------------------------
