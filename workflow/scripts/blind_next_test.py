"""Rule blind_next_test: one scenario built to be confounded, its proposed next tests and the uniform plan run on
its reference rig and judged -> results/blind/next_test.json (work in results/blind/next_test/)."""
import time

from isokinetic.blind.next_tests import proof_table
from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.blind_next_test import run_next_test

with job(snakemake) as j:
    start = time.perf_counter()
    row = run_next_test(Settings.from_config(snakemake.config), snakemake.output.proof, snakemake.output.work)
    j.log.info("%s in %.1f s:\n%s", row["scenario"], time.perf_counter() - start, proof_table([row]))
