"""Scaling benchmark: the workflow on N small raw campaigns, N = 1, 10, 100, 500.

    .venv/bin/python benchmark/scaling.py [--sizes 1 10 100 500] [--cores 2] [--keep DIR]
        [--as-shipped] [--no-gc-freeze] [--scheduling-only SECONDS]

For each N a scratch project is made (this repository's Snakefile, workflow/, profiles/ and
config/resources.yaml, a config with no virtual campaigns and no blind suite, and data/raw/ holding N
raw campaigns). One small virtual campaign is exported as a raw campaign once; the N campaigns are
copies of it under the ids campaign-0001, campaign-0002, ... (the id in each campaign.yaml is set to
its folder's name). Printed per N: the job count (the total of Snakemake's dry-run job stats), the
dry-run wall time on the unbuilt tree (building the DAG), the local build's wall and CPU time per
campaign, the CPU time of the Snakemake process itself (DAG, scheduling), and the peak memory of that
process; then where the CPU goes per campaign, per rule: the jobs' benchmark records, the import time of
each rule's job and the rule's share of the critical path (benchmark/jobtimes.py, benchmark/imports.py).
Compare CPU seconds and import times between runs: wall times move with the other load on the machine.
Then, on a built tree (N = 100 by default), one campaign is added and the jobs a dry run
would run are checked: only the new campaign's jobs and the global jobs (the jobs that name no
campaign in the first dry run, such as the index) may run. Targets are compared in the printout
(MISSED when one is missed); nothing is asserted, and the exit status is 0 unless the benchmark
itself fails. Wall times depend on other load on the machine: the load average is printed with them.

The start-up tricks can be switched off to weigh them: ``--as-shipped`` runs Snakemake's scheduler as it ships
(``ISOKINETIC_COALESCE_REEVALUATIONS=0``: no :mod:`isokinetic.scheduling` patch), ``--no-gc-freeze`` runs every job
without ``gc.freeze`` (``ISOKINETIC_GC_FREEZE=0``, :mod:`isokinetic.job`). ``--scheduling-only SECONDS`` measures
Snakemake's own scheduling alone, with the patch and as shipped: a DAG of the build's shape (per campaign ingest ->
characteristic -> analysis and diagnosis -> campaign_report; one report_index over all; :data:`TOY_SNAKEFILE`)
whose every job sleeps SECONDS and touches its output, so that the build lasts as long as jobs take while the
cores stay free; the patch is installed as ``workflow/rules/common.smk`` installs it, and the project's profile
is used. (Neither a dry run nor ``--touch`` reaches the patched method: Snakemake arms its wake-ups only in a real
build with its job-rate limiter, which ``--touch`` turns off.)

Peak memory is the largest resident set of the Snakemake main process alone, polled every 0.1 s
(psutil RSS, and on Linux the kernel's high-water mark VmHWM of that process, which also catches peaks
between two polls). os.wait4's ru_maxrss is not used: on Linux it is the largest of the child and
every descendant it waited for, i.e. the largest job, not Snakemake itself.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from textwrap import indent

import psutil
import yaml

from imports import rule_imports  # benchmark/imports.py and jobtimes.py, beside this script
from isokinetic.physics.damper import TABLE_1
from jobtimes import critical_path, job_records, rule_table

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")
DEFAULT_SIZES = (1, 10, 100, 500)
INCREMENTAL_SIZE = 100
POLL_S = 0.1

#: Targets of issue 11: per-campaign build cost at the largest N against N = 10, and the dry-run time.
COST_RATIO_MAX = 1.3
COST_RATIO_SIZES = (10, 500)
DRY_RUN_MAX_S = 20.0
DRY_RUN_TARGET_SIZE = 500

#: The one campaign every generated campaign copies: three short triangle cases (three is the fewest
#: the model fit accepts), 2 periods of 8 s at 20 Hz each, i.e. 320 samples per case.
SEED_NAME = "seed"
SEED_CAMPAIGN = {
    "description": "three short triangle cases",
    "seed": 7,
    "temperature_C": 40.0,
    "damper": dataclasses.asdict(TABLE_1),
    "effects": {"friction": {"coulomb_force_N": 90.0}, "leakage": {"conductance_m3_s_Pa": 2.2e-12}},
    "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
    "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8], "sample_rate_Hz": 20.0}},
}
#: Everything of the project's config but the campaigns: raw campaigns only, no blind suite.
BASE_CONFIG = {
    "raw_dir": "data/raw",
    "windows": {"start_fraction": 0.45, "end_fraction": 0.95},
    "repeatability": {"tolerance": 0.05},
    "validation": {"sample_rate_tolerance": 0.05},
    "design": {"convergence_fraction": 0.999, "max_amplitude_mm": 10.0, "min_amplitude_mm": 0.1},
}
PROJECT_PARTS = ("Snakefile", "workflow", "profiles")
#: Config files copied as they are when the source project has them (the rules' resources table).
PROJECT_CONFIGS = ("config/resources.yaml",)


# --- scratch projects --------------------------------------------------------------------------------


def campaign_name(index: int) -> str:
    """Id of the index-th generated campaign (1-based): campaign-0001, ..."""
    return f"campaign-{index:04d}"


def describe_seed() -> str:
    """One line saying what a generated campaign is."""
    plan = SEED_CAMPAIGN["plan"]["triangle"]
    n_cases = len(plan["velocities_mm_s"])
    periods = sorted(set(plan["periods_s"]))
    return (f"one campaign = {n_cases} triangle cases (velocities {plan['velocities_mm_s']} mm/s, "
            f"period {'/'.join(str(p) for p in periods)} s, 2 periods, {plan['sample_rate_Hz']:g} Hz), "
            f"exported once from a virtual campaign and copied N times")


def export_seed(work: Path) -> Path:
    """Export SEED_CAMPAIGN as a raw campaign folder once; returns the folder."""
    work.mkdir(parents=True, exist_ok=True)
    config = work / "seed-config.yaml"
    config.write_text(yaml.safe_dump({**BASE_CONFIG, "virtual_campaigns": {SEED_NAME: SEED_CAMPAIGN}}),
                      encoding="utf-8")
    out = work / SEED_NAME
    subprocess.run([sys.executable, "-m", "isokinetic", "export-virtual", "--config", str(config),
                    "--campaign", SEED_NAME, "--name", SEED_NAME, "--out", str(out)],
                   cwd=work, check=True, capture_output=True)
    return out


def add_campaign(source: Path, raw_dir: Path, name: str) -> None:
    """Copy the raw campaign folder ``source`` to raw_dir/name and name it so in its campaign.yaml (a
    campaign's id is its folder's name). Also used by benchmark/run.py."""
    folder = raw_dir / name
    shutil.copytree(source, folder)
    manifest = folder / "campaign.yaml"
    text, count = re.subn(rf"^campaign: {re.escape(source.name)}$", f"campaign: {name}",
                          manifest.read_text(encoding="utf-8"), flags=re.MULTILINE)
    if count != 1:
        raise RuntimeError(f"{manifest}: expected one 'campaign: {source.name}' line, found {count}")
    manifest.write_text(text, encoding="utf-8")


def make_project(source: Path, work: Path, seed: Path, n_campaigns: int) -> Path:
    """A scratch project in work: source's Snakefile, workflow/, profiles/, resources table, the config and
    n raw campaigns."""
    work.mkdir(parents=True)
    for part in PROJECT_PARTS:
        if (source / part).is_dir():
            shutil.copytree(source / part, work / part, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(source / part, work / part)
    (work / "config").mkdir()
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(BASE_CONFIG), encoding="utf-8")
    for name in PROJECT_CONFIGS:
        if (source / name).is_file():
            shutil.copy(source / name, work / name)
    raw_dir = work / BASE_CONFIG["raw_dir"]
    raw_dir.mkdir(parents=True)
    for index in range(1, n_campaigns + 1):
        add_campaign(seed, raw_dir, campaign_name(index))
    return work


# --- running Snakemake -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Run:
    """One Snakemake invocation: wall time, CPU time, its main process's peak RSS, exit status and output."""

    wall_s: float
    cpu_s: float            # user + system of Snakemake, every job and ILP solver run it started (wait4's rusage)
    main_cpu_s: float       # user + system of the Snakemake main process alone (DAG, scheduling, bookkeeping)
    peak_rss_bytes: int     # of the Snakemake main process alone
    returncode: int
    log: Path

    def text(self) -> str:
        return self.log.read_text(encoding="utf-8", errors="replace")


@dataclass
class Watch:
    """What the poller saw of one process: its peak RSS and its own CPU time at the last poll."""

    peak_rss_bytes: int = 0
    cpu_s: float = 0.0


def high_water_mark_bytes(pid: int) -> int:
    """The kernel's peak RSS (VmHWM) of one process, 0 where /proc does not report it."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError):
        pass
    return 0


def watch_process(pid: int, stop: threading.Event, seen: Watch) -> None:
    """Poll process pid alone (not its children) every POLL_S until stop: peak RSS and own CPU time."""
    try:
        process = psutil.Process(pid)
        while not stop.is_set():
            with process.oneshot():
                rss, cpu = process.memory_info().rss, process.cpu_times()
            seen.peak_rss_bytes = max(seen.peak_rss_bytes, rss, high_water_mark_bytes(pid))
            seen.cpu_s = cpu.user + cpu.system
            stop.wait(POLL_S)
    except (psutil.NoSuchProcess, psutil.ZombieProcess, psutil.AccessDenied):
        pass


def run_snakemake(project: Path, args: list[str], log: Path) -> Run:
    """Run snakemake with args in project (output to log): wall and CPU time, the main process's peak RSS."""
    seen = Watch()
    stop = threading.Event()
    with open(log, "w", encoding="utf-8") as out:
        start = time.perf_counter()
        proc = subprocess.Popen([SNAKEMAKE, *args], cwd=project, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True)
        watcher = threading.Thread(target=watch_process, args=(proc.pid, stop, seen), daemon=True)
        watcher.start()
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        except BaseException:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            stop.set()
            raise
        wall_s = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
    stop.set()
    watcher.join()
    return Run(wall_s, usage.ru_utime + usage.ru_stime, seen.cpu_s, seen.peak_rss_bytes, proc.returncode, log)


# --- reading Snakemake's dry-run output --------------------------------------------------------------


@dataclass(frozen=True)
class Job:
    """One job of a dry run: its rule, wildcards, outputs, inputs and benchmark record (benchmark/jobtimes.py
    links jobs through their files for the critical path)."""

    rule: str
    wildcards: dict[str, str]
    outputs: tuple[str, ...]
    inputs: tuple[str, ...] = ()
    benchmark: str = ""

    def campaigns(self, known: set[str]) -> set[str]:
        """Known campaign ids this job names, in a wildcard value or a component of an output path."""
        named = {v for v in self.wildcards.values() if v in known}
        return named | {part for path in self.outputs for part in Path(path).parts if part in known}

    def label(self) -> str:
        wildcards = ",".join(f"{k}={v}" for k, v in self.wildcards.items())
        return f"{self.rule}({wildcards})" if wildcards else self.rule


JOB_HEADER = re.compile(r"^\s*(?:local)?(?:rule|checkpoint) (?P<rule>\w+):\s*$")
JOB_FIELD = re.compile(r"^\s+(?P<key>\w+): (?P<value>.*)$")
STATS_TOTAL = re.compile(r"^total\s+(?P<count>\d+)\s*$", re.MULTILINE)


def parse_jobs(text: str) -> list[Job]:
    """The jobs a dry run lists (one 'rule <name>:' block each, also inside group jobs)."""
    jobs: list[Job] = []
    rule, fields = None, {}

    def close() -> None:
        if rule is not None:
            wildcards = dict(item.split("=", 1) for item in fields.get("wildcards", "").split(", ") if "=" in item)
            outputs, inputs = (tuple(p for p in fields.get(key, "").split(", ") if p) for key in ("output", "input"))
            jobs.append(Job(rule, wildcards, outputs, inputs, fields.get("benchmark", "")))

    for line in text.splitlines():
        header = JOB_HEADER.match(line)
        field = JOB_FIELD.match(line)
        if header:
            close()
            rule, fields = header["rule"], {}
        elif field and rule is not None:
            fields.setdefault(field["key"], field["value"])
        else:
            close()
            rule, fields = None, {}
    close()
    return jobs


def job_count(text: str) -> int:
    """Total of the last job-stats table of a dry run (0 when nothing is to be done)."""
    totals = STATS_TOTAL.findall(text)
    return int(totals[-1]) if totals else 0


def global_rules(jobs: list[Job], campaigns: set[str]) -> set[str]:
    """Rules of the jobs that name no campaign: the jobs over all campaigns (index, summaries, all)."""
    return {job.rule for job in jobs if not job.campaigns(campaigns)}


# --- the measurements --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Row:
    """Figures of one N."""

    n_campaigns: int
    jobs: int
    dry_run: Run
    build: Run | None       # None with --dry-run-only

    @property
    def per_campaign_s(self) -> float:
        return self.build.wall_s / self.n_campaigns

    @property
    def cpu_per_campaign_s(self) -> float:
        return self.build.cpu_s / self.n_campaigns

    @property
    def built(self) -> bool:
        return self.build is not None and self.build.returncode == 0

    def summary(self) -> str:
        """One line of figures, printed as soon as this N is measured."""
        line = (f"N={self.n_campaigns}: {self.jobs} jobs, dry run {self.dry_run.wall_s:.1f} s "
                f"(peak RSS {mib(self.dry_run.peak_rss_bytes)} MB)")
        if self.build is None:
            return line
        failed = "" if self.built else f"  FAILED (exit {self.build.returncode}): see {self.build.log}"
        return (f"{line}, build {self.build.wall_s:.1f} s ({self.per_campaign_s:.2f} s, "
                f"{self.cpu_per_campaign_s:.2f} CPU s per campaign; Snakemake's own CPU "
                f"{self.build.main_cpu_s:.1f} s), "
                f"peak RSS {mib(self.build.peak_rss_bytes)} MB{failed}")

    def table_row(self) -> str:
        """This N as a row of format_table."""
        dry = f"| {self.n_campaigns} | {self.jobs} | {self.dry_run.wall_s:.1f} s "
        if self.build is None:
            return dry + f"| - | - | - | - | {mib(self.dry_run.peak_rss_bytes)} / - MB |"
        failed = "" if self.built else f" (FAILED, exit {self.build.returncode})"
        return (dry + f"| {self.build.wall_s:.1f} s{failed} | {self.per_campaign_s:.2f} s "
                f"| {self.cpu_per_campaign_s:.2f} s | {self.build.main_cpu_s:.1f} s "
                f"| {mib(self.dry_run.peak_rss_bytes)} / {mib(self.build.peak_rss_bytes)} MB |")


def snakemake_args(cores: int, extra: list[str]) -> list[str]:
    return ["--cores", str(cores), *extra]


def measure(project: Path, n_campaigns: int, cores: int, extra: list[str], build: bool) -> tuple[Row, list[Job]]:
    """Dry run then (if build) build of an unbuilt project; its figures and the dry run's jobs."""
    dry = run_snakemake(project, ["-n", *snakemake_args(cores, extra)], project / "dry-run.log")
    if dry.returncode != 0:
        raise RuntimeError(f"dry run of N={n_campaigns} failed (exit {dry.returncode}): see {dry.log}")
    text = dry.text()
    built = run_snakemake(project, snakemake_args(cores, extra), project / "build.log") if build else None
    return Row(n_campaigns, job_count(text), dry, built), parse_jobs(text)


def incremental_check(project: Path, seed: Path, n_campaigns: int, globals_: set[str], campaign_rules: set[str],
                      cores: int, extra: list[str]) -> str:
    """Add one campaign to a built tree; print which jobs a dry run would run, PASS/FAIL, and the build time.
    Returns the verdict line for the targets."""
    new = campaign_name(n_campaigns + 1)
    add_campaign(seed, project / BASE_CONFIG["raw_dir"], new)
    known = {campaign_name(i) for i in range(1, n_campaigns + 2)}
    dry = run_snakemake(project, ["-n", *snakemake_args(cores, extra)], project / "incremental-dry-run.log")
    if dry.returncode != 0:
        raise RuntimeError(f"incremental dry run failed (exit {dry.returncode}): see {dry.log}")
    jobs = parse_jobs(dry.text())
    new_jobs = [j for j in jobs if j.campaigns(known) == {new}]
    global_jobs = [j for j in jobs if not j.campaigns(known) and j.rule in globals_]
    unexpected = [j for j in jobs if j not in new_jobs and j not in global_jobs]
    missing = sorted(campaign_rules - {j.rule for j in new_jobs})
    print(f"\nIncremental check: built tree of {n_campaigns} campaigns, {new} added; "
          f"dry run {dry.wall_s:.1f} s, {len(jobs)} jobs would run (stats total {job_count(dry.text())})")
    print(f"  global jobs (derived: jobs naming no campaign): {', '.join(sorted(globals_))}")
    print(f"  {new}: {', '.join(j.rule for j in new_jobs)}")
    print(f"  global: {', '.join(j.label() for j in global_jobs) or '-'}")
    if unexpected:
        print(f"  unexpected ({len(unexpected)}): {', '.join(j.label() for j in unexpected[:40])}"
              + (" ..." if len(unexpected) > 40 else ""))
    if missing:
        print(f"  per-campaign rules not run for {new}: {', '.join(missing)}")
    if not unexpected and not missing:
        verdict = f"PASS: only {new}'s {len(new_jobs)} jobs and the {len(global_jobs)} global jobs would run"
    else:
        verdict = (f"FAIL (MISSED): {len(unexpected)} other jobs would run"
                   + (f", {new}'s {', '.join(missing)} would not" if missing else ""))
    print(f"  {verdict}")
    build = run_snakemake(project, snakemake_args(cores, extra), project / "incremental-build.log")
    status = "" if build.returncode == 0 else f"  FAILED (exit {build.returncode}, see {build.log})"
    print(f"  build after adding {new}: {build.wall_s:.1f} s ({build.cpu_s:.1f} CPU s), "
          f"peak RSS {mib(build.peak_rss_bytes)} MB{status}")
    sys.stdout.flush()
    return (f"adding one campaign to a built tree of {n_campaigns}: {verdict}; "
            f"its build {build.wall_s:.1f} s{status}")


def where_it_goes(project: Path, row: Row, jobs: list[Job], imports: dict) -> str:
    """A built N's CPU per campaign, split into the jobs' records per rule (with each rule's import time and
    share of the critical path), Snakemake's own process and what the records do not catch."""
    records = job_records(project)
    n = row.n_campaigns
    jobs_cpu = sum(r["cpu_s"] for r in records)
    rest = row.build.cpu_s - row.build.main_cpu_s - jobs_cpu
    return (f"  where the CPU goes at N={n}, per campaign: {row.cpu_per_campaign_s:.2f} s = jobs' records "
            f"{jobs_cpu / n:.2f} + Snakemake's own process {row.build.main_cpu_s / n:.2f} + not in the records "
            f"{rest / n:.2f} (the records sample a job's CPU every 0.5 s)\n"
            + indent(rule_table(records, imports, critical_path(jobs, {r["path"]: r["s"] for r in records}),
                                per=n, per_label=" per campaign"), "  "))


def format_table(rows: list[Row]) -> str:
    """The per-N figures as a Markdown table (plain text, for the README)."""
    lines = ["| campaigns | jobs | dry run (DAG) | build | build per campaign | CPU per campaign "
             "| Snakemake's own CPU, build | peak RSS of Snakemake, dry run / build |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    lines += [r.table_row() for r in rows]
    return "\n".join(lines)


def mib(n_bytes: int) -> str:
    return f"{n_bytes / 2**20:.0f}"


def target_lines(rows: list[Row], incremental: str | None) -> list[str]:
    """The targets, each met, MISSED, or not measured (size not run)."""
    by_n = {r.n_campaigns: r for r in rows}
    built = {r.n_campaigns for r in rows if r.built}
    small, large = COST_RATIO_SIZES
    out = []
    if small in built and large in built:
        out += cost_ratio_lines(by_n[small], by_n[large], verdict=True)
    else:
        out.append(f"per-campaign cost N={large} / N={small}: not measured (run --sizes with {small} and {large})")
        larger = [n for n in sorted(built) if n > small]
        if small in built and larger:
            out += cost_ratio_lines(by_n[small], by_n[larger[-1]], verdict=False)
    if DRY_RUN_TARGET_SIZE in by_n:
        wall = by_n[DRY_RUN_TARGET_SIZE].dry_run.wall_s
        verdict = "met" if wall <= DRY_RUN_MAX_S else "MISSED"
        out.append(f"dry run at N={DRY_RUN_TARGET_SIZE}: {wall:.1f} s (target <= {DRY_RUN_MAX_S:g} s): {verdict}")
    else:
        out.append(f"dry run at N={DRY_RUN_TARGET_SIZE}: not measured")
    out.append(incremental or "adding one campaign to a built tree: not measured")
    return out


def cost_ratio_lines(small: Row, large: Row, verdict: bool) -> list[str]:
    """Per-campaign build cost of the large N over the small N, in wall and in CPU time."""
    ratio = large.per_campaign_s / small.per_campaign_s
    cpu_ratio = large.cpu_per_campaign_s / small.cpu_per_campaign_s
    target = f"target <= {COST_RATIO_MAX}x at N={COST_RATIO_SIZES[1]}"
    judged = ("met" if ratio <= COST_RATIO_MAX else "MISSED") if verdict else "for information"
    return [f"per-campaign cost N={large.n_campaigns} / N={small.n_campaigns}: {ratio:.2f}x ({target}): {judged}",
            f"  the same in CPU time (less sensitive to other load on the machine): {cpu_ratio:.2f}x"]


def load_average() -> str:
    """The 1-minute load average: above the core count, other work slowed the wall times down."""
    return f"{os.getloadavg()[0]:.1f}"


#: The environment variables of the start-up tricks' switches (isokinetic.scheduling, isokinetic.job).
AS_SHIPPED = {"ISOKINETIC_COALESCE_REEVALUATIONS": "0"}
NO_GC_FREEZE = {"ISOKINETIC_GC_FREEZE": "0"}


def switches(args: argparse.Namespace) -> dict[str, str]:
    """The environment every Snakemake run of this benchmark gets beyond this process's own."""
    return {**(AS_SHIPPED if args.as_shipped else {}), **(NO_GC_FREEZE if args.no_gc_freeze else {})}


#: A workflow of the build's shape whose jobs only sleep (config campaigns: how many, sleep_s: each job's seconds), with
#: the scheduler patch installed as common.smk installs it.
TOY_SNAKEFILE = """\
from isokinetic.scheduling import coalesce_reevaluations

coalesce_reevaluations()
CAMPAIGNS = [f"c{i:04d}" for i in range(1, int(config["campaigns"]) + 1)]
SLEEP = "sleep " + str(config["sleep_s"]) + " && touch {output}"

rule all:
    input: "index.txt"

rule report_index:
    input: expand("{c}/report.txt", c=CAMPAIGNS)
    output: "index.txt"
    shell: SLEEP

rule ingest:
    output: "{c}/ingest.txt"
    shell: SLEEP

rule characteristic:
    input: "{c}/ingest.txt"
    output: "{c}/characteristic.txt"
    shell: SLEEP

rule analysis:
    input: "{c}/characteristic.txt"
    output: "{c}/analysis.txt"
    shell: SLEEP

rule diagnosis:
    input: "{c}/characteristic.txt"
    output: "{c}/diagnosis.txt"
    shell: SLEEP

rule campaign_report:
    input: "{c}/analysis.txt", "{c}/diagnosis.txt"
    output: "{c}/report.txt"
    shell: SLEEP
"""


def scheduling_only(source: Path, scratch: Path, sizes: list[int], sleep_s: float, cores: int,
                    extra: list[str]) -> list[str]:
    """The toy DAG (TOY_SNAKEFILE) of each size built with the scheduler patch and as shipped: one line each."""
    lines = ["| campaigns | jobs | scheduler | build | Snakemake's own CPU | per job |",
             "|---:|---:|---|---:|---:|---:|"]
    for n in sizes:
        for label, env in (("with the patch", {}), ("as shipped", AS_SHIPPED)):
            project = scratch / f"toy-n{n}-{'shipped' if env else 'patched'}"
            project.mkdir(parents=True)
            (project / "Snakefile").write_text(TOY_SNAKEFILE, encoding="utf-8")
            shutil.copytree(source / "profiles", project / "profiles")
            os.environ.update(env or dict.fromkeys(AS_SHIPPED, "1"))
            run = run_snakemake(project, [*snakemake_args(cores, extra), "--config", f"campaigns={n}",
                                 f"sleep_s={sleep_s}"],
                                project / "build.log")
            jobs = 5 * n + 2
            status = "" if run.returncode == 0 else f" (FAILED, exit {run.returncode}: {run.log})"
            lines.append(f"| {n} | {jobs} | {label} | {run.wall_s:.1f} s{status} | {run.main_cpu_s:.1f} s "
                         f"| {run.main_cpu_s / jobs * 1e3:.0f} ms |")
            print(lines[-1], f"load average {load_average()}", flush=True)
    return lines


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(DEFAULT_SIZES), help="numbers of campaigns")
    parser.add_argument("--cores", "--jobs", type=int, default=2, dest="cores", help="snakemake --cores")
    parser.add_argument("--keep", type=Path, help="make the scratch projects in this folder and keep them")
    parser.add_argument("--incremental-on", type=int, default=None,
                        help=f"N of the built tree for the incremental check (default {INCREMENTAL_SIZE} if run, "
                             "else the largest N; 0 skips it)")
    parser.add_argument("--dry-run-only", action="store_true",
                        help="only the dry runs (job count, DAG time): no build, no incremental check")
    parser.add_argument("--source", type=Path, default=ROOT,
                        help="project whose Snakefile, workflow/ and profiles/ are copied (default: this one)")
    parser.add_argument("--as-shipped", action="store_true",
                        help="Snakemake's scheduler as it ships: no isokinetic.scheduling patch")
    parser.add_argument("--no-gc-freeze", action="store_true", help="every job without gc.freeze (isokinetic.job)")
    parser.add_argument("--scheduling-only", type=float, metavar="SECONDS",
                        help="Snakemake's own scheduling, with the patch and as shipped, of a DAG of the build's shape "
                             "whose jobs sleep SECONDS")
    parser.add_argument("--snakemake-args", nargs=argparse.REMAINDER, default=[],
                        help="further snakemake arguments for every run, e.g. --scheduler greedy (put last)")
    return parser.parse_args(argv)


def exit_on_sigterm(signum, frame) -> None:
    """SIGTERM as SystemExit: the running build's process group is killed and the figures so far printed."""
    raise SystemExit(128 + signum)


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    signal.signal(signal.SIGTERM, exit_on_sigterm)
    sizes = sorted(set(args.sizes))
    incremental = args.incremental_on
    if incremental is None:
        incremental = INCREMENTAL_SIZE if INCREMENTAL_SIZE in sizes else sizes[-1]
    if args.keep:
        args.keep.mkdir(parents=True, exist_ok=True)
        scratch = Path(tempfile.mkdtemp(prefix="scaling-", dir=args.keep))
    else:
        scratch = Path(tempfile.mkdtemp(prefix="isokinetic-scaling-"))
    extra = args.snakemake_args
    os.environ.update(switches(args))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; snakemake --cores {args.cores} {' '.join(extra)}".rstrip())
    print("switches: " + (" ".join(f"{k}={v}" for k, v in switches(args).items()) or "none (the build as committed)"))
    print(describe_seed() if args.scheduling_only is None else
          f"scheduling only: a DAG of the build's shape, every job sleeping {args.scheduling_only:g} s")
    print(f"workflow from {args.source}; scratch projects in {scratch}; load average {load_average()}")
    sys.stdout.flush()
    if args.scheduling_only is not None:
        try:
            print("\n".join(scheduling_only(args.source, scratch, sizes, args.scheduling_only, args.cores, extra)))
        finally:
            if not args.keep:
                shutil.rmtree(scratch, ignore_errors=True)
        return
    rows: list[Row] = []
    incremental_verdict = None
    imports = None
    try:
        seed = export_seed(scratch / "seed")
        for n in sizes:
            project = make_project(args.source, scratch / f"n{n}", seed, n)
            row, jobs = measure(project, n, args.cores, extra, build=not args.dry_run_only)
            rows.append(row)
            print(f"{row.summary()}; load average {load_average()}")
            if row.built:
                imports = imports or rule_imports(args.source)
                print(where_it_goes(project, row, jobs, imports))
            sys.stdout.flush()
            if n == incremental and row.built:
                campaigns = {campaign_name(i) for i in range(1, n + 1)}
                campaign_rules = {j.rule for j in jobs if j.campaigns(campaigns) == {campaign_name(1)}}
                incremental_verdict = incremental_check(project, seed, n, global_rules(jobs, campaigns),
                                                        campaign_rules, args.cores, extra)
            if not args.keep:
                shutil.rmtree(project)
    finally:
        if rows:
            print("\n" + format_table(rows))
            print("\n".join(["", *target_lines(rows, incremental_verdict)]))
        if not args.keep:
            shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
