"""The raw-campaign -> characteristic chain as one plain Python process, without Snakemake.

    .venv/bin/python benchmark/plain_chain.py data/raw/<campaign> OUT_DIR

Ingest, validate, windows, repeatability and characteristic of one raw campaign into OUT_DIR/<campaign>/,
by the package's own functions in a single interpreter (no job start-up, no lineage records, no
logging set-up). benchmark/run.py times it, whole process with its imports, against the same chain
run by the workflow's jobs: the ratio is what running a stage as a Snakemake job costs.
"""

import sys
import time
from pathlib import Path

start = time.perf_counter()
from isokinetic.stages.characteristic import write_characteristic  # noqa: E402
from isokinetic.stages.ingest import ingest_campaign  # noqa: E402


def main(raw_dir: Path, out_root: Path) -> None:
    root = out_root / raw_dir.name
    ingest_campaign(raw_dir, root)
    char = write_characteristic(root)
    print(f"{len(char)} characteristic points in {time.perf_counter() - start:.2f} s after interpreter start")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
