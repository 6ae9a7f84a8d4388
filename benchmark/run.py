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
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    full = timed([snakemake, "--cores", "2", "--forceall"])
    noop = timed([snakemake, "--cores", "2"])
    print(f"{'full rebuild (snakemake --cores 2 --forceall)':<50} {full:8.1f} s   target < 60 s")
    print(f"{'no-op rerun (snakemake --cores 2)':<50} {noop:8.1f} s   target < 5 s")
    sys.stdout.flush()
    subprocess.run([sys.executable, str(ROOT / "benchmark" / "virtual_rig_throughput.py")], cwd=ROOT, check=True)


if __name__ == "__main__":
    main()
