"""Ingest's peak memory is a small multiple of the case file's size (issue 20, finding 3; docs/hostile-input.md)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

pytestmark = pytest.mark.slow     # a 40 MB record

#: Peak memory an ingest needs per byte of case file (the peak's growth from a small file to a 40 MB one). About 3.3 x
#: (18.8 x before issue 20); measured against the interpreter alone it varied up to 8.7 x with what the job
#: imported on its way, hence the difference of two runs.
MAX_PEAK_FACTOR = 6.0

PROBE = """
import json, os, resource, sys
import pandas, pyarrow
from isokinetic.stages.ingest import ingest_campaign
page = os.sysconf("SC_PAGE_SIZE")
before = int(open("/proc/self/statm").read().split()[1]) * page
ingest_campaign(sys.argv[1], sys.argv[2])
print(json.dumps({"before": before, "peak": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}))
"""


def _big_campaign(raw, rows: int) -> int:
    """A one-case free campaign whose CSV holds ``rows`` rows of five columns; returns the file's size."""
    raw.mkdir(parents=True)
    manifest = {"format_version": 1, "campaign": "big", "sample_rate_Hz": 1000.0,
                "columns": {"time": {"name": "time_s", "unit": "s"}, "displacement": {"name": "disp_mm", "unit": "mm"},
                            "force": {"name": "force_kN", "unit": "kN"}, "command": {"name": "cmd_mm", "unit": "mm"}},
                "cases": [{"id": "C1", "waveform": "free", "file": "C1.csv"}]}
    (raw / "campaign.yaml").write_text(yaml.safe_dump(manifest), encoding="utf-8")
    rng = np.random.default_rng(11)
    t = np.arange(rows) / 1000.0
    y = 10.0 * np.sin(np.pi * t) + rng.normal(0.0, 1e-3, rows)
    force = 1.5 * np.sign(np.cos(np.pi * t)) + rng.normal(0.0, 0.01, rows)
    with open(raw / "C1.csv", "w", encoding="utf-8") as handle:
        handle.write("time_s,disp_mm,force_kN,cmd_mm,temp_C\n")
        np.savetxt(handle, np.column_stack([t, y, force, y, np.full(rows, 40.0)]),
                   fmt=["%.4f", "%.6f", "%.6f", "%.6f", "%.2f"], delimiter=",")
    return (raw / "C1.csv").stat().st_size


def _peak_bytes(work, rows: int) -> tuple[int, int]:
    """(peak resident memory of one ingest in a fresh interpreter, the case file's size)."""
    size = _big_campaign(work / "data" / "raw" / "big", rows)
    out = subprocess.run([sys.executable, "-c", PROBE, "data/raw/big", "results/big"], cwd=work,
                         capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])["peak"], size


def test_ingest_peak_memory_is_a_small_multiple_of_the_file(tmp_path):
    """The growth of the peak from a small file to a 40 MB one, per byte of file: what the file costs, apart from
    the interpreter and the modules a job imports on its way (the same for both files)."""
    small_peak, small_size = _peak_bytes(tmp_path / "small", 20_000)
    big_peak, big_size = _peak_bytes(tmp_path / "big", 950_000)                  # about 40 MB
    factor = (big_peak - small_peak) / (big_size - small_size)
    assert factor < MAX_PEAK_FACTOR, f"peak {factor:.1f} x the file's {big_size / 1e6:.0f} MB"
