"""Cost of the lineage stamps per job: written with the file now, written then rewritten before.

Run: .venv/bin/python benchmark/lineage_stamps.py [--campaign results/paper-lag-damper] [--repeat 25]

A typical job's outputs, from a built campaign folder: its windows.parquet, its diagnosis.json and
its six figures of the rule ``figures`` (Fig. 7-12; each redrawn from its PNG's pixels, so that the
PNG encoding is that of the real figure while the plotting, the same either way, does not add its
noise), written into a scratch folder

- the old way: written without a record, then each file read back and rewritten with it (the
  former ``lineage.stamp_parquet`` / ``stamp_json`` / ``stamp_png``, reimplemented below as they
  were: Parquet re-read and re-written, JSON re-parsed and re-dumped, PNG chunks parsed and an
  ``iTXt`` chunk inserted before ``IEND``);
- the new way: written once inside :func:`isokinetic.io.lineage_context` (the record in the
  Parquet schema, the JSON key, a PNG text chunk through ``savefig(metadata=...)``).

Each file is written both ways back to back (in turn old first and new first); the job's record
(:func:`isokinetic.audit.lineage.stage_lineage`) is built once either way and timed apart. Prints
medians over ``--repeat`` rounds, per file kind and per job. PNG encoding dominates the write time
and varies with the machine's load; the rewrite column is the work no longer done.
"""

from __future__ import annotations

import argparse
import json
import statistics
import struct
import tempfile
import time
import zlib
from collections.abc import Callable
from pathlib import Path

import matplotlib.image
import pandas as pd
import pyarrow.parquet as pq
from matplotlib.figure import Figure

from isokinetic.audit.lineage import stage_lineage
from isokinetic.io import LINEAGE_KEY, canonical_json, lineage_context, write_atomic, write_json, write_parquet
from isokinetic.plots.style import save_figure
from isokinetic.stages.figures import FIGURE_FILES

ROOT = Path(__file__).resolve().parents[1]
SIGNATURE_BYTES = 8  # a PNG file starts with its 8-byte signature


# ----------------------------------------------------------------------------------------------
# the old way: rewrite after writing (as isokinetic.lineage did before the stamps moved into io)
# ----------------------------------------------------------------------------------------------

def old_stamp_parquet(path: Path, record: dict) -> None:
    table = pq.read_table(path)
    meta = dict(table.schema.metadata or {})
    meta[LINEAGE_KEY.encode()] = canonical_json(record).encode("utf-8")
    table = table.replace_schema_metadata(meta)
    write_atomic(path, lambda tmp: pq.write_table(table, tmp))


def old_stamp_json(path: Path, record: dict) -> None:
    data = json.loads(path.read_text(encoding="utf-8"))
    data["lineage"] = dict(record)
    write_json(data, path)


def _png_chunks(data: bytes) -> list[tuple[bytes, bytes]]:
    chunks, pos = [], SIGNATURE_BYTES
    while pos < len(data):
        (length,), kind = struct.unpack(">I", data[pos:pos + 4]), data[pos + 4:pos + 8]
        chunks.append((kind, data[pos + 8:pos + 8 + length]))
        pos += 12 + length
        if kind == b"IEND":
            break
    return chunks


def _png_chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def old_stamp_png(path: Path, record: dict) -> None:
    key = LINEAGE_KEY.encode()
    data = path.read_bytes()
    chunks = [c for c in _png_chunks(data) if not (c[0] == b"iTXt" and c[1].startswith(key + b"\0"))]
    text = key + b"\0" + b"\0\0" + b"\0" + b"\0" + canonical_json(record).encode("utf-8")
    out = [data[:SIGNATURE_BYTES]]
    for kind, payload in chunks:
        if kind == b"IEND":
            out.append(_png_chunk(b"iTXt", text))
        out.append(_png_chunk(kind, payload))
    write_atomic(path, lambda tmp: Path(tmp).write_bytes(b"".join(out)))


# ----------------------------------------------------------------------------------------------
# one job, both ways
# ----------------------------------------------------------------------------------------------

def pixel_figures(campaign: Path, dpi: int = 120) -> list[Figure]:
    """The campaign's six figures, as figures showing their own pixels at the same size."""
    figs = []
    for name in FIGURE_FILES:
        pixels = matplotlib.image.imread(campaign / "figures" / name)
        fig = Figure(figsize=(pixels.shape[1] / dpi, pixels.shape[0] / dpi), dpi=dpi)
        fig.figimage(pixels)
        figs.append(fig)
    return figs


KINDS = ("parquet", "json", "png")
STAMP = {"parquet": old_stamp_parquet, "json": old_stamp_json, "png": old_stamp_png}


def writers(figs: list[Figure], windows: pd.DataFrame, diagnosis: dict) -> list[tuple[str, Callable[[Path], Path]]]:
    """(kind, write the file into a folder) for each file of the job, by the package's writers (isokinetic.io)."""
    out = [("parquet", lambda d: write_parquet(windows, d / "windows.parquet")),
           ("json", lambda d: write_json(diagnosis, d / "diagnosis.json"))]
    return out + [("png", lambda d, fig=fig, name=name: save_figure(fig, d / "figures" / name))
                  for fig, name in zip(figs, FIGURE_FILES, strict=True)]


def one_round(files, out: Path, record: dict, old_first: bool) -> dict[str, float]:
    """Seconds, per kind: old write, old stamp (rewrite), new write (with the record); each file both
    ways back to back, in turn old first and new first."""
    t = {f"{step} {kind}": 0.0 for kind in KINDS for step in ("old write", "old stamp", "new write")}
    for kind, write in files:
        for way in ("old", "new") if old_first else ("new", "old"):
            start = time.perf_counter()
            if way == "new":
                with lineage_context(record):
                    write(out / "new")
                t[f"new write {kind}"] += time.perf_counter() - start
                continue
            path = write(out / "old")
            written = time.perf_counter()
            STAMP[kind](path, record)
            t[f"old write {kind}"] += written - start
            t[f"old stamp {kind}"] += time.perf_counter() - written
    return t


def timed(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", default=str(ROOT / "results" / "paper-lag-damper"),
                        help="a built campaign folder (results/<campaign>)")
    parser.add_argument("--repeat", type=int, default=25)
    args = parser.parse_args()
    campaign = Path(args.campaign)
    windows = pd.read_parquet(campaign / "windows.parquet")
    diagnosis = {k: v for k, v in json.loads((campaign / "diagnosis.json").read_text()).items() if k != "lineage"}
    inputs = [campaign / "cases.parquet", campaign / "ingest"]
    figs = pixel_figures(campaign)
    t_record = statistics.median(timed(lambda: stage_lineage("windows", {}, inputs)) for _ in range(args.repeat))
    record = stage_lineage("windows", {"start_fraction": 0.45, "end_fraction": 0.95}, inputs,
                           campaign=campaign.name, config_sha256="0" * 64)
    with tempfile.TemporaryDirectory() as tmp:
        files = writers(figs, windows, diagnosis)
        rounds = [one_round(files, Path(tmp) / str(i), record, old_first=i % 2 == 0)
                  for i in range(args.repeat + 1)][1:]  # the first round warms the caches
        png_kB = sum(p.stat().st_size for p in (Path(tmp) / "1" / "new").rglob("*.png")) / 1024
        job_kB = sum(p.stat().st_size for p in (Path(tmp) / "1" / "old").rglob("*") if p.is_file()) / 1024

    def med(key: Callable[[dict], float]) -> float:  # median over the rounds, ms
        return 1e3 * statistics.median(key(r) for r in rounds)

    def old_write(r, kinds=KINDS):
        return sum(r[f"old write {k}"] for k in kinds)

    def rewrite(r, kinds=KINDS):
        return sum(r[f"old stamp {k}"] for k in kinds)

    def new_write(r, kinds=KINDS):
        return sum(r[f"new write {k}"] for k in kinds)

    print(f"{campaign}: windows.parquet ({len(windows)} rows), diagnosis.json, six figures ({png_kB:.0f} kB); "
          f"median of {args.repeat} rounds, ms")
    print(f"  {'':8} {'old: write':>11} {'+ rewrite':>10} {'new: write':>11} {'saved':>8}")
    for label, kinds in [(k, (k,)) for k in KINDS] + [("job", KINDS)]:
        old, again, new = (med(lambda r, f=f, ks=kinds: f(r, ks)) for f in (old_write, rewrite, new_write))
        saved = med(lambda r, ks=kinds: old_write(r, ks) + rewrite(r, ks) - new_write(r, ks))
        print(f"  {label:8} {old:11.1f} {again:10.1f} {new:11.1f} {saved:8.1f}")
    print(f"  the job's lineage record, built once either way (inputs hashed once): {1e3 * t_record:.1f} ms")
    print(f"  read back and rewritten after writing: 8 files, {job_kB:.0f} kB before; none now")


if __name__ == "__main__":
    main()
