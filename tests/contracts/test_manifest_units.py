"""campaign.yaml format 1.4: units through isokinetic.units, scaled channels, positional columns of a headerless
file, the csv block's header and sheet."""

from __future__ import annotations

import pytest

from conftest import CAMPAIGN
from isokinetic.contracts.manifest import ManifestError, load_manifest, si_conversion

MANIFEST_FILE = f"data/raw/{CAMPAIGN}/campaign.yaml"


def _columns(**channels):
    return lambda m: m["columns"].update(channels)


def _problems(case: str = "T01"):
    m = load_manifest(MANIFEST_FILE)
    return [(p.kind, p.column, p.message) for c in m.cases if c.id == case for p in c.problems]


@pytest.mark.parametrize("channel, unit, symbol", [("force", "kip", "kip"), ("displacement", "cm", "cm"),
                                                   ("force", "daN", "daN"), ("time", "Sec", "s"),
                                                   ("displacement", "µm", "um"), ("force", "lbs", "lbf")])
def test_a_unit_pint_reads_is_accepted_in_its_canonical_spelling(raw_campaign, channel, unit, symbol):
    raw_campaign.edit_manifest(lambda m: m["columns"][channel].update(unit=unit))
    m = load_manifest(MANIFEST_FILE)
    assert not _problems() and m.cases[0].columns[channel].unit == symbol


def test_the_units_of_format_1_3_are_still_accepted(raw_campaign):
    for channel, units in {"time": ["s", "ms", "Sec", "datetime"], "displacement": ["m", "mm", "um", "in"],
                           "force": ["N", "kN", "lbf", "kgf"]}.items():
        for unit in units:
            raw_campaign.edit_manifest(lambda m, channel=channel, unit=unit: m["columns"][channel].update(unit=unit))
            assert not _problems(), (channel, unit)


@pytest.mark.parametrize("unit", ["hms", "excel_serial"])
def test_clock_times_and_excel_serial_dates_are_time_units_of_1_5(raw_campaign, unit):
    raw_campaign.edit_manifest(lambda m: m["columns"]["time"].update(unit=unit))
    assert not _problems() and load_manifest(MANIFEST_FILE).cases[0].columns["time"].unit == unit
    raw_campaign.edit_manifest(lambda m: m["columns"]["time"].update(scale=2.0))
    with pytest.raises(ManifestError, match=f"key 'columns.time.scale': {unit} time is not scaled"):
        load_manifest(MANIFEST_FILE)


def test_a_voltage_declared_for_a_force_is_the_case_problem_naming_the_column(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["columns"]["force"].update(unit="V"))
    assert _problems() == [("column", "force_kN", "unit 'V' is a voltage unit (V), not a force unit; no known "
                                                  "force unit is close")]


def test_scale_and_offset_compose_with_the_unit(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["columns"]["force"].update(unit="kN", scale=2.0, offset=0.5))
    column = load_manifest(MANIFEST_FILE).cases[0].columns["force"]
    assert si_conversion("force", column) == (2000.0, 500.0)


@pytest.mark.parametrize("key, value, words", [("scale", 0, "must be a finite, non-zero number"),
                                               ("scale", "x", "must be a finite, non-zero number"),
                                               ("offset", "nan", "must be a finite number")])
def test_a_bad_scale_or_offset_refuses_the_campaign_naming_the_key(raw_campaign, key, value, words):
    raw_campaign.edit_manifest(lambda m: m["columns"]["force"].update({key: value}))
    with pytest.raises(ManifestError, match=f"key 'columns.force.{key}': {words}"):
        load_manifest(MANIFEST_FILE)


def test_a_headerless_file_names_its_columns_by_position(raw_campaign):
    raw_campaign.edit_manifest(lambda m: (m.update(csv={"header": "none"}), m["columns"].update(
        time={"name": 1, "unit": "s"}, displacement={"name": "col2", "unit": "mm"}, force={"name": 4, "unit": "N"},
        command=None), [c.pop("columns", None) for c in m["cases"]]))
    m = load_manifest(MANIFEST_FILE)
    assert m.csv.header == "none"
    assert [m.columns[ch].name for ch in ("time", "displacement", "force")] == ["col1", "col2", "col4"]


def test_a_position_in_a_file_with_a_header_refuses_the_campaign(raw_campaign):
    raw_campaign.edit_manifest(_columns(force={"name": 4, "unit": "N"}))
    with pytest.raises(ManifestError, match="a position \\(4\\) names a column of a headerless file only"):
        load_manifest(MANIFEST_FILE)


def test_a_header_name_in_a_headerless_file_refuses_the_campaign(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m.update(csv={"header": "none"}))
    with pytest.raises(ManifestError, match="a headerless file's columns are named by 1-based position"):
        load_manifest(MANIFEST_FILE)


@pytest.mark.parametrize("block, key, words", [
    ({"header": "maybe"}, "csv.header", "must be row or none"),
    ({"header": "none", "units_row": True}, "csv.header", "a headerless file has no units row"),
    ({"sheet": "Sheet1"}, "csv.sheet", "names a worksheet of an xlsx file"),
    ({"format": "xlsx", "sheet": 3}, "csv.sheet", "must be a worksheet's name"),
    ({"format": "xlsx", "delimiter": ";"}, "csv.delimiter", "an xlsx workbook has no delimiter"),
])
def test_bad_csv_block_1_4_keys_fail_the_campaign(raw_campaign, block, key, words):
    raw_campaign.edit_manifest(lambda m: m.update(csv=block))
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert str(info.value).startswith(f"{MANIFEST_FILE}: key {key!r}: ") and words in str(info.value)


def test_an_xlsx_block_names_its_sheet(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m.update(csv={"format": "xlsx", "sheet": "Run 1"}))
    fmt = load_manifest(MANIFEST_FILE).csv
    assert (fmt.format, fmt.sheet) == ("xlsx", "Run 1")
