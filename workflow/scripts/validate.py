"""Rule validate: schema and plan checks -> cases.parquet and quarantine.parquet."""
from pathlib import Path

from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.validate import write_validated
from isokinetic.windows import WindowSpec

log_to_file(snakemake.log[0])
write_validated(Path(snakemake.output.cases).parent,
                sample_rate_tolerance=snakemake.params.sample_rate_tolerance,
                window_spec=WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction))
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
