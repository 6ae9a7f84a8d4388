"""Rule ingest: raw campaign folder -> results/<campaign>/ingest (canonical SI Parquet)."""
from pathlib import Path

from isokinetic.audit.raw_folder import folder_problem
from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.ingest import run_ingest

with job(snakemake) as j:
    try:
        problem = folder_problem(snakemake.params.campaign_dir, snakemake.params.raw_dir)
        if problem is not None:  # the workflow refuses such a campaign before; this holds if the folder changed since
            raise ValueError(problem)
        run_ingest(Path(snakemake.output[0]).parent, Settings.from_config(snakemake.config),
                   snakemake.params.campaign_dir)
    except Exception as exc:  # the campaign fails alone; keep-going lets the others finish
        j.log.error("campaign %s not ingested: %s", snakemake.wildcards.campaign, exc)
        raise
