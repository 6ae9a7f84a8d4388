"""What a run left behind: the jobs that failed, each campaign's state, and the index rebuilt from what exists.

A failed campaign must never freeze ``results/index.html`` (issue 19 part 7, issue 20 part 5). The rule
``report_index`` builds the index when every campaign succeeded; when a job failed, Snakemake cannot run it
and the workflow's ``onerror`` handler calls :func:`rebuild_after_failure` instead: it reads the failed jobs
from Snakemake's log (:func:`failed_jobs`), writes the index and the design summary from whatever outputs
exist, listing every campaign whose outputs are missing, stale or whose job failed with the first error line
of its job log (:func:`campaign_failures`), and returns the run's closing summary (:func:`summary_lines`).

A campaign whose jobs were cut off (one Ctrl-C, a kill) is *interrupted* until it is rebuilt: Snakemake marks
each output of a running job incomplete (``.snakemake/incomplete/``, :func:`incomplete_outputs`) and removes
the mark only when the job finished, so a campaign with a marked output is shown interrupted, never with
its old numbers (issue 34, part 5).
"""

from __future__ import annotations

import base64
import binascii
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from isokinetic.audit.raw_inventory import UnusableFolder
from isokinetic.contracts.campaign_folder import CampaignFolder, read_parquet
from isokinetic.contracts.outputs import DESIGN_SUMMARY, RESULTS_DIR, STAGE_OUTPUTS

#: Snakemake's block for a failed job: ``Error in rule <name>:`` then indented ``key: value`` lines.
_ERROR_BLOCK = re.compile(r"^Error in rule (?P<rule>[\w.-]+):\s*$")
_BLOCK_LINE = re.compile(r"^\s+(?P<key>[\w ]+):\s?(?P<value>.*)$")
_CAMPAIGN_IN_PATH = re.compile(r"^(?:logs|results)/(?P<campaign>[^/\s]+)/")
#: The log of a refused campaign's job (rule refused): ``logs/_refused/<campaign>.log`` (no campaign id starts
#: with an underscore, so the folder is no campaign's).
_REFUSED_LOG = re.compile(r"^logs/_refused/(?P<campaign>[^/\s]+)\.(?:log|txt)$")
#: A log record line of a job (isokinetic.job.LOG_FORMAT): date, time, level, message.
_LOG_RECORD = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d+ (?P<level>[A-Z]+) (?P<message>.*)$")
#: Longest reason shown on the index and in the summary (a reason is a line, never a dump).
MAX_REASON = 240
#: Where Snakemake marks the outputs of jobs that started and have not finished (its persistence folder).
INCOMPLETE_DIR = ".snakemake/incomplete"
#: What to run after an interrupted build (README, "Running").
RERUN_INCOMPLETE = "snakemake --cores 2 --rerun-incomplete"


@dataclass(frozen=True)
class FailedJob:
    """A job that failed in a run: its rule, its campaign (None for the blind suite or a comparison), its
    log file and the first error line of that log."""

    rule: str
    campaign: str | None
    log: str | None
    reason: str

    def line(self) -> str:
        """The job as one line of the run's closing summary."""
        where = f"campaign {self.campaign}: " if self.campaign else ""
        log = f" (log: {self.log})" if self.log else ""
        return f"{where}rule {self.rule} failed: {self.reason}{log}"


def shorten(text: str, limit: int = MAX_REASON) -> str:
    """``text`` on one line, cut to ``limit`` characters with an ellipsis."""
    one = " ".join(str(text).split())
    return one if len(one) <= limit else one[: limit - 1] + "\u2026"


def first_error_line(log_path: str | os.PathLike | None) -> str | None:
    """The message of the first ERROR (or CRITICAL) record of a job's log, else its last traceback line
    (``SomeError: ...``); None when the log is missing or holds neither."""
    if log_path is None:
        return None
    try:
        lines = Path(log_path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return None
    for line in lines:
        m = _LOG_RECORD.match(line)
        if m and m["level"] in ("ERROR", "CRITICAL"):
            return shorten(m["message"])
    errors = [line for line in lines if re.match(r"^[\w.]*(Error|Exception)\b.*:", line.strip())]
    return shorten(errors[-1]) if errors else None


def _log_lines(snakemake_log: str | os.PathLike | Sequence[str | os.PathLike] | None) -> list[str]:
    """The lines of Snakemake's log file(s) of a run (its ``onerror`` handler gets a path or a list of them)."""
    paths = [snakemake_log] if isinstance(snakemake_log, (str, os.PathLike)) else list(snakemake_log or [])
    lines: list[str] = []
    for path in paths:
        if Path(path).is_file():
            lines += Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    return lines


def failed_jobs(snakemake_log: str | os.PathLike | Sequence[str | os.PathLike] | None,
                workdir: str | os.PathLike = ".") -> list[FailedJob]:
    """Every ``Error in rule`` block of Snakemake's log of a run, in order, once per rule and campaign."""
    blocks: list[dict] = []
    for line in _log_lines(snakemake_log):
        m = _ERROR_BLOCK.match(line)
        if m:
            blocks.append({"rule": m["rule"]})
            continue
        kv = _BLOCK_LINE.match(line)
        if blocks and kv and "done" not in blocks[-1]:
            blocks[-1].setdefault(kv["key"].strip(), kv["value"].strip())
        elif blocks:
            blocks[-1]["done"] = True
    jobs, seen = [], set()
    for b in blocks:
        log = b.get("log", "").split(" (")[0].split(",")[0].strip() or None
        campaign = _campaign_of(b, log)
        if (b["rule"], campaign) in seen:
            continue
        seen.add((b["rule"], campaign))
        reason = first_error_line(Path(workdir) / log if log else None)
        if reason is None:
            message = b.get("message", "")
            reason = shorten(message) if message and message != "None" else "no error line in its log"
        jobs.append(FailedJob(b["rule"], campaign, log, reason))
    return jobs


def _campaign_of(block: Mapping[str, str], log: str | None) -> str | None:
    """The campaign of a failed job: its ``campaign`` wildcard, else the folder of its log or output."""
    m = re.search(r"(?:^|,\s*)campaign=([^,\s]+)", block.get("wildcards", ""))
    if m:
        return m[1]
    for path in (log or "", block.get("output", "")):
        m = _REFUSED_LOG.match(path) or _CAMPAIGN_IN_PATH.match(path)
        if m and m["campaign"] not in ("blind", "compare"):
            return m["campaign"]
    return None


def newest_log_error(logs_dir: Path) -> tuple[str | None, str | None]:
    """The first error line of the newest job log in ``logs_dir`` that has one, and that log's path."""
    logs = sorted(logs_dir.glob("*.log"), key=lambda p: p.stat().st_mtime, reverse=True) if logs_dir.is_dir() else []
    for log in logs:
        reason = first_error_line(log)
        if reason:
            return reason, str(log)
    return None, None


def _newest_mtime(files: Iterable[Path]) -> float:
    return max((p.stat().st_mtime for p in files if p.is_file()), default=0.0)


def raw_inputs(raw_dir: Path, campaign_root: Path) -> list[Path]:
    """The raw files a campaign's results were made from: its manifest and the case files its cases table
    names (``raw_file``, relative to the project); a file in the folder that no case names is not one."""
    files = [raw_dir / "campaign.yaml"]
    try:
        cases_file = CampaignFolder.at(campaign_root).path("validate", "cases")
        named = read_parquet(cases_file, columns=["raw_file"])["raw_file"]
    except (OSError, ValueError, KeyError):
        return files
    return files + [Path(str(f)) for f in named.dropna().unique() if not str(f).startswith("virtual_rig:")]


def incomplete_outputs(incomplete_dir: str | os.PathLike = INCOMPLETE_DIR) -> list[str]:
    """The outputs Snakemake marks incomplete: one file per output under ``incomplete_dir``, named by the
    output's path in URL-safe base64 (a long name split into folders whose names start with ``@``)."""
    root = Path(incomplete_dir)
    if not root.is_dir():
        return []
    out = []
    for top, _dirs, files in os.walk(root):
        parts = [p.removeprefix("@") for p in Path(top).relative_to(root).parts]
        for name in files:
            try:
                out.append(base64.urlsafe_b64decode("".join(parts) + name).decode("utf-8"))
            except (binascii.Error, ValueError):  # Snakemake's own files there (migration_underway)
                continue
    return sorted(out)


def interrupted_campaigns(campaigns: Sequence[str], incomplete_dir: str | os.PathLike = INCOMPLETE_DIR,
                          results_root: str | os.PathLike = "results") -> dict[str, str]:
    """Campaign -> why it is shown interrupted, for each campaign with an output marked incomplete
    (:func:`incomplete_outputs`): a job of it was cut off and has not been rerun since."""
    prefix = Path(results_root).as_posix().rstrip("/") + "/"
    marked: dict[str, list[str]] = {}
    for path in incomplete_outputs(incomplete_dir):
        campaign = path.removeprefix(prefix).split("/", 1)[0] if path.startswith(prefix) else None
        if campaign in campaigns:
            marked.setdefault(campaign, []).append(path)
    return {c: (f"interrupted: a run was cut off while it rebuilt this campaign ({len(paths)} output(s) left "
                f"incomplete, e.g. {paths[0]}); its old results are not current; rebuild it with "
                f"`{RERUN_INCOMPLETE}`") for c, paths in marked.items()}


def campaign_failures(results_root: str | os.PathLike, logs_root: str | os.PathLike, campaigns: Sequence[str],
                      raw_dirs: Mapping[str, str | os.PathLike] | None = None,
                      failed: Sequence[FailedJob] = (),
                      incomplete_dir: str | os.PathLike | None = None) -> dict[str, str]:
    """Campaign -> why it has no current result, for each campaign that has none.

    A campaign is interrupted when an output of it is marked incomplete (:func:`interrupted_campaigns`; not
    looked at when ``incomplete_dir`` is None); it failed when a job of it failed in the run (``failed``),
    or when its page ``results/<c>/report.html`` is missing, or older than its manifest or a raw file its
    cases table names (:func:`raw_inputs`; ``raw_dirs``: campaign -> folder, raw campaigns only). The reason
    is the failed job's, else the first error line of the newest log in ``logs/<c>/``.
    """
    results_root, logs_root = Path(results_root), Path(logs_root)
    out: dict[str, str] = {}
    if incomplete_dir is not None:
        out.update(interrupted_campaigns(campaigns, incomplete_dir, results_root))
    for job in failed:
        if job.campaign in campaigns and job.campaign not in out:
            out[job.campaign] = job.line().removeprefix(f"campaign {job.campaign}: ")
    for c in campaigns:
        if c in out:
            continue
        page = CampaignFolder.at(results_root / c).path("campaign_report", "page")
        raw = Path((raw_dirs or {}).get(c, "")) if (raw_dirs or {}).get(c) else None
        if not page.is_file():
            problem = "not built"
        elif raw is not None and _newest_mtime(raw_inputs(raw, results_root / c)) > page.stat().st_mtime:
            problem = f"stale: {raw}/ changed after its results were made (rerun the workflow)"
        else:
            continue
        reason, log = newest_log_error(logs_root / c)
        out[c] = f"{problem}: {reason} (log: {log})" if reason else f"{problem} (no error in logs/{c}/)"
    return out


def summary_lines(failed: Sequence[FailedJob], failures: Mapping[str, str] | None = None) -> list[str]:
    """The run's closing summary: each interrupted campaign, one line per failed job (of a campaign not
    interrupted), then each failed campaign with no failed job."""
    failures = dict(failures or {})
    interrupted = {c for c, reason in failures.items() if reason.startswith("interrupted")}
    lines = [f"campaign {c}: {reason}" for c, reason in failures.items() if c in interrupted]
    lines += [job.line() for job in failed if job.campaign not in interrupted]
    named = {job.campaign for job in failed} | interrupted
    lines += [f"campaign {c}: {reason}" for c, reason in failures.items() if c not in named]
    if not lines:
        return []
    return [f"{len(lines)} failure(s) in this run:"] + [f"  {line}" for line in lines]


def state_lines(unusable: Sequence[str] = (), orphaned: Mapping[str, str] | None = None,
                results_root: str | os.PathLike = "results") -> list[str]:
    """The closing summary's lines on what the run did not build (issue 34, part 5): each folder under the raw
    data folder it cannot build (``unusable``: one line each, :class:`isokinetic.audit.raw_inventory
    .UnusableFolder`), and each orphaned ``results/<name>/`` (``orphaned``: name -> reason)."""
    lines = [f"  {line}" for line in unusable]
    lines += [f"  {Path(results_root).as_posix()}/{name}/: {reason}" for name, reason in (orphaned or {}).items()]
    if not lines:
        return []
    return [f"{len(lines)} folder(s) not built (listed apart on results/index.html):"] + lines


def rebuild_after_failure(snakemake_log: str | os.PathLike | Sequence[str | os.PathLike] | None, *,
                          campaigns: Sequence[str],
                          raw_dirs: Mapping[str, str | os.PathLike], comparisons: Sequence[str] = (),
                          blind_dir: str | os.PathLike | None = None, captions_dir: str | os.PathLike | None = None,
                          results_root: str | os.PathLike = "results", logs_root: str | os.PathLike = "logs",
                          index: str | os.PathLike = "results/index.html",
                          design_summary: str | os.PathLike = f"{RESULTS_DIR}/{DESIGN_SUMMARY}",
                          older_than: Sequence[str | os.PathLike] = (),
                          unusable: Sequence[Mapping[str, str]] = (),
                          orphaned: Mapping[str, str] | None = None,
                          incomplete_dir: str | os.PathLike | None = INCOMPLETE_DIR) -> list[str]:
    """After a failed run (Snakemake's ``onerror``): the index and the design summary rebuilt from the outputs
    that exist, every failed campaign listed with its reason; returns the run's closing summary lines.

    The two files are stand-ins for the rule ``report_index``'s outputs: they are dated just before the
    oldest of ``older_than`` (files that are always inputs of that rule; the epoch without them), so the
    next run that can build the rule's outputs does, even when nothing else changed (a broken campaign
    removed, say). ``unusable`` (raw folders the workflow does not build: folder, reason, fix) and
    ``orphaned`` (results/<name>/ -> reason) are listed apart on the index and named in the summary."""
    # imported here: the workflow calls this only after a failed run
    from isokinetic.audit.lineage import stage_lineage
    from isokinetic.io import lineage_context
    from isokinetic.report.report_index import write_index
    from isokinetic.stages.design_summary import write_design_summary

    failed = failed_jobs(snakemake_log)
    failures = campaign_failures(results_root, logs_root, campaigns, raw_dirs, failed, incomplete_dir)
    results_root = Path(results_root)
    plan_checks = [CampaignFolder.at(results_root / c).path("design", "plan_check") for c in campaigns
                   if c not in failures]
    plan_checks = [p for p in plan_checks if p.is_file()]
    record = stage_lineage("report_index", {"campaigns": list(campaigns), "built_by": "onerror handler",
                                            "failed": dict(failures)}, plan_checks)
    summary = STAGE_OUTPUTS["blind_score"]["summary"]
    blind = Path(blind_dir) if blind_dir is not None and (Path(blind_dir) / summary).is_file() else None
    with lineage_context(record):
        write_design_summary(plan_checks, design_summary)
        write_index(results_root, index, list(campaigns), blind_dir=blind, captions_dir=captions_dir,
                    lineage_record=record, comparisons=list(comparisons), failures=failures,
                    unusable=unusable, orphaned=orphaned)
    mark_stand_in([index, design_summary], older_than)
    lines = [UnusableFolder(**u).line() for u in unusable]
    return summary_lines(failed, failures) + state_lines(lines, orphaned, results_root)


def mark_stand_in(paths: Sequence[str | os.PathLike], older_than: Sequence[str | os.PathLike]) -> None:
    """Date ``paths`` one second before the oldest existing file of ``older_than`` (the epoch without one), so
    that Snakemake, which reruns a job whose input is newer than its output, rebuilds them on the next run."""
    times = [Path(p).stat().st_mtime for p in older_than if Path(p).is_file()]
    stamp = max(0.0, min(times) - 1.0) if times else 0.0
    for path in paths:
        if Path(path).is_file():
            os.utime(path, (stamp, stamp))
