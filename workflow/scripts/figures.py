"""Rule figures: the campaign's PNG figures, equivalents of Fig. 7-12 of the paper "A method for the
identification of hydraulic damper characteristics from steady velocity inputs" (Titurus et al.)."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.stages.figures import write_campaign_figures

with job(snakemake) as j:
    written = write_campaign_figures(Path(snakemake.input.cases).parent, Path(snakemake.output[0]).parent)
    missing = sorted(set(map(str, snakemake.output)) - {str(p) for p in written})
    if missing:
        raise RuntimeError(f"figures not written: {missing}")
    j.log.info("wrote %d figures", len(written))
