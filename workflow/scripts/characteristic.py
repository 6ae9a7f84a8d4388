"""Rule characteristic: windows + repeatability -> characteristic.parquet."""
import pandas as pd

from isokinetic.io import write_parquet
from isokinetic.job import job
from isokinetic.stages.characteristic import assemble

with job(snakemake) as j:
    char = assemble(pd.read_parquet(snakemake.input.windows), pd.read_parquet(snakemake.input.repeatability))
    write_parquet(char, snakemake.output[0])
    j.log.info("%d characteristic points", len(char))
