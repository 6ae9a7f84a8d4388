"""What the pipeline writes, where, and which stage and rule write it.

A *stage* is one step of the method (validate, windows, ...), a module of
:mod:`isokinetic.stages` (or :mod:`isokinetic.audit`, :mod:`isokinetic.report`) that writes its
own files; a *rule* is one Snakemake job, which runs one or more stages in one Python process
(:data:`RULE_STAGES`): each job pays 1-2 s of interpreter start-up and imports, so cheap stages
that always run together share a job. The one place these facts live: the workflow's rules build
their outputs from it, the report finds its figures and the rule behind each file in it, and
``trace`` names the stage and rule of a file from it. Paths are relative to a campaign's folder
``results/<campaign>/`` (or to ``results/blind/`` for the blind suite, ``results/compare/<name>/`` for
a comparison of campaigns). Standard library only, so that building the workflow's DAG stays fast.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: A campaign id (raw-campaign format spec): a folder name, a wildcard value, a file-name part.
CAMPAIGN_ID_PATTERN = "[a-z0-9][a-z0-9_-]*"
CAMPAIGN_ID = re.compile(CAMPAIGN_ID_PATTERN)
RESULTS_DIR = "results"
BLIND_DIR = "blind"
#: Comparisons of campaigns (config ``comparisons``) are written to ``results/compare/<name>/``.
COMPARE_DIR = "compare"
#: The build's design summary, every campaign's plan check in one table (stages/design_summary.py), below results/.
DESIGN_SUMMARY = "design/plan_check.parquet"
#: Snakemake's own report (``snakemake --report results/report.html``), which the index links when it exists.
SNAKEMAKE_REPORT = "report.html"


@dataclass(frozen=True)
class Figure:
    """One figure: its file name, the stage that draws it, where it goes and how it is titled.

    ``folder`` is relative to the campaign's results folder (``results/blind/`` for the blind
    suite); ``section`` is the report section that shows it; its Snakemake report caption is
    ``workflow/report/<name>.rst``.
    """

    name: str
    stage: str
    folder: str
    section: str
    title: str

    @property
    def path(self) -> str:
        """File path relative to the campaign's (or blind suite's) results folder."""
        return f"{self.folder}/{self.name}.png" if self.folder else f"{self.name}.png"

    @property
    def caption(self) -> str:
        """The Snakemake report caption, relative to the repository root."""
        return f"workflow/report/{self.name}.rst"


#: Every figure of the pipeline, in report order.
FIGURES = (
    Figure("fig20_case_temperature", "figures", "figures", "cases",
           "Fig. 20 - temperature of each case and the viscosity the models take at it"),
    Figure("fig07_time_and_loops", "figures", "figures", "characteristic",
           "Fig. 7 - time domain and displacement-force loops"),
    Figure("fig08_window_selection", "figures", "figures", "characteristic", "Fig. 8 - window selection"),
    Figure("fig09_characteristic", "figures", "figures", "characteristic", "Fig. 9 - steady characteristic"),
    Figure("fig10_low_velocity", "figures", "figures", "characteristic", "Fig. 10 - low-velocity detail"),
    Figure("fig11_loglog", "figures", "figures", "characteristic", "Fig. 11 - log-log characteristic"),
    Figure("fig12_noise", "figures", "figures", "characteristic", "Fig. 12 - force noise per segment"),
    Figure("fig13_comparison", "models", "models", "models",
           "Fig. 13 - identified, nominal and fitted characteristics"),
    Figure("fig14_comparison_loglog", "models", "models", "models", "Fig. 14 - comparison on log-log axes"),
    Figure("fig15_harmonic_loops", "harmonic", "harmonic", "harmonic", "Fig. 15 - harmonic loops"),
    Figure("fig05_stroke_to_converge", "design", "design", "design", "Fig. 5 - stroke to converge"),
    Figure("fig06_at_diagram", "design", "design", "design", "Fig. 6 - A-T diagram of the plan"),
    Figure("fig16_gap", "diagnosis", "diagnosis", "diagnosis", "Fig. 16 - the sim-to-real gap before and after"),
    Figure("fig21_next_tests", "diagnosis", "diagnosis", "diagnosis",
           "Fig. 21 - the next tests that would separate what the diagnosis cannot tell apart, on the A-T diagram"),
    Figure("fig17_blind_confusion", "blind_score", "", "blind", "Fig. 17 - blind test: truth against verdict"),
    Figure("fig18_compare_overlay", "compare", "", "compare",
           "Fig. 18 - the campaigns' characteristics overlaid, with uncertainty bands"),
    Figure("fig19_compare_difference", "compare", "", "compare",
           "Fig. 19 - difference to the reference campaign, with its 95 % interval"),
)


def figures_of(stage: str) -> tuple[Figure, ...]:
    """The figures a stage draws, in report order."""
    return tuple(f for f in FIGURES if f.stage == stage)


def figures_in(section: str) -> tuple[Figure, ...]:
    """The figures a report section shows, in report order."""
    return tuple(f for f in FIGURES if f.section == section)


def figure(name: str) -> Figure:
    """The figure of that name (``fig09_characteristic``)."""
    for f in FIGURES:
        if f.name == name:
            return f
    raise KeyError(f"no figure named {name!r}")


#: The tables and documents each stage writes (name -> path), figures apart (see FIGURES). A path
#: ending in "/" is a folder. The stage ``ingest`` and the stage ``virtual_rig`` write the same
#: folder: a raw campaign is ingested, a config campaign is simulated into it.
STAGE_OUTPUTS = {
    "ingest": {"ingest": "ingest/"},
    "virtual_rig": {"ingest": "ingest/"},
    "validate": {"cases": "cases.parquet", "quarantine": "quarantine.parquet"},
    "windows": {"windows": "windows.parquet"},
    "repeatability": {"repeatability": "repeatability.parquet"},
    "characteristic": {"characteristic": "characteristic.parquet", "energy": "energy.parquet"},
    "nominal": {"nominal": "nominal_windows.parquet"},
    "design": {"plan_check": "design/plan_check.parquet"},
    "harmonic": {"table": "harmonic/harmonic.parquet"},
    "static_force": {"static_force": "static_force.parquet"},
    "models": {"models": "models/models.parquet", "residuals": "models/model_residuals.parquet",
               "comparison": "models/comparison.parquet"},
    "exports": {"characteristic_csv": "characteristic.csv", "models_csv": "models/models.csv"},
    "diagnosis": {"json": "diagnosis.json", "next_tests": "next_tests.yaml"},
    "figures": {},
    "raw_check": {"raw_check": "raw_check.json"},
    "provenance": {"provenance": "provenance.json"},
    "campaign_report": {"page": "report.html"},
    "blind_score": {"scores": "scores.parquet", "summary": "summary.json"},
    "blind_next_test": {"proof": "next_test.json", "work": "next_test/"},
    "compare": {"table": "compare.parquet", "csv": "compare.csv", "summary": "compare.json"},
    "compare_report": {"page": "report.html"},
}

#: The files of the ingest folder (STAGE_OUTPUTS' ``ingest/``), name -> path relative to it: what ingest and
#: the virtual rig write (:mod:`isokinetic.contracts.campaign`), read through
#: :class:`isokinetic.contracts.campaign_folder.CampaignFolder`.
INGEST_FILES = {"meta": "campaign.json", "cases": "cases.parquet", "quarantine": "quarantine.parquet",
                "timeseries": "timeseries/"}


def ingest_path(name: str) -> str:
    """A file of the ingest folder relative to the campaign's results folder (``ingest/campaign.json``)."""
    return STAGE_OUTPUTS["ingest"]["ingest"] + INGEST_FILES[name].rstrip("/")


def result_file_names() -> frozenset[str]:
    """The name of every file the registry places (its last path part: ``windows.parquet``,
    ``campaign.json``, ``fig09_characteristic.png``), folders apart: the names no module outside
    :mod:`isokinetic.contracts` spells out (tests/contracts/test_outputs_literals.py)."""
    paths = [p for outputs in STAGE_OUTPUTS.values() for p in outputs.values()]
    paths += list(INGEST_FILES.values()) + [f.path for f in FIGURES]
    return frozenset(p.rsplit("/", 1)[-1] for p in paths if not is_folder(p))


#: The stages each per-campaign (or blind-suite) rule runs, in order, in one process. A rule's
#: module (``stages/<rule>.py``, ``audit/<rule>.py`` or ``report/<rule>.py``) runs them.
RULE_STAGES = {
    "virtual_rig": ("virtual_rig",),
    "ingest": ("ingest",),
    "characteristic": ("validate", "windows", "repeatability", "characteristic"),
    "analysis": ("design", "nominal", "harmonic", "static_force", "models", "exports", "figures"),
    "diagnosis": ("diagnosis",),
    "campaign_report": ("raw_check", "provenance", "campaign_report"),
    "blind_score": ("blind_score",),
    "blind_next_test": ("blind_next_test",),
    "compare": ("compare", "compare_report"),
}


def stage_rule(stage: str) -> str | None:
    """The rule whose job runs a stage (``windows`` -> ``characteristic``); None if none does."""
    return next((rule for rule, stages in RULE_STAGES.items() if stage in stages), None)


def rule_outputs_of(rule: str) -> dict[str, str]:
    """Name -> path of the tables and documents a rule's job writes (all its stages'), figures apart."""
    out: dict[str, str] = {}
    for stage in RULE_STAGES[rule]:
        out.update(STAGE_OUTPUTS.get(stage, {}))
    return out


def rule_figures(rule: str) -> tuple[Figure, ...]:
    """The figures a rule's job draws (all its stages'), in report order."""
    stages = RULE_STAGES[rule]
    return tuple(f for f in FIGURES if f.stage in stages)


def is_folder(path: str) -> bool:
    """Whether an output path of STAGE_OUTPUTS names a folder (it ends in a slash)."""
    return path.endswith("/")


def outputs_of(stage: str) -> dict[str, str]:
    """Name -> path of everything a stage writes (tables, documents and figures)."""
    out = dict(STAGE_OUTPUTS.get(stage, {}))
    out.update({f.name: f.path for f in figures_of(stage)})
    return out


def stage_of(path: str) -> str | None:
    """The stage that writes a file, from its path relative to the campaign's results folder.

    ``ingest/...`` is the ingest folder: "ingest or virtual_rig". None for a file no stage writes.
    """
    path = path.replace("\\", "/")
    if path.startswith("ingest/"):
        return "ingest or virtual_rig"
    for f in FIGURES:
        if f.path == path:
            return f.stage
    for stage, outputs in STAGE_OUTPUTS.items():
        if stage in ("ingest", "virtual_rig"):
            continue
        if path in outputs.values():
            return stage
    return None


def rule_of(path: str) -> str | None:
    """The rule whose job writes a file (path relative to the campaign's results folder); see :func:`stage_of`."""
    stage = stage_of(path)
    return stage if stage is None or stage == "ingest or virtual_rig" else stage_rule(stage)


def sibling_table(path: str) -> str | None:
    """A table or document written by the same job as a figure (it shares that lineage record): its
    stage's first, else its rule's first."""
    for f in FIGURES:
        if f.path == path:
            own = STAGE_OUTPUTS.get(f.stage) or {}
            rule = stage_rule(f.stage)
            return next(iter((own or (rule_outputs_of(rule) if rule else {})).values()), None)
    return None


def campaign_path(campaign: str, path: str) -> str:
    """``results/<campaign>/<path>`` (``{campaign}`` keeps the Snakemake wildcard)."""
    return f"{RESULTS_DIR}/{campaign}/{path.rstrip('/')}"


def comparison_folder(name: str) -> str:
    """``compare/<name>``: a comparison's folder below ``results/`` (``{comparison}`` keeps the wildcard)."""
    return f"{COMPARE_DIR}/{name}"
