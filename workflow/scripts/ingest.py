"""Rule ingest: raw campaign folder -> results/<campaign>/ingest (canonical SI Parquet)."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.ingest import ingest_campaign

with job(snakemake) as j:
    try:
        ingest_campaign(snakemake.params.campaign_dir, Path(snakemake.output[0]).parent)
    except Exception as exc:  # the campaign fails alone; keep-going lets the others finish
        j.log.error("campaign %s not ingested: %s", snakemake.wildcards.campaign, exc)
        raise
