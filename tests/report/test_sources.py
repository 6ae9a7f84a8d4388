"""Lineage of the files the pages read: the rule of each file and the table whose record a figure shares."""

from __future__ import annotations

from pathlib import Path, PurePosixPath

from isokinetic.audit.trace import KINDS
from isokinetic.contracts.outputs import FIGURES, rule_of, sibling_table
from isokinetic.report import browser, sources

from .fixture_results import CAMPAIGN_FIGURES

#: The rule the pages name for every file they read, and the table whose record a figure shares
#: (the report's own tables before the registry in isokinetic.contracts.outputs replaced them).
RULES = {"ingest/campaign.json": "ingest or virtual_rig", "cases.parquet": "validate", "quarantine.parquet": "validate",
         "characteristic.parquet": "characteristic", "repeatability.parquet": "repeatability",
         "design/plan_check.parquet": "design", "models/models.parquet": "models",
         "models/comparison.parquet": "models", "harmonic/harmonic.parquet": "harmonic",
         "diagnosis.json": "diagnosis", "scores.parquet": "blind_score", "summary.json": "blind_score",
         "provenance.json": "provenance"}
SIBLINGS = {"figures": None, "models": "models/models.parquet", "harmonic": "harmonic/harmonic.parquet",
            "design": "design/plan_check.parquet", "diagnosis": "diagnosis.json", "blind_score": "scores.parquet"}


def test_rule_and_sibling_of_every_file_the_pages_read():
    for rel, rule in RULES.items():
        assert rule_of(rel) == rule, rel
    for fig in FIGURES:
        assert rule_of(fig.path) == fig.rule, fig
        assert sibling_table(fig.path) == SIBLINGS[fig.rule], fig
    assert [Path(f.path).name for f in CAMPAIGN_FIGURES] == browser.campaign_figure_files()
    assert len(CAMPAIGN_FIGURES) == 12 and [f.section for f in FIGURES if f not in CAMPAIGN_FIGURES] == ["blind"]


def test_trace_command_audits_one_row():
    assert sources.trace_command("results/c/x.parquet", "case=T01,direction=+") == \
        "python -m isokinetic trace results/c/x.parquet case=T01,direction=+"
    quarantined = sources.audit_command(Path("results/c/quarantine.parquet"), "results/c/quarantine.parquet",
                                        "case=T04,stage=validate")
    assert quarantined == "python -m isokinetic trace results/c/cases.parquet case=T04"
    assert sources.audit_command(Path("results/c/summary.json"), "results/c/summary.json", "targets") is None


def test_traceable_tables_are_those_trace_knows():
    assert {PurePosixPath(k.path).name for k in KINDS.values() if "*" not in k.path} == sources.TRACEABLE
