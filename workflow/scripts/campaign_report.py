"""Rule campaign_report: provenance.json, then the campaign's self-contained report page."""
from pathlib import Path

from isokinetic.audit.provenance import write_provenance
from isokinetic.job import job
from isokinetic.report.browser import check_pages
from isokinetic.report.campaign_report import write_campaign_report

with job(snakemake) as j:
    prov_path, out = Path(snakemake.output.provenance), Path(snakemake.output.page)
    prov = write_provenance(prov_path.parent, prov_path, config_sha256=j.lineage["config_sha256"])
    j.log.info("campaign %s: %d raw file(s), %d stage(s), checks %s", prov["campaign"], len(prov["raw"]["files"]),
               len(prov["stages"]), "ok" if prov["checks"]["ok"] else "FAILED (see warnings)")
    captions = Path(snakemake.input.captions[0]).parent if snakemake.input.captions else None
    write_campaign_report(out.parent, out, captions_dir=captions, lineage_record=j.lineage)
    problems = list(check_pages(out.parents[1], [out.parent.name], index=False, browser=False))
    if problems:
        raise RuntimeError("report page incomplete:\n" + "\n".join(problems))
    j.log.info("wrote %s (%d bytes)", out, out.stat().st_size)
