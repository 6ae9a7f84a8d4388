"""Rule campaign_report: raw_check.json (the raw files unchanged since ingest), provenance.json, then the
campaign's self-contained report page."""
from pathlib import Path

from isokinetic.audit.provenance import write_provenance
from isokinetic.audit.raw_check import RawDataChanged, check_raw
from isokinetic.job import job
from isokinetic.report.browser import check_pages
from isokinetic.report.campaign_report import write_campaign_report

with job(snakemake) as j:
    raw_check = Path(snakemake.output.raw_check)
    try:  # first: a raw file changed since ingest fails the job (its outputs are removed) before anything is written
        check_raw(raw_check.parent, raw_check)
    except RawDataChanged as exc:  # keep-going lets the other campaigns finish
        j.log.error("%s", exc)
        raise
    j.log.info("campaign %s: every raw file unchanged since ingest", snakemake.wildcards.campaign)
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
