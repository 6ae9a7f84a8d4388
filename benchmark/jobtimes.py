"""Where a build's time goes, per rule: Snakemake's ``benchmark:`` records of the jobs, the import time of each
rule's job (benchmark/imports.py) and the critical path through the job graph. Used by benchmark/run.py and
benchmark/scaling.py.

A job's record (logs/**/<rule>.benchmark.tsv) gives its wall time, interpreter start and imports included, and
its CPU time as Snakemake samples it: every 0.5 s, so up to the last half second of each job is missed (a
lower bound). The compute time of a rule is that CPU time less the CPU of a job's start-up (interpreter and
imports, benchmark/imports.py). The critical path is the longest chain of jobs, each weighted by its wall time,
linked through their files (a job needs the job that writes one of its inputs, or the folder holding it); a
rule's share is the part of that chain's length its jobs make up.
"""

from __future__ import annotations

import csv
import os
from collections import defaultdict
from collections.abc import Mapping
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # scaling.py imports this module
    from imports import ImportProfile  # benchmark/imports.py, beside this script
    from scaling import Job  # benchmark/scaling.py: a dry run's job (rule, wildcards, outputs, inputs, benchmark)


def job_records(work: Path) -> list[dict]:
    """Every ``benchmark:`` record under logs/: rule, campaign, its path, wall s, max RSS MB, CPU s."""
    rows = []
    for path in sorted((work / "logs").rglob("*.benchmark.tsv")):
        with path.open(encoding="utf-8") as f:
            last = list(csv.DictReader(f, delimiter="\t"))[-1]
        rule = path.name.removesuffix(".benchmark.tsv").split("-chunk")[0]
        rows.append({"rule": rule, "campaign": path.parent.name if path.parent != work / "logs" else "",
                     "path": path.relative_to(work).as_posix(), "s": float(last["s"]),
                     "max_rss_MB": float(last["max_rss"]), "cpu_s": _number(last["cpu_time"])})
    return rows


def _number(text: str) -> float:
    """A record's figure; Snakemake writes NA when a job ended before its first sample."""
    try:
        return float(text)
    except ValueError:
        return 0.0


def critical_path(jobs: list[Job], seconds: Mapping[str, float]) -> list[Job]:
    """The longest chain of jobs (weights: ``seconds`` by benchmark path, 0 for a job without a record),
    first job first. Job A follows job B when an input of A is an output of B or lies under one (a folder)."""
    writer = {Path(out): i for i, job in enumerate(jobs) for out in job.outputs}

    def producers(i: int) -> set[int]:
        found = set()
        for path in map(Path, jobs[i].inputs):
            for candidate in (path, *path.parents):
                if candidate in writer and writer[candidate] != i:
                    found.add(writer[candidate])
                    break
        return found

    @cache
    def longest(i: int) -> tuple[float, tuple[int, ...]]:
        before = [longest(j) for j in producers(i)]
        length, chain = max(before, default=(0.0, ()))
        return length + seconds.get(jobs[i].benchmark, 0.0), (*chain, i)

    if not jobs:
        return []
    _, chain = max(longest(i) for i in range(len(jobs)))
    return [jobs[i] for i in chain]


def load_average() -> str:
    """The 1-, 5- and 15-minute load averages: above the core count, other work slowed the wall times down."""
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def rule_table(records: list[dict], imports: Mapping[str, ImportProfile] | None = None,
               path: list[Job] | None = None, per: int = 1, per_label: str = "") -> str:
    """Per rule: jobs, wall and CPU seconds (summed, divided by ``per``), import time of one job, compute
    (CPU less imports) and, given the critical path, the seconds and share of it that the rule's jobs make."""
    by_rule: dict[str, list[dict]] = defaultdict(list)
    for r in records:
        by_rule[r["rule"]].append(r)
    seconds = {r["path"]: r["s"] for r in records}
    on_path: dict[str, float] = defaultdict(float)
    for job in path or []:
        on_path[job.rule] += seconds.get(job.benchmark, 0.0)
    total_path = sum(on_path.values())
    lines = [f"{'rule':<18}{'jobs':>5}{'wall s':>9}{'max s':>7}{'CPU s':>8}{'RSS MB':>8}{'start-up CPU':>14}"
             f"{'compute CPU s':>15}{'crit. path s':>14}{'share':>7}    (wall, CPU, compute: sums{per_label}, CPU "
             "from the records is a lower bound; max s, RSS: largest job; start-up: CPU s of one job's interpreter "
             "and imports, then its import time and top 3 packages [s]; critical path: seconds of the build)"]
    for rule, rs in sorted(by_rule.items(), key=lambda kv: -sum(r["cpu_s"] for r in kv[1])):
        cpu = sum(r["cpu_s"] for r in rs)
        imp = imports.get(rule) if imports else None
        compute = f"{max(0.0, cpu - len(rs) * imp.cpu_s) / per:>15.2f}" if imp else f"{'-':>15}"
        crit = (f"{on_path[rule]:>14.1f}{on_path[rule] / total_path:>7.0%}" if path and total_path
                else f"{'-':>14}{'-':>7}")
        lines.append(f"{rule:<18}{len(rs):>5}{sum(r['s'] for r in rs) / per:>9.2f}{max(r['s'] for r in rs):>7.1f}"
                     f"{cpu / per:>8.2f}{max(r['max_rss_MB'] for r in rs):>8.0f}"
                     + (f"{imp.cpu_s:>14.2f}" if imp else f"{'-':>14}") + f"{compute}{crit}"
                     + (f"    imports {imp.summary()}" if imp else ""))
    lines.append(f"{'all jobs':<18}{len(records):>5}{sum(r['s'] for r in records) / per:>9.2f}{'':>7}"
                 f"{sum(r['cpu_s'] for r in records) / per:>8.2f}{'':>37}"
                 + (f"{total_path:>14.1f}" if path else ""))
    if path:
        lines.append("critical path: " + " -> ".join(j.label() for j in path))
    return "\n".join(lines)
