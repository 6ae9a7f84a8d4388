"""Diagnosis time of periodic-record campaigns on one core: the blind benchmark's sine campaigns, a long sine sweep
and a crank-like sweep (issue 35: each <= 10 s), all written by the reference rig.

    .venv/bin/python benchmark/diagnosis_speed.py [--keep DIR] [--sine N]

- the blind benchmark's sine-only scenarios (benchmark/blind_suite.py's composition: seed 777, 6 per effect, 9 pairs,
  9 without effect, 16 out of the catalogue, ``--sine`` sine-only, default 14): 5-7 frequencies of 4 cycles at
  1 kHz, each with no effect or one catalogue effect;
- a sweep of 12 frequencies (0.2-10 Hz, peak speeds 0.05-1.2 mm/s), 10 cycles each at 2 kHz, with entrained air,
  the rig's nuisances and a servo's second and third harmonics;
- a crank-like sweep: 8 speeds of a slider-crank's motion (second harmonic 6 % of the stroke, fourth 0.2 %), 10
  cycles each at 1 kHz, with leakage and an asymmetry.

Each campaign is ingested and reduced first, then diagnosed in a fresh process pinned to one core (imports
excluded, as benchmark/run.py's diagnosis table); wall and CPU seconds and the model runs are printed beside the
target and the load average. Asserts nothing.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from jobtimes import load_average  # benchmark/jobtimes.py, beside this script

TARGET_S = 10.0


def long_sweep(raw: Path) -> str:
    """The 12-step, 10-cycle, 2 kHz sine sweep with air (module docstring); its campaign name."""
    from isokinetic.reference import campaign as rrc
    from isokinetic.reference import rig as rr

    freqs = np.geomspace(0.2, 10.0, 12)
    speeds = np.geomspace(0.05e-3, 1.2e-3, 12)
    distortion = ((2, 0.02, 0.4), (3, 0.01, -1.1))
    cases = [rr.SineCase(f"S{i + 1:02d}", round(float(f), 3), float(v / (2 * math.pi * f)), 10, 2000.0, distortion)
             for i, (f, v) in enumerate(zip(freqs, speeds, strict=True))]
    rig = rr.RigImperfections(force_noise_N=4.0, force_noise_rel=0.008, delay_s=0.006, servo_lag_s=0.004)
    rrc.write_campaign(raw / "sweep-12x10-2khz", cases, rr.TABLE1,
                       rr.TrueEffects(air_fraction_at_charge=0.004, charge_pressure_Pa=2.0e6), rig=rig, seed=35,
                       declare_charge_pressure=True)
    return "sweep-12x10-2khz"


def crank_sweep(raw: Path) -> str:
    """The crank-like sweep with leakage and an asymmetry (module docstring); its campaign name."""
    from isokinetic.reference import campaign as rrc
    from isokinetic.reference import rig as rr

    stroke_m = 60e-6
    kinematics = ((2, 0.06, math.pi / 2), (4, 0.002, -math.pi / 2))
    cases = [rr.SineCase(f"C{i + 1:02d}", round(float(f), 3), stroke_m, 10, 1000.0, kinematics)
             for i, f in enumerate(np.geomspace(0.3, 4.0, 8))]
    rig = rr.RigImperfections(force_noise_N=3.0, force_noise_rel=0.006)
    rrc.write_campaign(raw / "crank-8x10-1khz", cases, rr.TABLE1,
                       rr.TrueEffects(leakage_gap_m=4e-6, asymmetry=0.06), rig=rig, seed=36)
    return "crank-8x10-1khz"


def blind_sines(raw: Path, truth: Path, n_sine: int) -> list[str]:
    """The blind benchmark's sine-only scenarios (benchmark/blind_suite.py's defaults), written to ``raw``."""
    from isokinetic.blind.generate import generate_scenarios, scenario_names, write_suite
    from isokinetic.contracts.scenarios import suite_composition

    suite = (777, 6, 9, 9, 16, n_sine)   # benchmark/blind_suite.py's defaults
    composition = suite_composition(*suite)
    names = [n for n, c in zip(scenario_names(len(composition)), composition, strict=True) if c[3] == "sine"]
    write_suite(generate_scenarios(*suite, names=names), raw, truth)
    return names


def diagnosis_seconds(results: Path) -> tuple[float, float, int]:
    """(wall s, CPU s, model runs) of diagnosing a reduced campaign in a fresh process pinned to one core."""
    code = ("import time, pathlib; from isokinetic.stages.diagnosis import diagnose; t = time.perf_counter(); "
            f"c = time.process_time(); r, obs, _ = diagnose(pathlib.Path({str(results)!r})); "
            "print(time.perf_counter() - t, time.process_time() - c, r.get('model_evaluations') or 0, "
            "''.join(r.get('verdict') and ','.join(r['verdict']) or '-'), r.get('explained'))")
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    pin = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    out = subprocess.run([*pin, sys.executable, "-c", code], check=True, env=env, capture_output=True, text=True)
    wall, cpu, runs, verdict, explained = out.stdout.strip().splitlines()[-1].split()
    return float(wall), float(cpu), int(runs), f"{verdict} ({'explained' if explained == 'True' else 'not'})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", type=Path, help="work in this folder and keep it")
    parser.add_argument("--sine", type=int, default=14, help="blind benchmark sine scenarios (0: none)")
    args = parser.parse_args()
    from isokinetic.stages.blind_diagnose import process_raw_campaign

    work = args.keep or Path(tempfile.mkdtemp(prefix="isokinetic-diag-speed-"))
    raw, truth, results = work / "raw", work / "truth", work / "results"
    names = [long_sweep(raw), crank_sweep(raw)] + (blind_sines(raw, truth, args.sine) if args.sine else [])
    print(f"\n{'periodic-record diagnosis, one core':<36}{'cases':>6}{'runs':>7}{'wall s':>8}{'CPU s':>8}  "
          f"{'verdict':<28}target <= {TARGET_S:g} s")
    for name in names:
        root = process_raw_campaign(raw / name, results)
        cases = len(list((raw / name).glob("*.csv")))
        wall, cpu, runs, verdict = diagnosis_seconds(root)
        print(f"{name:<36}{cases:>6}{runs:>7}{wall:>8.2f}{cpu:>8.2f}  {verdict:<28}"
              f"{'met' if cpu <= TARGET_S else 'MISSED'}   load {load_average()}", flush=True)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
