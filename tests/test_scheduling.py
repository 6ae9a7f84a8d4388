"""isokinetic.scheduling: at most one pending scheduler wake-up in Snakemake's JobScheduler; the private method it
replaces checked against the installed (pinned) Snakemake."""

import ast
import importlib.util
import inspect
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


def shipped_scheduler_module():
    """A fresh copy of Snakemake's job_scheduler module, its JobScheduler untouched by any patch of this process."""
    spec = importlib.util.find_spec("snakemake.scheduling.job_scheduler")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_installed_snakemakes_method_has_the_shape_the_patch_replaces():
    """The pinned Snakemake (environment.lock) still has the private method, taking one delay, and the shipped
    method wakes the scheduler exactly as the replacement does: one release of _open_jobs after the delay."""
    shipped = shipped_scheduler_module().JobScheduler._schedule_reevalutation
    assert list(inspect.signature(shipped).parameters) == ["self", "delay"]
    assert list(inspect.signature(schedule_one_reevaluation).parameters) == ["scheduler", "delay"]
    scheduler = FakeScheduler()
    shipped(scheduler, 0.02)
    assert scheduler.wake_ups(0.3) == 1


def test_the_installed_snakemakes_scheduler_calls_the_method_with_one_delay_and_waits_on_its_semaphore():
    """Where Snakemake calls the method (each with one argument, the delay) and what a wake-up releases: the
    semaphore its scheduling loop waits on, made in JobScheduler.__init__."""
    tree = ast.parse(inspect.getsource(shipped_scheduler_module()))
    calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)]
    wakes = [c for c in calls if c.func.attr == "_schedule_reevalutation"]
    assert wakes and all(len(c.args) + len(c.keywords) == 1 for c in wakes)
    assert all(ast.unparse(c.func.value) == "self" for c in wakes)
    waits = [c for c in calls if c.func.attr == "acquire" and ast.unparse(c.func.value) == "self._open_jobs"]
    assert waits, "the scheduling loop no longer waits on self._open_jobs"
    (init,) = [f for f in ast.walk(tree) if isinstance(f, ast.FunctionDef) and f.name == "__init__"
               and any(isinstance(n, ast.Attribute) and n.attr == "_open_jobs" for n in ast.walk(f))]
    made = [n.value for n in ast.walk(init) if isinstance(n, ast.Assign)
            and any(ast.unparse(t) == "self._open_jobs" for t in n.targets)]
    assert [ast.unparse(v) for v in made] == ["threading.Semaphore(0)"]
