"""The scripts' one entry: a job's log file and lineage record, set up once; files stamped as written."""

import gc
import json
import logging

import pandas as pd
import pytest
from matplotlib.figure import Figure

import isokinetic.io
from isokinetic.io import canonical_json, current_lineage, read_lineage, sha256_file, write_json, write_parquet
from isokinetic.job import GC_FREEZE_SWITCH, job
from isokinetic.plots.style import save_figure


class Named(list):
    """The shape of snakemake's Namedlist as a script sees it: a list with named items."""

    def __init__(self, **items):
        super().__init__(items.values())
        self._names = dict(items)
        self.__dict__.update(items)

    def items(self):
        return self._names.items()


def fake_job(tmp_path, rule="windows", params=None, wildcards=None, inputs=None, outputs=None):
    """A stand-in for the ``snakemake`` object of a script job."""
    class Job:
        pass
    smk = Job()
    smk.rule = rule
    smk.params = Named(**(params or {}))
    smk.wildcards = Named(**(wildcards or {}))
    smk.input = Named(**(inputs or {}))
    smk.output = Named(**(outputs or {}))
    smk.log = Named(log=str(tmp_path / "job.log"))
    smk.config = {"windows": {"start_fraction": 0.45, "end_fraction": 0.95}}
    return smk


def frame(n=20):
    return pd.DataFrame({"case": [f"T{i % 5:02d}" for i in range(n)], "segment": [i % 4 + 1 for i in range(n)],
                         "force_N": [0.5 * i for i in range(n)]})


def test_every_file_written_in_the_job_carries_its_record_and_inputs_are_hashed_once(tmp_path, monkeypatch):
    cases = write_parquet(frame(), tmp_path / "cases.parquet")
    ingest = tmp_path / "ingest"
    write_parquet(frame(), ingest / "timeseries" / "T01.parquet")
    write_parquet(frame(), ingest / "cases.parquet")
    hashed = []
    read = isokinetic.io._read_sha256
    monkeypatch.setattr(isokinetic.io, "_read_sha256", lambda p: hashed.append(str(p)) or read(p))
    smk = fake_job(tmp_path, params={"start_fraction": 0.45}, wildcards={"campaign": "demo"},
                   inputs={"cases": str(cases), "ingest": str(ingest)})
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 0])
    with job(smk) as j:
        out = [write_parquet(frame(), tmp_path / "out" / "windows.parquet"),
               write_json({"verdict": "none"}, tmp_path / "out" / "diagnosis.json"),
               save_figure(fig, tmp_path / "out" / "fig.png")]
        assert current_lineage() is j.lineage
        assert sha256_file(cases) == j.lineage["inputs"][str(cases)]   # a stage hashing an input again
    assert sorted(hashed) == sorted([str(cases), *(str(p) for p in ingest.rglob("*.parquet"))])  # once each
    record = json.loads(canonical_json(j.lineage))
    assert record["rule"] == "windows" and record["campaign"] == "demo"
    assert set(record["inputs"]) == {str(cases), str(ingest)}
    assert [read_lineage(p) for p in out] == [record] * 3
    assert current_lineage() is None                       # scoped to the job
    after = write_parquet(frame(), tmp_path / "after.parquet")
    assert read_lineage(after) is None


def test_the_log_goes_to_the_job_log_file_and_is_closed_after(tmp_path, capsys):
    smk = fake_job(tmp_path)
    with job(smk) as j:
        j.log.info("%d windows", 12)
        logging.getLogger("isokinetic.windows").warning("case T03: short record")
    text = (tmp_path / "job.log").read_text(encoding="utf-8")
    assert "INFO 12 windows" in text and "WARNING case T03: short record" in text
    assert "short record" in capsys.readouterr().err       # warnings on stderr too, not the info
    assert not logging.getLogger("isokinetic").handlers


def test_a_failing_job_logs_nothing_extra_and_leaves_no_context(tmp_path):
    smk = fake_job(tmp_path)
    with pytest.raises(RuntimeError, match="broken"), job(smk) as j:
        j.log.error("campaign demo not ingested: broken")
        raise RuntimeError("broken")
    assert "campaign demo not ingested: broken" in (tmp_path / "job.log").read_text(encoding="utf-8")
    assert current_lineage() is None


def snakemake_job(tmp_path):
    """The very object Snakemake gives a script job (snakemake.iocontainers.Snakemake), no inputs."""
    from snakemake.iocontainers import InputFiles, Log, OutputFiles, Params, ResourceList, Snakemake, Wildcards

    return Snakemake(InputFiles(), OutputFiles(), Params(), Wildcards(), 1, ResourceList(),
                     Log([str(tmp_path / "job.log")]), {}, "windows", None)


class Cycle:
    """Cyclic garbage with a finalizer: ``done`` is set when the collector frees it."""

    def __init__(self, done: list):
        self.me, self.done = self, done

    def __del__(self):
        self.done.append(True)


def test_a_job_in_its_own_process_freezes_what_it_keeps_after_collecting_its_garbage(tmp_path):
    frozen_before, done = gc.get_freeze_count(), []
    try:
        with job(snakemake_job(tmp_path)):
            entered = gc.get_freeze_count()
            kept = [1.0, 2.0]                     # alive at the job's end
            Cycle(done)                           # garbage only the cyclic collector frees
            assert any(obj is kept for obj in gc.get_objects())
        assert entered > frozen_before
        assert not any(obj is kept for obj in gc.get_objects())    # frozen: no generation holds it
        assert done == [True]                     # collected, finalizer run, before the freeze
    finally:
        gc.unfreeze()                             # this test's process goes on


def test_the_switch_at_zero_runs_a_job_in_its_own_process_without_the_freeze(tmp_path, monkeypatch):
    monkeypatch.setenv(GC_FREEZE_SWITCH, "0")
    frozen_before = gc.get_freeze_count()
    with job(snakemake_job(tmp_path)):
        assert gc.get_freeze_count() == frozen_before
    assert gc.get_freeze_count() == frozen_before


def test_a_job_run_in_a_tests_process_leaves_the_collector_alone(tmp_path):
    frozen_before = gc.get_freeze_count()
    with job(fake_job(tmp_path)):
        pass
    assert gc.get_freeze_count() == frozen_before
