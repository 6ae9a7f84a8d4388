"""Rule blind_generate: one chunk of the seeded blind suite -> results/blind/raw/chunk<k>/<scenario>/ and
results/blind/truth/chunk<k>/."""
import time

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.blind_generate import generate_scenarios, write_suite

with job(snakemake) as j:
    p = snakemake.params
    start = time.perf_counter()
    scenarios = generate_scenarios(p.seed, p.n_per_effect, p.n_pairs, p.n_none, p.n_out, p.n_sine,
                                   spec=Settings.from_config(snakemake.config).window, names=list(p.names))
    names = [s.name for s in scenarios]
    if names != list(p.names):
        raise RuntimeError(f"generated scenarios {names} differ from the workflow's {list(p.names)}")
    write_suite(scenarios, snakemake.output.raw, snakemake.output.truth)
    j.log.info("%d blind scenarios generated and exported in %.1f s", len(scenarios), time.perf_counter() - start)
