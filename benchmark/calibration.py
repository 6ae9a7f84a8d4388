"""False-alarm calibration of the diagnosis' test on campaigns without any damper effect.

    .venv/bin/python benchmark/calibration.py [--n 60] [--jobs 2]

For each noise kind (``white``: white plus white proportional force noise; ``coloured``: white
plus proportional first-order noise with its corner drawn in [0.1, 5] Hz), N scenarios of the
independent reference rig (isokinetic.reference.rig) with every rig nuisance drawn as in the blind
suite (delay, servo lag, load-cell offset and gain, LVDT noise, viscosity drift) and no damper
effect are taken through the real chain (ingest to characteristic) and the diagnosis'
observations; the nominal test's p-value (nominal model plus the profiled instrument terms, χ²
with the pooled noise model) is recorded. A calibrated test rejects a fraction alpha of them at
level alpha. Prints the measured rejection rate against alpha = 0.05, 0.01, 0.001 and the mean
χ²/dof; asserts nothing.
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

from isokinetic.diagnosis.search import Diagnoser
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.blind_generate import export_scenario, make_scenario
from isokinetic.stages.diagnosis import prepare

ALPHAS = (0.05, 0.01, 0.001)
SEED = 20261122


def null_p_value(args: tuple[str, int]) -> tuple[str, float]:
    kind, k = args
    scenario = make_scenario(f"null-{kind}-{k:03d}", (), np.random.SeedSequence([SEED, k]))
    if kind == "white":  # proportional noise without colour: a corner far above fs/2
        scenario = dataclasses.replace(scenario, rig=dataclasses.replace(scenario.rig, noise_corner_Hz=1.0e4))
    with tempfile.TemporaryDirectory() as tmp:
        export_scenario(scenario, Path(tmp) / "raw", Path(tmp) / "truth")
        root = process_raw_campaign(Path(tmp) / "raw" / scenario.name, Path(tmp) / "work")
        _campaign, damper, _cases, obs, reason = prepare(root)
        if obs is None:
            return kind, float("nan")
        return kind, Diagnoser(obs, damper).nominal_p_value()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=60, help="scenarios per noise kind")
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    started = time.perf_counter()
    tasks = [(kind, k) for kind in ("white", "coloured") for k in range(args.n)]
    with ProcessPoolExecutor(args.jobs) as pool:
        results = list(pool.map(null_p_value, tasks))
    print(f"false alarms of the nominal test on scenarios without effects ({args.n} per kind, "
          f"{time.perf_counter() - started:.0f} s)")
    print(f"{'noise':<10} {'n':>4} " + " ".join(f"{'p < ' + format(a, 'g'):>12}" for a in ALPHAS))
    for kind in ("white", "coloured"):
        p = np.array([v for k, v in results if k == kind])
        p = p[np.isfinite(p)]
        rates = " ".join(f"{(p < a).mean():>7.3f} ({int((p < a).sum()):>2d})" for a in ALPHAS)
        print(f"{kind:<10} {p.size:>4} {rates}")
    print(f"{'nominal':<10} {'':>4} " + " ".join(f"{a:>12g}" for a in ALPHAS))
    sys.stdout.flush()


if __name__ == "__main__":
    main()
