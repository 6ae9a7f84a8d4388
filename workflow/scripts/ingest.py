"""Rule ingest: raw campaign folder -> results/<campaign>/ingest (canonical SI Parquet)."""
from pathlib import Path

from isokinetic.ingest import ingest_campaign
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
try:
    ingest_campaign(snakemake.params.campaign_dir, Path(snakemake.output[0]).parent)
except Exception as exc:  # the campaign fails alone; keep-going lets the others finish
    log.error("campaign %s not ingested: %s", snakemake.wildcards.campaign, exc)
    raise
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
