"""Input checks: NaN/inf, time order, record length, sample rate, sample count."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from conftest import CAMPAIGN, assert_quarantine, set_cell
from isokinetic import tables
from isokinetic.campaign import timeseries_relpath, write_ingested
from isokinetic.ingest import ingest_campaign
from isokinetic.plan import CasePlan, triangle_displacement
from isokinetic.validate import Problem, quarantine_frame, quarantine_rows, validate_campaign, write_validated


def _swap_rows(column, a, b):
    def edit(t):
        t.loc[[a, b], column] = t.loc[[b, a], column].to_numpy()
        return t
    return edit


def _scale_time(factor):
    def edit(t):
        t["time_s"] = (t["time_s"].astype(float) * factor).map("{:.10g}".format)
        return t
    return edit


@pytest.mark.parametrize("case, edit, column, row, message", [
    ("T02", set_cell(23, "force_kN", ""), "force_kN", 23, "missing value (NaN)"),
    ("T02", set_cell(23, "force_kN", "NaN"), "force_kN", 23, "missing value (NaN)"),
    ("T03", set_cell(40, "force_inv_kN", "-inf"), "force_inv_kN", 40, "non-finite value inf"),  # inverted
    ("T01", _swap_rows("time_s", 50, 51), "time_s", 51, "time 1.0 s is not above the previous row's 1.02 s"),
    ("H01", set_cell(9, "time_s", "0.04"), "time_s", 9, "time 0.04 s is not above the previous row's 0.04 s"),
], ids=["nan-empty-cell", "nan-literal", "inf", "time-swapped", "time-repeated"])
def test_schema_failures_name_the_first_bad_row(raw_campaign, case, edit, column, row, message):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    # campaign.write_ingested only takes schema-valid series, so ingest quarantines these.
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, case, "ingest", column, row)])
    assert quarantine["reason"].tolist() == [f"campaign demo, case {case}, column {column!r}, row {row}: {message}"]


def test_validate_rechecks_the_schema_of_ingested_series(raw_campaign):
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    path = raw_campaign.root / timeseries_relpath("T02")
    df = pd.read_parquet(path)
    df.loc[23:30, "force_N"] = math.nan
    df.to_parquet(path, index=False)            # written by something that did not check it
    cases, quarantine = write_validated(raw_campaign.root)
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "validate", "force_N", 23)])


@pytest.mark.parametrize("keep", [300, 399])
def test_record_shorter_than_the_plan(raw_campaign, keep):
    raw_campaign.edit_table("T02", lambda t: t.iloc[:keep])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "validate", "time_s", None)])
    assert f"record lasts {(keep - 1) / 100:.6g} s, the triangle plan needs 4 s" in quarantine["reason"].iloc[0]


def test_sine_needs_one_period(raw_campaign):
    raw_campaign.edit_table("H01", lambda t: t.iloc[:100])    # 0.5 s < 1/1.75 Hz
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "H01", "validate", "time_s", None)])


def test_sample_rate_far_from_the_manifest(raw_campaign):
    raw_campaign.edit_table("T01", _scale_time(1.25))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "validate", "time_s", None)])
    assert quarantine["reason"].iloc[0] == ("campaign demo, case T01, column 'time_s': median sample interval "
                                           "0.025 s is +25.0% off 1/sample_rate_Hz = 0.02 s (tolerance 5.0%)")
    cases, quarantine = write_validated(raw_campaign.root, sample_rate_tolerance=0.3)
    assert quarantine.empty and (cases["status"] == "ok").all()


def test_too_few_samples(raw_campaign):
    raw_campaign.edit_table("F01", lambda t: t.iloc[:5])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "F01", "validate", "time_s", None)])
    assert quarantine["reason"].iloc[0].endswith("only 5 samples, at least 10 needed")


def test_ingest_and_validation_rows_together(raw_campaign):
    raw_campaign.edit_table("T01", set_cell(17, "force_kN", "abc"))
    raw_campaign.edit_table("F01", lambda t: t.iloc[:5])
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "force_kN", 17),
                                                        (CAMPAIGN, "F01", "validate", "time_s", None)])
    on_disk = pd.read_parquet(raw_campaign.root / "quarantine.parquet")
    pd.testing.assert_frame_equal(on_disk, quarantine)
    tables.validate_table(pd.read_parquet(raw_campaign.root / "cases.parquet"), tables.CASES)


def _simulated_case(plan: CasePlan, n: int) -> tuple[dict, pd.DataFrame]:
    t = np.arange(n) / plan.sample_rate_Hz
    y = triangle_displacement(t, plan.amplitude_m, plan.period_s)
    df = pd.DataFrame({"row": np.arange(n), "time_s": t, "displacement_m": y, "force_N": np.gradient(y, t) * 1e6,
                       "command_m": y})
    row = {"campaign": "sim", **dataclasses.asdict(plan), "raw_file": "", "raw_sha256": "",
           "timeseries_file": timeseries_relpath(plan.case), "n_samples": n, "status": "ok"}
    return row, df


def test_simulated_campaign_is_validated_the_same_way(tmp_path):
    plans = [CasePlan("T01", "triangle", 100.0, amplitude_m=1e-4, period_s=2.0, duration_s=4.0),
             CasePlan("T02", "triangle", 100.0, amplitude_m=1e-4, period_s=2.0, duration_s=4.0)]
    built = [_simulated_case(plans[0], 400), _simulated_case(plans[1], 250)]   # T02 cut short
    meta = {"format_version": 1, "campaign": "sim", "source": "simulation", "description": None,
            "temperature_C": 40.0, "damper": None, "manifest_file": "", "manifest_sha256": "", "metadata": {}}
    earlier = quarantine_rows("sim", "T00", "ingest", [Problem("file", "missing", kind="key")])
    write_ingested(tmp_path / "ingest", meta, pd.DataFrame([row for row, _ in built]), quarantine_frame(earlier),
                   {p.case: df for p, (_, df) in zip(plans, built)})
    cases, quarantine = validate_campaign(tmp_path)
    assert cases.set_index("case")["status"].to_dict() == {"T01": "ok", "T02": "quarantined"}
    assert list(zip(quarantine["case"], quarantine["stage"], quarantine["column"])) == [
        ("T00", "ingest", "file"), ("T02", "validate", "time_s")]
    tables.validate_table(quarantine, tables.QUARANTINE)
