"""File helpers: atomic writes and content hashes."""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
from pathlib import Path

import pandas as pd


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


_TMP_SUFFIX = ".tmp"


def _is_tmp_of(candidate: str, name: str) -> bool:
    """Whether ``candidate`` is a temporary sibling ``write_atomic`` makes for the file ``name``
    (``.<name>.<8 random characters>.tmp``, as ``tempfile.mkstemp`` names it)."""
    return re.fullmatch(rf"\.{re.escape(name)}\.[a-z0-9_]{{8}}{re.escape(_TMP_SUFFIX)}", candidate) is not None


def remove_stale_tmp(path: str | os.PathLike) -> list[Path]:
    """Delete the temporary siblings a killed writer of ``path`` left behind; return them.

    A writer killed between creating its temporary file and renaming it (SIGKILL, power loss)
    cannot clean up. The next writer of the same output does: Snakemake's directory lock admits
    one build per tree and one job per output, so any such sibling is stale.
    """
    path = Path(path)
    if not path.parent.is_dir():
        return []
    stale = [p for p in path.parent.iterdir() if _is_tmp_of(p.name, path.name)]
    for p in stale:
        p.unlink(missing_ok=True)
    return stale


def write_atomic(path: str | os.PathLike, write) -> Path:
    """Write ``path`` through a temporary sibling and a rename: a reader sees the old file or the
    new one, never a part. ``write(tmp)`` fills the temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_tmp(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=_TMP_SUFFIX)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are ordinary files
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_parquet(df: pd.DataFrame, path: str | os.PathLike) -> Path:
    """Write a Parquet file atomically (a reader never sees a half-written file)."""
    return write_atomic(path, lambda tmp: df.to_parquet(tmp, index=False))


def write_json(obj, path: str | os.PathLike) -> Path:
    """Write JSON atomically, keys sorted, for byte-stable outputs."""
    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(obj, fh, indent=2, sort_keys=True, allow_nan=False)
            fh.write("\n")
    return write_atomic(path, write)


def write_text(text: str, path: str | os.PathLike) -> Path:
    """Write a text file atomically with '\\n' line ends."""
    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
    return write_atomic(path, write)
