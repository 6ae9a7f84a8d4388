"""Benchmark figures for the README: full rebuild, no-op rerun, virtual rig throughput.

    .venv/bin/python benchmark/run.py

Prints measured figures; asserts nothing (targets are compared in the printout). Run from the
project root with the project's environment active or via .venv/bin/python.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent


def timed(cmd: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    snakemake = str(BIN / "snakemake")
    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, {os.cpu_count()} cores, Python {platform.python_version()}")
    full = timed([snakemake, "--cores", "2", "--forceall"])
    noop = timed([snakemake, "--cores", "2"])
    print(f"{'full rebuild (snakemake --cores 2 --forceall)':<50} {full:8.1f} s   target < 60 s")
    print(f"{'no-op rerun (snakemake --cores 2)':<50} {noop:8.1f} s   target < 5 s")
    sys.stdout.flush()
    diag = diagnosis_seconds("paper-lag-damper")
    print(f"{'diagnosis of paper-lag-damper (23 cases), one core':<50} {diag:8.1f} s   target < 30 s")
    sys.stdout.flush()
    subprocess.run([sys.executable, str(ROOT / "benchmark" / "virtual_rig_throughput.py")], cwd=ROOT, check=True)


def diagnosis_seconds(campaign: str) -> float:
    """Wall time of diagnosing a built campaign in a fresh process pinned to one core (imports excluded)."""
    code = ("import time, pathlib; from isokinetic.stages.diagnosis import diagnose; t = time.perf_counter(); "
            f"diagnose(pathlib.Path('results/{campaign}')); print(time.perf_counter() - t)")
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    out = subprocess.run(["taskset", "-c", "0", sys.executable, "-c", code], cwd=ROOT, check=True, env=env,
                         capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
