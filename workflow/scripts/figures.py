"""Rule figures: the campaign's PNG figures (paper Fig. 7-12 equivalents)."""
from pathlib import Path

from isokinetic.figures import write_campaign_figures
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
written = write_campaign_figures(Path(snakemake.input.cases).parent, Path(snakemake.output[0]).parent)
missing = sorted(set(map(str, snakemake.output)) - {str(p) for p in written})
if missing:
    raise RuntimeError(f"figures not written: {missing}")
log.info("wrote %d figures", len(written))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
