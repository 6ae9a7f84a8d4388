"""Rule windows: one steady point per constant-velocity half-period -> windows.parquet."""
from pathlib import Path

from isokinetic.io import write_parquet
from isokinetic.job import job
from isokinetic.stages.windows import WindowSpec, windows_stage

with job(snakemake) as j:
    spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
    windows = windows_stage(Path(snakemake.input.cases).parent, spec)
    write_parquet(windows, snakemake.output[0])
    j.log.info("%d windows from %d cases", len(windows), windows["case"].nunique())
