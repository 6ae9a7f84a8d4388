"""Rule ingest: raw campaign folder -> results/<campaign>/ingest (canonical SI Parquet)."""
from pathlib import Path

from isokinetic.audit.raw_folder import folder_problem
from isokinetic.job import job
from isokinetic.stages.ingest import ingest_campaign

with job(snakemake) as j:
    try:
        problem = folder_problem(snakemake.params.campaign_dir, snakemake.params.raw_dir)
        if problem is not None:  # the workflow refuses such a campaign before; this holds if the folder changed since
            raise ValueError(problem)
        limit = getattr(snakemake.params, "max_case_file_MB", None)  # config ingest.max_case_file_MB, when given
        ingest_campaign(snakemake.params.campaign_dir, Path(snakemake.output[0]).parent,
                        **({} if limit is None else {"max_case_file_MB": float(limit)}))
    except Exception as exc:  # the campaign fails alone; keep-going lets the others finish
        j.log.error("campaign %s not ingested: %s", snakemake.wildcards.campaign, exc)
        raise
