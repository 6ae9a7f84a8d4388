"""Rule nominal: the nominal model through the campaign's plan and windows -> nominal_windows.parquet."""
from pathlib import Path

from isokinetic.io import write_parquet
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.nominal import nominal_stage
from isokinetic.windows import WindowSpec

log = log_to_file(snakemake.log[0])
spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
windows = nominal_stage(Path(snakemake.input.cases).parent, spec)
write_parquet(windows, snakemake.output[0])
log.info("%d nominal-model windows", len(windows))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
