"""Rule report_index: results/index.html over every campaign, the comparisons and the blind suite, and every
campaign's plan check in one table (results/design/plan_check.parquet)."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.report.report_index import write_index
from isokinetic.report.run_status import INCOMPLETE_DIR, campaign_failures
from isokinetic.stages.design_summary import write_design_summary

with job(snakemake) as j:
    summary = write_design_summary(list(snakemake.input.plan_checks), snakemake.output.design_summary)
    j.log.info("plan checks: %d cases from %d campaigns, %d flagged", len(summary), len(snakemake.input.plan_checks),
               int(summary["flagged"].sum()))
    out = Path(snakemake.output.index)
    campaigns = list(snakemake.params.campaigns)
    refused = {c: f"refused: {reason}" for c, reason in dict(snakemake.params.refused).items()}
    failures = {**refused, **campaign_failures(out.parent, Path(snakemake.log[0]).parent,
                                               [c for c in campaigns if c not in refused],
                                               dict(snakemake.params.raw_dirs), incomplete_dir=INCOMPLETE_DIR)}
    for campaign, reason in failures.items():
        j.log.warning("campaign %s: %s", campaign, reason)
    unusable, orphaned = list(snakemake.params.unusable), dict(snakemake.params.orphaned)
    for folder in unusable:
        j.log.warning("%s/: not built: %s; %s", folder["folder"], folder["reason"], folder["fix"])
    for name, reason in orphaned.items():
        j.log.warning("%s/%s/: %s", out.parent, name, reason)
    write_index(out.parent, out, list(snakemake.params.campaigns), blind_dir=snakemake.params.blind_dir,
                captions_dir=Path(snakemake.input.captions[0]).parent, lineage_record=j.lineage,
                comparisons=list(snakemake.params.comparisons), failures=failures, unusable=unusable,
                orphaned=orphaned)
    j.log.info("wrote %s (%d bytes) over %d campaigns", out, out.stat().st_size, len(snakemake.params.campaigns))
