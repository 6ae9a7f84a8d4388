"""The benchmark's own arithmetic (benchmark/imports.py, benchmark/jobtimes.py): import-time summary, rule -> script,
critical path. Checked against small hand-made inputs whose answers are worked out here."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmark"))
import imports  # noqa: E402  (benchmark/imports.py)
import jobtimes  # noqa: E402
import scaling  # noqa: E402

IMPORTTIME = """\
import time: self [us] | cumulative | imported package
import time:       100 |        100 |       numpy._core
import time:       400 |        500 |     numpy
import time:      2000 |       2000 |     pandas._libs
import time:      1000 |       3500 |   pandas
import time:        50 |       3550 | isokinetic.io
"""


def test_import_time_is_summed_per_top_level_package():
    profile = imports.parse_importtime(IMPORTTIME)
    assert profile.total_s == pytest.approx(3550e-6)
    assert profile.by_package_s == pytest.approx({"numpy": 500e-6, "pandas": 3000e-6, "isokinetic": 50e-6})
    assert [name for name, _ in profile.top(2)] == ["pandas", "numpy"]


def test_each_rule_is_paired_with_the_script_its_rule_names(tmp_path):
    rules = tmp_path / "workflow" / "rules"
    rules.mkdir(parents=True)
    (rules / "a.smk").write_text('rule first:\n    output:\n        "x"\n    script:\n        "../scripts/one.py"\n\n\n'
                                 'rule shell_only:\n    shell:\n        "true"\n\n\n'
                                 'rule second:\n    script:\n        "../scripts/two.py"\n', encoding="utf-8")
    found = imports.rule_scripts(tmp_path / "workflow")
    assert found == {"first": (tmp_path / "workflow" / "scripts" / "one.py").resolve(),
                     "second": (tmp_path / "workflow" / "scripts" / "two.py").resolve()}


def test_critical_path_follows_files_and_folders_to_the_longest_chain():
    def job(rule, inputs, outputs):
        return scaling.Job(rule, {}, tuple(outputs), tuple(inputs), f"logs/{rule}.tsv")

    jobs = [job("ingest", ["raw/a.csv"], ["r/ingest"]),              # a folder
            job("char", ["r/ingest/cases.parquet"], ["r/char.parquet"]),
            job("diag", ["r/char.parquet"], ["r/diag.json"]),
            job("report", ["r/char.parquet", "r/diag.json", "r/fig.png"], ["r/report.html"]),
            job("figs", ["r/char.parquet"], ["r/fig.png"])]
    seconds = {"logs/ingest.tsv": 1.0, "logs/char.tsv": 2.0, "logs/diag.tsv": 3.0, "logs/figs.tsv": 4.0,
               "logs/report.tsv": 0.5}
    # ingest -> char -> figs -> report = 7.5 s beats ingest -> char -> diag -> report = 6.5 s
    assert [j.rule for j in jobtimes.critical_path(jobs, seconds)] == ["ingest", "char", "figs", "report"]
    seconds["logs/diag.tsv"] = 5.0
    assert [j.rule for j in jobtimes.critical_path(jobs, seconds)] == ["ingest", "char", "diag", "report"]
