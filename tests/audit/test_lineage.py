"""Lineage records: a job's record is complete, the rig spec round-trips, the git state, row keys."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from isokinetic import __version__
from isokinetic.audit import lineage
from isokinetic.io import canonical_json, lineage_context, read_lineage, sha256_file, write_json, write_parquet
from isokinetic.stages.virtual_rig import VirtualCampaign
from test_job import fake_job
from testconfig import load_test_config

ROOT = Path(__file__).resolve().parents[2]


def frame(n=50):
    rng = np.random.default_rng(1)
    return pd.DataFrame({"case": [f"T{i % 5:02d}" for i in range(n)], "segment": np.arange(n, dtype="int64") % 4 + 1,
                         "force_N": rng.normal(size=n), "ok": rng.normal(size=n) > 0})


def test_from_snakemake_records_rule_params_inputs_config_and_git(tmp_path, monkeypatch):
    monkeypatch.setenv("ISOKINETIC_GIT_COMMIT", "abc123")
    monkeypatch.setenv("ISOKINETIC_GIT_DIRTY", "1")
    cases = write_parquet(frame(), tmp_path / "cases.parquet")
    ingest = tmp_path / "ingest"
    write_parquet(frame(), ingest / "timeseries" / "T01.parquet")
    job = fake_job(tmp_path, params={"start_fraction": 0.45, "end_fraction": 0.95},
                   wildcards={"campaign": "demo"}, inputs={"cases": str(cases), "ingest": str(ingest)},
                   outputs={"out": str(tmp_path / "windows.parquet")})
    rec = lineage.from_snakemake(job)
    assert rec["rule"] == "windows" and rec["campaign"] == "demo" and rec["wildcards"] == {"campaign": "demo"}
    assert rec["params"] == {"start_fraction": 0.45, "end_fraction": 0.95}
    assert rec["params_sha256"] == lineage.sha256_text(canonical_json(rec["params"]))
    assert rec["config_sha256"] == lineage.sha256_text(canonical_json(job.config))
    assert rec["inputs"] == {str(cases): sha256_file(cases), str(ingest): lineage.path_sha256(ingest)}
    assert (rec["git_commit"], rec["git_dirty"], rec["package_version"]) == ("abc123", True, __version__)
    assert rec["log"] == [str(tmp_path / "job.log")] and rec["created_utc"].endswith("Z")


def test_virtual_rig_spec_round_trips_through_the_record(tmp_path):
    """An auditor can rebuild the simulated campaign from the ingest files' lineage alone."""
    config = load_test_config()
    for name, spec in config["virtual_campaigns"].items():
        job = fake_job(tmp_path, rule="virtual_rig", params={"spec": spec}, wildcards={"campaign": name})
        with lineage_context(lineage.from_snakemake(job)):
            path = write_json({"campaign": name}, tmp_path / f"{name}.json")
        recorded = read_lineage(path)["params"]["spec"]
        assert recorded == spec
        assert VirtualCampaign.from_config(name, recorded) == VirtualCampaign.from_config(name, spec)


@pytest.mark.parametrize("env, expected", [({"ISOKINETIC_GIT_COMMIT": "c0ffee", "ISOKINETIC_GIT_DIRTY": "0"},
                                            ("c0ffee", False)),
                                           ({"ISOKINETIC_GIT_COMMIT": "", "ISOKINETIC_GIT_DIRTY": ""}, (None, None))])
def test_git_state_comes_from_the_environment(monkeypatch, env, expected):
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    assert lineage.git_state() == expected


def test_outside_a_workflow_the_commit_is_that_of_the_working_directory(tmp_path, monkeypatch):
    """Read from the .git above the working directory, never from where the package is installed."""
    monkeypatch.delenv("ISOKINETIC_GIT_COMMIT", raising=False)
    git = tmp_path / "checkout" / ".git"
    (git / "refs" / "heads").mkdir(parents=True)
    (git / "HEAD").write_text("ref: refs/heads/main\n")
    (git / "refs" / "heads" / "main").write_text("1234abcd" * 5 + "\n")
    (tmp_path / "checkout" / "results").mkdir()
    monkeypatch.chdir(tmp_path / "checkout" / "results")
    assert lineage.git_state() == ("1234abcd" * 5, None)
    (git / "refs" / "heads" / "main").unlink()
    (git / "packed-refs").write_text(f"# pack-refs\n{'feed' * 10} refs/heads/main\n")
    assert lineage.read_head() == "feed" * 10
    monkeypatch.chdir(tmp_path)                                  # no checkout here, whatever the package's
    assert lineage.git_state() == (None, None)
