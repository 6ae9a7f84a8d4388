"""Rule virtual_rig: simulate a config-defined campaign into results/<campaign>/ingest."""
from pathlib import Path

from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.virtual_rig import VirtualCampaign, write_campaign

log = log_to_file(snakemake.log[0])
spec = VirtualCampaign.from_config(snakemake.wildcards.campaign, snakemake.params.spec)
write_campaign(spec, Path(snakemake.output[0]).parent)
log.info("simulated %d cases of %s", len(spec.cases), spec.name)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
