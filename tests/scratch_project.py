"""A scratch copy of the project with a tiny config, for the end-to-end workflow tests."""

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SNAKEMAKE = str(Path(sys.executable).parent / "snakemake")

#: One simulated campaign of three short triangle cases (three is the fewest the models stage fits).
TINY = {
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
            "effects": {"friction": {"coulomb_force_N": 90.0}, "leakage": {"conductance_m3_s_Pa": 2.2e-12}},
            "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
            "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8],
                                  "sample_rate_Hz": 20.0}},
        }
    },
}


def make_project(work: Path, config: dict = TINY) -> Path:
    """The Snakefile, workflow/, profiles/ and resources table of this project with ``config`` in ``work``."""
    work.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "profiles", work / "profiles")
    (work / "config").mkdir()
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    shutil.copy(ROOT / "config" / "resources.yaml", work / "config" / "resources.yaml")
    return work


def export(work: Path, name: str, campaign: str = "tiny") -> None:
    """Export the virtual campaign as a raw campaign data/raw/<name> of the scratch project."""
    subprocess.run([sys.executable, "-m", "isokinetic", "export-virtual", "--config", "config/config.yaml",
                    "--campaign", campaign, "--name", name, "--out", f"data/raw/{name}"], cwd=work, check=True,
                   capture_output=True)


def kill_build(proc: subprocess.Popen) -> None:
    """SIGKILL a build started with ``start_new_session=True``: Snakemake and all its jobs."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)
