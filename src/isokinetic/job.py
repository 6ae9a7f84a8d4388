"""One entry for the pipeline's scripts: a job's log file and lineage record, set up once.

Every script under ``workflow/scripts/`` reads::

    with job(snakemake) as j:
        table = some_stage(...)
        write_parquet(table, snakemake.output[0])
        j.log.info("%d rows", len(table))

Entering the block sends the package's log records to the job's log file ``snakemake.log[0]``
(warnings to stderr too) and builds the job's lineage record once
(:func:`isokinetic.audit.lineage.from_snakemake`: rule, params, config hash, git state and the
sha256 of every input). Inside the block every Parquet, JSON and PNG file the package writes
carries that record as it is written (:func:`isokinetic.io.lineage_context`), no output is read
back or rewritten afterwards, and no file is hashed twice (:func:`isokinetic.io.hash_once`: a stage
that hashes an input again, as ingest does its raw files, reuses the record's hash). A rule with a
``vector_format`` param (``svg`` or ``pdf``; config ``figures.vector_format``) has every figure also
written in that format beside its PNG (:func:`isokinetic.io.vector_figures`). Leaving the block closes
the log file.

In a job's own process (``smk`` is Snakemake's object, not a test's stand-in) the block also spares the
interpreter's exit most of its work (issue 23): entering it freezes every object the imports made
(``gc.freeze``: the cyclic collector no longer walks them, during the job nor at exit), and leaving it
collects the job's own cyclic garbage (their finalizers run while the interpreter is whole) and freezes
what is left. Objects are still freed as their references go. The exit of a process holding pandas,
matplotlib or scipy otherwise walks them all once more: 0.05-0.2 CPU-s of every job.
``ISOKINETIC_GC_FREEZE=0`` in the environment leaves the collector as Python ships it (benchmark/scaling.py
``--no-gc-freeze`` weighs it).
"""

from __future__ import annotations

import gc
import logging
import os
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass

from isokinetic.audit.lineage import from_snakemake
from isokinetic.io import hash_once, lineage_context, vector_figures

LOGGER_NAME = "isokinetic"
LOG_FORMAT = "%(asctime)s %(levelname)s %(message)s"
#: The environment variable that, set to 0, runs the jobs without gc.freeze.
GC_FREEZE_SWITCH = "ISOKINETIC_GC_FREEZE"


@dataclass(frozen=True)
class Job:
    """A running pipeline job: its logger and its lineage record."""

    log: logging.Logger
    lineage: dict


def log_to_file(path: str) -> logging.Logger:
    """Send the package's log records to ``path`` (and warnings to stderr) for one job."""
    logger = logging.getLogger(LOGGER_NAME)
    logger.setLevel(logging.INFO)
    _drop_handlers(logger)
    fmt = logging.Formatter(LOG_FORMAT)
    to_file = logging.FileHandler(path, mode="w", encoding="utf-8")
    to_file.setFormatter(fmt)
    to_stderr = logging.StreamHandler(sys.stderr)
    to_stderr.setLevel(logging.WARNING)
    to_stderr.setFormatter(fmt)
    logger.addHandler(to_file)
    logger.addHandler(to_stderr)
    logging.captureWarnings(True)
    return logger


def _drop_handlers(logger: logging.Logger) -> None:
    for handler in list(logger.handlers):
        logger.removeHandler(handler)
        handler.close()


def in_job_process(smk) -> bool:
    """Whether ``smk`` is the ``snakemake`` object Snakemake gives a script job, whose process ends with the
    job (not a stand-in: tests run :func:`job` in their own process)."""
    containers = sys.modules.get("snakemake.iocontainers")
    return containers is not None and isinstance(smk, containers.Snakemake)


def freezes_collector(smk, environ: Mapping[str, str] = os.environ) -> bool:
    """Whether the job ``smk`` freezes the cyclic collector's objects: in a job's own process
    (:func:`in_job_process`), unless ``environ`` sets GC_FREEZE_SWITCH to 0."""
    return in_job_process(smk) and environ.get(GC_FREEZE_SWITCH, "1") != "0"


@contextmanager
def job(smk) -> Iterator[Job]:
    """The Snakemake job ``smk`` (a script's ``snakemake`` object) as a :class:`Job`; see the module docstring."""
    log = log_to_file(str(smk.log[0]))
    own_process = freezes_collector(smk)
    if own_process:
        gc.freeze()
    try:
        with hash_once():
            record = from_snakemake(smk)
            with lineage_context(record), vector_figures(getattr(smk.params, "vector_format", None)):
                yield Job(log=log, lineage=record)
    except Exception as e:  # the job's log names why it failed (the run's closing summary quotes it)
        log.error("job failed: %s: %s", type(e).__name__, e)
        raise
    finally:
        _drop_handlers(log)
        logging.captureWarnings(False)
        if own_process:
            gc.collect()
            gc.freeze()
