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

from .hostile import release, write_protect

#: Snakemake builds of a scratch project (quick loop: -m "not slow and not workflow")
pytestmark = [pytest.mark.slow, pytest.mark.workflow]


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
    assert set(own) == {"ingest", "characteristic", "analysis", "diagnosis", "campaign_report"}, planned
    outputs = [line for block in own.values() for line in block.splitlines() if line.strip().startswith("output:")]
    assert all("results/tiny-copy/" in line for line in outputs), outputs
    assert "virtual_rig" not in jobs


def test_raw_file_changed_since_ingest_fails_the_report_job_before_it_writes(project, tmp_path):
    work = copy_project(project, tmp_path)
    t01 = work / "data/raw/tiny-export/T01.csv"
    st = t01.stat()
    t01.write_bytes(t01.read_bytes().replace(b"0", b"1", 1))
    os.utime(t01, ns=(st.st_atime_ns, st.st_mtime_ns))   # same mtime: Snakemake sees no reason to rerun ingest
    proc = snakemake(work, "--forcerun", "campaign_report", "results/tiny-export/report.html", check=False)
    assert proc.returncode != 0
    line = next(x for x in (proc.stdout + proc.stderr).splitlines()
                if x.strip().startswith("campaign tiny-export: rule campaign_report failed:"))
    assert "raw file data/raw/tiny-export/T01.csv has sha256" in line, line
    assert not any((work / "results/tiny-export" / name).exists() for name in ("raw_check.json", "report.html"))


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


def test_failed_campaign_is_listed_on_a_rebuilt_index_and_named_in_the_closing_summary(project, tmp_path):
    work = copy_project(project, tmp_path)
    broken = work / "data/raw/broken"
    shutil.copytree(work / "data/raw/tiny-export", broken)
    text = (broken / "campaign.yaml").read_text(encoding="utf-8").replace("campaign: tiny-export", "campaign: broken")
    (broken / "campaign.yaml").write_text(text.replace("format_version: 1", "format_version: 99"), encoding="utf-8")
    # a campaign that built before and fails now: its old results must not be shown as this run's
    stale = work / "data/raw/tiny-export/campaign.yaml"
    stale.write_text(stale.read_text(encoding="utf-8").replace("format_version: 1", "format_version: 98"),
                     encoding="utf-8")
    index = work / "results/index.html"
    proc = snakemake(work, check=False)
    assert proc.returncode != 0
    out = proc.stdout + proc.stderr
    for campaign, version in (("broken", 99), ("tiny-export", 98)):
        line = next(x for x in out.splitlines() if x.strip().startswith(f"campaign {campaign}: rule ingest failed:"))
        assert f"unknown version {version}" in line and f"(log: logs/{campaign}/ingest.log)" in line, line
    page = index.read_text(encoding="utf-8")
    rows = {name: page[page.index(f'id="campaign-{name}"'):].split("</tr>")[0] for name in
            ("tiny", "tiny-export", "broken")}
    assert 'href="tiny/report.html"' in rows["tiny"] and "failed" not in rows["tiny"]
    for name, version in (("broken", 99), ("tiny-export", 98)):
        assert "failed" in rows[name] and f"unknown version {version}" in rows[name], rows[name]
        assert "report.html" not in rows[name]
    assert "2 of 3 campaign(s) failed" in page
    summary = pd.read_parquet(work / "results/design/plan_check.parquet")
    assert set(summary["campaign"]) == {"tiny"}
    # the handler's index is a stand-in: once the broken campaign is gone and the other fixed, the rule rebuilds it
    shutil.rmtree(broken)
    stale.write_text(stale.read_text(encoding="utf-8").replace("format_version: 98", "format_version: 1"),
                     encoding="utf-8")
    assert "report_index" in snakemake(work, "-n").stdout
    snakemake(work)
    page = index.read_text(encoding="utf-8")
    assert "failed" not in plain_text(page) and 'id="campaign-broken"' not in page
    assert 'href="tiny-export/report.html"' in page
    assert set(pd.read_parquet(work / "results/design/plan_check.parquet")["campaign"]) == {"tiny", "tiny-export"}
    assert "Nothing to be done" in snakemake(work, "-n").stdout


def planned_rules(work, *targets):
    """The rules of the jobs a dry run plans (empty when there is nothing to be done)."""
    out = snakemake(work, "-n", *targets).stdout
    return [block.split(":", 1)[0] for block in ("\n" + out).split("\nrule ")[1:]] + [
        block.split(":", 1)[0] for block in ("\n" + out).split("\nlocalrule ")[1:]]


def test_stray_file_names_with_pattern_characters_reach_no_job(project, tmp_path):
    work = copy_project(project, tmp_path)
    raw = work / "data/raw/tiny-export"
    for name in ("notes <old>.txt", "notes {old}.txt", "notes <results>.txt"):
        (raw / name).write_text("not campaign data", encoding="utf-8")
    (raw / "passwd.csv").symlink_to("/etc/passwd")
    # no manifest names them: they are nobody's input, so the graph builds and nothing reruns
    assert planned_rules(work) == []


def test_case_file_named_with_pattern_characters_is_read_and_its_change_reruns_ingest(project, tmp_path):
    work = copy_project(project, tmp_path)
    raw = work / "data/raw/tiny-export"
    (raw / "T01.csv").rename(raw / "T{01}.csv")
    doc = yaml.safe_load((raw / "campaign.yaml").read_text(encoding="utf-8"))
    next(c for c in doc["cases"] if c["file"] == "T01.csv")["file"] = "T{01}.csv"
    (raw / "campaign.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    snakemake(work, "results/tiny-export/cases.parquet")
    cases = pd.read_parquet(work / "results/tiny-export/cases.parquet").set_index("case")
    assert cases.loc["T01", "raw_file"] == "data/raw/tiny-export/T{01}.csv" and set(cases["status"]) == {"ok"}
    assert planned_rules(work, "results/tiny-export/cases.parquet") == []
    st = (raw / "T{01}.csv").stat()
    os.utime(raw / "T{01}.csv", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert "ingest" in planned_rules(work, "results/tiny-export/cases.parquet")


def index_row(work, campaign):
    page = (work / "results/index.html").read_text(encoding="utf-8")
    return plain_text(page[page.index(f'id="campaign-{campaign}"'):].split("</tr>")[0])


def test_write_protected_stale_outputs_fail_their_campaign_alone(project, tmp_path):
    work = copy_project(project, tmp_path)
    protected = work / "results/tiny-export/cases.parquet"
    manifest = work / "data/raw/tiny-export/campaign.yaml"
    with manifest.open("a", encoding="utf-8") as fh:         # its outputs are stale now
        fh.write("# edited\n")
    write_protect(protected)
    try:
        planned = planned_rules(work)
        assert "refused" in planned and "ingest" not in planned, planned
        proc = snakemake(work, check=False)
    finally:
        release(protected)
    assert proc.returncode != 0 and "ProtectedOutputException" not in proc.stdout + proc.stderr
    line = next(x for x in (proc.stdout + proc.stderr).splitlines()
                if x.strip().startswith("campaign tiny-export: rule refused failed:"))
    assert "results/tiny-export/cases.parquet" in line and "write-protected" in line, line
    row = index_row(work, "tiny-export")
    assert "failed" in row and "write-protected" in row, row
    assert "failed" not in index_row(work, "tiny")


def test_campaign_folder_leading_outside_the_raw_folder_is_refused_alone(project, tmp_path):
    work = copy_project(project, tmp_path)
    outside = tmp_path / "elsewhere" / "evil"
    shutil.copytree(work / "data/raw/tiny-export", outside)
    text = (outside / "campaign.yaml").read_text(encoding="utf-8")
    (outside / "campaign.yaml").write_text(text.replace("campaign: tiny-export", "campaign: evil"), encoding="utf-8")
    (work / "data/raw/evil").symlink_to(outside)
    proc = snakemake(work, check=False)
    assert proc.returncode != 0
    line = next(x for x in (proc.stdout + proc.stderr).splitlines()
                if x.strip().startswith("campaign evil: rule refused failed:"))
    assert "is a symlink leading outside data/raw/" in line, line
    assert not (work / "results/evil").exists() and not (work / "logs/evil").exists()
    assert "leading outside" in index_row(work, "evil") and "failed" not in index_row(work, "tiny-export")


def test_index_is_rebuilt_even_when_a_campaigns_tables_are_unreadable(project, tmp_path):
    work = copy_project(project, tmp_path)
    # the jobs reading it fail, and so would the raw check after the run, which reads it too
    (work / "results/tiny-export/cases.parquet").write_bytes(b"garbage")
    proc = snakemake(work, check=False)
    assert proc.returncode != 0
    assert "index.html rebuilt" in proc.stdout + proc.stderr, (proc.stdout + proc.stderr)[-3000:]
    assert "failed" in index_row(work, "tiny-export") and "failed" not in index_row(work, "tiny")


def plain_text(page):
    """The visible text of a page: tags, the inline style sheet and script left out."""
    import re

    body = re.sub(r"<(style|script)\b.*?</\1>", "", page, flags=re.S)
    return re.sub(r"<[^>]+>", " ", body)


def test_unbuilt_raw_folders_and_orphaned_results_are_listed_on_the_index_and_in_the_summary(project, tmp_path):
    work = copy_project(project, tmp_path)
    raw = work / "data/raw"
    shutil.copytree(raw / "tiny-export", raw / "Bench 3")            # a name the workflow rejects
    (raw / "bench4").mkdir()                                          # data, no manifest yet
    (raw / "bench4" / "T01.csv").write_text("t,x,F\n0,0,0\n", encoding="utf-8")
    shutil.move(raw / "tiny-export", tmp_path / "away")               # a campaign folder deleted or renamed
    assert set(planned_rules(work)) == {"report_index", "all"}       # only the index learns of them
    proc = snakemake(work)
    out = "\n".join(x.strip() for x in (proc.stdout + proc.stderr).splitlines())
    assert "3 folder(s) not built (listed apart on results/index.html):" in out
    assert "data/raw/Bench 3/: not built: folder name 'Bench 3' is not a campaign id; rename it to bench-3" in out
    assert "data/raw/bench4/: not built: no campaign.yaml; draft one with " in out
    assert "results/tiny-export/: orphaned: raw folder missing: data/raw/tiny-export/ is gone" in out
    page = (work / "results/index.html").read_text(encoding="utf-8")
    text = plain_text(page)
    assert "data/raw/Bench 3/" in text and "rename it to bench-3" in text
    assert "data/raw/bench4/" in text and "init-campaign data/raw/bench4" in text
    orphan = plain_text(page[page.index('id="orphaned-tiny-export"'):].split("</tr>")[0])
    assert "orphaned: raw folder missing" in orphan
    assert 'id="campaign-tiny-export"' not in page and "tiny-export/report.html" not in page
    assert "checks pass" not in text and 'href="tiny/report.html"' in page
    assert planned_rules(work) == []                                  # a no-op rerun stays one
    # the folder back: its results are current again, nothing of it reruns, the index lists it as before
    shutil.move(tmp_path / "away", raw / "tiny-export")
    assert set(planned_rules(work)) == {"report_index", "all"}
    snakemake(work)
    page = (work / "results/index.html").read_text(encoding="utf-8")
    assert 'href="tiny-export/report.html"' in page and "orphaned" not in plain_text(page)


def test_an_interrupted_campaign_is_shown_interrupted_until_it_is_rebuilt(project, tmp_path):
    """One Ctrl-C (SIGINT to the whole foreground group) while a campaign is rebuilt."""
    import signal
    import time

    work = copy_project(project, tmp_path)
    with (work / "data/raw/tiny-export/campaign.yaml").open("a", encoding="utf-8") as fh:
        fh.write("# edited\n")                                         # its jobs rerun
    log = tmp_path / "interrupted.log"
    with open(log, "w") as out:
        # SIGINT at its default: a test run started in the background of a shell without job control inherits it
        # ignored (POSIX), and Snakemake would then build on through the Ctrl-C; unbuffered, so that "rule analysis:"
        # reaches the log as the job starts
        proc = subprocess.Popen([SNAKEMAKE, "--cores", "2"], cwd=work, stdout=out, stderr=subprocess.STDOUT,
                                start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 90
        while "rule analysis:" not in log.read_text(encoding="utf-8", errors="replace"):
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()[-3000:]
            time.sleep(0.05)
        time.sleep(0.3)
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=60) != 0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    out = log.read_text(encoding="utf-8")
    line = next(x.strip() for x in out.splitlines() if x.strip().startswith("campaign tiny-export: interrupted: "))
    assert "--rerun-incomplete" in line, line
    page = (work / "results/index.html").read_text(encoding="utf-8")
    row = page[page.index('id="campaign-tiny-export"'):].split("</tr>")[0]
    assert "interrupted" in row and "report.html" not in row and "title=" not in row, row  # no old numbers
    assert "failed" not in index_row(work, "tiny")
    snakemake(work, "--rerun-incomplete")
    assert "interrupted" not in plain_text((work / "results/index.html").read_text(encoding="utf-8"))
    assert 'href="tiny-export/report.html"' in (work / "results/index.html").read_text(encoding="utf-8")
    assert planned_rules(work) == []


def with_package_copy(work):
    """A copy of the package beside the scratch project, first on the path of its builds: (its folder, the
    environment that runs Snakemake and its jobs with it)."""
    import isokinetic

    copy = work / "pkg" / "isokinetic"
    shutil.copytree(os.path.dirname(isokinetic.__file__), copy, ignore=shutil.ignore_patterns("__pycache__"))
    return copy, {**os.environ, "PYTHONPATH": str(copy.parent)}


def planned_rules_with(work, env):
    out = subprocess.run([SNAKEMAKE, "--cores", "2", "-n"], cwd=work, capture_output=True, text=True, env=env,
                         check=True).stdout
    return out, {block.split(":", 1)[0] for marker in ("\nrule ", "\nlocalrule ")
                 for block in ("\n" + out).split(marker)[1:]}


def test_editing_a_method_module_reruns_the_jobs_that_run_it_and_what_follows_only(project, tmp_path):
    work = copy_project(project, tmp_path)
    copy, env = with_package_copy(work)
    out, planned = planned_rules_with(work, env)
    assert "Nothing to be done" in out   # the same code from another folder: nothing to redo
    draft = copy / "init_campaign" / "draft.py"   # no rule runs init-campaign
    draft.write_text(draft.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    assert "Nothing to be done" in planned_rules_with(work, env)[0]
    plot = copy / "plots" / "diagnosis.py"        # Fig. 16: drawn by the diagnosis rule
    plot.write_text(plot.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    _out, planned = planned_rules_with(work, env)
    assert "diagnosis" in planned
    assert planned <= {"diagnosis", "campaign_report", "report_index", "all"}   # downstream of it only


def test_the_chain_run_outside_snakemake_gives_the_builds_tables(project, tmp_path):
    # one chain (issue 36): the blind suite and scratch rebuilds run isokinetic.stages.chain with the settings of
    # the project's config, and get what the workflow's jobs wrote
    import pandas as pd

    from isokinetic.contracts.settings import load_settings
    from isokinetic.stages.chain import run_chain

    built = project / "results" / "tiny-export"
    chained = run_chain(project / "data/raw/tiny-export", tmp_path / "tiny-export", load_settings(project))
    for table in ("ingest/cases.parquet", "ingest/timeseries/T01.parquet", "cases.parquet", "windows.parquet",
                  "repeatability.parquet", "characteristic.parquet", "design/plan_check.parquet",
                  "models/models.parquet"):
        a, b = pd.read_parquet(built / table), pd.read_parquet(chained / table)
        for frame in (a, b):   # where the raw file was read from is the only difference allowed
            frame.drop(columns=[c for c in ("raw_file",) if c in frame], inplace=True)
        pd.testing.assert_frame_equal(a, b, check_exact=True, obj=table)
    diag = [json.loads((root / "diagnosis.json").read_text(encoding="utf-8")) for root in (built, chained)]
    for d in diag:   # the job's lineage record, the times it took and the raw files' paths as given differ
        for key in ("lineage", "seconds", "sources"):
            d.pop(key, None)
        (d.get("next_tests") or {}).pop("seconds", None)
    assert diag[0] == diag[1]
