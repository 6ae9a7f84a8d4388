"""Lineage: which rule, code, parameters and inputs made a derived file.

Every Parquet file a rule writes carries, in its schema metadata under the key
``isokinetic.lineage``, a JSON record (:func:`stage_lineage`):

    {"rule": "windows", "campaign": "paper-lag-damper",
     "package_version": "0.1.0", "git_commit": "d1bfcc8…", "git_dirty": false,
     "python": "3.11.7", "params": {...}, "params_sha256": "…", "config_sha256": "…",
     "inputs": {"results/x/cases.parquet": "<sha256>", ...}, "created_utc": "2026-11-21T08:20:00Z"}

JSON outputs carry the same record under their top-level key ``lineage``; PNG figures in an
``iTXt`` chunk with the keyword ``isokinetic.lineage`` (pixels untouched). Row-level lineage
lives in the tables themselves (raw file, sha256, row range and time window of each window;
the keys of the rows an aggregate was computed from, written by :func:`row_keys`).

A pipeline script ends with ``finish(snakemake)``: the job's record (:func:`from_snakemake`) on
every output (:func:`stamp_outputs`, folders: every Parquet, JSON and PNG file inside).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import platform
import struct
import zlib
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
    from .io import write_atomic

    table = pq.read_table(path)
    meta = dict(table.schema.metadata or {})
    meta[METADATA_KEY] = canonical_json(lineage).encode("utf-8")
    table = table.replace_schema_metadata(meta)
    write_atomic(path, lambda tmp: pq.write_table(table, tmp))


def stamp_json(path: str | os.PathLike, lineage: Mapping) -> None:
    """Add the lineage record to a JSON object file under the key 'lineage' (rewritten atomically)."""
    from .io import write_json

    data = json.loads(Path(path).read_text(encoding="utf-8"))
    data["lineage"] = dict(lineage)
    write_json(data, path)


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    """(type, payload) of every chunk of a PNG file's bytes (ValueError if not a PNG)."""
    if not data.startswith(PNG_SIGNATURE):
        raise ValueError("not a PNG file")
    chunks, pos = [], len(PNG_SIGNATURE)
    while pos < len(data):
        if pos + 8 > len(data):
            raise ValueError("truncated PNG chunk header")
        (length,), kind = struct.unpack(">I", data[pos:pos + 4]), data[pos + 4:pos + 8]
        payload = data[pos + 8:pos + 8 + length]
        if len(payload) != length:
            raise ValueError("truncated PNG chunk")
        chunks.append((kind, payload))
        pos += 12 + length
        if kind == b"IEND":
            break
    return chunks


def _png_chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def _is_lineage_chunk(kind: bytes, payload: bytes) -> bool:
    return kind == b"iTXt" and payload.startswith(METADATA_KEY + b"\0")


def stamp_png(path: str | os.PathLike, lineage: Mapping) -> None:
    """Put the lineage record in a PNG's ``iTXt`` chunk (keyword ``isokinetic.lineage``, before IEND).

    The image chunks are copied byte for byte; an earlier lineage chunk is replaced.
    """
    from .io import write_atomic

    chunks = [c for c in _png_chunks(Path(path).read_bytes()) if not _is_lineage_chunk(*c)]
    # iTXt: keyword NUL, compression flag, compression method, language tag NUL, translated keyword NUL, text
    text = METADATA_KEY + b"\0" + b"\0\0" + b"\0" + b"\0" + canonical_json(lineage).encode("utf-8")
    out = [PNG_SIGNATURE]
    for kind, payload in chunks:
        if kind == b"IEND":
            out.append(_png_chunk(b"iTXt", text))
        out.append(_png_chunk(kind, payload))

    def write(tmp):
        Path(tmp).write_bytes(b"".join(out))
    write_atomic(path, write)


def _png_lineage(path: Path) -> dict | None:
    for kind, payload in _png_chunks(path.read_bytes()):
        if _is_lineage_chunk(kind, payload):
            # keyword NUL flag method language NUL translated NUL text
            rest = payload[len(METADATA_KEY) + 1:]
            flag, rest = rest[0], rest[2:]
            _lang, _, rest = rest.partition(b"\0")
            _trans, _, text = rest.partition(b"\0")
            if flag:
                text = zlib.decompress(text)
            return json.loads(text.decode("utf-8"))
    return None


#: File types that carry a lineage record.
STAMPED_SUFFIXES = (".parquet", ".json", ".png")


def read_lineage(path: str | os.PathLike) -> dict | None:
    """The lineage record of a Parquet, JSON or PNG file written by the pipeline (None when absent)."""
    path = Path(path)
    if path.suffix == ".json":
        data = json.loads(path.read_text(encoding="utf-8"))
        return data.get("lineage") if isinstance(data, dict) else None
    if path.suffix == ".png":
        return _png_lineage(path)
    meta = pq.read_schema(path).metadata or {}
    raw = meta.get(METADATA_KEY)
    return None if raw is None else json.loads(raw.decode("utf-8"))


def stamp_outputs(outputs: Iterable[str | os.PathLike], lineage: Mapping) -> list[Path]:
    """Stamp every Parquet, JSON and PNG file among the outputs (folders: every such file inside).

    Other files (CSV, YAML, logs) and JSON files whose top level is not an object are left as they are.
    """
    stamped = []
    for out in outputs:
        out = Path(out)
        files = sorted(p for p in out.rglob("*") if p.is_file()) if out.is_dir() else [out]
        for f in files:
            if f.name.startswith("."):          # an atomic write's temporary file
                continue
            if f.suffix == ".parquet":
                stamp_parquet(f, lineage)
            elif f.suffix == ".png":
                stamp_png(f, lineage)
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
    """The lineage record of the running Snakemake job (rule, params, inputs, config hash).

    Besides :func:`stage_lineage`'s keys: ``wildcards`` (all of the job's wildcards) and ``log``
    (the job's log files), so a record leads to the log of the run that made the file.
    """
    params = {k: v for k, v in smk.params.items()}
    wildcards = dict(smk.wildcards.items()) if hasattr(smk, "wildcards") else {}
    campaign = wildcards.get("campaign")
    config_sha = sha256_text(canonical_json(smk.config)) if getattr(smk, "config", None) is not None else None
    record = stage_lineage(smk.rule, params, list(smk.input), campaign=campaign, config_sha256=config_sha)
    record["wildcards"] = {str(k): str(v) for k, v in wildcards.items()}
    record["log"] = [str(p) for p in getattr(smk, "log", [])]
    return record


def finish(smk) -> list[Path]:
    """Last line of every pipeline script: stamp the job's outputs with its lineage record."""
    return stamp_outputs(smk.output, from_snakemake(smk))


# ----------------------------------------------------------------------------------------------
# row-level lineage: keys of the rows an aggregate was computed from
# ----------------------------------------------------------------------------------------------

def row_keys(frame, columns: Iterable[str] = ("case", "segment")) -> str:
    """Compact explicit list of row keys: 'T01/1,T01/2,T02/1' (values joined by '/', rows by ',').

    Case ids cannot hold '/' or ',' (manifest.CASE_ID_RULE), so the text parses back unambiguously
    (:func:`parse_row_keys`). Rows keep the frame's order; duplicates are dropped.
    """
    columns = list(columns)
    seen, keys = set(), []
    for values in frame[columns].itertuples(index=False, name=None):
        key = "/".join(str(v) for v in values)
        if key not in seen:
            seen.add(key)
            keys.append(key)
    return ",".join(keys)


def parse_row_keys(text: str) -> list[tuple[str, int]]:
    """(case, segment) pairs of a :func:`row_keys` text over ('case', 'segment')."""
    out = []
    for key in filter(None, (text or "").split(",")):
        case, _, segment = key.rpartition("/")
        out.append((case, int(segment)))
    return out
