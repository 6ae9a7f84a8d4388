"""Rule models: nominal families, fitted models, comparison table and Fig. 13 / Fig. 14."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.models import write_models
from isokinetic.stages.windows import WindowSpec

with job(snakemake) as j:
    spec = WindowSpec(snakemake.params.start_fraction, snakemake.params.end_fraction)
    write_models(Path(snakemake.input.characteristic).parent, Path(snakemake.output.models).parent, spec)
