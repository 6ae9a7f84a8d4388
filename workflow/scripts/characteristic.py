"""Rule characteristic: validate -> windows -> repeatability -> characteristic of one campaign."""
from pathlib import Path

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.characteristic import run_characteristic

with job(snakemake) as j:
    run_characteristic(Path(snakemake.output.cases).parent, Settings.from_config(snakemake.config))
