"""Rule design_summary: every campaign's plan check in results/design/plan_check.parquet."""
from isokinetic.job import job
from isokinetic.stages.design_summary import write_design_summary

with job(snakemake) as j:
    summary = write_design_summary(list(snakemake.input), snakemake.output[0])
    j.log.info("%d cases from %d campaigns, %d flagged", len(summary), len(snakemake.input),
               int(summary["flagged"].sum()))
