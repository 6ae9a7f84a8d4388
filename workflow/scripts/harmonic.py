"""Rule harmonic: sine and free records -> harmonic.parquet and the loops figure."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.harmonic import write_harmonic

with job(snakemake) as j:
    write_harmonic(Path(snakemake.input.cases).parent, Path(snakemake.output.table).parent)
