"""Rule models: nominal families, fitted models, comparison table and Fig. 13 / Fig. 14."""
from pathlib import Path

from isokinetic.lineage import finish
from isokinetic.logs import log_to_file
from isokinetic.models import write_models
from isokinetic.windows import WindowSpec

log_to_file(snakemake.log[0])
spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
write_models(Path(snakemake.input.characteristic).parent, Path(snakemake.output.models).parent, spec)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
