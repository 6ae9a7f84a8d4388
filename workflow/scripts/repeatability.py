"""Rule repeatability: period 1 against period 2 -> repeatability.parquet."""
import pandas as pd

from isokinetic.io import write_parquet
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.repeatability import repeatability

log = log_to_file(snakemake.log[0])
rep = repeatability(pd.read_parquet(snakemake.input[0]), snakemake.params.tolerance)
write_parquet(rep, snakemake.output[0])
for row in rep[rep["flagged"]].itertuples():
    log.warning("campaign %s, case %s, direction %s: period 2 differs from period 1 by %+.1f %% "
                "(tolerance %.1f %%)", row.campaign, row.case, row.direction, 100 * row.rel_diff,
                100 * row.tolerance)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
