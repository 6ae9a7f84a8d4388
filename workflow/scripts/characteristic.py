"""Rule characteristic: windows + repeatability -> characteristic.parquet."""
import pandas as pd

from isokinetic.characteristic import assemble
from isokinetic.io import write_parquet
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
char = assemble(pd.read_parquet(snakemake.input.windows), pd.read_parquet(snakemake.input.repeatability))
write_parquet(char, snakemake.output[0])
log.info("%d characteristic points", len(char))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
