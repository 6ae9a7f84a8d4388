"""Rule design_summary: every campaign's plan check in results/design/plan_check.parquet."""
import pandas as pd

from isokinetic import tables
from isokinetic.io import write_parquet
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
frames = [pd.read_parquet(path) for path in snakemake.input]
summary = pd.concat(frames, ignore_index=True) if frames else tables.empty(tables.PLAN_CHECK)
write_parquet(tables.validate_table(summary, tables.PLAN_CHECK), snakemake.output[0])
log.info("%d cases from %d campaigns, %d flagged", len(summary), len(frames), int(summary["flagged"].sum()))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
