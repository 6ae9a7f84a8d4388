"""Rule report_index: results/index.html over every campaign and the blind suite."""
from pathlib import Path

from isokinetic.lineage import from_snakemake
from isokinetic.logs import log_to_file
from isokinetic.report import write_index

log = log_to_file(snakemake.log[0])
out = Path(snakemake.output[0])
write_index(out.parent, out, list(snakemake.params.campaigns), blind_dir=snakemake.params.blind_dir,
            captions_dir=Path(snakemake.input.captions).parent, lineage_record=from_snakemake(snakemake))
log.info("wrote %s (%d bytes) over %d campaigns", out, out.stat().st_size, len(snakemake.params.campaigns))
