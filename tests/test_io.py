"""Atomic writes: a reader never sees a part-written file, and a killed writer's leftovers go."""

import os
import subprocess
import sys
import textwrap

import pandas as pd
import pytest

from isokinetic.io import remove_stale_tmp, write_atomic, write_json, write_parquet


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
