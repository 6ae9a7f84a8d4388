"""Stage compare (isokinetic.stages.compare): a comparison's files, read from the campaigns' results folders.
The method is tested in tests/measurement/test_comparison.py, whose synthetic campaigns this uses."""

from __future__ import annotations

import json

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.io import write_parquet
from isokinetic.measurement.comparison import CompareSpec
from isokinetic.measurement.model_fit import fit_models
from isokinetic.stages.compare import write_compare
from measurement.test_comparison import SPEEDS_A, SPEEDS_B, characteristic


def test_write_compare_writes_table_csv_summary_and_figures(tmp_path):
    for c, speeds, seed in (("a", SPEEDS_A, 1), ("b", SPEEDS_B, 2)):
        char = characteristic(c, speeds, seed=seed)
        write_parquet(char, tmp_path / c / "characteristic.parquet")
        write_parquet(fit_models(char)[0], tmp_path / c / "models" / "models.parquet")
    spec = CompareSpec("ab", ("a", "b"), description="two plans")
    paths = write_compare(spec, {"a": tmp_path / "a", "b": tmp_path / "b"}, tmp_path / "compare" / "ab")
    names = sorted(p.name for p in paths)
    assert names == ["compare.csv", "compare.json", "compare.parquet", "fig18_compare_overlay.png",
                     "fig19_compare_difference.png"]
    table = pd.read_parquet(tmp_path / "compare" / "ab" / "compare.parquet")
    assert tables.passes(table, tables.COMPARE)
    csv = (tmp_path / "compare" / "ab" / "compare.csv").read_text(encoding="utf-8").split("\n")
    units = dict(zip(csv[0].split(","), csv[1].split(","), strict=True))
    assert units["velocity_m_s"] == "m/s" and units["difference_se_N"] == "N" and units["z"] == ""
    summary = json.loads((tmp_path / "compare" / "ab" / "compare.json").read_text(encoding="utf-8"))
    assert summary["reference"] == "a" and summary["description"] == "two plans"
    assert summary["pairs"][0]["n_rows"] == len(table)
