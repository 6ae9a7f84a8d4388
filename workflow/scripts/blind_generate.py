"""Rule blind_generate: the seeded blind suite -> results/blind/raw/<scenario>/ and results/blind/truth/."""
import time

from isokinetic.job import job
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.blind_generate import generate_scenarios, write_suite

with job(snakemake) as j:
    p = snakemake.params
    start = time.perf_counter()
    scenarios = generate_scenarios(p.seed, p.n_per_effect, p.n_pairs, p.n_none, p.n_out,
                                   spec=WindowSpec(p.start_fraction, p.end_fraction))
    names = [s.name for s in scenarios]
    if names != list(p.names):
        raise RuntimeError(f"generated scenarios {names} differ from the workflow's {list(p.names)}")
    write_suite(scenarios, snakemake.output.raw, snakemake.output.truth)
    j.log.info("%d blind scenarios generated and exported in %.1f s", len(scenarios), time.perf_counter() - start)
