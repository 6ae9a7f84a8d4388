"""Rule refused: a campaign the workflow refuses fails alone, its log naming the reason."""
from isokinetic.audit.refused import refuse
from isokinetic.job import job

with job(snakemake) as j:
    j.log.error("campaign %s refused: %s", snakemake.wildcards.campaign, snakemake.params.reason)
    refuse(snakemake.wildcards.campaign, snakemake.params.reason)
