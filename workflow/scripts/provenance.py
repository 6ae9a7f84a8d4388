"""Rule provenance: raw files, environment, code and every stage of a campaign -> provenance.json."""
from pathlib import Path

from isokinetic.lineage import finish, from_snakemake
from isokinetic.logs import log_to_file
from isokinetic.provenance import write_provenance

log = log_to_file(snakemake.log[0])
out = Path(snakemake.output[0])
prov = write_provenance(out.parent, out, config_sha256=from_snakemake(snakemake)["config_sha256"])
log.info("campaign %s: %d raw file(s), %d stage(s), checks %s", prov["campaign"], len(prov["raw"]["files"]),
         len(prov["stages"]), "ok" if prov["checks"]["ok"] else "FAILED (see warnings)")
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
