"""Rule design_summary (stages.design_summary): the campaigns' plan checks stacked in input order."""

from __future__ import annotations

import math

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.io import write_parquet
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.stages.design import plan_check
from isokinetic.stages.design_summary import design_summary, write_design_summary


def _check(campaign: str, *amplitudes_m: float) -> pd.DataFrame:
    cases = [CasePlan(case=f"T{i:02d}", waveform="triangle", sample_rate_Hz=50.0, amplitude_m=y, period_s=80.0,
                      phase_rad=-math.pi / 2, duration_s=160.0) for i, y in enumerate(amplitudes_m, start=1)]
    return plan_check(campaign, cases, TABLE_1, phi=0.999, max_amplitude_m=10e-3, min_amplitude_m=0.1e-3,
                      start_fraction=0.45)


def test_summary_stacks_the_campaigns_in_input_order(tmp_path):
    paths = [write_parquet(_check("b", 2e-3, 12e-3), tmp_path / "b.parquet"),
             write_parquet(_check("a", 2e-3), tmp_path / "a.parquet")]
    summary = write_design_summary(paths, tmp_path / "out" / "plan_check.parquet")
    assert list(summary["campaign"]) == ["b", "b", "a"] and int(summary["flagged"].sum()) == 1
    back = tables.validate_table(pd.read_parquet(tmp_path / "out" / "plan_check.parquet"), tables.PLAN_CHECK)
    pd.testing.assert_frame_equal(back, summary)


def test_summary_of_no_campaign_is_an_empty_plan_check():
    summary = design_summary([])
    assert summary.empty and list(summary.columns) == list(tables.empty(tables.PLAN_CHECK).columns)
