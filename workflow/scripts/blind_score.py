"""Rule blind_score: verdicts against the truth -> scores.parquet, summary.json, Fig. 17; prints the summary."""
import sys

from isokinetic.blind.score import summary_text
from isokinetic.job import job
from isokinetic.stages.blind_score import write_scores

with job(snakemake) as j:
    scores, summary = write_scores(snakemake.input.truth, snakemake.input.diagnoses, snakemake.output.scores,
                                   snakemake.output.summary, snakemake.output.figure)
    text = summary_text(summary)
    j.log.info("\n%s", text)
    print(text, file=sys.stderr, flush=True)
