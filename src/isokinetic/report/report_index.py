"""Rule ``report_index``: ``results/index.html``, every campaign's verdict and key numbers, and the blind suite.

One row per campaign (cases, quarantined cases, characteristic points, flagged plan cases and
repeatability pairs, the Wallaschek fit's residual scale, the diagnosis verdict and gap), linked
to its page (:mod:`isokinetic.report.campaign_report`), or, for a campaign that failed or was interrupted
(a reason starting with "interrupted", :func:`isokinetic.report.run_status.interrupted_campaigns`), that
reason alone; apart, the folders under the raw data folder that are not built and the orphaned results
(:mod:`isokinetic.audit.raw_inventory`), with why and the fix; then the comparisons of campaigns
(``results/compare/<name>/``, config ``comparisons``), each linked to its page
(:mod:`isokinetic.report.compare_report`); then the blind test of the diagnosis (``results/blind/``):
its targets, detection by magnitude bin, Fig. 17 and every scenario. Every number's title names its
file, rule and commit, as on the campaign pages.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import SNAKEMAKE_REPORT, STAGE_OUTPUTS, comparison_folder, figure
from isokinetic.io import write_text
from isokinetic.report.cells import Cell, Col, Row, Table, badge, number_cell, table_view
from isokinetic.report.embed import figure_view, read_captions
from isokinetic.report.layout import footer, render
from isokinetic.report.numbers import esc, fmt, fmt_pct, text, yes_no
from isokinetic.report.sources import Source, Sources, lineage_of, lineage_rows, read_json, read_parquet, trace_command

COUNTED = ["counted by the index"]
#: Cells of a campaign's row between its name and its page link (counts, residual scale, diagnosis).
N_CAMPAIGN_CELLS = 11
BLIND_FIGURE = figure("fig17_blind_confusion")
SCORE_COLS = [Col("scenario", "scenario", text, False), Col("truth", "truth", lambda x: text(x or "(none)"), False),
              Col("verdict", "verdict", lambda x: text(x or "(none)"), False), Col("exact", "exact", yes_no, False),
              Col("magnitude_x_detection", "magnitude [x detection]", lambda x: fmt(x, 3)),
              Col("magnitude_bin", "bin", text, False), Col("gap_before", "gap before", lambda x: fmt(x, 3)),
              Col("gap_after", "gap after", lambda x: fmt(x, 3)), Col("shrink", "shrink", lambda x: fmt(x, 3)),
              Col("error", "error", text, False)]


# ----------------------------------------------------------------------------------------------
# one row per campaign
# ----------------------------------------------------------------------------------------------

def _counts(root: Path, srcs: Sources) -> list[Cell]:
    """The counts of a campaign's row: cases, quarantined, points, flagged plan cases and pairs."""
    cases_, q_, char_, pc_, rep_ = (STAGE_OUTPUTS["validate"]["cases"], STAGE_OUTPUTS["validate"]["quarantine"],
                                    STAGE_OUTPUTS["characteristic"]["characteristic"],
                                    STAGE_OUTPUTS["design"]["plan_check"],
                                    STAGE_OUTPUTS["repeatability"]["repeatability"])
    cases, q, char, pc, rep = (read_parquet(root / rel) for rel in (cases_, q_, char_, pc_, rep_))

    def cell(value: str, rel: str, column: str) -> Cell:
        return number_cell(value, srcs(rel).title("", column, COUNTED))

    return [cell(f"{int((cases['status'] == 'ok').sum())} / {len(cases)}" if cases is not None else "-",
                 cases_, "count of rows with status ok / all rows"),
            cell(str(q["case"].nunique() if q is not None and len(q) else 0) if q is not None else "-",
                 q_, "distinct cases"),
            cell(str(len(char)) if char is not None else "-", char_, "rows"),
            cell(str(int(pc["flagged"].sum())) if pc is not None else "-", pc_, "count of flagged rows"),
            cell(str(int(rep["flagged"].sum())) if rep is not None else "-", rep_, "count of flagged rows")]


def _residual_scale(root: Path, srcs: Sources) -> Cell:
    models = read_parquet(root / STAGE_OUTPUTS["models"]["models"])
    src = srcs(STAGE_OUTPUTS["models"]["models"])
    scale = None
    if models is not None and len(models) and "wallaschek" in set(models["model"]):
        scale = models.loc[models["model"] == "wallaschek", "residual_scale"].iloc[0]
    return number_cell(fmt(scale, 3), src.title("model=wallaschek,direction=both,parameter=F_C", "residual_scale"))


def _verdict(root: Path, srcs: Sources) -> list[Cell]:
    """The diagnosis cells of a campaign's row: verdict, gaps and shrink, or why there are none."""
    diag = read_json(root / STAGE_OUTPUTS["diagnosis"]["json"])
    src = srcs(STAGE_OUTPUTS["diagnosis"]["json"])
    if not diag or diag.get("status", "ok") != "ok":
        missing = f"{STAGE_OUTPUTS['diagnosis']['json']} missing"
        reason = (diag or {}).get("reason") or (missing if diag is None else "not diagnosed")
        return [Cell(esc(reason), src.title("status", "status"), colspan=5)]
    verdict = ", ".join(diag.get("verdict") or []) or "[] nominal"
    explained = diag.get("explained", True)
    shown = badge("explained", "good") if explained else badge("not explained", "bad")
    return [Cell(f"{esc(verdict)} {shown}", src.title("verdict", "verdict")),
            number_cell(fmt(diag.get("gap_before"), 4), src.title("gap_before", "gap_before")),
            number_cell(fmt(diag.get("gap_after"), 3), src.title("gap_after", "gap_after")),
            number_cell(fmt(diag.get("holdout_gap_after"), 3), src.title("holdout_gap_after", "holdout_gap_after")),
            number_cell(fmt(diag.get("shrink"), 3), src.title("shrink", "shrink"))]


def _source(folder: CampaignFolder) -> str:
    """The campaign's source (campaign.json), '-' without a readable record: a failed campaign's folder may hold
    one from an older writer, and the index lists it all the same."""
    try:
        return (folder.meta.source if folder.has_meta() else None) or "-"
    except (OSError, ValueError):       # not JSON, or not a campaign.json (CampaignMetaError)
        return "-"


def _campaign_row(results_root: Path, campaign: str, failure: str | None = None) -> tuple[dict, list[Source]]:
    """A campaign's row of the index and the files it read; a failed campaign's row is its reason alone (its
    files, if any, are from an earlier run and are not shown as this run's results)."""
    root = results_root / campaign
    folder = CampaignFolder.at(root)
    srcs = Sources(root, read_json(folder.path("provenance", "provenance")))
    source = _source(folder)
    if failure is not None:
        state = "interrupted" if failure.startswith("interrupted") else "failed"
        cells = [Cell(f"{badge(state, 'bad')} {esc(failure)}", cls="reason", colspan=N_CAMPAIGN_CELLS)]
        return {"name": campaign, "source": source, "cells": cells, "report": False,
                "failed": True}, []
    cells = _counts(root, srcs) + [_residual_scale(root, srcs)] + _verdict(root, srcs)
    row = {"name": campaign, "source": source, "cells": cells,
           "report": folder.path("campaign_report", "page").is_file(), "failed": False}
    return row, srcs.all()


def _unusable_rows(unusable: Sequence[Mapping[str, str]]) -> list[dict]:
    """A row per folder under the raw data folder that is not built: the folder, why, and the fix
    (:class:`isokinetic.audit.raw_inventory.UnusableFolder` as a mapping)."""
    return [{"folder": u["folder"], "reason": u["reason"], "fix": u["fix"]} for u in unusable]


def _orphan_rows(results_root: Path, orphaned: Mapping[str, str]) -> list[dict]:
    """A row per orphaned ``results/<name>/`` (:func:`isokinetic.audit.raw_inventory.orphaned_results`): its
    folder and why; none of its numbers, and no link to its old page."""
    return [{"name": name, "folder": f"{results_root.as_posix()}/{name}/", "reason": reason}
            for name, reason in orphaned.items()]


# ----------------------------------------------------------------------------------------------
# one row per comparison
# ----------------------------------------------------------------------------------------------

def _comparison_row(results_root: Path, name: str) -> tuple[dict, list[Source]]:
    """A comparison's row of the index (its compare.json) and the files it read."""
    folder = comparison_folder(name)
    srcs = Sources(results_root / folder)
    rel = STAGE_OUTPUTS["compare"]["summary"]
    summary = read_json(results_root / folder / rel)
    src = srcs(rel)
    page = STAGE_OUTPUTS["compare_report"]["page"]
    row = {"name": name, "href": f"{folder}/{page}", "report": (results_root / folder / page).is_file(),
           "campaigns": "-", "description": "", "cells": [Cell("compare.json missing", colspan=4)]}
    if summary is None:
        return row, srcs.all()
    campaigns = list(summary.get("campaigns") or [])
    row["campaigns"] = ", ".join(campaigns)
    row["description"] = summary.get("description") or ""
    pairs = summary.get("pairs") or []

    def total(key: str) -> float:
        return sum(p.get(key) or 0 for p in pairs)

    z = [p["max_abs_z"] for p in pairs if p.get("max_abs_z") is not None]
    n_sig = int(total("n_significant"))
    shown = f"{n_sig} " + (badge("none", "good") if n_sig == 0 else badge("differ", "bad"))
    row["cells"] = [
        number_cell(f"{int(total('n_rows'))} ({int(total('n_measured'))} measured, {int(total('n_model'))} model)",
                    src.title("pairs", "n_rows,n_measured,n_model", COUNTED)),
        number_cell(shown, src.title("pairs", "n_significant", COUNTED)),
        number_cell(fmt(total("expected_by_chance"), 2), src.title("pairs", "expected_by_chance", COUNTED)),
        number_cell(fmt(max(z), 3) if z else "-", src.title("pairs", "max_abs_z", COUNTED))]
    return row, srcs.all()


# ----------------------------------------------------------------------------------------------
# the blind suite
# ----------------------------------------------------------------------------------------------

def pass_badge(ok: bool | None) -> str:
    return badge("N/A", "warn") if ok is None else (badge("PASS", "good") if ok else badge("FAIL", "bad"))


def _target_result(target: Mapping) -> tuple[str, str, Mapping]:
    """A blind-suite target's result and threshold as shown, and the target with its misses."""
    if "claimed" in target:
        return (f"{target.get('claimed')}/{target.get('n')} claimed",
                f"&le; alpha = {fmt(target['alpha'])}" if "alpha" in target else "0 claimed", target)
    if "flagged" in target:
        return (f"{target.get('flagged')}/{target.get('n')} = {fmt_pct(target.get('rate'))}",
                f"&ge; {fmt_pct(target.get('threshold'))}", target)
    if "rate" in target:
        return (f"{target.get('exact', '?')}/{target.get('n', '?')} = {fmt_pct(target.get('rate'))}",
                f"&ge; {fmt_pct(target.get('threshold'))}", target)
    if "param_error_max" in target:
        misses = sorted({*target.get("param_misses", []), *target.get("delay_misses", []),
                         *target.get("offset_misses", []), *target.get("lag_misses", []),
                         *target.get("scale_misses", [])})
        sensor = "n_lag" in target  # issue 21: the force-channel lag and the LVDT gain
        return (f"effect sizes within {fmt_pct(target.get('param_error_max'))}; delay within "
                f"{fmt((target.get('delay_error_max_s') or 0) * 1e3, 3)} ms; offset within "
                f"{fmt(target.get('offset_error_max_N'), 3)} N"
                + (f"; lag within {fmt((target.get('lag_error_max_s') or 0) * 1e3, 3)} ms; LVDT gain within "
                   f"{fmt_pct(target.get('scale_error_max'))}" if sensor else ""),
                "15 % (or 3 SE); 2 ms; 2 N" + ("; 5 ms; 0.3 %" if sensor else ""), {**target, "misses": misses})
    return (f"median {fmt(target.get('median'), 3)} over {target.get('n', '?')}",
            f"&ge; {fmt(target.get('threshold'), 3)}", target)


def _targets(summary: Mapping, src: Source) -> Table:
    rows = []
    for key, target in (summary.get("targets") or {}).items():
        result, threshold, target = _target_result(target)
        misses = ", ".join(map(str, target.get("misses") or [])) or "-"
        rows.append(Row([Cell(f"<strong>{esc(key)}</strong>"), Cell(esc(target.get("description", ""))),
                         number_cell(result, src.title(f"targets.{key}", key)), Cell(threshold),
                         Cell(pass_badge(target.get("pass"))), Cell(esc(misses))]))
    return Table(["target", "what", "result", "threshold", "", "misses"], rows, id="blind-targets")


def _bins(summary: Mapping, src: Source) -> Table | None:
    bins = summary.get("bins") or {}
    if not bins:
        return None
    rows = []
    for name, b in bins.items():
        t = src.title(f"bins.{name}", name)
        rows.append(Row([Cell(f"{esc(name)} detection"), number_cell(f'{b.get("exact", "-")}/{b.get("n", "-")}', t),
                         number_cell(fmt_pct(b.get("rate")), t),
                         number_cell(f'{b.get("exact_single", "-")}/{b.get("n_single", "-")}', t),
                         number_cell(fmt_pct(b.get("rate_single")), t)]))
    return Table(["bin", "exact", "rate", "exact (single effect)", "rate (single effect)"], rows, id="blind-bins")


def _blind_section(blind_dir: Path, captions: Mapping[str, str]) -> tuple[dict, list[Source]]:
    """The blind suite's section and the files it read."""
    srcs = Sources(blind_dir)
    summary_file, scores_file = STAGE_OUTPUTS["blind_score"]["summary"], STAGE_OUTPUTS["blind_score"]["scores"]
    summary = read_json(blind_dir / summary_file)
    scores = read_parquet(blind_dir / scores_file)
    ssrc = srcs(summary_file)
    if summary is None:
        return {"summary": None}, srcs.all()
    scores_label = srcs(scores_file).label
    view = {"summary": {k: summary.get(k, "?") for k in ("n_scenarios", "n_single", "n_pairs", "n_none")},
            "n_errors": summary.get("n_errors", 0), "exact_rate": fmt_pct(summary.get("exact_rate")),
            "all_pass": bool(summary.get("all_pass")), "targets": _targets(summary, ssrc),
            "bins": _bins(summary, ssrc), "lineage": lineage_of(ssrc, "targets"), "scores_label": scores_label,
            "scores_audit": trace_command(scores_label, "scenario=<id>"),
            "figure": figure_view(srcs(BLIND_FIGURE.path), BLIND_FIGURE, captions.get(BLIND_FIGURE.name, ""),
                                  href_prefix=f"{blind_dir.name}/"),
            "scores": None}
    if scores is not None:
        view["scores"] = table_view(scores, [c for c in SCORE_COLS if c.key in scores], srcs(scores_file),
                                    ["scenario"], row_class=lambda r: "" if r.get("exact") else "flagged",
                                    table_id="blind-scores")
        view["n_scores"] = len(scores)
    return view, srcs.all()


# ----------------------------------------------------------------------------------------------
# the page
# ----------------------------------------------------------------------------------------------

def render_index(results_root: str | os.PathLike, campaigns: Sequence[str], *,
                 blind_dir: str | os.PathLike | None = None, captions_dir: str | os.PathLike | None = None,
                 lineage_record: Mapping | None = None, comparisons: Sequence[str] = (),
                 failures: Mapping[str, str] | None = None, unusable: Sequence[Mapping[str, str]] = (),
                 orphaned: Mapping[str, str] | None = None) -> str:
    """``results/index.html``: every campaign with its verdict and key numbers, or, for a campaign in
    ``failures`` (campaign -> reason, :func:`isokinetic.report.run_status.campaign_failures`), why it has
    none; apart, each folder under the raw data folder that is not built (``unusable``: folder, reason, fix)
    and each orphaned campaign result (``orphaned``: name -> reason); each comparison (linked to its page),
    and the blind-suite scores."""
    results_root = Path(results_root)
    captions = read_captions(captions_dir)
    failures = dict(failures or {})
    rows, sources = [], []
    for c in campaigns:
        row, srcs = _campaign_row(results_root, c, failures.get(c))
        rows.append(row)
        sources += srcs
    nav = [("campaigns", "Campaigns")]
    nav += [("not-built", "Not built")] if unusable else []
    nav += [("orphaned", "Orphaned")] if orphaned else []
    compared = []
    for name in comparisons:
        row, srcs = _comparison_row(results_root, name)
        compared.append(row)
        sources += srcs
    if compared:
        nav.append(("comparisons", "Comparisons"))
    blind = None
    if blind_dir is not None:
        blind, srcs = _blind_section(Path(blind_dir), captions)
        sources += srcs
        nav.append(("blind", "Blind test"))
    nav.append(("lineage", "Lineage"))
    return render("report_index.html.j2", title="isokinetic - results", nav=nav, lineage_record=lineage_record,
                  campaigns=rows, n_failed=sum(r["failed"] for r in rows), unusable=_unusable_rows(unusable),
                  orphaned=_orphan_rows(results_root, dict(orphaned or {})),
                  snakemake_report=(results_root / SNAKEMAKE_REPORT).is_file(), comparisons=compared, blind=blind,
                  lineage_files=lineage_rows(sources),
                  footer=footer(lineage_record, sources))


def write_index(results_root: str | os.PathLike, out_path: str | os.PathLike, campaigns: Sequence[str],
                **kwargs) -> Path:
    """Write :func:`render_index` to ``out_path`` atomically."""
    return write_text(render_index(results_root, campaigns, **kwargs), out_path)
