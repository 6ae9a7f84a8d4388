"""isokinetic.scheduling: at most one pending scheduler wake-up in Snakemake's JobScheduler."""

import threading
import time

from snakemake.scheduling.job_scheduler import JobScheduler

from isokinetic.scheduling import SWITCH, coalesce_reevaluations, schedule_one_reevaluation


class FakeScheduler:
    """What the wake-up touches of a JobScheduler: its semaphore of scheduling passes."""

    def __init__(self):
        self._open_jobs = threading.Semaphore(0)

    def wake_ups(self, wait_s: float) -> int:
        time.sleep(wait_s)
        n = 0
        while self._open_jobs.acquire(blocking=False):
            n += 1
        return n


def test_many_requests_while_one_is_pending_wake_the_scheduler_once():
    scheduler = FakeScheduler()
    for _ in range(50):
        schedule_one_reevaluation(scheduler, 0.05)
    assert scheduler.wake_ups(0.3) == 1


def test_a_request_after_the_wake_up_arms_a_new_one():
    scheduler = FakeScheduler()
    schedule_one_reevaluation(scheduler, 0.02)
    assert scheduler.wake_ups(0.2) == 1
    schedule_one_reevaluation(scheduler, 0.02)
    assert scheduler.wake_ups(0.2) == 1


def test_pending_wake_up_does_not_keep_the_process_alive():
    scheduler = FakeScheduler()
    schedule_one_reevaluation(scheduler, 60.0)
    pending = [t for t in threading.enumerate() if isinstance(t, threading.Timer) and t.is_alive()]
    assert pending and all(t.daemon for t in pending)
    for t in pending:
        t.cancel()


def test_snakemake_scheduler_gets_the_coalescing_wake_up(monkeypatch):
    monkeypatch.setattr(JobScheduler, "_schedule_reevalutation", JobScheduler._schedule_reevalutation)
    assert coalesce_reevaluations()
    assert JobScheduler._schedule_reevalutation is schedule_one_reevaluation


def test_a_scheduler_without_the_method_is_left_alone(caplog):
    class Other:
        pass

    assert not coalesce_reevaluations(Other)
    assert not hasattr(Other, "_schedule_reevalutation")
    assert "not coalesced" in caplog.text


def test_the_switch_at_zero_leaves_snakemake_as_it_ships():
    class Scheduler:
        def _schedule_reevalutation(self, delay):
            pass

    shipped = Scheduler._schedule_reevalutation
    assert not coalesce_reevaluations(Scheduler, {SWITCH: "0"})
    assert Scheduler._schedule_reevalutation is shipped
    assert coalesce_reevaluations(Scheduler, {SWITCH: "1"})
    assert Scheduler._schedule_reevalutation is schedule_one_reevaluation
