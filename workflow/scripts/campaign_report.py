"""Rule campaign_report: results/<campaign>/report.html, a self-contained page for people."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.report.browser import check_pages
from isokinetic.report.campaign_report import write_campaign_report

with job(snakemake) as j:
    out = Path(snakemake.output[0])
    captions = Path(snakemake.input.captions[0]).parent if snakemake.input.captions else None
    write_campaign_report(out.parent, out, captions_dir=captions, lineage_record=j.lineage)
    problems = list(check_pages(out.parents[1], [out.parent.name], index=False, browser=False))
    if problems:
        raise RuntimeError("report page incomplete:\n" + "\n".join(problems))
    j.log.info("wrote %s (%d bytes)", out, out.stat().st_size)
