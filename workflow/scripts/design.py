"""Rule design: plan check (G-numbers, stroke to converge) and Fig. 5 / Fig. 6 of a campaign."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.design import plan_warnings, write_design

with job(snakemake) as j:
    plan_check, written = write_design(Path(snakemake.input.cases).parent, Path(snakemake.output.plan_check).parent,
                                       phi=snakemake.params.phi, max_amplitude_m=snakemake.params.max_amplitude_m,
                                       min_amplitude_m=snakemake.params.min_amplitude_m,
                                       start_fraction=snakemake.params.start_fraction)
    for line in plan_warnings(plan_check):
        j.log.warning("plan check: %s", line)
    j.log.info("%d cases checked, %d flagged", len(plan_check), int(plan_check["flagged"].sum()))
