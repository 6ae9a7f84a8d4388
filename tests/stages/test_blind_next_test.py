"""Rule blind_next_test's runner (isokinetic.stages.blind_next_test): one scenario built to be confounded, run end
to end through the build's chain."""

from __future__ import annotations

import hashlib
import json

import pytest

from isokinetic.blind.next_tests import read_manifest
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.stages.blind_next_test import BUILD_KIND, run_next_test


def hashes(folder) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}


@pytest.mark.slow
def test_the_builds_scenario_runs_end_to_end_each_plan_on_a_copy_of_its_campaign(tmp_path):
    row = run_next_test(DEFAULTS, tmp_path / "next_test.json", tmp_path / "work")
    assert json.loads((tmp_path / "next_test.json").read_text(encoding="utf-8"))["scenario"] == row["scenario"] == \
        "blind-c-" + BUILD_KIND.replace("_", "-")
    raw = tmp_path / "work" / "raw" / row["scenario"]
    original = read_manifest(raw)
    for plan in ("proposed", "uniform") if row["in_proof"] and row["n_cases"] else ():
        copy = tmp_path / "work" / "proof" / plan / "raw" / row["scenario"]
        assert {k: v for k, v in hashes(raw).items() if k != "campaign.yaml"}.items() <= hashes(copy).items()
        assert read_manifest(copy)["cases"][: len(original["cases"])] == original["cases"]
        assert row[plan]["rig_time_s"] > 0
