"""Rule characteristic: validate -> windows -> repeatability -> characteristic of one campaign."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.validate import GapTolerance

with job(snakemake) as j:
    p = snakemake.params
    write_characteristic(Path(snakemake.output.cases).parent, WindowSpec(p.start_fraction, p.end_fraction),
                         repeatability_tolerance=p.repeatability_tolerance,
                         sample_rate_tolerance=p.sample_rate_tolerance,
                         gap_tolerance=GapTolerance(p.max_missing_fraction, p.max_gap_s))
