"""Rule virtual_rig: simulate a config-defined campaign into results/<campaign>/ingest."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign

with job(snakemake) as j:
    spec = VirtualCampaign.from_config(snakemake.wildcards.campaign, snakemake.params.spec)
    write_campaign(spec, Path(snakemake.output[0]).parent)
    j.log.info("simulated %d cases of %s", len(spec.cases), spec.name)
