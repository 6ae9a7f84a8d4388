"""Rule compare: one comparison of campaigns -> compare.parquet, compare.csv, compare.json, Fig. 18-19, report.html."""
from pathlib import Path

from isokinetic.job import job
from isokinetic.measurement.comparison import CompareSpec
from isokinetic.report.compare_report import write_compare_report
from isokinetic.stages.compare import write_compare

with job(snakemake) as j:
    p = snakemake.params
    spec = CompareSpec(snakemake.wildcards.comparison, tuple(p.campaigns), **dict(p.settings))
    roots = {c: Path(f).parent for c, f in zip(spec.campaigns, snakemake.input.characteristics, strict=True)}
    page = Path(snakemake.output.page)
    written = write_compare(spec, roots, page.parent)
    captions = Path(snakemake.input.captions[0]).parent if snakemake.input.captions else None
    written.append(write_compare_report(page.parent, page, captions_dir=captions, lineage_record=j.lineage))
    # vector copies of the figures (config figures.vector_format) are written beside the PNGs, unlisted
    expected = set(map(str, snakemake.output)) - set(map(str, getattr(snakemake.output, "vectors", [])))
    missing = sorted(expected - {str(path) for path in written})
    if missing:
        raise RuntimeError(f"compare did not write: {missing}")
    j.log.info("comparison %s of %s: %d files written", spec.name, ", ".join(spec.campaigns), len(written))
