"""Rule design: plan check (G-numbers, stroke to converge) and Fig. 5 / Fig. 6 of a campaign."""
from pathlib import Path

from isokinetic.design import plan_warnings, write_design
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
plan_check, written = write_design(Path(snakemake.input.cases).parent, Path(snakemake.output.plan_check).parent,
                                   phi=snakemake.params.phi, max_amplitude_m=snakemake.params.max_amplitude_m,
                                   min_amplitude_m=snakemake.params.min_amplitude_m,
                                   start_fraction=snakemake.params.start_fraction)
for line in plan_warnings(plan_check):
    log.warning("plan check: %s", line)
log.info("%d cases checked, %d flagged", len(plan_check), int(plan_check["flagged"].sum()))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
