"""What of a raw campaign folder the workflow may touch (issue 20, finding 2).

- :func:`folder_problem`: a campaign folder that resolves outside the raw data folder (a symlink to
  elsewhere) is refused with its reason; nothing in it is read.
- :func:`manifest_files`: the files a campaign's ingest reads, the manifest and every case file it names
  (a relative path, possibly into a subfolder); only these are handed to Snakemake and hashed. A file whose
  path holds one of Snakemake's pattern characters (``{}`` wildcards, ``<>`` path variables) cannot be given
  to Snakemake as a path (it would be expanded as a pattern): :func:`snakemake_inputs` gives it as a
  fingerprint (size and modification time) for a parameter instead, so that a change still reruns ingest.
- :func:`unused_entries`: every other entry of the folder, listed by name only (never opened, hashed or
  followed), a symlink leading out of the folder marked as such.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from isokinetic.contracts.manifest import MANIFEST_NAME, load_manifest

#: Characters Snakemake reads as patterns in a path: ``{name}`` wildcards and ``<name>`` path variables.
PATTERN_CHARACTERS = re.compile(r"[{}<>]")
#: At most this many unused entries are listed (a note says how many more there are).
MAX_LISTED = 200


def plain_path(path: str) -> bool:
    """True when Snakemake takes ``path`` literally (no ``{}`` or ``<>``)."""
    return PATTERN_CHARACTERS.search(path) is None


def inside(path: Path, folder: Path) -> bool:
    """True when ``path`` (symlinks followed) lies inside ``folder`` (symlinks followed)."""
    try:
        path.resolve().relative_to(folder.resolve())
    except (ValueError, OSError, RuntimeError):
        return False
    return True


def folder_problem(campaign_dir: str | os.PathLike, raw_dir: str | os.PathLike) -> str | None:
    """Why the campaign folder may not be read (it resolves outside ``raw_dir``), or None."""
    folder, raw = Path(campaign_dir), Path(raw_dir)
    if not inside(folder, raw):
        return (f"campaign folder {folder.as_posix()} is a symlink leading outside {raw.as_posix()}/: "
                "refused, nothing in it is read (copy the campaign into the raw data folder)")
    return None


def manifest_files(campaign_dir: str | os.PathLike) -> list[str]:
    """The manifest and the case files it names, as paths relative to the folder, each once, in order: only
    regular files inside the folder (symlinks followed only when they stay inside). Just the manifest when it
    cannot be read (ingest then fails the campaign with the manifest's error); [] when even that is refused."""
    folder = Path(campaign_dir)
    names = [MANIFEST_NAME]
    try:
        names += [c.file for c in load_manifest(folder / MANIFEST_NAME).cases if c.file is not None]
    except Exception:  # noqa: BLE001 - any broken manifest: its ingest job names the error, the DAG stands
        pass
    out: list[str] = []
    for name in dict.fromkeys(names):
        path = folder / name
        if path.is_file() and inside(path, folder):
            out.append(name)
    return out


@dataclass(frozen=True)
class SnakemakeInputs:
    """A raw campaign's files for the ingest job: ``paths`` handed to Snakemake as inputs (plain paths) and
    ``fingerprints`` ('<name> <size> <mtime_ns>') of the files whose names Snakemake would read as patterns."""

    paths: tuple[str, ...]
    fingerprints: tuple[str, ...]


def snakemake_inputs(campaign_dir: str | os.PathLike) -> SnakemakeInputs:
    """:func:`manifest_files` split into plain paths (``campaign_dir/<name>``) and fingerprints."""
    folder = Path(campaign_dir)
    paths, prints = [], []
    for name in manifest_files(folder):
        path = (folder / name).as_posix()
        if plain_path(path):
            paths.append(path)
        else:
            st = (folder / name).stat()
            prints.append(f"{name} {st.st_size} {st.st_mtime_ns}")
    return SnakemakeInputs(tuple(paths), tuple(prints))


def _entry(folder: Path, path: Path) -> dict:
    rel = path.relative_to(folder).as_posix()
    if path.is_symlink():
        if not inside(path, folder):
            return {"path": rel, "kind": "symlink", "note": "symlink leading outside the campaign folder: not read"}
        return {"path": rel, "kind": "symlink", "note": "symlink inside the campaign folder"}
    kind = "file" if path.is_file() else "folder" if path.is_dir() else "other"
    return {"path": rel, "kind": kind, "note": "" if kind == "file" else "not a regular file"}


def unused_entries(campaign_dir: str | os.PathLike, used: Iterable[str], limit: int = MAX_LISTED) -> list[dict]:
    """Every entry of the folder (files, symlinks, FIFOs; subfolders walked, symlinked ones not followed) that
    is not one of ``used`` (paths relative to the folder): ``{path, kind, note}``, by name, nothing opened.
    At most ``limit`` entries, then one that says how many more there are."""
    folder = Path(campaign_dir)
    used = {Path(u).as_posix() for u in used}
    out, more = [], 0
    for top, dirs, files in os.walk(folder, followlinks=False):
        here = Path(top)
        dirs.sort()
        for name in sorted(files) + [d for d in dirs if (here / d).is_symlink()]:
            path = here / name
            if path.relative_to(folder).as_posix() in used:
                continue
            if len(out) < limit:
                out.append(_entry(folder, path))
            else:
                more += 1
    if more:
        out.append({"path": "", "kind": "more", "note": f"and {more} more entries not listed"})
    return out


__all__ = ["PATTERN_CHARACTERS", "plain_path", "inside", "folder_problem", "manifest_files", "SnakemakeInputs",
           "snakemake_inputs", "unused_entries"]
