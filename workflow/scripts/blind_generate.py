"""Rule blind_generate: the seeded blind suite -> results/blind/raw/<scenario>/ and results/blind/truth/."""
import time

from isokinetic.blind import generate_scenarios, write_suite
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.windows import WindowSpec

log = log_to_file(snakemake.log[0])
p = snakemake.params
start = time.perf_counter()
scenarios = generate_scenarios(p.seed, p.n_per_effect, p.n_pairs, p.n_none, p.n_out,
                               spec=WindowSpec(p.start_fraction, p.end_fraction))
names = [s.name for s in scenarios]
if names != list(p.names):
    raise RuntimeError(f"generated scenarios {names} differ from the workflow's {list(p.names)}")
write_suite(scenarios, snakemake.output.raw, snakemake.output.truth)
log.info("%d blind scenarios generated and exported in %.1f s", len(scenarios), time.perf_counter() - start)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
