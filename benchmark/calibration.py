"""False-alarm calibration of the diagnosis' tests on campaigns without any damper effect.

    .venv/bin/python benchmark/calibration.py [--n 60] [--sine 0] [--jobs 2]

For each noise kind (``white``: white plus white proportional force noise; ``coloured``: white
plus proportional first-order noise with its corner drawn in [0.1, 5] Hz), N scenarios of the
independent reference rig (isokinetic.reference.rig) with every rig nuisance drawn as in the blind
suite (delay, servo lag, load-cell offset and gain, LVDT noise, viscosity drift) and no damper
effect are taken through the real chain (ingest to characteristic) and the diagnosis'
observations; the diagnosis' own nominal test's p-value (``nominal_p_value``: nominal model plus the profiled
load-cell terms, its zero drift included, χ² with the pooled noise model) is recorded. A scenario whose force
channel has a low-pass is rejected by it rightly: the lag is a sensor term the nominal test does not hold. A
calibrated test rejects a fraction alpha of the others at level alpha. Prints the measured rejection rate
against alpha = 0.05, 0.01, 0.001; asserts nothing.

The residual-structure tests (:mod:`isokinetic.diagnosis.structure`) are calibrated on the same scenarios: each
is diagnosed in full (:func:`isokinetic.stages.diagnosis.diagnose`) and the family-wise p-value of its verdict's
structure tests (the smallest Holm-adjusted p over the axes tested) is recorded; a calibrated family rejects a
fraction at most alpha at level alpha. ``--sine N`` adds N sine-only campaigns without effects (the blind suite's
sweeps; their diagnosis is slower).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from isokinetic.blind.generate import export_scenario, make_scenario
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.diagnosis import diagnose

ALPHAS = (0.05, 0.01, 0.001)
SEED = 20261122


KINDS = ("white", "coloured", "sine")


def null_p_value(args: tuple[str, int]) -> tuple[str, float, float, list[str]]:
    """(kind, the nominal test's p-value, the structure tests' family-wise p-value, the axes with structure at
    ALPHA of the diagnosis package) of null scenario ``k`` of a noise kind (NaN where it is not diagnosed)."""
    kind, k = args
    scenario = make_scenario(f"null-{kind}-{k:03d}", (), np.random.SeedSequence([SEED, k]),
                             waveform="sine" if kind == "sine" else "triangle")
    if kind == "white":  # proportional noise without colour: a corner far above fs/2
        scenario = dataclasses.replace(scenario, rig=dataclasses.replace(scenario.rig, noise_corner_Hz=1.0e4))
    with tempfile.TemporaryDirectory() as tmp:
        export_scenario(scenario, Path(tmp) / "raw", Path(tmp) / "truth")
        root = process_raw_campaign(Path(tmp) / "raw" / scenario.name, Path(tmp) / "work")
        result, obs, _predictions = diagnose(root)
        if obs is None:
            return kind, float("nan"), float("nan"), []
        tests = (result.get("structure") or {}).get("tests") or [{"p_adjusted": 1.0}]
        return (kind, float(result["nominal_p_value"]),   # the diagnosis' own test: its zero drift profiled too
                min(float(t["p_adjusted"]) for t in tests), list((result.get("structure") or {}).get("axes") or []))


def rate_table(title: str, results, column: int) -> None:
    """Print the rejection rate of p-values ``results[i][column]`` per noise kind against ALPHAS."""
    print(title)
    print(f"{'noise':<10} {'n':>4} " + " ".join(f"{'p < ' + format(a, 'g'):>12}" for a in ALPHAS))
    for kind in KINDS:
        p = np.array([r[column] for r in results if r[0] == kind])
        p = p[np.isfinite(p)]
        if p.size:
            rates = " ".join(f"{(p < a).mean():>7.3f} ({int((p < a).sum()):>2d})" for a in ALPHAS)
            print(f"{kind:<10} {p.size:>4} {rates}")
    print(f"{'nominal':<10} {'':>4} " + " ".join(f"{a:>12g}" for a in ALPHAS))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=60, help="scenarios per noise kind")
    parser.add_argument("--sine", type=int, default=0, help="sine-only scenarios without effects")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    started = time.perf_counter()
    tasks = [(kind, k) for kind in ("white", "coloured") for k in range(args.n)] + [("sine", k) for k in
                                                                                      range(args.sine)]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(null_p_value, tasks))
    seconds = time.perf_counter() - started
    rate_table(f"false alarms of the nominal test on scenarios without effects ({args.n} per kind, {args.sine} sine; "
               f"{seconds:.0f} s)", results, 1)
    rate_table("\nfalse alarms of the residual-structure tests (family-wise over the axes, Holm) on the verdicts "
               "of the same scenarios", results, 2)
    axes = [a for r in results for a in r[3]]
    print(f"axes with structure at the diagnosis' alpha: {', '.join(axes) if axes else 'none'}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
