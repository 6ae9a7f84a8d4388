"""Proof of the diagnosis' next tests on the independent reference rig (issue 37, part 3), outside the pipeline.

    .venv/bin/python benchmark/next_tests.py [--seed 777] [--per-effect 6] [--pairs 9] [--none 9] [--out 16]
                                             [--sine 14] [--kinds all] [--names blind-003 ...] [--jobs 2]
                                             [--keep DIR]

Draws benchmark/blind_suite.py's suite (the same composition and seed) and the scenarios built to be confounded
(isokinetic.blind.confounded, every kind, or ``--kinds`` a comma list, ``none`` for none), diagnoses each through
the raw-campaign chain, and for every one whose verdict has a confounding (or whose ``next_tests`` says a test is
needed) runs the plan the diagnosis proposes and the uniform plan of as many cases and the same rig time on the
scenario's own reference rig, each appended to a copy of its campaign and diagnosed again
(isokinetic.blind.next_tests). Prints the table (scenario, confounding, plan size and rig time, resolved by the
proposed plan, by the uniform one) and the two rates against the target (>= 90 % and proposed > uniform).
``--names``: only these scenarios of the suite (development). Works in a temporary folder (``--keep DIR``: in DIR,
kept, with the rows in ``DIR/next_tests.json``); asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from blind_suite import add_suite_arguments  # benchmark/blind_suite.py, beside this script
from isokinetic.blind import confounded as cf
from isokinetic.blind.generate import export_scenario, generate_scenarios
from isokinetic.blind.next_tests import proof_row, proof_summary, proof_table
from isokinetic.contracts.scenarios import scenario_names, suite_composition
from isokinetic.stages.blind_diagnose import diagnose_raw_campaign


def diagnose(raw: Path, work: Path) -> dict:
    """The build's chain of one raw campaign into ``work``: its diagnosis."""
    return diagnose_raw_campaign(raw, work)


def prove(task: tuple) -> tuple[dict, float]:
    """(proof row, CPU-seconds) of one scenario: a suite's (drawn by name) or a confounded kind's."""
    start = time.process_time()
    seed, counts, name, kind, root = task
    root = Path(root)
    if kind:
        k = cf.BY_NAME[kind]
        scenario = cf.make_confounded(k, seed, cf.KINDS.index(k))
        raw = cf.export_confounded(k, scenario, root / "raw", root / "truth")
    else:
        (scenario,) = generate_scenarios(seed, *counts, names=[name])
        raw = export_scenario(scenario, root / "raw", root / "truth")
    truth = json.loads((root / "truth" / f"{scenario.name}.json").read_text(encoding="utf-8"))
    return proof_row(raw, truth, root / "work" / scenario.name, diagnose), time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_suite_arguments(parser)
    parser.add_argument("--kinds", default="all", help="confounded kinds: 'all', 'none' or a comma list")
    parser.add_argument("--names", nargs="*", help="only these scenarios of the suite")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", type=Path, metavar="DIR", help="work in DIR (created) and keep it")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    started = time.perf_counter()
    counts = (args.per_effect, args.pairs, args.none, args.out, args.sine)
    names = args.names if args.names is not None else scenario_names(len(suite_composition(args.seed, *counts)))
    kinds = [k.name for k in cf.KINDS] if args.kinds == "all" else [] if args.kinds == "none" else \
        args.kinds.split(",")
    keep = contextlib.nullcontext(str(args.keep)) if args.keep else tempfile.TemporaryDirectory()
    with keep as tmp:
        tasks = [(args.seed, counts, "", k, tmp) for k in kinds] + [(args.seed, counts, n, "", tmp) for n in names]
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(prove, tasks))
        rows = [r for r, _cpu in results]
        if args.keep:
            (Path(tmp) / "next_tests.json").write_text(json.dumps(rows, indent=1, default=str), encoding="utf-8")
    summary = proof_summary(rows)
    print(f"next tests on the reference rig: seed {args.seed}, {len(tasks)} scenarios ({len(kinds)} built to be "
          f"confounded), {summary['n']} with a confounding; {time.perf_counter() - started:.0f} s with {args.jobs} "
          f"processes, {sum(c for _r, c in results):.0f} CPU-s")
    print(proof_table(rows))
    built = [r for r in rows if r["expected"]]
    if built:
        print("\nscenarios built to be confounded:")
        for r in built:
            print(f"  {r['scenario']}: expected {r['expected']}; listed {r.get('confounded') or 'nothing'}"
                  f"{'' if r.get('in_proof') else ' (' + str(r.get('note')) + ')'}")


if __name__ == "__main__":
    main()
