"""Rule repeatability: period 1 against period 2 -> repeatability.parquet."""
import pandas as pd

from isokinetic.io import write_parquet
from isokinetic.job import job
from isokinetic.stages.repeatability import repeatability

with job(snakemake) as j:
    rep = repeatability(pd.read_parquet(snakemake.input[0]), snakemake.params.tolerance)
    write_parquet(rep, snakemake.output[0])
    for row in rep[rep["flagged"]].itertuples():
        j.log.warning("campaign %s, case %s, direction %s: period 2 differs from period 1 by %+.1f %% "
                      "(tolerance %.1f %%)", row.campaign, row.case, row.direction, 100 * row.rel_diff,
                      100 * row.tolerance)
