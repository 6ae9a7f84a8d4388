"""After a failed run: the failed jobs read from Snakemake's log, each campaign's state, the rebuilt index."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pandas as pd

from isokinetic.io import write_parquet
from isokinetic.report import run_status

from .fixture_results import CAMPAIGN, build_campaign, plain

#: Two failed jobs as Snakemake 9 writes them into its log (.snakemake/log/*.snakemake.log), around other lines.
SNAKEMAKE_LOG = """\
Building DAG of jobs...
[Wed Nov 25 18:27:20 2026]
Error in rule ingest:
    message: None
    jobid: 4
    input: data/raw/broken/T01.csv, data/raw/broken/campaign.yaml
    output: results/broken/ingest
    log: logs/broken/ingest.log (check log file(s) for error details)
Select jobs to execute...
[Wed Nov 25 18:27:22 2026]
Error in rule blind_score:
    message: None
    jobid: 9
    output: results/blind/scores.parquet
    log: logs/blind_score.log (check log file(s) for error details)
Exiting because a job execution failed. Look above for error messages
"""
INGEST_ERROR = ("campaign broken not ingested: data/raw/broken/campaign.yaml: key 'format_version': unknown "
                "version 99; this reader knows 1")


def _write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def test_failed_jobs_are_read_from_the_snakemake_log_with_the_first_error_of_their_own_log(tmp_path):
    _write(tmp_path / "logs/broken/ingest.log", f"2026-11-25 18:27:20,206 INFO reading\n"
                                                f"2026-11-25 18:27:20,206 ERROR {INGEST_ERROR}\n"
                                                "2026-11-25 18:27:20,207 ERROR a later error\n")
    _write(tmp_path / "logs/blind_score.log", "Traceback (most recent call last):\n  File x\nValueError: bad truth\n")
    log = _write(tmp_path / "run.log", SNAKEMAKE_LOG)
    jobs = run_status.failed_jobs([log], workdir=tmp_path)
    assert [(j.rule, j.campaign, j.log) for j in jobs] == [("ingest", "broken", "logs/broken/ingest.log"),
                                                          ("blind_score", None, "logs/blind_score.log")]
    assert jobs[0].reason == INGEST_ERROR and jobs[1].reason == "ValueError: bad truth"
    assert jobs[0].line() == f"campaign broken: rule ingest failed: {INGEST_ERROR} (log: logs/broken/ingest.log)"
    assert jobs[1].line() == "rule blind_score failed: ValueError: bad truth (log: logs/blind_score.log)"
    assert run_status.failed_jobs(tmp_path / "absent.log") == [] and run_status.failed_jobs(None) == []


def test_a_log_without_an_error_line_says_so_and_long_reasons_are_cut(tmp_path):
    log = _write(tmp_path / "run.log", SNAKEMAKE_LOG)
    jobs = run_status.failed_jobs(log, workdir=tmp_path)  # neither job log exists
    assert {j.reason for j in jobs} == {"no error line in its log"}
    long = run_status.shorten("x " * 400)
    assert len(long) == run_status.MAX_REASON and long.endswith("\u2026") and "\n" not in long


def test_campaign_failures_name_failed_missing_and_stale_campaigns_only(tmp_path):
    results, logs, raw = tmp_path / "results", tmp_path / "logs", tmp_path / "raw"
    for c in ("good", "failed", "stale"):
        _write(raw / c / "campaign.yaml", "x")
        _write(results / c / "report.html", "page")
    _write(raw / "missing" / "campaign.yaml", "x")
    _write(logs / "missing" / "characteristic.log", "2026-11-25 18:27:20,206 ERROR no usable case\n")
    later = time.time() + 5
    os.utime(raw / "stale" / "campaign.yaml", (later, later))
    failed = [run_status.FailedJob("analysis", "failed", "logs/failed/analysis.log", "boom")]
    out = run_status.campaign_failures(results, logs, ["good", "failed", "stale", "missing", "virtual"],
                                       {c: raw / c for c in ("good", "failed", "stale", "missing")}, failed)
    assert sorted(out) == ["failed", "missing", "stale", "virtual"]
    assert out["failed"] == "rule analysis failed: boom (log: logs/failed/analysis.log)"
    assert out["missing"] == f"not built: no usable case (log: {logs / 'missing' / 'characteristic.log'})"
    assert out["stale"].startswith("stale: ") and "changed after its results were made" in out["stale"]
    assert out["virtual"] == "not built (no error in logs/virtual/)"


def test_rebuilt_index_lists_the_good_campaign_and_the_failed_one_with_its_reason(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    build_campaign(Path("results", CAMPAIGN))
    Path("results", CAMPAIGN, "report.html").write_text("page", encoding="utf-8")
    _write(Path("logs/broken/ingest.log"), f"2026-11-25 18:27:20,206 ERROR {INGEST_ERROR}\n")
    log = _write(Path("run.log"), SNAKEMAKE_LOG.replace("Error in rule blind_score", "Done rule blind_score"))
    caption = _write(Path("workflow/report/fig17_blind_confusion.rst"), "caption")
    lines = run_status.rebuild_after_failure(log, campaigns=[CAMPAIGN, "broken"], raw_dirs={}, older_than=[caption])
    for stand_in in ("results/index.html", "results/design/plan_check.parquet"):  # older than an input of the rule
        assert Path(stand_in).stat().st_mtime < caption.stat().st_mtime
    assert lines == ["1 failure(s) in this run:",
                     f"  campaign broken: rule ingest failed: {INGEST_ERROR} (log: logs/broken/ingest.log)"]
    page = Path("results/index.html").read_text(encoding="utf-8")
    text = plain(page)
    assert "1 of 2 campaign(s) failed in the last run" in text and INGEST_ERROR in text
    broken_row = page[page.index('id="campaign-broken"'):].split("</tr>")[0]
    assert "rule ingest failed" in broken_row and "report.html" not in broken_row
    assert f'href="{CAMPAIGN}/report.html"' in page
    summary = pd.read_parquet("results/design/plan_check.parquet")
    expected = pd.read_parquet(Path("results", CAMPAIGN, "design", "plan_check.parquet"))
    pd.testing.assert_frame_equal(summary, expected)


def test_rebuilt_design_summary_leaves_out_the_failed_campaigns_old_plan_check(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    build_campaign(Path("results", CAMPAIGN))
    Path("results", CAMPAIGN, "report.html").write_text("page", encoding="utf-8")
    old = pd.read_parquet(Path("results", CAMPAIGN, "design", "plan_check.parquet")).assign(campaign="broken")
    write_parquet(old, Path("results/broken/design/plan_check.parquet"))
    log = _write(Path("run.log"), SNAKEMAKE_LOG)
    run_status.rebuild_after_failure(log, campaigns=[CAMPAIGN, "broken"], raw_dirs={})
    assert set(pd.read_parquet("results/design/plan_check.parquet")["campaign"]) == {CAMPAIGN}


def test_only_the_manifest_and_the_named_raw_files_make_results_stale(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for c in ("notes", "named"):
        _write(Path("raw", c, "campaign.yaml"), "x")
        _write(Path("raw", c, "T01.csv"), "t,f\n")
        write_parquet(pd.DataFrame({"case": ["T01"], "raw_file": [f"raw/{c}/T01.csv"]}),
                      Path("results", c, "cases.parquet"))
        _write(Path("results", c, "report.html"), "page")
    later = time.time() + 5
    _write(Path("raw/notes/notes.txt"), "not a case file")
    os.utime("raw/notes/notes.txt", (later, later))
    os.utime("raw/named/T01.csv", (later, later))
    out = run_status.campaign_failures("results", "logs", ["notes", "named"], {c: Path("raw", c) for c in
                                                                              ("notes", "named")})
    assert list(out) == ["named"] and out["named"].startswith("stale: raw/named/ changed")


def test_a_refused_campaign_job_is_named_by_its_log(tmp_path):
    _write(tmp_path / "logs/_refused/broken.log", "2026-11-25 18:27:20,206 ERROR campaign broken refused: because\n")
    log = _write(tmp_path / "run.log", "Error in rule refused:\n    message: None\n    jobid: 7\n"
                                       "    output: logs/_refused/broken.txt\n"
                                       "    log: logs/_refused/broken.log (check log file(s) for error details)\n")
    jobs = run_status.failed_jobs([log], workdir=tmp_path)
    assert [(j.rule, j.campaign, j.reason) for j in jobs] == [("refused", "broken", "campaign broken refused: because")]


def _mark_incomplete(incomplete_dir: Path, output: str, max_len: int = 255) -> Path:
    """Mark ``output`` incomplete as Snakemake does (its own record path: the output's path in URL-safe base64,
    split into '@' folders when longer than a file name may be), with its record's content."""
    from types import SimpleNamespace

    from snakemake.persistence.file import FilePersistence

    record = Path(FilePersistence._record_path(SimpleNamespace(_fetch_max_len=lambda _: max_len),
                                               str(incomplete_dir), output))
    return _write(record, '{"external_jobid": null}')


def test_an_output_marked_incomplete_shows_its_campaign_interrupted(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # Snakemake records outputs relative to the project, as the workflow names them
    results, logs, incomplete = Path("results"), Path("logs"), Path(".snakemake/incomplete")
    for c in ("cut", "long-cut", "good"):
        _write(results / c / "report.html", "old page")     # the old page is there: the campaign looks built
    _mark_incomplete(incomplete, "results/cut/characteristic.parquet")
    _mark_incomplete(incomplete, "results/long-cut/models/models.parquet", max_len=12)
    _mark_incomplete(incomplete, "results/index.html")     # the index's own: no campaign's
    _write(incomplete / "migration_underway", "")          # Snakemake's own file there
    assert run_status.incomplete_outputs(incomplete) == ["results/cut/characteristic.parquet", "results/index.html",
                                                         "results/long-cut/models/models.parquet"]
    out = run_status.campaign_failures(results, logs, ["cut", "long-cut", "good"], incomplete_dir=incomplete)
    assert sorted(out) == ["cut", "long-cut"]
    assert out["cut"].startswith("interrupted: ") and "results/cut/characteristic.parquet" in out["cut"]
    assert "--rerun-incomplete" in out["long-cut"]
    # without the marks (the jobs rerun and finished), nothing is interrupted
    assert run_status.campaign_failures(results, logs, ["cut", "long-cut", "good"],
                                        incomplete_dir="none") == {}


def test_rebuilt_index_and_summary_name_interrupted_unbuilt_and_orphaned_folders(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    build_campaign(Path("results", CAMPAIGN))
    Path("results", CAMPAIGN, "report.html").write_text("page", encoding="utf-8")
    _mark_incomplete(Path(".snakemake/incomplete"), f"results/{CAMPAIGN}/cases.parquet")
    log = _write(Path("run.log"), "Exiting because a job execution failed.\n")
    unusable = [{"folder": "data/raw/Bench 3", "reason": "folder name 'Bench 3' is not a campaign id",
                 "fix": "rename it to bench-3"}]
    lines = run_status.rebuild_after_failure(log, campaigns=[CAMPAIGN], raw_dirs={}, unusable=unusable,
                                             orphaned={"gone": "orphaned: raw folder missing: data/raw/gone/"})
    assert lines[0] == "1 failure(s) in this run:" and lines[1].startswith(f"  campaign {CAMPAIGN}: interrupted: ")
    assert lines[2:] == ["2 folder(s) not built (listed apart on results/index.html):",
                         "  data/raw/Bench 3/: not built: folder name 'Bench 3' is not a campaign id; "
                         "rename it to bench-3",
                         "  results/gone/: orphaned: raw folder missing: data/raw/gone/"]
    page = Path("results/index.html").read_text(encoding="utf-8")
    row = page[page.index(f'id="campaign-{CAMPAIGN}"'):].split("</tr>")[0]
    assert "interrupted" in row and "report.html" not in row and "title=" not in row   # no old numbers
    text = plain(page)
    assert "data/raw/Bench 3/" in text and "rename it to bench-3" in text
    assert "orphaned: raw folder missing: data/raw/gone/" in text
