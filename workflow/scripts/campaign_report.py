"""Rule campaign_report: results/<campaign>/report.html, a self-contained page for people."""
from pathlib import Path

from isokinetic.lineage import from_snakemake
from isokinetic.logs import log_to_file
from isokinetic.report import check_pages, write_campaign_report

log = log_to_file(snakemake.log[0])
out = Path(snakemake.output[0])
captions = Path(snakemake.input.captions[0]).parent if snakemake.input.captions else None
write_campaign_report(out.parent, out, captions_dir=captions, lineage_record=from_snakemake(snakemake))
problems = [p for p in check_pages(out.parents[1], [out.parent.name], index=False, browser=False)]
if problems:
    raise RuntimeError("report page incomplete:\n" + "\n".join(problems))
log.info("wrote %s (%d bytes)", out, out.stat().st_size)
