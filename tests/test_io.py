"""Atomic writes: a reader never sees a part-written file, and a killed writer's leftovers go.
Lineage: the record attached as a file is written (Parquet, JSON, PNG), the data kept, the record read back."""

import json
import os
import struct
import subprocess
import sys
import textwrap
import zlib

import matplotlib.image
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from matplotlib.figure import Figure

from isokinetic.audit import lineage
from isokinetic.io import (
    LINEAGE_KEY,
    canonical_json,
    lineage_context,
    read_lineage,
    remove_stale_tmp,
    sha256_file,
    vector_figures,
    write_atomic,
    write_json,
    write_parquet,
)
from isokinetic.plots.style import save_figure


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    path = write_json({"a": 1}, tmp_path / "d.json")

    def broken(tmp):
        with open(tmp, "w") as fh:
            fh.write('{"a": ')
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        write_atomic(path, broken)
    assert path.read_text() == '{\n  "a": 1\n}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json"]


def test_killed_writer_leftover_is_removed_by_the_next_write_of_that_output(tmp_path):
    """A SIGKILL between creating the temporary file and the rename leaves it behind; the next
    write of the same output clears it (Snakemake reruns the killed job with --rerun-incomplete)."""
    target = tmp_path / "characteristic.parquet"
    script = textwrap.dedent(f"""
        import os, signal
        from isokinetic.io import write_atomic
        def die(tmp):
            open(tmp, "wb").write(b"PAR1 half")
            os.kill(os.getpid(), signal.SIGKILL)
        write_atomic({str(target)!r}, die)
    """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True)
    assert run.returncode == -9
    leftovers = [p.name for p in tmp_path.iterdir()]
    assert len(leftovers) == 1 and leftovers[0].startswith(".characteristic.parquet.")
    assert not target.exists()

    write_parquet(pd.DataFrame({"x": [1.0]}), target)
    assert [p.name for p in tmp_path.iterdir()] == ["characteristic.parquet"]
    assert pd.read_parquet(target)["x"].tolist() == [1.0]


def test_stale_temporary_clean_up_spares_other_outputs_and_their_files(tmp_path):
    mine = tmp_path / ".a.parquet.k3j9x_2q.tmp"
    longer_name = tmp_path / ".a.parquet.bak.k3j9x_2q.tmp"  # temporary of output 'a.parquet.bak'
    other = tmp_path / ".b.parquet.k3j9x_2q.tmp"
    user_file = tmp_path / ".a.parquet.notes.tmp"
    for p in (mine, longer_name, other, user_file):
        p.write_bytes(b"x")

    assert remove_stale_tmp(tmp_path / "a.parquet") == [mine]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in (longer_name, other, user_file))


def test_atomic_write_gives_ordinary_file_permissions(tmp_path):
    umask = os.umask(0o022)
    try:
        path = write_json({}, tmp_path / "d.json")
    finally:
        os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o644


# ----------------------------------------------------------------------------------------------
# the lineage record, attached as the file is written
# ----------------------------------------------------------------------------------------------

def frame(n=50):
    rng = np.random.default_rng(1)
    return pd.DataFrame({"case": [f"T{i % 5:02d}" for i in range(n)], "segment": np.arange(n, dtype="int64") % 4 + 1,
                         "force_N": rng.normal(size=n), "ok": rng.normal(size=n) > 0})


RECORD = lineage.stage_lineage("windows", {"start_fraction": 0.45}, [], campaign="demo")
PLAIN = json.loads(canonical_json(RECORD))


def figure() -> Figure:
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 0])
    return fig


def test_parquet_carries_the_record_in_its_schema_and_keeps_the_data(tmp_path):
    df = frame()
    plain = write_parquet(df, tmp_path / "plain.parquet")
    assert read_lineage(plain) is None
    df.to_parquet(tmp_path / "pandas.parquet", index=False)  # outside a job: the bytes pandas writes
    assert sha256_file(plain) == sha256_file(tmp_path / "pandas.parquet")
    with lineage_context(RECORD):
        path = write_parquet(df, tmp_path / "t.parquet")
    pd.testing.assert_frame_equal(pd.read_parquet(path), df)
    assert read_lineage(path) == PLAIN
    assert pq.read_schema(path).metadata[b"isokinetic.lineage"] == canonical_json(RECORD).encode()


def test_json_object_gets_one_key_and_keeps_the_rest(tmp_path):
    data = {"a": 1, "b": [1.5, None, "x"], "nested": {"k": True}}
    with lineage_context(RECORD):
        path = write_json(data, tmp_path / "d.json")
        listed = write_json([1, 2], tmp_path / "list.json")     # not an object: left alone
    got = json.loads(path.read_text())
    assert got.pop("lineage") == read_lineage(path) == PLAIN
    assert got == data and "lineage" not in data                # the caller's object is not changed
    assert json.loads(listed.read_text()) == [1, 2] and read_lineage(listed) is None


def test_png_carries_the_record_in_a_text_chunk_and_keeps_every_pixel(tmp_path):
    plain = save_figure(figure(), tmp_path / "plain.png")
    with lineage_context(RECORD):
        path = save_figure(figure(), tmp_path / "f.png")
    assert read_lineage(plain) is None and read_lineage(path) == PLAIN
    assert np.array_equal(matplotlib.image.imread(path), matplotlib.image.imread(plain))
    with lineage_context(RECORD):                               # same figure and record: same bytes
        again = save_figure(figure(), tmp_path / "g.png")
    assert sha256_file(again) == sha256_file(path)


@pytest.mark.parametrize("fmt, magic, stamp, absent", [
    ("svg", b"<?xml", b"<dc:description>", (b"<dc:date>", b"Matplotlib v")),
    ("pdf", b"%PDF", b"/Subject", (b"/CreationDate", b"/Producer"))])
def test_a_vector_copy_is_written_beside_the_png_reproducibly_with_the_record(tmp_path, fmt, magic, stamp, absent):
    with lineage_context(RECORD), vector_figures(fmt):
        save_figure(figure(), tmp_path / "f.png")
        save_figure(figure(), tmp_path / "g.png")
    first, second = (tmp_path / f"f.{fmt}").read_bytes(), (tmp_path / f"g.{fmt}").read_bytes()
    assert first.startswith(magic) and first == second      # no date, no random ids: same figure, same bytes
    assert stamp in first and not any(x in first for x in absent)
    assert (tmp_path / "f.png").is_file()


def test_no_vector_copy_outside_a_block_or_with_none(tmp_path):
    save_figure(figure(), tmp_path / "a.png")
    with vector_figures("none"):
        save_figure(figure(), tmp_path / "b.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png"]
    with pytest.raises(ValueError, match="expected one of none, svg, pdf"), vector_figures("eps"):
        pass


def _chunk(kind: bytes, payload: bytes) -> bytes:
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))


def test_png_stamped_by_earlier_versions_still_reads(tmp_path):
    """Earlier versions rewrote the PNG with an iTXt chunk before IEND (after the image data)."""
    data = save_figure(figure(), tmp_path / "plain.png").read_bytes()
    itxt = LINEAGE_KEY.encode() + b"\0\0\0\0\0" + canonical_json(RECORD).encode()
    end = data.rindex(b"IEND") - 4
    old = tmp_path / "old.png"
    old.write_bytes(data[:end] + _chunk(b"iTXt", itxt) + data[end:])
    assert read_lineage(old) == PLAIN


def test_every_file_written_in_the_context_is_stamped_folders_included(tmp_path):
    folder = tmp_path / "ingest"
    with lineage_context(RECORD):
        write_parquet(frame(), folder / "timeseries" / "T01.parquet")
        write_parquet(frame(), folder / "cases.parquet")
        write_json({"campaign": "demo"}, folder / "campaign.json")
    assert all(read_lineage(p) == PLAIN for p in folder.rglob("*") if p.is_file())
