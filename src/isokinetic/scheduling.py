"""One pending scheduler reevaluation in Snakemake instead of one per finished job.

Snakemake's job scheduler (``snakemake.scheduling.job_scheduler.JobScheduler``, 9.x) ends every
scheduling pass by arming a ``threading.Timer`` that wakes the scheduler again after the rate
limiter's timespan (``--max-jobs-per-timespan``, default ``100/1s``, always on). Every wake-up is
itself a pass that arms another timer, so each finished job starts a chain that never ends: after k
finished jobs the scheduler runs about k passes a second, each over every ready job. A build's
scheduling work then grows with the square of the number of jobs (measured on 100 campaigns, 602
jobs: 97,757 passes). The timers are also not daemon threads, so the process waits for the last
one (up to 1 s) before it exits.

:func:`coalesce_reevaluations` keeps at most one such timer pending (a daemon thread). A pass it
triggers arms the next one, so the rate limiter is still reevaluated every timespan while jobs
wait. Scheduling decisions are unchanged: jobs are started from the pass that follows a job's end,
as before. It replaces a private method, which no documented setting reaches (``--max-jobs-per-timespan``
only sets the timers' delay); ``ISOKINETIC_COALESCE_REEVALUATIONS=0`` in the environment builds without it, as
Snakemake ships (benchmark/run.py times the default rebuild both ways).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Mapping

log = logging.getLogger(__name__)

#: The attribute of a scheduler that holds its one pending timer.
PENDING = "_isokinetic_pending_reevaluation"
#: The environment variable that, set to 0, leaves Snakemake's scheduler as it ships.
SWITCH = "ISOKINETIC_COALESCE_REEVALUATIONS"


def schedule_one_reevaluation(scheduler, delay: float) -> None:
    """Wake ``scheduler`` (releases its ``_open_jobs`` semaphore) after ``delay`` seconds, unless a
    wake-up is already pending: a drop-in for ``JobScheduler._schedule_reevalutation``."""
    pending = getattr(scheduler, PENDING, None)
    if pending is not None and pending.is_alive():
        return
    timer = threading.Timer(delay, scheduler._open_jobs.release)
    timer.daemon = True
    setattr(scheduler, PENDING, timer)
    timer.start()


def coalesce_reevaluations(scheduler_class=None, environ: Mapping[str, str] = os.environ) -> bool:
    """Install :func:`schedule_one_reevaluation` on Snakemake's ``JobScheduler`` (or on
    ``scheduler_class``). Returns False, with a warning, when the class has no such method (a
    Snakemake whose scheduler changed), and False where ``environ`` sets SWITCH to 0: the build then runs as
    Snakemake ships it."""
    if environ.get(SWITCH, "1") == "0":
        log.info("%s=0: scheduler reevaluations not coalesced", SWITCH)
        return False
    if scheduler_class is None:
        from snakemake.scheduling.job_scheduler import JobScheduler as scheduler_class
    if not callable(getattr(scheduler_class, "_schedule_reevalutation", None)):
        log.warning("%s has no _schedule_reevalutation: scheduler reevaluations not coalesced",
                    scheduler_class.__qualname__)
        return False
    scheduler_class._schedule_reevalutation = schedule_one_reevaluation
    return True
