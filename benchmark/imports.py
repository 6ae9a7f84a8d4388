"""Import time of each rule's job: what a job pays before its first line of work.

    .venv/bin/python benchmark/imports.py [--repeat 3] [--before DIR]

A rule's job is a fresh interpreter running the rule's script (workflow/scripts/<rule>.py) after
Snakemake's preamble (pickle, snakemake.logging, snakemake.iocontainers). Its import time is measured
with ``python -X importtime -c "import <preamble>; import <the modules the script imports>"``: the sum
of every module's own time, and that sum per top-level package (the top 3 are printed), and the CPU time
of that interpreter, start to exit (compare these between runs: the import time is wall clock). Best of
``--repeat`` runs (least CPU); the load average is printed beside each figure, as other work on the machine
slows imports down. ``--before DIR`` measures a second checkout (DIR/workflow/scripts, DIR/src first on the
path) in the same loop, run for run, so the two columns were measured back to back.
Also used by benchmark/run.py (per-rule table) and benchmark/scaling.py.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import os
import re
import resource
import subprocess
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: What Snakemake's script preamble imports before the script runs (snakemake.script.PythonScript).
PREAMBLE = ("pickle", "snakemake.logging", "snakemake.iocontainers")
IMPORT_LINE = re.compile(r"^import time:\s+(?P<self>\d+) \|\s+(?P<cumulative>\d+) \|(?P<name>.*)$")
RULE = re.compile(r"^(?:rule|checkpoint) (?P<rule>\w+):", re.MULTILINE)
SCRIPT = re.compile(r"""^\s+script:\s*\n\s+["'](?P<path>[^"']+)["']""", re.MULTILINE)


@dataclass(frozen=True)
class ImportProfile:
    """Import time of one set of modules: total [s] and per top-level package [s] (``-X importtime``: wall
    clock, so other load inflates it), and the CPU time of the whole interpreter that imported them [s]
    (start, imports, exit: what a job spends before its work, less sensitive to other load)."""

    total_s: float
    by_package_s: dict[str, float]
    cpu_s: float = float("nan")

    def top(self, n: int = 3) -> list[tuple[str, float]]:
        return sorted(self.by_package_s.items(), key=lambda kv: -kv[1])[:n]

    def summary(self, n: int = 3) -> str:
        """'1.47 s (matplotlib 0.41, numpy 0.20, pandas 0.13)': the import time and its top packages."""
        return f"{self.total_s:.2f} s ({', '.join(f'{p} {s:.2f}' for p, s in self.top(n))})"


def rule_scripts(workflow: Path) -> dict[str, Path]:
    """Rule -> its script, from the ``script:`` directive of each rule in workflow/rules/*.smk."""
    found = {}
    for smk in sorted((workflow / "rules").glob("*.smk")):
        text = smk.read_text(encoding="utf-8")
        heads = list(RULE.finditer(text))
        for i, head in enumerate(heads):
            body = text[head.end():heads[i + 1].start() if i + 1 < len(heads) else len(text)]
            script = SCRIPT.search(body)
            if script:
                found[head["rule"]] = (smk.parent / script["path"]).resolve()
    return found


def script_imports(script: Path) -> list[str]:
    """The modules a script imports at its top level (``import a.b`` and ``from a.b import c`` give a.b)."""
    modules = []
    for node in ast.parse(script.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.ImportFrom) and node.module and not node.level:
            modules.append(node.module)
        elif isinstance(node, ast.Import):
            modules += [alias.name for alias in node.names]
    return modules


def parse_importtime(stderr: str) -> ImportProfile:
    """Sum of the modules' own times, in total and per top-level package, from ``-X importtime`` output."""
    per: Counter[str] = Counter()
    for line in stderr.splitlines():
        m = IMPORT_LINE.match(line)
        if m:
            per[m["name"].strip().split(".")[0]] += int(m["self"])
    return ImportProfile(sum(per.values()) / 1e6, {k: v / 1e6 for k, v in per.items()})


#: What Snakemake sets in a one-thread job's environment (snakemake.shell: the linear-algebra libraries' thread
#: counts); without them numpy's OpenBLAS starts a thread per core at import, 0.05-0.1 CPU-s that no job pays.
JOB_THREAD_VARIABLES = ("OMP_NUM_THREADS", "GOTO_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                        "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


def import_once(modules: list[str], src: Path | None = None, cwd: Path | None = None) -> ImportProfile:
    """One fresh interpreter importing ``modules`` (``src`` first on the path, e.g. another checkout's src/), in
    a one-thread job's environment (JOB_THREAD_VARIABLES)."""
    env = {**os.environ, **dict.fromkeys(JOB_THREAD_VARIABLES, "1")}
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src), *filter(None, [env.get("PYTHONPATH")])])
    code = "; ".join(f"import {m}" for m in modules)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True,
                          env=env, cwd=cwd or ROOT)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"importing {', '.join(modules)} failed:\n{proc.stderr[-2000:]}")
    cpu_s = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return dataclasses.replace(parse_importtime(proc.stderr), cpu_s=cpu_s)


def best_of(runs: list[ImportProfile]) -> ImportProfile:
    """The run with the least CPU (the least disturbed by other load)."""
    return min(runs, key=lambda p: p.cpu_s)


def job_modules(script: Path) -> list[str]:
    """What a rule's job imports: Snakemake's preamble, then the script's imports."""
    return [*PREAMBLE, *script_imports(script)]


def rule_imports(project: Path, repeat: int = 3, src: Path | None = None) -> dict[str, ImportProfile]:
    """Rule -> import profile of its job (best of ``repeat``) for the project's workflow/."""
    return {rule: best_of([import_once(job_modules(script), src) for _ in range(repeat)])
            for rule, script in sorted(rule_scripts(project / "workflow").items())}


def load_average() -> str:
    return f"{os.getloadavg()[0]:.1f}"


def compare(after: Path, before: Path, repeat: int) -> None:
    """Both checkouts' job start-up (CPU of the importing interpreter; import time and its top packages),
    measured run for run in one loop, side by side."""
    scripts_after, scripts_before = rule_scripts(after / "workflow"), rule_scripts(before / "workflow")
    print(f"{'rule':<17}{'CPU s before':>13}{'after':>7}{'imports before':>16}{'after':>7}{'load':>6}"
          "  top packages [s] before | after")
    for rule in sorted(set(scripts_after) | set(scripts_before)):
        runs_b, runs_a = [], []
        for _ in range(repeat):
            if rule in scripts_before:
                runs_b.append(import_once(job_modules(scripts_before[rule]), before / "src", before))
            if rule in scripts_after:
                runs_a.append(import_once(job_modules(scripts_after[rule]), after / "src", after))
        b, a = (best_of(r) if r else None for r in (runs_b, runs_a))
        nan = float("nan")
        print(f"{rule:<17}{b.cpu_s if b else nan:>13.2f}{a.cpu_s if a else nan:>7.2f}"
              f"{b.total_s if b else nan:>16.2f}{a.total_s if a else nan:>7.2f}{load_average():>6}  "
              f"{b.summary() if b else '-'} | {a.summary() if a else '-'}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per job, best taken")
    parser.add_argument("--project", type=Path, default=ROOT, help="checkout measured (default: this one)")
    parser.add_argument("--before", type=Path, help="another checkout, measured in the same loop")
    args = parser.parse_args()
    if args.before:
        compare(args.project.resolve(), args.before.resolve(), args.repeat)
        return
    print(f"{'rule':<17}{'CPU s':>7}{'import s':>9}{'load':>6}  top 3 packages [s]")
    for rule, script in sorted(rule_scripts(args.project / "workflow").items()):
        profile = best_of([import_once(job_modules(script), args.project / "src") for _ in range(args.repeat)])
        print(f"{rule:<17}{profile.cpu_s:>7.2f}{profile.total_s:>9.2f}{load_average():>6}  {profile.summary()}",
              flush=True)


if __name__ == "__main__":
    main()
