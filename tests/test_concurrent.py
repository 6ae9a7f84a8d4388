"""Concurrent runs are safe: a second build on the same tree is refused by Snakemake's directory lock.

A scratch project with one tiny simulated campaign; the first build is killed once the second one
has been refused, and the tree is unlocked as after any crash.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")

CONFIG = {
    "raw_dir": "data/raw",
    "windows": {"start_fraction": 0.45, "end_fraction": 0.95},
    "repeatability": {"tolerance": 0.05},
    "validation": {"sample_rate_tolerance": 0.05},
    "design": {"convergence_fraction": 0.999, "max_amplitude_mm": 10.0, "min_amplitude_mm": 0.1},
    "virtual_campaigns": {
        "tiny": {
            "description": "three short triangle cases",
            "seed": 7,
            "temperature_C": 40.0,
            "damper": {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
                       "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
                       "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9},
            "effects": {"friction": {"coulomb_force_N": 90.0}},
            "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
            "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8],
                                  "sample_rate_Hz": 20.0}},
        }
    },
}


def test_second_build_on_the_same_tree_is_refused(tmp_path):
    work = tmp_path / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "profiles", work / "profiles")
    (work / "config").mkdir()
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(CONFIG), encoding="utf-8")
    locks = work / ".snakemake" / "locks"

    log = tmp_path / "first.log"
    with open(log, "w") as out:
        first = subprocess.Popen([SNAKEMAKE, "--cores", "2"], cwd=work, stdout=out, stderr=subprocess.STDOUT,
                                 start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not (locks.is_dir() and any(locks.iterdir())):
            assert first.poll() is None, f"first build ended before locking:\n{log.read_text()[-3000:]}"
            assert time.monotonic() < deadline, "first build never locked the directory"
            time.sleep(0.05)

        second = subprocess.run([SNAKEMAKE, "--cores", "2"], cwd=work, capture_output=True, text=True, timeout=60)
        assert first.poll() is None, "the first build finished too early for the test to mean anything"
        message = second.stdout + second.stderr
        assert second.returncode != 0
        assert "Directory cannot be locked" in message, message[-3000:]
        assert "--unlock" in message  # the message says what to do after a crash
        assert "rule " not in message.split("Directory cannot be locked")[0].split("Building DAG")[-1], \
            "the refused build started a job"
    finally:
        try:
            os.killpg(first.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        first.wait(timeout=30)

    # A killed build leaves its lock behind; --unlock clears it.
    assert any(locks.iterdir())
    unlock = subprocess.run([SNAKEMAKE, "--unlock"], cwd=work, capture_output=True, text=True, timeout=60)
    assert unlock.returncode == 0, unlock.stderr[-3000:]
    assert not locks.exists() or not any(locks.iterdir())
