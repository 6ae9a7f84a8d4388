"""Rule windows: one steady point per constant-velocity half-period -> windows.parquet."""
from pathlib import Path

from isokinetic.io import write_parquet
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.windows import WindowSpec, windows_stage

log = log_to_file(snakemake.log[0])
spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
windows = windows_stage(Path(snakemake.input.cases).parent, spec)
write_parquet(windows, snakemake.output[0])
log.info("%d windows from %d cases", len(windows), windows["case"].nunique())
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
