# Helpers shared by the rules: config validation and campaign discovery.

import logging
import os
import re
import subprocess
from pathlib import Path

from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

validate(config, schema="../schemas/config.schema.yaml")
if config["windows"]["start_fraction"] >= config["windows"]["end_fraction"]:
    raise WorkflowError("config key 'windows': start_fraction must be below end_fraction, got "
                        f"{config['windows']['start_fraction']} >= {config['windows']['end_fraction']}")

CAMPAIGN_ID = re.compile(r"[a-z0-9][a-z0-9_-]*")


def export_git_state():
    """Git commit and dirty flag of the code, for every job's lineage (read here, once)."""
    def git(*args):
        return subprocess.run(["git", "-C", workflow.basedir, *args], capture_output=True, text=True,
                              timeout=10).stdout.strip()
    try:
        commit = git("rev-parse", "HEAD")
        dirty = "1" if git("status", "--porcelain", "--untracked-files=no") else "0"
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "", ""
    os.environ["ISOKINETIC_GIT_COMMIT"] = commit
    os.environ["ISOKINETIC_GIT_DIRTY"] = dirty if commit else ""


export_git_state()
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
                "%s: folder name %r is not a campaign id ([a-z0-9][a-z0-9_-]*); campaign skipped",
                manifest.parent, name)
    return found


RAW_CAMPAIGNS = discover_raw_campaigns(RAW_DIR)
VIRTUAL_CAMPAIGNS = sorted(config.get("virtual_campaigns") or {})
_clash = sorted(set(RAW_CAMPAIGNS) & set(VIRTUAL_CAMPAIGNS))
if _clash:
    raise WorkflowError(f"campaign names used both by a raw campaign in {RAW_DIR}/ and by "
                        f"config 'virtual_campaigns': {', '.join(_clash)}; rename one of them")
CAMPAIGNS = RAW_CAMPAIGNS + VIRTUAL_CAMPAIGNS


def one_of(names):
    """Wildcard constraint matching exactly one of the names (or nothing)."""
    return "|".join(re.escape(n) for n in names) or "(?!)"


def raw_files(wildcards):
    """Every file of a raw campaign folder: a change to any of them reruns its ingest."""
    folder = RAW_DIR / wildcards.campaign
    return sorted(str(p) for p in folder.iterdir() if p.is_file())


FIGURES = ["fig07_time_and_loops", "fig08_window_selection", "fig09_characteristic",
           "fig10_low_velocity", "fig11_loglog", "fig12_noise"]
DESIGN_FIGURES = ["fig05_stroke_to_converge", "fig06_at_diagram"]
MODEL_FIGURES = ["fig13_comparison", "fig14_comparison_loglog"]


def campaign_outputs(campaign):
    root = f"results/{campaign}"
    return ([f"{root}/characteristic.parquet", f"{root}/repeatability.parquet", f"{root}/quarantine.parquet",
             f"{root}/models/models.parquet", f"{root}/harmonic/harmonic.parquet", f"{root}/diagnosis.json"]
            + [f"{root}/figures/{name}.png" for name in FIGURES]
            + [f"{root}/design/{name}.png" for name in DESIGN_FIGURES]
            + ([f"{root}/raw_check.json"] if campaign in RAW_CAMPAIGNS else []))


def check_raw_after_run():
    """After a run: every raw file an ingest read still has the sha256 it recorded (else log each)."""
    from isokinetic.rawcheck import describe, raw_changes

    bad = [describe(c, change) for c in RAW_CAMPAIGNS if Path(f"results/{c}/ingest").is_dir()
           for change in raw_changes(f"results/{c}")]
    for line in bad:
        logging.getLogger("isokinetic").error(line)
    return bad


BLIND_OUTPUTS = ["results/blind/scores.parquet", "results/blind/summary.json",
                 "results/blind/fig17_blind_confusion.png"]


def all_outputs():
    return ["results/design/plan_check.parquet"] + [
        path for campaign in CAMPAIGNS for path in campaign_outputs(campaign)] + [
        f"results/{campaign}/provenance.json" for campaign in CAMPAIGNS] + [
        f"results/{campaign}/report.html" for campaign in CAMPAIGNS] + ["results/index.html"] + (
        BLIND_OUTPUTS if config.get("blind") else [])


def blind_scenario_names(blind):
    """Names of the blind scenarios of the config's ``blind`` block (isokinetic.scenarios)."""
    from isokinetic.scenarios import scenario_names, suite_size

    if not blind:
        return []
    return scenario_names(suite_size(blind.get("n_per_effect", 0), blind.get("n_pairs", 0),
                                     blind.get("n_none", 0), blind.get("n_out_of_catalogue", 0)))
