# Helpers shared by the rules: config validation, campaign discovery, and every rule's outputs,
# built from isokinetic.contracts.outputs (the one place that says what is written where).

import functools
import logging
import os
import re
import subprocess
from pathlib import Path

from snakemake.exceptions import WorkflowError
import yaml
from snakemake.utils import validate

import isokinetic
from isokinetic.audit.raw_folder import SnakemakeInputs, snakemake_inputs
from isokinetic.audit.raw_inventory import UnusableFolder, orphaned_results, unusable_folders
from isokinetic.audit.refused import refusal
from isokinetic.code_closure import code_hash
from isokinetic.contracts.outputs import DESIGN_SUMMARY as DESIGN_SUMMARY_FILE
from isokinetic.contracts.outputs import (
    BLIND_DIR,
    CAMPAIGN_ID,
    CAMPAIGN_ID_PATTERN,
    COMPARE_DIR,
    FIGURES,
    RESULTS_DIR,
    campaign_path,
    comparison_folder,
    is_folder,
    rule_figures,
    rule_outputs_of,
)
from isokinetic.contracts.scenarios import balanced_chunks, scenario_names, suite_composition
from isokinetic.contracts.settings import Settings, rule_settings, with_defaults
from isokinetic.scheduling import coalesce_reevaluations

# Snakemake 9 arms a new 1 s scheduler wake-up after every scheduling pass, so wake-ups pile up with
# every finished job and the scheduling work grows with the square of the job count; one pending
# wake-up is enough (isokinetic.scheduling; benchmark/scaling.py). ISOKINETIC_COALESCE_REEVALUATIONS=0 in the
# environment leaves Snakemake as it ships (benchmark/run.py times the default rebuild both ways).
coalesce_reevaluations()

validate(config, schema="../schemas/config.schema.yaml")
# every default of the schema filled (objects the config omits too), so that the scripts' snakemake.config and
# SETTINGS, the one record of the method's settings (isokinetic.contracts.settings), agree
CONFIG_SCHEMA = Path(workflow.current_basedir).parent / "schemas" / "config.schema.yaml"
config.update(with_defaults(config, yaml.safe_load(CONFIG_SCHEMA.read_text(encoding="utf-8"))))
if config["windows"]["start_fraction"] >= config["windows"]["end_fraction"]:
    raise WorkflowError(
        "config key 'windows': start_fraction must be below end_fraction, got "
        f"{config['windows']['start_fraction']} >= {config['windows']['end_fraction']}"
    )
SETTINGS = Settings.from_config(config)


def export_git_state():
    """Git commit and dirty flag of the code, for every job's lineage (read here, once)."""

    def git(*args):
        return subprocess.run(
            ["git", "-C", workflow.basedir, *args], capture_output=True, text=True, timeout=10
        ).stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        dirty = "1" if git("status", "--porcelain", "--untracked-files=no") else "0"
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "", ""
    os.environ["ISOKINETIC_GIT_COMMIT"] = commit
    os.environ["ISOKINETIC_GIT_DIRTY"] = dirty if commit else ""


export_git_state()

#: The rules' scripts and the package they run (its source folder, wherever it is installed from).
SCRIPTS_DIR = Path(workflow.current_basedir).parent / "scripts"
PACKAGE_DIR = Path(isokinetic.__file__).parent


def code_version(script):
    """sha256 of the package modules a rule's script runs (its import closure: isokinetic.code_closure), a
    param of every rule: editing a module reruns each job whose script reaches it, and what follows from it,
    and no other (Snakemake's own code trigger sees only the thin script)."""
    return code_hash(SCRIPTS_DIR / script, PACKAGE_DIR)


RAW_DIR = Path(config["raw_dir"])


def discover_raw_campaigns(raw_dir):
    """Folders <raw_dir>/<campaign>/ holding a campaign.yaml; names must be campaign ids."""
    found = []
    for manifest in sorted(raw_dir.glob("*/campaign.yaml")):
        name = manifest.parent.name
        if CAMPAIGN_ID.fullmatch(name):
            found.append(name)
        else:
            logging.getLogger("isokinetic").warning(
                "%s: folder name %r is not a campaign id (%s); campaign skipped",
                manifest.parent,
                name,
                CAMPAIGN_ID_PATTERN,
            )
    return found


RAW_CAMPAIGNS = discover_raw_campaigns(RAW_DIR)
VIRTUAL_CAMPAIGNS = sorted(config.get("virtual_campaigns") or {})
_clash = sorted(set(RAW_CAMPAIGNS) & set(VIRTUAL_CAMPAIGNS))
if _clash:
    raise WorkflowError(
        f"campaign names used both by a raw campaign in {RAW_DIR}/ and by "
        f"config 'virtual_campaigns': {', '.join(_clash)}; rename one of them"
    )
CAMPAIGNS = RAW_CAMPAIGNS + VIRTUAL_CAMPAIGNS


def one_of(names):
    """Wildcard constraint matching exactly one of the names (or nothing)."""
    return "|".join(re.escape(n) for n in names) or "(?!)"


@functools.cache
def raw_inputs(campaign):
    """The manifest and the case files it names (isokinetic.audit.raw_folder): plain paths for Snakemake and
    fingerprints of the files whose names Snakemake would read as patterns; nothing for a refused campaign.
    Another entry of the folder never reaches the job graph (a stray 'notes {old}.txt' stops nothing)."""
    if campaign in REFUSED:
        return SnakemakeInputs((), ())
    try:
        return snakemake_inputs(RAW_DIR / campaign)
    except OSError:  # the folder changed under us: ingest names the problem
        return SnakemakeInputs((str(RAW_DIR / campaign / "campaign.yaml"),), ())


def raw_files(wildcards):
    """The raw files of a campaign its ingest reads: a change to any of them reruns its ingest."""
    return list(raw_inputs(wildcards.campaign).paths)


def raw_fingerprints(wildcards):
    """Size and modification time of the raw files whose names hold pattern characters (a params change
    reruns ingest, as an input change would)."""
    return list(raw_inputs(wildcards.campaign).fingerprints)


def refusals(raw_campaigns, campaigns):
    """Campaign -> why the workflow refuses it, before any job (isokinetic.audit.refused): a raw campaign
    folder leading outside the raw data folder, or existing outputs (results/<c>/, logs/<c>/) it could not
    replace (Snakemake would stop the whole build on a write-protected output). A refused campaign gets none
    of its jobs; its rule refused's job fails with the reason, alone."""
    reasons = {c: refusal(c, RAW_DIR if c in raw_campaigns else None, RESULTS_DIR, "logs") for c in campaigns}
    return {c: reason for c, reason in reasons.items() if reason is not None}


REFUSED = refusals(RAW_CAMPAIGNS, CAMPAIGNS)
#: The campaigns the workflow processes (every campaign but the refused ones).
ACTIVE = [c for c in CAMPAIGNS if c not in REFUSED]
#: No invisible state (isokinetic.audit.raw_inventory): each folder under the raw data folder the workflow does
#: not build (no manifest, a name that is no campaign id), with why and the fix (folder, reason, fix), and each
#: results/<name>/ of a campaign, comparison or blind suite this build does not have (ORPHANED, set below once
#: the comparisons and the blind block are read: folder -> why). The index lists both apart (as its
#: params: a change rebuilds it) and the run's closing summary names them (onsuccess, onerror).
UNUSABLE = [{"folder": u.folder, "reason": u.reason, "fix": u.fix} for u in unusable_folders(RAW_DIR)]


def unbuilt_lines():
    """The closing summary's lines naming each folder the run did not build (UNUSABLE, ORPHANED); none without."""
    if not UNUSABLE and not ORPHANED:
        return []
    # imported here, and only when there is something to say, so that building the DAG does not pay for it
    from isokinetic.report.run_status import state_lines

    return state_lines([UnusableFolder(**u).line() for u in UNUSABLE], ORPHANED, RESULTS_DIR)


def report_unbuilt():
    """After a successful run (onsuccess): each folder it did not build named in its closing summary."""
    from snakemake.logging import logger

    for line in unbuilt_lines():
        logger.warning(line)


#: Every figure is also written in this vector format beside its PNG (config figures.vector_format).
VECTOR_FORMAT = (config.get("figures") or {}).get("vector_format", "none")


def rule_outputs(rule, campaign="{campaign}"):
    """Name -> output of a rule's job (all its stages'), from isokinetic.contracts.outputs: a folder as
    directory(), figures as report items with their caption (one figure is named 'figure', several are
    the list 'figures'), and their vector copies as the list 'vectors' (config figures.vector_format)."""
    out = {}
    for name, path in rule_outputs_of(rule).items():
        out[name] = directory(campaign_path(campaign, path)) if is_folder(path) else campaign_path(campaign, path)
    labels = {"campaign": campaign}
    figures = [report_item(campaign_path(campaign, f.path), f.name, campaign, labels) for f in rule_figures(rule)]
    if len(figures) == 1:
        out["figure"] = figures[0]
    elif figures:
        out["figures"] = figures
    if figures and VECTOR_FORMAT != "none":
        out["vectors"] = [
            campaign_path(campaign, str(Path(f.path).with_suffix(f".{VECTOR_FORMAT}"))) for f in rule_figures(rule)
        ]
    return out


def report_item(path, name, category, labels):
    """A figure for `snakemake --report`, with its caption workflow/report/<name>.rst."""
    return report(path, caption=f"../report/{name}.rst", category=category, labels={**labels, "figure": name})


def output_path(rule, name, campaign="{campaign}"):
    """results/<campaign>/<path> of one named table or document of a rule's job."""
    return campaign_path(campaign, rule_outputs_of(rule)[name])


def figure_paths(rule, campaign="{campaign}"):
    """results/<campaign>/<folder>/<figure>.png of every figure a rule's job draws."""
    return [campaign_path(campaign, f.path) for f in rule_figures(rule)]


def benchmark_path(rule, campaign="{campaign}"):
    """Snakemake's benchmark record of a job (wall time, memory): logs/<campaign>/<rule>.benchmark.tsv."""
    return f"logs/{campaign}/{rule}.benchmark.tsv"


def campaign_outputs(campaign):
    """What a campaign's report reads: its tables, their CSV exports, diagnosis and figures."""
    return (
        [
            output_path(rule, name, campaign)
            for rule, name in (
                ("characteristic", "characteristic"),
                ("characteristic", "repeatability"),
                ("characteristic", "quarantine"),
                ("analysis", "models"),
                ("analysis", "table"),
                ("analysis", "static_force"),
                ("analysis", "characteristic_csv"),
                ("analysis", "models_csv"),
                ("diagnosis", "json"),
            )
        ]
        + figure_paths("analysis", campaign)
        + figure_paths("diagnosis", campaign)
    )


def check_raw_after_run():
    """After a run: every raw file an ingest read still has the sha256 it recorded (else log each). A refused
    campaign is not looked at (its results are not this run's); a campaign whose ingest records cannot be
    read is named, not checked, and the others still are."""
    # imported here, once at the end of a run, so that building the DAG does not pay for it
    from isokinetic.audit.raw_check import describe, raw_changes

    log = logging.getLogger("isokinetic")
    bad = []
    for c in RAW_CAMPAIGNS:
        if c in REFUSED or not Path(f"results/{c}/ingest").is_dir():
            continue
        try:
            bad += [describe(c, change) for change in raw_changes(f"results/{c}")]
        except Exception as e:
            log.warning("campaign %s: raw files not checked after the run: %s: %s", c, type(e).__name__, str(e)[:200])
    for line in bad:
        log.error(line)
    return bad


BLIND_ROOT = f"{RESULTS_DIR}/{BLIND_DIR}"
BLIND_OUTPUTS = (
    [campaign_path(BLIND_DIR, p) for p in rule_outputs_of("blind_score").values()]
    + [campaign_path(BLIND_DIR, f.path) for f in rule_figures("blind_score")]
    + [campaign_path(BLIND_DIR, p) for p in rule_outputs_of("blind_next_test").values() if not is_folder(p)]
)
#: Every campaign's plan check in one table, written by the index job.
DESIGN_SUMMARY = f"{RESULTS_DIR}/{DESIGN_SUMMARY_FILE}"


def blind_composition(blind):
    """The blind suite's composition (isokinetic.contracts.scenarios.suite_composition) of the config's
    ``blind`` block: one (truth, multiples, out-of-catalogue kind, waveform) per scenario."""
    if not blind:
        return []
    return suite_composition(
        int(blind.get("seed", 0)),
        blind.get("n_per_effect", 0),
        blind.get("n_pairs", 0),
        blind.get("n_none", 0),
        blind.get("n_out_of_catalogue", 0),
        blind.get("n_sine", 0),
    )


BLIND = config.get("blind") or {}
BLIND_KINDS = blind_composition(BLIND)
BLIND_NAMES = scenario_names(len(BLIND_KINDS))
BLIND_CHUNKS = max(1, min(int(BLIND.get("chunks", 2)), len(BLIND_NAMES)))
#: Scenario names per chunk, balanced by expected cost (each chunk is generated and diagnosed on its own).
BLIND_CHUNK_NAMES = [[BLIND_NAMES[i] for i in c] for c in balanced_chunks(BLIND_KINDS, BLIND_CHUNKS)]
if BLIND and "blind" in CAMPAIGNS:
    raise WorkflowError("a campaign named 'blind' would share results/blind/ with the blind test; rename it")


def blind_chunk(wildcards):
    """The scenarios of chunk k (BLIND_CHUNK_NAMES)."""
    return BLIND_CHUNK_NAMES[int(wildcards.chunk)]


COMPARISONS = config.get("comparisons") or {}


def check_comparisons(comparisons, campaigns):
    """Each comparison names campaigns this build has (virtual_campaigns keys and raw folders)."""
    for name, spec in comparisons.items():
        for campaign in spec["campaigns"]:
            if campaign not in campaigns:
                raise WorkflowError(
                    f"config 'comparisons': comparison {name!r} names campaign {campaign!r}, which is neither "
                    f"a key of 'virtual_campaigns' nor a raw campaign folder in {RAW_DIR}/ "
                    f"(campaigns: {', '.join(campaigns) or 'none'})"
                )


check_comparisons(COMPARISONS, CAMPAIGNS)
if COMPARISONS and COMPARE_DIR in CAMPAIGNS:
    raise WorkflowError(
        f"a campaign named {COMPARE_DIR!r} would share results/{COMPARE_DIR}/ with the comparisons; rename it"
    )


def comparison_settings(name):
    """The settings a comparison gives beyond its campaigns (description, alpha, model,
    velocity_tolerance); the others take isokinetic.measurement.comparison.CompareSpec's defaults."""
    return {key: value for key, value in COMPARISONS[name].items() if key != "campaigns"}


def comparison_inputs(wildcards):
    """The characteristic and fitted models of every campaign of a comparison, in its order."""
    campaigns = COMPARISONS[wildcards.comparison]["campaigns"]
    return {
        "characteristics": [output_path("characteristic", "characteristic", c) for c in campaigns],
        "models": [output_path("analysis", "models", c) for c in campaigns],
    }


def comparison_outputs(name):
    """Everything a comparison's job writes: table, CSV, summary, Fig. 18-19, page."""
    folder = comparison_folder(name)
    return [campaign_path(folder, p) for p in rule_outputs_of("compare").values()] + figure_paths("compare", folder)


#: The comparisons whose campaigns are all processed (a comparison naming a refused campaign is not built).
ACTIVE_COMPARISONS = [name for name, spec in COMPARISONS.items() if not set(spec["campaigns"]) & set(REFUSED)]
ORPHANED = orphaned_results(RESULTS_DIR, CAMPAIGNS, RAW_DIR, comparisons=list(COMPARISONS), blind=bool(BLIND))


def comparison_pages():
    """results/compare/<name>/report.html of every comparison built (the index links them)."""
    return [output_path("compare", "page", comparison_folder(name)) for name in ACTIVE_COMPARISONS]


def refused_marker(campaign="{campaign}"):
    """The output of a refused campaign's job (never written: the job fails with the reason)."""
    return f"logs/_refused/{campaign}.txt"


def all_outputs():
    """Every result of the workflow: each campaign's outputs, provenance and page, the index and the
    plan-check summary, the blind suite, the comparisons; and each figure's vector copy when the config
    asks for one (figures.vector_format). A refused campaign gets its rule refused's job instead, which
    fails with the reason (and no comparison naming it is built)."""
    outputs = (
        [DESIGN_SUMMARY, "results/index.html"]
        + [path for campaign in ACTIVE for path in campaign_outputs(campaign)]
        + [output_path("campaign_report", name, campaign) for campaign in ACTIVE for name in ("provenance", "page")]
        + [refused_marker(campaign) for campaign in REFUSED]
        + (BLIND_OUTPUTS if BLIND else [])
        + [path for name in ACTIVE_COMPARISONS for path in comparison_outputs(name)]
    )
    if VECTOR_FORMAT == "none":
        return outputs
    return outputs + [str(Path(p).with_suffix(f".{VECTOR_FORMAT}")) for p in map(str, outputs) if p.endswith(".png")]


def report_failed_run(snakemake_log):
    """After a failed run (onerror): results/index.html and the design summary rebuilt from the outputs that
    exist, each failed campaign listed with its reason, and the run's closing summary naming every failed
    campaign and job (isokinetic.report.run_status)."""
    from snakemake.logging import logger

    # imported here, once after a failed run, so that building the DAG does not pay for it
    from isokinetic.report.run_status import failed_jobs, rebuild_after_failure, summary_lines

    try:
        lines = rebuild_after_failure(
            snakemake_log,
            campaigns=CAMPAIGNS,
            raw_dirs={campaign: str(RAW_DIR / campaign) for campaign in RAW_CAMPAIGNS if campaign not in REFUSED},
            comparisons=list(COMPARISONS),
            blind_dir=BLIND_ROOT if BLIND else None,
            captions_dir=str(Path(FIGURES[0].caption).parent),
            results_root=RESULTS_DIR,
            index=f"{RESULTS_DIR}/index.html",
            design_summary=DESIGN_SUMMARY,
            older_than=[f.caption for f in rule_figures("blind_score")],
            unusable=UNUSABLE,
            orphaned=ORPHANED,
        )
        lines.append(f"{RESULTS_DIR}/index.html rebuilt: it lists every campaign, the failed ones with their reason")
    except Exception as e:
        lines = summary_lines(failed_jobs(snakemake_log)) + unbuilt_lines()
        lines.append(f"{RESULTS_DIR}/index.html could not be rebuilt after the failed run: {type(e).__name__}: {e}")
    for line in lines:
        logger.error(line)
