"""End-to-end: the Snakemake workflow on a tiny config in a scratch copy of the project."""

import hashlib
import json
import os
import shutil
import subprocess

import pandas as pd
import pytest
import yaml

from scratch_project import SNAKEMAKE, TINY, export, make_project


def snakemake(workdir, *args, check=True):
    proc = subprocess.run([SNAKEMAKE, "--cores", "2", *args], cwd=workdir, capture_output=True, text=True)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A scratch project: the workflow, the tiny config and one exported raw campaign, built once."""
    work = make_project(tmp_path_factory.mktemp("project"))
    export(work, "tiny-export")
    before = raw_tree(work)
    snakemake(work)
    (work / "raw_tree_before.json").write_text(json.dumps(before), encoding="utf-8")
    return work


def raw_tree(work):
    """sha256, mode, size and mtime of every entry under data/raw (the run must change none)."""
    out = {}
    for path in sorted((work / "data/raw").rglob("*")):
        st = os.lstat(path)
        out[str(path.relative_to(work))] = [hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "",
                                           st.st_mode, st.st_size, st.st_mtime_ns]
    return out


def copy_project(project, tmp_path):
    work = tmp_path / "copy"
    shutil.copytree(project, work, symlinks=True)
    return work


def test_pipeline_writes_characteristic_and_figures_for_every_campaign(project):
    for campaign in ("tiny", "tiny-export"):
        root = project / "results" / campaign
        char = pd.read_parquet(root / "characteristic.parquet")
        assert len(char) == 12  # 3 cases x 4 windows
        assert sorted((root / "figures").glob("*.png")) and all(
            p.stat().st_size > 0 for p in (root / "figures").glob("*.png"))


def test_exported_raw_campaign_gives_the_simulated_characteristic(project):
    sim = pd.read_parquet(project / "results" / "tiny" / "characteristic.parquet")
    raw = pd.read_parquet(project / "results" / "tiny-export" / "characteristic.parquet")
    keys = ["case", "segment", "direction", "period", "n_samples", "row_start", "row_stop"]
    pd.testing.assert_frame_equal(sim[keys], raw[keys])
    for col in ["velocity_m_s", "force_N", "force_std_N", "window_start_s", "window_end_s"]:
        assert raw[col].to_numpy() == pytest.approx(sim[col].to_numpy(), rel=1e-9, abs=1e-12), col


def test_full_run_changes_no_byte_under_data_raw(project):
    before = json.loads((project / "raw_tree_before.json").read_text(encoding="utf-8"))
    assert before and raw_tree(project) == before


def test_rerun_with_nothing_changed_does_nothing(project):
    assert "Nothing to be done" in snakemake(project, "-n").stdout


def test_new_raw_campaign_runs_only_its_own_jobs(project, tmp_path):
    work = copy_project(project, tmp_path)
    src, dst = work / "data/raw/tiny-export", work / "data/raw/tiny-copy"
    shutil.copytree(src, dst)
    manifest = (dst / "campaign.yaml").read_text(encoding="utf-8")
    manifest = manifest.replace("campaign: tiny-export", "campaign: tiny-copy")
    (dst / "campaign.yaml").write_text(manifest, encoding="utf-8")
    planned = snakemake(work, "-n").stdout
    jobs = {block.split(":", 1)[0]: block for block in planned.split("\nrule ")[1:]}
    own = {name: block for name, block in jobs.items() if name not in ("all", "report_index")}
    assert set(own) == {"ingest", "characteristic", "analysis", "diagnosis", "campaign_report", "raw_check"}, planned
    outputs = [line for block in own.values() for line in block.splitlines() if line.strip().startswith("output:")]
    assert all("results/tiny-copy/" in line for line in outputs), outputs
    assert "virtual_rig" not in jobs


def test_broken_manifest_fails_its_campaign_alone(project, tmp_path):
    work = copy_project(project, tmp_path)
    shutil.rmtree(work / "results")
    broken = work / "data/raw/broken"
    shutil.copytree(work / "data/raw/tiny-export", broken)
    text = (broken / "campaign.yaml").read_text(encoding="utf-8").replace("campaign: tiny-export", "campaign: broken")
    (broken / "campaign.yaml").write_text(text.replace("format_version: 1", "format_version: 99"), encoding="utf-8")
    proc = snakemake(work, check=False)
    assert proc.returncode != 0
    log = (work / "logs/broken/ingest.log").read_text(encoding="utf-8")
    assert "campaign.yaml" in log and "format_version" in log
    for campaign in ("tiny", "tiny-export"):
        assert (work / "results" / campaign / "characteristic.parquet").exists()
    assert not (work / "results/broken/characteristic.parquet").exists()


def test_bad_config_key_is_named(project, tmp_path):
    bad = dict(TINY, windows={"start_fraction": 0.45, "end_fraction": 1.5})
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad), encoding="utf-8")
    proc = snakemake(project, "-n", "--configfile", str(path), check=False)
    assert proc.returncode != 0
    assert "['windows']['end_fraction']" in proc.stdout + proc.stderr


def test_vector_format_writes_an_svg_beside_every_figure_of_the_jobs_that_draw(project, tmp_path):
    work = copy_project(project, tmp_path)
    vector = ["--config", "figures={vector_format: svg}"]
    planned = snakemake(work, "-n", *vector).stdout
    jobs = [block.split(":", 1)[0] for block in planned.split("\nrule ")[1:]]
    # only the jobs that draw rerun (their outputs grew), and the pages that show their figures
    assert set(jobs) - {"all", "report_index", "campaign_report"} == {"analysis", "diagnosis"}, jobs
    snakemake(work, "results/tiny/figures/fig09_characteristic.svg", *vector)
    figures = work / "results" / "tiny" / "figures"
    pngs = sorted(p.stem for p in figures.glob("*.png"))
    assert pngs and sorted(p.stem for p in figures.glob("*.svg")) == pngs
    assert (figures / "fig09_characteristic.svg").read_bytes().startswith(b"<?xml")
