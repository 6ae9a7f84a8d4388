"""Rule raw_check: every raw file the campaign's ingest read still has the sha256 recorded then."""
from pathlib import Path

from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.rawcheck import RawDataChanged, check_raw

log = log_to_file(snakemake.log[0])
out = Path(snakemake.output[0])
try:
    check_raw(out.parent, out)
except RawDataChanged as exc:  # the job fails (its output is removed); keep-going lets the others finish
    log.error("%s", exc)
    raise
log.info("campaign %s: every raw file unchanged since ingest", snakemake.wildcards.campaign)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
