"""SLOW (about 60 s): interruptions lose nothing.

The whole ``snakemake`` process group is SIGKILLed at a few points of a build of a tiny scratch
project (one simulated campaign and its raw export, three short cases each, no blind block); each
time the directory is unlocked and the build resumed with ``--rerun-incomplete``. The finished tree
must hold the same table *contents* as an uninterrupted build (Parquet read back with pandas, JSON
without lineage and timestamps, PNG decoded pixels), and at no moment may a half-written file sit
under a final name: every Parquet, JSON and PNG file present right after a kill parses completely.

Deselect with ``pytest -k 'not kill_and_rerun'`` when iterating on something else.
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from PIL import Image

from isokinetic.io import read_lineage
from scratch_project import SNAKEMAKE, export, kill_build, make_project

#: Snakemake builds of a scratch project (quick loop: -m "not slow and not workflow")
pytestmark = [pytest.mark.slow, pytest.mark.workflow]

#: Kill points, applied one after the other to the same tree: SIGKILL the process group
#: ``delay`` seconds after the ``n``-th job of that run was started (so a job is mid-way).
KILL_POINTS = [(2, 0.7), (4, 1.3), (6, 0.4)]
JOB_START = re.compile(r"^(?:local)?rule \w+:$", re.M)
#: Keys whose values differ between two builds of the same data: lineage records, run times, and
#: diagnosis.json's own run time (``seconds``).
VOLATILE_KEYS = {"lineage", "created_utc", "last_run_utc", "seconds"}
SHA256 = re.compile(r"[0-9a-f]{64}")


def make_tiny_project(work: Path) -> Path:
    """The scratch project with the tiny simulated campaign and its raw export."""
    make_project(work)
    export(work, "tiny-export")
    return work


def snakemake(work: Path, *args: str) -> subprocess.CompletedProcess:
    proc = subprocess.run([SNAKEMAKE, *args], cwd=work, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, f"snakemake {' '.join(args)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc


def run_and_kill(work: Path, n_jobs: int, delay: float, log: Path) -> None:
    """Start a build, SIGKILL its whole process group ``delay`` s after its ``n_jobs``-th job started."""
    with open(log, "w") as out:
        proc = subprocess.Popen([SNAKEMAKE, "--cores", "2", "--rerun-incomplete"], cwd=work, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while len(JOB_START.findall(log.read_text(encoding="utf-8", errors="replace"))) < n_jobs:
            assert proc.poll() is None, f"build ended before its job {n_jobs}:\n{log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, "no progress"
            time.sleep(0.05)
        time.sleep(delay)
        assert proc.poll() is None, f"build ended before the kill point:\n{log.read_text()[-3000:]}"
    finally:
        kill_build(proc)


def scrub(obj, derived: bool = False):
    """JSON without lineage and run times; sha256 of derived files (which hold lineage) masked."""
    if isinstance(obj, dict):
        return {k: scrub(v, derived or k.startswith("results/")) for k, v in obj.items() if k not in VOLATILE_KEYS}
    if isinstance(obj, list):
        return [scrub(v, derived) for v in obj]
    if derived and isinstance(obj, str) and SHA256.fullmatch(obj):
        return "<sha256 of a derived file>"
    return obj


def content_hash(path: Path) -> str:
    """Hash of what a results file says, not of its bytes (lineage carries a timestamp)."""
    if path.suffix == ".parquet":
        df = pd.read_parquet(path)  # schema metadata (lineage, pandas index) is not part of the frame
        text = repr(list(df.columns)) + repr([str(t) for t in df.dtypes]) + df.to_csv(index=False)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()
    if path.suffix == ".json":
        data = scrub(json.loads(path.read_text(encoding="utf-8")))
        return hashlib.sha256(json.dumps(data, sort_keys=True).encode("utf-8")).hexdigest()
    if path.suffix == ".png":
        pixels = np.asarray(Image.open(path).convert("RGBA"))
        return hashlib.sha256(repr(pixels.shape).encode() + pixels.tobytes()).hexdigest()
    raise ValueError(path)


def results_contents(work: Path) -> dict[str, str]:
    """Content hash of every Parquet, JSON and PNG file under results/ (HTML reports are left out:
    they quote lineage records and run times)."""
    files = sorted(p for p in (work / "results").rglob("*")
                   if p.is_file() and p.suffix in (".parquet", ".json", ".png") and not p.name.startswith("."))
    return {p.relative_to(work).as_posix(): content_hash(p) for p in files}


def assert_no_torn_file(work: Path) -> None:
    """Every file under a final name parses completely (atomic writes: never half-written)."""
    for p in (work / "results").rglob("*"):
        if not p.is_file() or p.name.startswith("."):
            continue
        if p.suffix == ".parquet":
            pq.read_table(p)
        elif p.suffix == ".json":
            json.loads(p.read_text(encoding="utf-8"))
        elif p.suffix == ".png":
            Image.open(io.BytesIO(p.read_bytes())).load()


def tmp_files(work: Path) -> list[str]:
    return sorted(p.relative_to(work).as_posix() for p in (work / "results").rglob("*.tmp"))


def test_kill_and_rerun_gives_the_uninterrupted_results(tmp_path):
    """SLOW: three SIGKILLs of the build, each followed by --unlock and --rerun-incomplete."""
    clean = make_tiny_project(tmp_path / "clean")
    snakemake(clean, "--cores", "2")
    expected = results_contents(clean)
    assert len(expected) > 40 and any(k.endswith("characteristic.parquet") for k in expected)

    work = make_tiny_project(tmp_path / "killed")
    for i, (n_jobs, delay) in enumerate(KILL_POINTS):
        run_and_kill(work, n_jobs, delay, tmp_path / f"kill{i}.log")
        assert not (work / "results/index.html").exists(), "the kill came after the last job"
        assert_no_torn_file(work)
        # A SIGKILL leaves Snakemake's directory lock behind: the next build refuses until --unlock.
        assert any((work / ".snakemake/locks").iterdir())
        snakemake(work, "--unlock")
    snakemake(work, "--cores", "2", "--rerun-incomplete")

    assert "Nothing to be done" in snakemake(work, "--cores", "2", "-n").stdout
    assert tmp_files(work) == []
    got = results_contents(work)
    assert sorted(got) == sorted(expected)
    differ = [k for k in expected if got[k] != expected[k]]
    assert differ == [], f"contents differ from the uninterrupted build: {differ}"
    for name in got:  # every output of the resumed build was finished and stamped
        assert read_lineage(work / name) is not None, name
    for campaign in ("tiny", "tiny-export"):
        prov = json.loads((work / f"results/{campaign}/provenance.json").read_text(encoding="utf-8"))
        assert prov["checks"]["ok"], prov["checks"]
