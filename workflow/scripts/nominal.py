"""Rule nominal: the nominal model through the campaign's plan and windows -> nominal_windows.parquet."""
from pathlib import Path

from isokinetic.io import write_parquet
from isokinetic.job import job
from isokinetic.stages.nominal import nominal_stage
from isokinetic.stages.windows import WindowSpec

with job(snakemake) as j:
    spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
    windows = nominal_stage(Path(snakemake.input.cases).parent, spec)
    write_parquet(windows, snakemake.output[0])
    j.log.info("%d nominal-model windows", len(windows))
