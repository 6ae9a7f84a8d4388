"""Rule raw_check: every raw file the campaign's ingest read still has the sha256 recorded then."""
from pathlib import Path

from isokinetic.audit.raw_check import RawDataChanged, check_raw
from isokinetic.job import job

with job(snakemake) as j:
    out = Path(snakemake.output[0])
    try:
        check_raw(out.parent, out)
    except RawDataChanged as exc:  # the job fails (its output is removed); keep-going lets the others finish
        j.log.error("%s", exc)
        raise
    j.log.info("campaign %s: every raw file unchanged since ingest", snakemake.wildcards.campaign)
