"""Lineage of the files the pages read: the rule of each file and the table whose record a figure shares."""

from __future__ import annotations

from pathlib import Path, PurePosixPath

from isokinetic.audit.trace import KINDS
from isokinetic.contracts.outputs import FIGURES, rule_of, sibling_table, stage_of, stage_rule
from isokinetic.report import browser, sources

from .fixture_results import CAMPAIGN_FIGURES

#: The stage and rule (job) the pages name for every file they read, and the table whose record a
#: figure shares (its stage's table, else the first its job writes).
STAGES = {"ingest/campaign.json": ("ingest or virtual_rig", "ingest or virtual_rig"),
          "cases.parquet": ("validate", "characteristic"), "quarantine.parquet": ("validate", "characteristic"),
          "characteristic.parquet": ("characteristic", "characteristic"),
          "repeatability.parquet": ("repeatability", "characteristic"),
          "design/plan_check.parquet": ("design", "analysis"), "models/models.parquet": ("models", "analysis"),
          "models/comparison.parquet": ("models", "analysis"), "harmonic/harmonic.parquet": ("harmonic", "analysis"),
          "diagnosis.json": ("diagnosis", "diagnosis"), "scores.parquet": ("blind_score", "blind_score"),
          "summary.json": ("blind_score", "blind_score"), "provenance.json": ("provenance", "campaign_report"),
          "compare.parquet": ("compare", "compare"), "compare.json": ("compare", "compare")}
SIBLINGS = {"figures": "design/plan_check.parquet", "models": "models/models.parquet",
            "harmonic": "harmonic/harmonic.parquet", "design": "design/plan_check.parquet",
            "diagnosis": "diagnosis.json", "blind_score": "scores.parquet", "compare": "compare.parquet"}


def test_rule_and_sibling_of_every_file_the_pages_read():
    for rel, (stage, rule) in STAGES.items():
        assert (stage_of(rel), rule_of(rel)) == (stage, rule), rel
    for fig in FIGURES:
        assert (stage_of(fig.path), rule_of(fig.path)) == (fig.stage, stage_rule(fig.stage)), fig
        assert sibling_table(fig.path) == SIBLINGS[fig.stage], fig
    assert [Path(f.path).name for f in CAMPAIGN_FIGURES] == browser.campaign_figure_files()
    assert len(CAMPAIGN_FIGURES) == 14 and [f.section for f in FIGURES if f not in CAMPAIGN_FIGURES] == [
        "blind", "compare", "compare"]


def test_trace_command_audits_one_row():
    assert sources.trace_command("results/c/x.parquet", "case=T01,direction=+") == \
        "python -m isokinetic trace results/c/x.parquet case=T01,direction=+"
    quarantined = sources.audit_command(Path("results/c/quarantine.parquet"), "results/c/quarantine.parquet",
                                        "case=T04,stage=validate")
    assert quarantined == "python -m isokinetic trace results/c/cases.parquet case=T04"
    assert sources.audit_command(Path("results/c/summary.json"), "results/c/summary.json", "targets") is None


def test_traceable_tables_are_those_trace_knows():
    assert {PurePosixPath(k.path).name for k in KINDS.values() if "*" not in k.path} == sources.TRACEABLE
