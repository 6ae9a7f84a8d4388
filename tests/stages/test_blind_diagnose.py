"""Rule blind_diagnose: a small suite from its raw campaigns to its diagnoses, and the workflow's wiring."""

import hashlib
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from isokinetic.blind.generate import generate_scenarios, write_suite
from isokinetic.blind.score import read_truths, score, summarize, summary_text
from isokinetic.contracts.scenarios import EFFECTS
from isokinetic.stages.blind_diagnose import diagnose_suite

ROOT = Path(__file__).resolve().parents[2]
# small plans (8 speeds, no 240 s periods) keep the end-to-end suite fast
SMALL = {"multiple": 3.0, "n_velocities": (8, 8), "low_end_mm_s": (0.015, 0.05)}


def tree_hashes(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------------------------
# end to end: one scenario per effect plus one without, each at 3x detection
# --------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_small_blind_suite_attributes_every_effect(tmp_path):
    # the rig nuisances of issue 9 only: what the sensor chain (issue 21) does to attribution is measured by
    # the suite's targets (results/blind/summary.json, docs/diagnosis.md, "Blind test of the diagnosis")
    scenarios = generate_scenarios(5, 1, 0, 1, **SMALL, sensor_chain=False)
    assert sorted(s.truth for s in scenarios) == sorted([()] + [(e,) for e in EFFECTS])
    write_suite(scenarios, tmp_path / "raw", tmp_path / "truth")
    shutil.copytree(tmp_path / "raw", tmp_path / "raw-before")
    diagnoses = diagnose_suite(tmp_path / "raw", [s.name for s in scenarios], tmp_path / "work")
    assert tree_hashes(tmp_path / "raw") == tree_hashes(tmp_path / "raw-before")  # raw data untouched
    for s in scenarios:
        folder = tmp_path / "work" / s.name
        for name in ("cases.parquet", "windows.parquet", "characteristic.parquet", "diagnosis.json"):
            assert (folder / name).is_file(), (s.name, name)
    scores = score(read_truths(tmp_path / "truth"), diagnoses)
    assert scores["verdict"].tolist() == scores["truth"].tolist(), scores[["scenario", "truth", "verdict"]]
    summary = summarize(scores)
    assert summary["all_pass"], summary_text(summary)


# --------------------------------------------------------------------------------------------
# workflow wiring
# --------------------------------------------------------------------------------------------

@pytest.mark.slow
@pytest.mark.workflow
def test_workflow_runs_one_generate_then_diagnose_chain_per_chunk(tmp_path):
    work = tmp_path / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow", ignore=shutil.ignore_patterns("__pycache__"))
    (work / "config").mkdir()
    (work / "data" / "raw").mkdir(parents=True)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    config["virtual_campaigns"] = {}
    config.pop("comparisons", None)  # they name the virtual campaigns
    config["blind"] = {"seed": 1, "n_per_effect": 1, "n_pairs": 1, "n_none": 2, "n_sine": 1, "chunks": 2}
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    proc = subprocess.run([str(Path(sys.executable).parent / "snakemake"), "-n", "-p", "--cores", "2"], cwd=work,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout + proc.stderr
    stats = {w[0]: w[1] for w in map(str.split, out.splitlines())
             if len(w) == 2 and w[0].startswith("blind_") and w[1].isdigit()}
    # and one scenario built to be confounded, its next tests run end to end (issue 37)
    assert stats == {"blind_generate": "2", "blind_diagnose": "2", "blind_score": "1", "blind_next_test": "1"}
    for chunk in ("chunk0", "chunk1"):
        assert f"results/blind/raw/{chunk}" in out and f"results/blind/diagnosis/{chunk}" in out
    # each chunk's diagnosis waits for its own generation only
    dag = subprocess.run([str(Path(sys.executable).parent / "snakemake"), "--dag"], cwd=work, capture_output=True,
                         text=True)
    assert dag.returncode == 0, dag.stderr[-3000:]
    rule = {node: label.split("\\n")[0] for node, label in re.findall(r'(\d+)\[label = "([^"]+)"', dag.stdout)}
    edges = re.findall(r"(\d+) -> (\d+)", dag.stdout)
    feeding = {b: [a for a, b2 in edges if b2 == b and rule[a] == "blind_generate"] for b in rule
               if rule[b] == "blind_diagnose"}
    assert sorted(len(v) for v in feeding.values()) == [1, 1] and len({v[0] for v in feeding.values()}) == 2


# --------------------------------------------------------------------------------------------
# one chain, one record of settings (issue 36)
# --------------------------------------------------------------------------------------------

def test_the_blind_chain_applies_the_builds_settings_to_every_stage(tmp_path):
    # the blind suite used to run ingest and validate with their own defaults, whatever the config said: a
    # file-size limit below every case file now sets every case aside, as the build's ingest would
    import dataclasses

    import pandas as pd

    from isokinetic.contracts.settings import load_settings
    from isokinetic.stages.blind_diagnose import process_raw_campaign

    scenarios = generate_scenarios(5, 0, 0, 1, **SMALL, sensor_chain=False)
    write_suite(scenarios, tmp_path / "raw", tmp_path / "truth")
    raw = tmp_path / "raw" / scenarios[0].name
    settings = load_settings(ROOT)
    root = process_raw_campaign(raw, tmp_path / "as-built", settings)
    assert (pd.read_parquet(root / "ingest" / "cases.parquet")["status"] == "ok").all()
    tight = dataclasses.replace(settings, max_case_file_MB=1e-6)
    root = process_raw_campaign(raw, tmp_path / "tight", tight)
    assert (pd.read_parquet(root / "ingest" / "cases.parquet")["status"] != "ok").all()
