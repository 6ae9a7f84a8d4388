"""Rule analysis: design check, nominal model, harmonic records, model fits and figures of one campaign."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.analysis import DesignLimits, write_analysis

with job(snakemake) as j:
    p = snakemake.params
    written = write_analysis(Path(snakemake.input.characteristic).parent, WindowSpec(p.start_fraction, p.end_fraction),
                             DesignLimits(p.phi, p.max_amplitude_m, p.min_amplitude_m))
    # vector copies of the figures (config figures.vector_format) are written beside the PNGs, unlisted
    expected = set(map(str, snakemake.output)) - set(map(str, getattr(snakemake.output, "vectors", [])))
    missing = sorted(expected - {str(p) for p in written})
    if missing:
        raise RuntimeError(f"analysis did not write: {missing}")
