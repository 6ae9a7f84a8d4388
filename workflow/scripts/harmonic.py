"""Rule harmonic: sine and free records -> harmonic.parquet and the loops figure."""
from pathlib import Path

from isokinetic.harmonic import write_harmonic
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log_to_file(snakemake.log[0])
write_harmonic(Path(snakemake.input.cases).parent, Path(snakemake.output.table).parent)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
