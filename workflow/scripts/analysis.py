"""Rule analysis: design check, nominal model, harmonic records, model fits and figures of one campaign."""
from pathlib import Path

from isokinetic.contracts.settings import Settings
from isokinetic.job import job
from isokinetic.stages.analysis import run_analysis

with job(snakemake) as j:
    written = run_analysis(Path(snakemake.input.characteristic).parent, Settings.from_config(snakemake.config))
    # vector copies of the figures (config figures.vector_format) are written beside the PNGs, unlisted
    expected = set(map(str, snakemake.output)) - set(map(str, getattr(snakemake.output, "vectors", [])))
    missing = sorted(expected - {str(p) for p in written})
    if missing:
        raise RuntimeError(f"analysis did not write: {missing}")
