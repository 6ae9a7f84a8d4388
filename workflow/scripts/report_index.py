"""Rule report_index: results/index.html over every campaign and the blind suite."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.report.report_index import write_index

with job(snakemake) as j:
    out = Path(snakemake.output[0])
    write_index(out.parent, out, list(snakemake.params.campaigns), blind_dir=snakemake.params.blind_dir,
                captions_dir=Path(snakemake.input.captions[0]).parent, lineage_record=j.lineage)
    j.log.info("wrote %s (%d bytes) over %d campaigns", out, out.stat().st_size, len(snakemake.params.campaigns))
