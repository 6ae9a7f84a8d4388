"""Rule blind_score: verdicts against the truth -> scores.parquet, summary.json, Fig. 17; prints the summary."""
import sys

from isokinetic.blind import summary_text, write_scores
from isokinetic.lineage import finish
from isokinetic.logs import log_to_file

log = log_to_file(snakemake.log[0])
scores, summary = write_scores(snakemake.input.truth, snakemake.input.diagnoses, snakemake.output.scores,
                               snakemake.output.summary, snakemake.output.figure)
text = summary_text(summary)
log.info("\n%s", text)
print(text, file=sys.stderr, flush=True)
finish(snakemake)  # lineage record on every output (isokinetic.lineage)
