"""File helpers: atomic writes, content hashes, and the lineage record attached as a file is written.

Where is the lineage record attached? Here, and only here. A pipeline job (:mod:`isokinetic.job`)
builds its record once (:func:`isokinetic.audit.lineage.from_snakemake`) and enters
:func:`lineage_context`; until the block ends, every file written by this module's writers
carries that record as it is written, never by a rewrite afterwards:

- Parquet (:func:`write_parquet`): schema metadata under the key ``isokinetic.lineage``
  (:data:`LINEAGE_KEY`), the record as :func:`canonical_json` text;
- JSON (:func:`write_json`): the top-level key ``lineage`` of an object (a list is left as it is);
- PNG (:func:`write_png`, behind :func:`isokinetic.plots.style.save_figure`): a text chunk with the
  keyword ``isokinetic.lineage`` (matplotlib's ``savefig(metadata=...)``, written by Pillow).

The context is a :class:`contextvars.ContextVar`: scoped to the ``with`` block of one job, it
leaves no global state behind and stage functions need no lineage argument. Outside a context
(tests, ``python -m isokinetic trace`` scratch folders) files carry no record.
:func:`read_lineage` reads the record back from all three kinds of file.

Within :func:`hash_once` (a job's block too), :func:`sha256_file` reads a file once: the job's
record hashes every input, and a stage that hashes the same file again (ingest's raw files, the
report's sources) gets the hash already made, unless the file's size, mtime or inode changed.
"""

from __future__ import annotations

import contextvars
import datetime as dt
import hashlib
import json
import math
import os
import re
import tempfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import pyarrow as pa
import pyarrow.parquet as pq

if TYPE_CHECKING:  # annotations only: a job that reads no table with pandas (raw_check) never loads it (issue 23)
    import pandas as pd

#: Key of the record: Parquet schema metadata, PNG text keyword.
LINEAGE_KEY = "isokinetic.lineage"
#: Top-level key of the record in a JSON object.
JSON_LINEAGE_KEY = "lineage"
#: File types that carry a lineage record.
LINEAGE_SUFFIXES = (".parquet", ".json", ".png")

_RECORD: contextvars.ContextVar[Mapping | None] = contextvars.ContextVar("isokinetic_lineage", default=None)
_HASHES: contextvars.ContextVar[dict | None] = contextvars.ContextVar("isokinetic_hashes", default=None)


def _read_sha256(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes (read once within :func:`hash_once`)."""
    memo = _HASHES.get()
    if memo is None:
        return _read_sha256(path)
    st = os.stat(path)
    key, stamp = os.path.realpath(path), (st.st_size, st.st_mtime_ns, st.st_ino)
    if key not in memo or memo[key][0] != stamp:
        memo[key] = (stamp, _read_sha256(path))
    return memo[key][1]


@contextmanager
def hash_once() -> Iterator[None]:
    """Within the block, each file is hashed once (again only when its size, mtime or inode changed)."""
    token = _HASHES.set({})
    try:
        yield
    finally:
        _HASHES.reset(token)


def canonical_json(obj) -> str:
    """Stable JSON text (sorted keys, no spaces, ASCII): for hashing, and the record's text in a file."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


# ----------------------------------------------------------------------------------------------
# the lineage context
# ----------------------------------------------------------------------------------------------

@contextmanager
def lineage_context(record: Mapping | None) -> Iterator[Mapping | None]:
    """Within the block, every file written by this module's writers carries ``record``."""
    token = _RECORD.set(record)
    try:
        yield record
    finally:
        _RECORD.reset(token)


def current_lineage() -> Mapping | None:
    """The record of the enclosing :func:`lineage_context` (None outside one)."""
    return _RECORD.get()


#: Vector formats a figure may also be written in, beside its PNG (config ``figures.vector_format``).
VECTOR_FORMATS = ("svg", "pdf")
_VECTOR: contextvars.ContextVar[str | None] = contextvars.ContextVar("isokinetic_vector_format", default=None)


@contextmanager
def vector_figures(vector_format: str | None) -> Iterator[str | None]:
    """Within the block every figure saved as a PNG (:func:`write_png`'s callers, through
    :func:`isokinetic.plots.style.save_figure`) is also written as ``vector_format`` (``svg`` or ``pdf``)
    beside it; None or ``none``: PNG only. A job enters it with its rule's ``vector_format`` param."""
    fmt = None if vector_format in (None, "none") else str(vector_format)
    if fmt is not None and fmt not in VECTOR_FORMATS:
        raise ValueError(f"vector format {vector_format!r}: expected one of none, {', '.join(VECTOR_FORMATS)}")
    token = _VECTOR.set(fmt)
    try:
        yield fmt
    finally:
        _VECTOR.reset(token)


def current_vector_format() -> str | None:
    """The format of the enclosing :func:`vector_figures` block (None outside one)."""
    return _VECTOR.get()


# ----------------------------------------------------------------------------------------------
# atomic writes
# ----------------------------------------------------------------------------------------------

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


def parquet_table(df: pd.DataFrame) -> pa.Table:
    """The Arrow table ``DataFrame.to_parquet(index=False)`` writes, plus the current lineage record."""
    table = pa.Table.from_pandas(df, preserve_index=False)
    meta = dict(table.schema.metadata or {})
    if df.attrs:  # as pandas does
        meta[b"PANDAS_ATTRS"] = json.dumps(df.attrs).encode("utf-8")
    record = current_lineage()
    if record is not None:
        meta[LINEAGE_KEY.encode("utf-8")] = canonical_json(record).encode("utf-8")
    return table.replace_schema_metadata(meta)


def write_parquet(df: pd.DataFrame, path: str | os.PathLike) -> Path:
    """Write a Parquet file atomically (a reader never sees a half-written file), with the lineage
    record of the current context in its schema metadata."""
    table = parquet_table(df)
    return write_atomic(path, lambda tmp: pq.write_table(table, tmp, compression="snappy"))


def write_json(obj, path: str | os.PathLike) -> Path:
    """Write JSON atomically, keys sorted, for byte-stable outputs; an object gets the current
    lineage record under its top-level key ``lineage`` (``obj`` itself is not changed)."""
    record = current_lineage()
    if record is not None and isinstance(obj, Mapping):
        obj = {**obj, JSON_LINEAGE_KEY: dict(record)}

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            json.dump(obj, fh, indent=2, sort_keys=True, allow_nan=False)
            fh.write("\n")
    return write_atomic(path, write)


#: zlib level of the PNGs written (Pillow's default is 6): level 1 compresses a figure about twice as
#: fast (20-50 ms less for a large one) for files ~5 % larger; the pixels are the same.
PNG_COMPRESS_LEVEL = 1


def write_png(fig, path: str | os.PathLike, *, dpi: float, metadata: Mapping[str, str | None] | None = None) -> Path:
    """Write a matplotlib figure as a PNG atomically (zlib level :data:`PNG_COMPRESS_LEVEL`);
    ``metadata`` becomes text chunks (``savefig(metadata=...)``), the current lineage record one more
    (keyword ``isokinetic.lineage``)."""
    meta = dict(metadata or {})
    record = current_lineage()
    if record is not None:
        meta[LINEAGE_KEY] = canonical_json(record)
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=dpi, metadata=meta,
                                                      pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL}))


def write_vector(fig, path: str | os.PathLike, vector_format: str) -> Path:
    """Write a matplotlib figure as SVG or PDF atomically, byte for byte reproducible: no date, no software
    stamp, fixed SVG element ids; the current lineage record in the document's description (SVG
    ``Description``, PDF ``Subject``)."""
    import matplotlib  # only where a figure is written

    record = current_lineage()
    lineage = None if record is None else canonical_json(record)
    if vector_format == "svg":
        meta = {"Date": None, "Creator": None, "Description": lineage}
    elif vector_format == "pdf":
        meta = {"CreationDate": None, "ModDate": None, "Creator": None, "Producer": None, "Subject": lineage}
    else:
        raise ValueError(f"vector format {vector_format!r}: expected one of {', '.join(VECTOR_FORMATS)}")
    with matplotlib.rc_context({"svg.hashsalt": "isokinetic", "svg.fonttype": "path"}):
        return write_atomic(path, lambda tmp: fig.savefig(tmp, format=vector_format, metadata=meta))


def write_text(text: str, path: str | os.PathLike) -> Path:
    """Write a text file atomically with '\\n' line ends."""
    def write(tmp):
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
    return write_atomic(path, write)


# ----------------------------------------------------------------------------------------------
# reading the record back
# ----------------------------------------------------------------------------------------------

def _png_text(path: Path) -> str | None:
    from PIL import Image  # only where a PNG is read back (a job that draws has Pillow through matplotlib)

    with Image.open(path) as image:
        if image.format != "PNG":
            raise ValueError(f"{path}: not a PNG file")
        text = image.info.get(LINEAGE_KEY)  # chunks before the image data
        if text is None:                    # chunks after it (files stamped by earlier versions)
            text = image.text.get(LINEAGE_KEY)
    return None if text is None else str(text)


def read_lineage(path: str | os.PathLike) -> dict | None:
    """The lineage record of a Parquet, JSON or PNG file written by the pipeline (None when absent)."""
    path = Path(path)
    if path.suffix == ".json":
        data = json.loads(path.read_text(encoding="utf-8"))
        return data.get(JSON_LINEAGE_KEY) if isinstance(data, dict) else None
    if path.suffix == ".png":
        text = _png_text(path)
        return None if text is None else json.loads(text)
    raw = (pq.read_schema(path).metadata or {}).get(LINEAGE_KEY.encode("utf-8"))
    return None if raw is None else json.loads(raw.decode("utf-8"))


def jsonable(value):
    """Metadata from YAML made JSON-safe: dates as ISO text, keys as text, non-finite floats as text."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (dt.date, dt.datetime)):
        return value.isoformat()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)
