"""Rule validate: schema and plan checks -> cases.parquet and quarantine.parquet."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.validate import write_validated
from isokinetic.stages.windows import WindowSpec

with job(snakemake) as j:
    write_validated(Path(snakemake.output.cases).parent,
                    sample_rate_tolerance=snakemake.params.sample_rate_tolerance,
                    window_spec=WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction))
