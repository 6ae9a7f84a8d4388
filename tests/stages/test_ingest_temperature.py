"""Temperature at ingest (format 1.1): the temperature channel (C or K), a case's temperature_C, the
campaign's, and the viscosity law; bad temperatures are set aside naming case, column and row."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from conftest import CAMPAIGN, assert_quarantine
from isokinetic.contracts.campaign import viscosity_scales
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.manifest import ManifestError, load_manifest

LAW = {"kind": "walther", "points": [[40.0, 0.030], [100.0, 0.006]]}


def _with_temperature_column(values_of_row, name="oil_K", unit="K", cases=("T01", "T02")):
    """Edits adding a temperature column to some cases and declaring it campaign-wide."""
    def table_edit(table: pd.DataFrame) -> pd.DataFrame:
        table[name] = [values_of_row(i) for i in range(len(table))]
        return table

    def manifest_edit(m: dict) -> None:
        m["columns"]["temperature"] = {"name": name, "unit": unit}
        for entry in m["cases"]:
            if entry["id"] not in cases:
                entry.setdefault("columns", {})["temperature"] = None
    return table_edit, manifest_edit


def _read(campaign):
    ingested = CampaignFolder.at(campaign.root)
    return ingested.meta, ingested.ingested_cases().set_index("case"), ingested


def test_a_temperature_channel_in_kelvin_is_kept_in_celsius_and_summarised_per_case(raw_campaign):
    table_edit, manifest_edit = _with_temperature_column(lambda i: f"{313.15 + 0.01 * i:.2f}")
    for case in ("T01", "T02"):
        raw_campaign.edit_table(case, table_edit)
    raw_campaign.edit_manifest(manifest_edit)
    raw_campaign.run()
    meta, cases, ingested = _read(raw_campaign)
    series = ingested.timeseries("T01")
    assert series["temperature_C"].iloc[0] == pytest.approx(40.0, abs=1e-9)
    n = len(series)
    t01 = cases.loc["T01"]
    assert t01["temperature_source"] == "channel"
    assert t01["temperature_C"] == pytest.approx(40.0 + 0.01 * (n - 1) / 2, abs=1e-9)
    assert t01["temperature_span_C"] == pytest.approx(0.01 * (n - 1), abs=1e-9)
    # cases without the channel fall back to the campaign's temperature_C
    assert (cases.loc["T03", "temperature_source"], cases.loc["T03", "temperature_C"]) == ("campaign", 40.0)
    assert math.isnan(cases.loc["T03", "temperature_span_C"])
    assert "temperature_C" not in ingested.timeseries("T03")


def test_a_case_temperature_overrides_the_campaigns(raw_campaign):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T02").__setitem__("temperature_C", 55.5))
    raw_campaign.run()
    _meta, cases, _ = _read(raw_campaign)
    assert (cases.loc["T02", "temperature_source"], cases.loc["T02", "temperature_C"]) == ("case", 55.5)
    assert (cases.loc["T01", "temperature_source"], cases.loc["T01", "temperature_C"]) == ("campaign", 40.0)


def test_no_temperature_anywhere_leaves_it_unknown(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m.pop("temperature_C"))
    raw_campaign.run()
    _meta, cases, _ = _read(raw_campaign)
    assert cases["temperature_C"].isna().all() and (cases["temperature_source"] == "").all()


def test_a_temperature_sample_outside_the_plausible_range_sets_the_case_aside(raw_campaign):
    # a channel in K declared as C: 313 C is refused at its first row, naming the column
    table_edit, manifest_edit = _with_temperature_column(lambda i: "313.15", name="oil", unit="C", cases=("T01",))
    raw_campaign.edit_table("T01", table_edit)
    raw_campaign.edit_manifest(manifest_edit)
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "oil", 0)])
    assert "313.15 C" in quarantine["reason"].iloc[0] and "unit error" in quarantine["reason"].iloc[0]


def test_a_case_temperature_that_is_not_plausible_is_that_cases_problem(raw_campaign):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "T03").__setitem__("temperature_C", 313.15))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T03", "ingest", "temperature_C", None)])


def test_the_viscosity_law_is_recorded_and_gives_each_case_its_viscosity(raw_campaign):
    def edit(m):
        m["damper"]["viscosity_law"] = LAW
        raw_campaign.case_entry(m, "T02")["temperature_C"] = 100.0
    raw_campaign.edit_manifest(edit)
    raw_campaign.run()
    meta, cases, _ = _read(raw_campaign)
    assert meta.viscosity_law_block == LAW and "viscosity_law" not in meta.metadata.get("damper", {})
    scales = viscosity_scales(meta, cases.reset_index())
    assert scales["T02"] == pytest.approx(0.006 / 0.030, rel=1e-12)
    assert scales["T01"] == pytest.approx(1.0, rel=1e-12)   # 40 C, the law's first point


@pytest.mark.parametrize("edit, key, words", [
    (lambda m: m["damper"].__setitem__("viscosity_law", {"kind": "walther", "points": [[40, 0.03]]}),
     "damper.viscosity_law", "exactly two points"),
    (lambda m: m["damper"].__setitem__("viscosity_law", "ISO VG 32"), "damper.viscosity_law", "expected a mapping"),
    (lambda m: m.__setitem__("temperature_C", 313.15), "temperature_C", "outside"),
    (lambda m: m.__setitem__("temperature_C", "warm"), "temperature_C", "must be a number"),
])
def test_a_broken_temperature_key_refuses_the_campaign_naming_it(raw_campaign, edit, key, words):
    raw_campaign.edit_manifest(edit)
    with pytest.raises(ManifestError, match=words) as err:
        load_manifest(raw_campaign.raw_dir / "campaign.yaml")
    assert err.value.key == key
