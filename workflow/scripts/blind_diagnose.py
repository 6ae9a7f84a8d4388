"""Rule blind_diagnose: ingest-to-diagnosis of one chunk of blind scenarios (no access to the truth)."""
import time
from pathlib import Path

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.blind_diagnose import diagnose_suite

with job(snakemake) as j:
    p = snakemake.params
    start = time.perf_counter()
    out = Path(snakemake.output[0])
    out.mkdir(parents=True, exist_ok=True)
    results = diagnose_suite(snakemake.input[0], p.names, out, Settings.from_config(snakemake.config))
    failed = sorted(n for n, d in results.items() if d is None)
    j.log.info("%d scenarios diagnosed in %.1f s%s", len(results), time.perf_counter() - start,
               f"; failed: {', '.join(failed)}" if failed else "")
