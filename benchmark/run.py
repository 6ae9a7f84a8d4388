"""Benchmark figures for docs/benchmarks.md (the README keeps a short "How fast" table of them): full rebuild,
no-op rerun, a new raw campaign, the chain's job overhead against a plain script, where the time goes per rule,
diagnosis and virtual-rig speed.

    .venv/bin/python benchmark/run.py [--keep DIR] [--diagnoses PROJECT]

Everything runs in a scratch copy of the project (Snakefile, workflow/, config/, profiles/, data/),
so the checkout's results/ are never touched. Prints measured figures next to the targets of
issue 11; asserts nothing. Run with the project's environment (.venv/bin/python).

- full rebuild: ``snakemake --cores 2`` on the copy with nothing built (the default config: three
  campaigns and the 13-scenario blind suite), wall and CPU (the jobs' and Snakemake's: on two cores a build
  whose CPU is twice its wall time is bound by its work); then the same on a second fresh copy without
  start-up tricks (``ISOKINETIC_COALESCE_REEVALUATIONS=0``: Snakemake's scheduler as it ships, without
  isokinetic.scheduling's patch of its private ``_schedule_reevalutation``; issue 35 asks for both);
- no-op rerun: the same command again, best of three, wall and CPU, beside Snakemake's start-up alone
  (``snakemake --version``), so the workflow's own part (Snakefile, campaign scan, job graph) shows;
- new raw campaign: a copy of data/raw/lag-damper-demo dropped in as a new campaign, then
  ``snakemake --cores 2`` until its report (and the index) are rebuilt;
- chain: that campaign's ingest and characteristic jobs (Snakemake's ``benchmark:`` records: wall
  time of each job, interpreter start and imports included), against benchmark/plain_chain.py doing
  the same ingest -> characteristic in one plain process (also timed whole), best of three each;
- per rule: the ``benchmark:`` records of the full rebuild, summed per rule, beside the import time of the
  rule's job (benchmark/imports.py) and the rule's share of the critical path (benchmark/jobtimes.py);
- the load average (1/5/15 min) beside each figure: wall times on a busy machine are longer;
- diagnosis: each built campaign's diagnosis in a fresh process on one core (``--diagnoses PROJECT``:
  only this, on a project already built, read-only), then the periodic-record campaigns of
  benchmark/diagnosis_speed.py (the blind benchmark's sine campaigns, a 12-step 10-cycle 2 kHz sweep, a crank-like
  sweep).
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from imports import rule_imports  # benchmark/imports.py, beside this script
from jobtimes import critical_path, job_records, load_average, rule_table
from scaling import add_campaign, parse_jobs  # benchmark/scaling.py

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


def timed(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> float:
    """Wall time of a command that must succeed [s]."""
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    elapsed = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed in {cwd}:\n{proc.stdout[-3000:]}")
    return elapsed


def timed_cpu(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[float, float]:
    """(wall, CPU) seconds of a command that must succeed; CPU: user + system of it and its children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    wall = timed(cmd, cwd, env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime


def print_noop(work: Path) -> None:
    """The no-op rerun (best of 3, wall and CPU), beside Snakemake's start-up alone (``snakemake --version``:
    interpreter, Snakemake and its plugins, no workflow): the difference is the workflow's own part (reading
    the Snakefile and config, the campaign scan, the job graph). A slow start-up with little CPU is waiting:
    an installed executor plugin probing its cluster (snakemake-executor-plugin-slurm runs
    ``scontrol show config``, which waits for an unreachable controller for up to 10 s)."""
    noop = min((timed_cpu([SNAKEMAKE, "--cores", "2"], work) for _ in range(3)), key=lambda t: t[0])
    bare = min((timed_cpu([SNAKEMAKE, "--version"], work) for _ in range(3)), key=lambda t: t[0])
    line("no-op rerun (best of 3)", noop[0], "target <= 1.5 s")
    print(f"{'  its CPU; Snakemake start-up alone (--version): wall, CPU':<58}{noop[1]:8.1f} s   "
          f"{bare[0]:.1f} s, {bare[1]:.1f} s CPU; the workflow's part {noop[0] - bare[0]:.1f} s wall, "
          f"{noop[1] - bare[1]:.1f} s CPU", flush=True)


def print_rebuild_as_shipped(work: Path) -> None:
    """The full rebuild on a second fresh copy beside ``work`` with Snakemake's scheduler as it ships
    (``ISOKINETIC_COALESCE_REEVALUATIONS=0``: no patch of its private ``_schedule_reevalutation``), wall and CPU."""
    bare = scratch_project(Path(tempfile.mkdtemp(prefix="isokinetic-bench-shipped-")))
    env = dict(os.environ, ISOKINETIC_COALESCE_REEVALUATIONS="0")
    wall, cpu = timed_cpu([SNAKEMAKE, "--cores", "2"], bare, env)
    line("  the same with Snakemake's scheduler as it ships", wall, "target <= 40 s")
    print(f"{'  its CPU (jobs and Snakemake)':<58}{cpu:8.1f} s", flush=True)
    shutil.rmtree(bare, ignore_errors=True)


def build_jobs(work: Path) -> list:
    """The jobs of the built project, with their files (a dry run with --forceall: every job, none run)."""
    proc = subprocess.run([SNAKEMAKE, "-n", "--forceall", "--cores", "2"], cwd=work, stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    return parse_jobs(proc.stdout) if proc.returncode == 0 else []


def print_rules(rows: list[dict], jobs: list, work: Path) -> None:
    """Per rule: job times of the full rebuild, the import time of its job, its share of the critical path."""
    imports = rule_imports(work)
    print(f"\nper rule, full rebuild (load average {load_average()} now; import s/job best of 3, measured now):")
    print(rule_table(rows, imports, critical_path(jobs, {r["path"]: r["s"] for r in rows})))


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
    """One figure with its target and the load average (1/5/15 min) when it was taken."""
    print(f"{label:<58}{value:8.1f} s   {target:<18}load {load_average()}", flush=True)


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
    full, full_cpu = timed_cpu([SNAKEMAKE, "--cores", "2"], work)
    line("full rebuild (snakemake --cores 2, nothing built)", full, "target <= 40 s")
    print(f"{'  its CPU (jobs and Snakemake)':<58}{full_cpu:8.1f} s", flush=True)
    print_rebuild_as_shipped(work)
    rebuild_rows, rebuild_jobs = job_records(work), build_jobs(work)
    print_noop(work)
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
    print_rules(rebuild_rows, rebuild_jobs, work)
    sys.stdout.flush()
    print_diagnoses(work)
    subprocess.run([sys.executable, str(ROOT / "benchmark" / "diagnosis_speed.py")], cwd=ROOT / "benchmark",
                   check=True)
    subprocess.run([sys.executable, str(ROOT / "benchmark" / "virtual_rig_throughput.py")], cwd=ROOT, check=True)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


def diagnosis_seconds(work: Path, campaign: str) -> tuple[float, float, int, int, float]:
    """(wall time [s], CPU time [s], cases diagnosed, model runs, the next-test plan's wall time [s]: 0 where none
    is needed) of diagnosing a built campaign in a fresh process pinned to one core (imports excluded); reads
    results/<campaign>/ and writes nothing. The CPU time is the one to compare on a busy machine (the wall time
    waits for the core whenever another process has it)."""
    code = ("import time, pathlib; from isokinetic.stages.diagnosis import diagnose; t = time.perf_counter(); "
            "c = time.process_time(); "
            f"r, obs, _ = diagnose(pathlib.Path('results/{campaign}')); s = time.perf_counter() - t; "
            "print(s, time.process_time() - c, 0 if obs is None else len(obs.plans), r.get('model_evaluations') or 0, "
            "(r.get('next_tests') or {}).get('seconds') or 0.0)")
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    pin = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    out = subprocess.run([*pin, sys.executable, "-c", code], cwd=work, check=True, env=env,
                         capture_output=True, text=True)
    seconds, cpu, cases, runs, plan = out.stdout.strip().splitlines()[-1].split()
    return float(seconds), float(cpu), int(cases), int(runs), float(plan)


def built_campaigns(work: Path) -> list[str]:
    """The campaigns of a build that have a diagnosis (results/<campaign>/diagnosis.json), by name."""
    return sorted(p.parent.name for p in (work / "results").glob("*/diagnosis.json"))


def print_diagnoses(work: Path) -> None:
    """The diagnosis time of every built campaign, one core each (issue 35: <= 2 s for paper-lag-damper, 27
    triangle cases); of it, the next-test plan's (issue 37: none where nothing is confounded)."""
    print(f"\n{'diagnosis, one core':<26}{'cases':>6}{'model runs':>12}{'wall s':>9}{'CPU s':>8}{'plan s':>8}")
    for campaign in built_campaigns(work):
        seconds, cpu, cases, runs, plan = diagnosis_seconds(work, campaign)
        target = "   target <= 2 s" if campaign == "paper-lag-damper" else ""
        print(f"{campaign:<26}{cases:>6}{runs:>12}{seconds:>9.2f}{cpu:>8.2f}{plan:>8.2f}   load {load_average()}"
              f"{target}", flush=True)


if __name__ == "__main__":
    main()
