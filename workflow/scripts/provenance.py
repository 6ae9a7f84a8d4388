"""Rule provenance: raw files, environment, code and every stage of a campaign -> provenance.json."""
from pathlib import Path

from isokinetic.audit.provenance import write_provenance
from isokinetic.job import job

with job(snakemake) as j:
    out = Path(snakemake.output[0])
    prov = write_provenance(out.parent, out, config_sha256=j.lineage["config_sha256"])
    j.log.info("campaign %s: %d raw file(s), %d stage(s), checks %s", prov["campaign"], len(prov["raw"]["files"]),
               len(prov["stages"]), "ok" if prov["checks"]["ok"] else "FAILED (see warnings)")
