"""Rule blind_generate: one chunk of the seeded blind suite -> results/blind/raw/chunk<k>/<scenario>/ and
results/blind/truth/chunk<k>/."""
import time

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.blind_generate import write_chunk

with job(snakemake) as j:
    p = snakemake.params
    start = time.perf_counter()
    scenarios = write_chunk(p.seed, (p.n_per_effect, p.n_pairs, p.n_none, p.n_out, p.n_sine), p.names,
                            Settings.from_config(snakemake.config), snakemake.output.raw, snakemake.output.truth)
    j.log.info("%d blind scenarios generated and exported in %.1f s", len(scenarios), time.perf_counter() - start)
