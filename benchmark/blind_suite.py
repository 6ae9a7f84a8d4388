"""The larger blind suite of the diagnosis, outside the pipeline: >= 60 reference-rig scenarios.

    .venv/bin/python benchmark/blind_suite.py [--seed 777] [--per-effect 6] [--pairs 9] [--none 9]
                                              [--out 16] [--sine 14] [--jobs 2] [--no-sensor-chain] [--keep DIR]

Generates the suite exactly as the pipeline's blind_generate does (isokinetic.blind.generate,
reference rig, nuisances and the sensor chain's in every scenario), diagnoses every scenario through
the raw-campaign chain in ``--jobs`` processes, scores it and prints the same summary table as the
pipeline's blind_score, plus the wall time and the CPU-seconds per scenario kind, and a table of the hidden
out-of-catalogue kinds (target (g): their signature's rms_z, verdict, ``explained`` and the axes named).
``--sine``: sine-only campaigns after the triangle ones (none, then each effect alone, in turn; the
triangle scenarios are the same with or without them). ``--no-sensor-chain``: the same scenarios with an ideal sensor
chain (no force-channel low-pass, LVDT gain error, zero drift or dropouts), to see what the chain costs.
Works in a temporary folder (``--keep DIR``: in DIR, kept, with each scenario's diagnosis CPU-seconds in
``DIR/cpu.json`` and the scores in ``DIR/scores.parquet``, so that two versions' diagnoses of the same
scenarios can be compared); asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pandas as pd

from isokinetic.blind.generate import generate_scenarios, write_suite
from isokinetic.blind.score import read_truths, score, summarize, summary_text
from isokinetic.contracts.scenarios import balanced_chunks, kind_name, suite_composition
from isokinetic.stages.blind_diagnose import diagnose_suite


def diagnose_chunk(args: tuple[str, list[str], str]) -> tuple[dict, dict]:
    """(diagnoses, CPU-seconds per scenario) of one chunk."""
    raw, names, work = args
    out, cpu = {}, {}
    for name in names:
        start = time.process_time()
        out.update(diagnose_suite(raw, [name], work))
        cpu[name] = time.process_time() - start
    return out, cpu


def add_suite_arguments(parser: argparse.ArgumentParser) -> None:
    """The benchmark suite's composition as command-line options, with its defaults (seed 777: 6 per effect, 9
    pairs, 9 without effect, 16 out of the catalogue, 14 sine-only): one place for benchmark/next_tests.py too."""
    parser.add_argument("--seed", type=int, default=777)
    parser.add_argument("--per-effect", type=int, default=6)
    parser.add_argument("--pairs", type=int, default=9)
    parser.add_argument("--none", type=int, default=9)
    parser.add_argument("--out", type=int, default=16, help="out-of-catalogue scenarios (cycling through the "
                        "kinds; 16: each of the eight twice)")
    parser.add_argument("--sine", type=int, default=14, help="sine-only scenarios (0: the triangle suite alone)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_suite_arguments(parser)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--no-sensor-chain", action="store_true", help="an ideal sensor chain (same scenarios)")
    parser.add_argument("--keep", type=Path, metavar="DIR", help="work in DIR (created) and keep it")
    args = parser.parse_args()
    started = time.perf_counter()
    scenarios = generate_scenarios(args.seed, args.per_effect, args.pairs, args.none, args.out, args.sine,
                                   sensor_chain=not args.no_sensor_chain)
    keep = contextlib.nullcontext(str(args.keep)) if args.keep else tempfile.TemporaryDirectory()
    with keep as tmp:
        raw, truth, work = Path(tmp) / "raw", Path(tmp) / "truth", Path(tmp) / "work"
        write_suite(scenarios, raw, truth)
        generated = time.perf_counter() - started
        names = [s.name for s in scenarios]
        kinds = suite_composition(args.seed, args.per_effect, args.pairs, args.none, args.out, args.sine)
        chunks = [(str(raw), [names[i] for i in c], str(work)) for c in balanced_chunks(kinds, args.jobs)]
        diagnoses: dict = {}
        cpu: dict = {}
        with ProcessPoolExecutor(args.jobs) as pool:
            for part, seconds in pool.map(diagnose_chunk, chunks):
                diagnoses.update(part)
                cpu.update(seconds)
        scores = score(read_truths(truth), diagnoses)
        if args.keep:
            (Path(tmp) / "cpu.json").write_text(json.dumps(cpu, indent=1, sort_keys=True), encoding="utf-8")
            scores.to_parquet(Path(tmp) / "scores.parquet")
    summary = summarize(scores)
    chain = "without" if args.no_sensor_chain else "with"
    print(f"blind suite: seed {args.seed}, {len(scenarios)} scenarios {chain} the sensor chain; generated in "
          f"{generated:.0f} s, total {time.perf_counter() - started:.0f} s with {args.jobs} processes")
    print(summary_text(summary))
    kind = [kind_name((("x",) * n, {}, o, w)) for w, o, n in
            zip(scores["waveform"], scores["out_of_catalogue"], scores["n_truth"], strict=True)]
    kinds = scores.assign(kind=kind, cpu_s=scores["scenario"].map(cpu))
    print("\ndiagnosis CPU-seconds per scenario, by kind:")
    print(kinds.groupby("kind")["cpu_s"].describe()[["count", "mean", "50%", "max"]].round(2).to_string())
    wrong = scores[~scores["exact"] & (scores["out_of_catalogue"] == "")]
    if len(wrong):
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print("\nnot exact:")
            print(wrong[["scenario", "waveform", "truth", "verdict", "explained", "magnitude_x_detection", "true_lag_s",
                         "lag_error_s", "scale_error", "offset_error_N", "confounded"]].to_string(index=False))
    hidden = scores[scores["hidden_rms_z"].notna()]
    if len(hidden):
        with pd.option_context("display.width", 200, "display.max_columns", 20):
            print("\nhidden out-of-catalogue kinds (target g):")
            print(hidden[["scenario", "out_of_catalogue", "hidden_rms_z", "hidden_visible", "verdict", "explained",
                          "expected_axis", "where_axes", "axis_named"]].round(2).to_string(index=False))


if __name__ == "__main__":
    main()
