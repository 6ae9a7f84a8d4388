"""The workflow on a Slurm cluster (profiles/slurm, through the executor plugin) gives the local build's tables.

Needs a reachable cluster with job accounting (`.ci/slurm-up` starts a one-node one on this machine).
Skipped when there is none, unless ISOKINETIC_REQUIRE_SLURM=1 (as in .ci/run), when it fails with the reason.
"""

import json
import os
import re
import shutil
import signal
import subprocess
from pathlib import Path

import pandas as pd
import pytest
import yaml

from scratch_project import ROOT, SNAKEMAKE, TINY, export, kill_build, make_project

#: Snakemake builds of a scratch project (quick loop: -m "not slow and not workflow")
pytestmark = [pytest.mark.slow, pytest.mark.workflow]

#: The test cluster's overrides of profiles/slurm (fast status polling).
TEST_PROFILE = Path(__file__).resolve().parent / "slurm_profile"
#: A build that has not ended by then has hung (e.g. job states unreadable without accounting).
BUILD_TIMEOUT_S = 900


def slurm_unavailable() -> str | None:
    """Why no Slurm cluster can run the test here, or None when sinfo and sacct answer."""
    for command in (["sinfo", "-h", "-o", "%P %a %D %t"], ["sacct", "-n", "-X", "-S", "now"]):
        if shutil.which(command[0]) is None:
            return f"{command[0]} not found: no Slurm client on this machine (.ci/slurm-up starts a one-node cluster)"
        try:
            proc = subprocess.run(command, capture_output=True, text=True, timeout=30)
        except subprocess.TimeoutExpired:
            return f"{' '.join(command)} did not answer within 30 s"
        if proc.returncode != 0:
            return f"{' '.join(command)} failed (exit {proc.returncode}): {proc.stderr.strip()[:500]}"
    return None


@pytest.fixture(scope="module")
def slurm_cluster():
    reason = slurm_unavailable()
    if reason is None:
        return
    if os.environ.get("ISOKINETIC_REQUIRE_SLURM") == "1":
        pytest.fail(f"ISOKINETIC_REQUIRE_SLURM=1 but no Slurm cluster is reachable: {reason}")
    pytest.skip(f"no Slurm cluster reachable: {reason}")


def small_project(work: Path) -> Path:
    """A scratch project holding one raw campaign (the tiny virtual one, exported) and no virtual campaign."""
    make_project(work, TINY)
    export(work, "tiny-raw")
    config = {key: value for key, value in TINY.items() if key != "virtual_campaigns"}
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    return work


def start_build(work: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([SNAKEMAKE, *args], cwd=work, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True)


def finish_build(proc: subprocess.Popen, work: Path) -> str:
    """Snakemake's log of a build started by start_build; a build still running after BUILD_TIMEOUT_S is
    interrupted (its cluster jobs cancelled) and reported."""
    try:
        out, _ = proc.communicate(timeout=BUILD_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)  # snakemake cancels its cluster jobs on an interrupt
        try:
            out, _ = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            out = ""
        kill_build(proc)
        raise AssertionError(f"{' '.join(proc.args)} still running after {BUILD_TIMEOUT_S} s:\n{out[-4000:]}") from None
    if proc.returncode != 0:
        logs = "\n".join(f"--- {p}\n{p.read_text(errors='replace')[-2000:]}"
                         for p in sorted((work / ".snakemake" / "slurm_logs").rglob("*.log")))
        raise AssertionError(f"{' '.join(proc.args)} failed:\n{out[-4000:]}\n{logs}")
    return out


def results_files(work: Path) -> set[str]:
    return {p.relative_to(work / "results").as_posix() for p in (work / "results").rglob("*") if p.is_file()}


def slurm_job_ids(log: str) -> list[str]:
    """Slurm job ids of the jobs the plugin submitted, from Snakemake's log."""
    return re.findall(r"has been submitted with SLURM jobid (\d+)", log)


@pytest.fixture(scope="module")
def builds(slurm_cluster, tmp_path_factory):
    """The same small project built on the cluster (profiles/slurm) and locally, side by side."""
    local = small_project(tmp_path_factory.mktemp("builds") / "local")
    cluster = shutil.copytree(local, local.parent / "slurm")
    # side by side: the cluster build mostly waits for the plugin's status checks
    slurm = start_build(cluster, "--profile", str(ROOT / "profiles" / "slurm"), "--workflow-profile", str(TEST_PROFILE))
    try:
        finish_build(start_build(local, "--cores", "2"), local)
    finally:
        log = finish_build(slurm, cluster)
    return local, cluster, log


def test_build_runs_as_one_cluster_job_per_campaign_plus_the_index(builds):
    _, _, log = builds
    ids = slurm_job_ids(log)
    assert len(ids) == 2, f"expected 2 cluster jobs (the campaign's group, report_index), got {ids}:\n{log[-3000:]}"
    rows = subprocess.run(["sacct", "-n", "-X", "-P", "-o", "State,Account,Partition", "-j", ",".join(ids)],
                          capture_output=True, text=True, check=True).stdout.split()
    default = yaml.safe_load((ROOT / "config" / "resources.yaml").read_text(encoding="utf-8"))["default"]
    expected = f"COMPLETED|{default['slurm_account']}|{default['slurm_partition']}"
    assert rows == [expected] * 2, rows


def test_cluster_build_writes_the_local_build_tables(builds):
    local, cluster, _ = builds
    files = results_files(local)
    assert results_files(cluster) == files
    tables = sorted(f for f in files if f.endswith(".parquet"))
    assert "tiny-raw/characteristic.parquet" in tables
    for table in tables:  # contents only: the lineage in each file's metadata names its own build
        pd.testing.assert_frame_equal(pd.read_parquet(cluster / "results" / table),
                                      pd.read_parquet(local / "results" / table), check_exact=True, obj=table)


def test_cluster_build_gives_the_local_verdicts(builds):
    local, cluster, _ = builds
    verdicts = {}
    for work in (local, cluster):
        verdicts[work] = {p.parent.name: json.loads(p.read_text(encoding="utf-8"))["verdict"]
                          for p in sorted((work / "results").glob("*/diagnosis.json"))}
    assert verdicts[local] and verdicts[cluster] == verdicts[local]
