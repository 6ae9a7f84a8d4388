"""Concurrent runs are safe: a second build on the same tree is refused (Snakemake's directory lock, or its
incomplete-files check when the first build has a job running).

A scratch project with one tiny simulated campaign; the first build is killed once the second one
has been refused, and the tree is unlocked as after any crash.
"""

from __future__ import annotations

import subprocess
import time

import pytest

from scratch_project import SNAKEMAKE, kill_build, make_project

#: Snakemake builds of a scratch project (quick loop: -m "not slow and not workflow")
pytestmark = [pytest.mark.slow, pytest.mark.workflow]


def test_second_build_on_the_same_tree_is_refused(tmp_path):
    work = make_project(tmp_path / "project")
    locks = work / ".snakemake" / "locks"

    log = tmp_path / "first.log"
    with open(log, "w") as out:
        first = subprocess.Popen([SNAKEMAKE, "--cores", "2"], cwd=work, stdout=out, stderr=subprocess.STDOUT,
                                 start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not (locks.is_dir() and any(locks.iterdir())):
            assert first.poll() is None, f"first build ended before locking:\n{log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, "first build never locked the directory"
            time.sleep(0.05)

        second = subprocess.run([SNAKEMAKE, "--cores", "2"], cwd=work, capture_output=True, text=True, timeout=60)
        assert first.poll() is None, "the first build finished too early for the test to mean anything"
        message = second.stdout + second.stderr
        assert second.returncode != 0
        # Snakemake refuses in one of two ways, depending on when the second build looks: the first build's
        # running job has files marked incomplete (checked while building the DAG, before the lock; a
        # --rerun-incomplete would then meet the lock), or the lock itself
        if "IncompleteFilesException" in message:
            assert "results/tiny/" in message.split("Incomplete files:")[-1], message[-3000:]
        else:
            assert "Directory cannot be locked" in message, message[-3000:]
            assert "--unlock" in message  # the message says what to do after a crash
        assert "rule " not in message.split("Building DAG")[-1], "the refused build started a job"
    finally:
        kill_build(first)

    # A killed build leaves its lock behind; --unlock clears it.
    assert any(locks.iterdir())
    unlock = subprocess.run([SNAKEMAKE, "--unlock"], cwd=work, capture_output=True, text=True, timeout=60)
    assert unlock.returncode == 0, unlock.stderr[-3000:]
    assert not locks.exists() or not any(locks.iterdir())
