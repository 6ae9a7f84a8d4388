"""Lineage records: stamping keeps the data, the record reads back, a Snakemake job's record is complete."""

import json
from pathlib import Path

import matplotlib.image
import numpy as np
import pandas as pd
import pytest
import yaml
from matplotlib.figure import Figure

from isokinetic import __version__, lineage
from isokinetic.figures import save_figure
from isokinetic.io import sha256_file, write_json, write_parquet
from isokinetic.virtual_rig import VirtualCampaign

ROOT = Path(__file__).resolve().parents[1]


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
    job = Job()
    job.rule = rule
    job.params = Named(**(params or {}))
    job.wildcards = Named(**(wildcards or {}))
    job.input = Named(**(inputs or {}))
    job.output = Named(**(outputs or {}))
    job.log = Named(log=str(tmp_path / "job.log"))
    job.config = {"windows": {"start_fraction": 0.45, "end_fraction": 0.95}}
    return job


def frame(n=50):
    rng = np.random.default_rng(1)
    return pd.DataFrame({"case": [f"T{i % 5:02d}" for i in range(n)], "segment": np.arange(n, dtype="int64") % 4 + 1,
                         "force_N": rng.normal(size=n), "ok": rng.normal(size=n) > 0})


RECORD = lineage.stage_lineage("windows", {"start_fraction": 0.45}, [], campaign="demo")


def test_stamping_parquet_keeps_the_data_and_the_record_reads_back(tmp_path):
    df = frame()
    path = write_parquet(df, tmp_path / "t.parquet")
    assert lineage.read_lineage(path) is None
    assert lineage.stamp_outputs([path], RECORD) == [path]
    pd.testing.assert_frame_equal(pd.read_parquet(path), df)
    assert lineage.read_lineage(path) == json.loads(lineage.canonical_json(RECORD))
    again = dict(RECORD, rule="other")
    lineage.stamp_outputs([path], again)          # re-stamping replaces the record
    assert lineage.read_lineage(path)["rule"] == "other"
    pd.testing.assert_frame_equal(pd.read_parquet(path), df)


def test_stamping_json_adds_one_key_and_keeps_the_rest(tmp_path):
    data = {"a": 1, "b": [1.5, None, "x"], "nested": {"k": True}}
    path = write_json(data, tmp_path / "d.json")
    lineage.stamp_outputs([path], RECORD)
    got = json.loads(path.read_text())
    assert got.pop("lineage") == lineage.read_lineage(path) == json.loads(lineage.canonical_json(RECORD))
    assert got == data
    listed = write_json([1, 2], tmp_path / "list.json")     # not an object: left alone
    before = sha256_file(listed)
    assert lineage.stamp_outputs([listed], RECORD) == [] and sha256_file(listed) == before


def test_stamping_png_keeps_every_pixel(tmp_path):
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1, 2], [0, 1, 0])
    path = save_figure(fig, tmp_path / "f.png")
    before_pixels = matplotlib.image.imread(path)
    before_chunks = lineage._png_chunks(path.read_bytes())
    lineage.stamp_outputs([path], RECORD)
    assert lineage.read_lineage(path) == json.loads(lineage.canonical_json(RECORD))
    assert np.array_equal(matplotlib.image.imread(path), before_pixels)
    after = [c for c in lineage._png_chunks(path.read_bytes()) if not lineage._is_lineage_chunk(*c)]
    assert after == before_chunks
    lineage.stamp_outputs([path], RECORD)        # one lineage chunk, however often stamped
    assert sum(lineage._is_lineage_chunk(*c) for c in lineage._png_chunks(path.read_bytes())) == 1


def test_folder_outputs_get_every_table_and_json_inside_stamped(tmp_path):
    folder = tmp_path / "ingest"
    write_parquet(frame(), folder / "timeseries" / "T01.parquet")
    write_parquet(frame(), folder / "cases.parquet")
    write_json({"campaign": "demo"}, folder / "campaign.json")
    (folder / "notes.csv").write_text("a,b\n1,2\n")
    stamped = lineage.stamp_outputs([folder], RECORD)
    assert sorted(p.relative_to(folder).as_posix() for p in stamped) == [
        "campaign.json", "cases.parquet", "timeseries/T01.parquet"]
    assert (folder / "notes.csv").read_text() == "a,b\n1,2\n"


def test_from_snakemake_records_rule_params_inputs_config_and_git(tmp_path, monkeypatch):
    monkeypatch.setenv("ISOKINETIC_GIT_COMMIT", "abc123")
    monkeypatch.setenv("ISOKINETIC_GIT_DIRTY", "1")
    cases = write_parquet(frame(), tmp_path / "cases.parquet")
    ingest = tmp_path / "ingest"
    write_parquet(frame(), ingest / "timeseries" / "T01.parquet")
    out = tmp_path / "windows.parquet"
    job = fake_job(tmp_path, params={"start_fraction": 0.45, "end_fraction": 0.95},
                   wildcards={"campaign": "demo"}, inputs={"cases": str(cases), "ingest": str(ingest)},
                   outputs={"out": str(out)})
    rec = lineage.from_snakemake(job)
    assert rec["rule"] == "windows" and rec["campaign"] == "demo" and rec["wildcards"] == {"campaign": "demo"}
    assert rec["params"] == {"start_fraction": 0.45, "end_fraction": 0.95}
    assert rec["params_sha256"] == lineage.sha256_text(lineage.canonical_json(rec["params"]))
    assert rec["config_sha256"] == lineage.sha256_text(lineage.canonical_json(job.config))
    assert rec["inputs"] == {str(cases): sha256_file(cases), str(ingest): lineage.path_sha256(ingest)}
    assert (rec["git_commit"], rec["git_dirty"], rec["package_version"]) == ("abc123", True, __version__)
    assert rec["log"] == [str(tmp_path / "job.log")] and rec["created_utc"].endswith("Z")
    write_parquet(frame(), out)
    assert lineage.finish(job) == [out]
    assert lineage.read_lineage(out)["inputs"] == rec["inputs"]


def test_virtual_rig_spec_round_trips_through_the_record(tmp_path):
    """An auditor can rebuild the simulated campaign from the ingest files' lineage alone."""
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    for name, spec in config["virtual_campaigns"].items():
        job = fake_job(tmp_path, rule="virtual_rig", params={"spec": spec}, wildcards={"campaign": name})
        path = write_json({"campaign": name}, tmp_path / f"{name}.json")
        lineage.stamp_outputs([path], lineage.from_snakemake(job))
        recorded = lineage.read_lineage(path)["params"]["spec"]
        assert recorded == spec
        assert VirtualCampaign.from_config(name, recorded) == VirtualCampaign.from_config(name, spec)


def test_row_keys_round_trip():
    df = pd.DataFrame({"case": ["T01", "T01", "T2.b", "T01"], "segment": [1, 3, 2, 1]})
    text = lineage.row_keys(df)
    assert text == "T01/1,T01/3,T2.b/2"
    assert lineage.parse_row_keys(text) == [("T01", 1), ("T01", 3), ("T2.b", 2)]
    assert lineage.parse_row_keys("") == []


@pytest.mark.parametrize("env, expected", [({"ISOKINETIC_GIT_COMMIT": "c0ffee", "ISOKINETIC_GIT_DIRTY": "0"},
                                            ("c0ffee", False)),
                                           ({"ISOKINETIC_GIT_COMMIT": "", "ISOKINETIC_GIT_DIRTY": ""}, (None, None))])
def test_git_state_comes_from_the_environment(monkeypatch, env, expected):
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    assert lineage.git_state() == expected
