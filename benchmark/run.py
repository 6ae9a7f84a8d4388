"""Benchmark figures for the README: full rebuild, no-op rerun, a new raw campaign, the chain's job
overhead against a plain script, where the time goes per rule, diagnosis and virtual-rig speed.

    .venv/bin/python benchmark/run.py [--keep DIR] [--diagnoses PROJECT]

Everything runs in a scratch copy of the project (Snakefile, workflow/, config/, profiles/, data/),
so the checkout's results/ are never touched. Prints measured figures next to the targets of
issue 11; asserts nothing. Run with the project's environment (.venv/bin/python).

- full rebuild: ``snakemake --cores 2`` on the copy with nothing built (the default config: three
  campaigns and the 21-scenario blind suite);
- no-op rerun: the same command again, best of three;
- new raw campaign: a copy of data/raw/lag-damper-demo dropped in as a new campaign, then
  ``snakemake --cores 2`` until its report (and the index) are rebuilt;
- chain: that campaign's ingest and characteristic jobs (Snakemake's ``benchmark:`` records: wall
  time of each job, interpreter start and imports included), against benchmark/plain_chain.py doing
  the same ingest -> characteristic in one plain process (also timed whole), best of three each;
- per rule: the ``benchmark:`` records of the full rebuild, summed per rule;
- diagnosis: each built campaign's diagnosis in a fresh process on one core (``--diagnoses PROJECT``:
  only this, on a project already built, read-only).
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from scaling import add_campaign  # benchmark/scaling.py, beside this script

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
SNAKEMAKE = str(BIN / "snakemake")
DEMO = "lag-damper-demo"
NEW = "lag-damper-demo-copy"


def scratch_project(work: Path) -> Path:
    """A copy of the project's workflow, config, profiles and raw data in ``work``, nothing built."""
    work.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    for folder in ("workflow", "config", "profiles", "data"):
        shutil.copytree(ROOT / folder, work / folder, ignore=shutil.ignore_patterns("__pycache__"))
    return work


def timed(cmd: list[str], cwd: Path) -> float:
    """Wall time of a command that must succeed [s]."""
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    elapsed = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed in {cwd}:\n{proc.stdout[-3000:]}")
    return elapsed


def job_records(work: Path) -> list[dict]:
    """Every ``benchmark:`` record under logs/: rule, campaign, wall s, max RSS MB, CPU s."""
    rows = []
    for path in sorted((work / "logs").rglob("*.benchmark.tsv")):
        with path.open(encoding="utf-8") as f:
            last = list(csv.DictReader(f, delimiter="\t"))[-1]
        rule = path.name.removesuffix(".benchmark.tsv").split("-chunk")[0]
        rows.append({"rule": rule, "campaign": path.parent.name if path.parent != work / "logs" else "",
                     "s": float(last["s"]), "max_rss_MB": float(last["max_rss"]),
                     "cpu_s": float(last["cpu_time"])})
    return rows


def print_rules(rows: list[dict]) -> None:
    per_rule: dict[str, list[dict]] = defaultdict(list)
    for r in rows:
        per_rule[r["rule"]].append(r)
    print(f"\n{'rule':<18}{'jobs':>5}{'wall s (sum)':>14}{'max s':>8}{'CPU s':>8}{'max RSS MB':>12}")
    for rule, rs in sorted(per_rule.items(), key=lambda kv: -sum(r["s"] for r in kv[1])):
        print(f"{rule:<18}{len(rs):>5}{sum(r['s'] for r in rs):>14.1f}{max(r['s'] for r in rs):>8.1f}"
              f"{sum(r['cpu_s'] for r in rs):>8.1f}{max(r['max_rss_MB'] for r in rs):>12.0f}")
    print(f"{'all jobs':<18}{len(rows):>5}{sum(r['s'] for r in rows):>14.1f}{'':>8}"
          f"{sum(r['cpu_s'] for r in rows):>8.1f}")


def chain_seconds(work: Path, campaign: str) -> tuple[float, float]:
    """(sum of the ingest and characteristic jobs' wall times, whole snakemake command) of one campaign."""
    target = f"results/{campaign}/characteristic.parquet"
    whole = timed([SNAKEMAKE, "--forcerun", "ingest", "characteristic", "--cores", "2", target], work)
    jobs = [r for r in job_records(work) if r["campaign"] == campaign and r["rule"] in ("ingest", "characteristic")]
    return sum(r["s"] for r in jobs), whole


def plain_seconds(work: Path, campaign: str) -> float:
    out = Path(tempfile.mkdtemp(prefix="plain-", dir=work))
    return timed([sys.executable, str(ROOT / "benchmark" / "plain_chain.py"), f"data/raw/{campaign}", str(out)], work)


def line(label: str, value: float, target: str) -> None:
    print(f"{label:<58}{value:8.1f} s   {target}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, help="build in this folder and keep it (default: a temporary one)")
    parser.add_argument("--diagnoses", type=Path, metavar="PROJECT",
                        help="only time the diagnoses of the campaigns already built in PROJECT (read-only)")
    args = parser.parse_args()
    if args.diagnoses:
        print_diagnoses(args.diagnoses.resolve())
        return
    work = scratch_project(args.keep or Path(tempfile.mkdtemp(prefix="isokinetic-bench-")))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; scratch project {work}")
    full = timed([SNAKEMAKE, "--cores", "2"], work)
    line("full rebuild (snakemake --cores 2, nothing built)", full, "target <= 40 s")
    rebuild_rows = job_records(work)
    noop = min(timed([SNAKEMAKE, "--cores", "2"], work) for _ in range(3))
    line("no-op rerun (best of 3)", noop, "target <= 1.5 s")
    add_campaign(work / "data" / "raw" / DEMO, work / "data" / "raw", NEW)
    added = timed([SNAKEMAKE, "--cores", "2"], work)
    line(f"new raw campaign ({NEW}) to its report and the index", added, "target <= 15 s")
    chains = [chain_seconds(work, NEW) for _ in range(3)]
    plain = min(plain_seconds(work, NEW) for _ in range(3))
    jobs, whole = min(c[0] for c in chains), min(c[1] for c in chains)
    line("chain ingest -> characteristic: its two jobs (best of 3)", jobs, "")
    line("  the same as one plain process (benchmark/plain_chain.py)", plain, "")
    print(f"{'  ratio jobs / plain':<58}{jobs / plain:8.2f} x   target <= 3 x")
    line("  whole snakemake command for it (start-up and DAG included)", whole, "")
    print_rules(rebuild_rows)
    sys.stdout.flush()
    print_diagnoses(work)
    subprocess.run([sys.executable, str(ROOT / "benchmark" / "virtual_rig_throughput.py")], cwd=ROOT, check=True)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


def diagnosis_seconds(work: Path, campaign: str) -> tuple[float, int, int]:
    """(wall time [s], cases diagnosed, model runs) of diagnosing a built campaign in a fresh process
    pinned to one core (imports excluded); reads results/<campaign>/ and writes nothing."""
    code = ("import time, pathlib; from isokinetic.stages.diagnosis import diagnose; t = time.perf_counter(); "
            f"r, obs, _ = diagnose(pathlib.Path('results/{campaign}')); s = time.perf_counter() - t; "
            "print(s, 0 if obs is None else len(obs.plans), r.get('model_evaluations') or 0)")
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    pin = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    out = subprocess.run([*pin, sys.executable, "-c", code], cwd=work, check=True, env=env,
                         capture_output=True, text=True)
    seconds, cases, runs = out.stdout.strip().splitlines()[-1].split()
    return float(seconds), int(cases), int(runs)


def built_campaigns(work: Path) -> list[str]:
    """The campaigns of a build that have a diagnosis (results/<campaign>/diagnosis.json), by name."""
    return sorted(p.parent.name for p in (work / "results").glob("*/diagnosis.json"))


def print_diagnoses(work: Path) -> None:
    """The diagnosis time of every built campaign, one core each (issue 21: <= 3 s for paper-lag-damper)."""
    print(f"\n{'diagnosis, one core':<26}{'cases':>6}{'model runs':>12}{'wall s':>9}")
    for campaign in built_campaigns(work):
        seconds, cases, runs = diagnosis_seconds(work, campaign)
        target = "   target <= 3 s" if campaign == "paper-lag-damper" else ""
        print(f"{campaign:<26}{cases:>6}{runs:>12}{seconds:>9.2f}{target}", flush=True)


if __name__ == "__main__":
    main()
