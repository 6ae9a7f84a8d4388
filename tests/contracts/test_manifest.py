"""campaign.yaml: broken manifests fail the campaign, case problems stay with their case."""

from __future__ import annotations

import math

import pytest

from conftest import CAMPAIGN, CASE_IDS
from isokinetic.contracts.manifest import CsvDialect, ManifestError, load_manifest

MANIFEST_FILE = f"data/raw/{CAMPAIGN}/campaign.yaml"


def test_good_manifest(raw_campaign):
    m = load_manifest(MANIFEST_FILE)
    assert (m.campaign, m.source, m.temperature_C, m.sample_rate_Hz) == (CAMPAIGN, "rig", 40.0, 50.0)
    assert [c.id for c in m.cases] == CASE_IDS
    assert all(not c.problems for c in m.cases)
    assert m.damper.piston_area_m2 == 4.0e-3
    assert len(m.sha256) == 64
    t01, t02, t03, h01, f01 = m.cases
    assert (t01.plan.amplitude_m, t01.plan.period_s, t01.plan.phase_rad) == (0.3e-3, 4.0, -math.pi / 2)
    assert t02.plan.sample_rate_Hz == 100.0 and t01.plan.sample_rate_Hz == 50.0
    assert math.isnan(t01.plan.duration_s)
    assert t03.columns["force"].name == "force_inv_kN" and t03.columns["force"].invert
    assert t03.columns["force"].unit == "kN"            # inherited field by field
    assert (h01.plan.frequency_Hz, h01.plan.phase_rad) == (1.75, 0.0)
    assert f01.waveform == "free" and math.isnan(f01.plan.amplitude_m)
    assert m.metadata == {"operator": "fixture", "cases": {"T03": {"note": "load cell mounted upside down"}}}


def _parent(m: dict, path: tuple):
    """The container of the last key of ``path`` inside a manifest dict."""
    for key in path[:-1]:
        m = m[key]
    return m


def _drop(*path):
    return lambda m: _parent(m, path).pop(path[-1])


def _set(value, *path):
    return lambda m: _parent(m, path).__setitem__(path[-1], value)


def _duplicate_case(m):
    m["cases"].append(dict(m["cases"][0]))


@pytest.mark.parametrize("edit, key, words", [
    (_drop("format_version"), "format_version", "missing"),
    (_set(2, "format_version"), "format_version", "unknown version 2"),
    (_drop("campaign"), "campaign", "missing"),
    (_set("Demo!", "campaign"), "campaign", "must match"),
    (_set("other", "campaign"), "campaign", "differs from the folder name 'demo'"),
    (_drop("columns", "force", "name"), "columns.force.name", "missing"),
    (_drop("columns", "time"), "columns.time", "missing"),
    (_drop("columns", "displacement"), "columns.displacement", "missing"),
    (_drop("cases"), "cases", "missing"),
    (_set([], "cases"), "cases", "non-empty list"),
    (_duplicate_case, "cases[5].id", "duplicate case id 'T01'"),
    (_set("x", "damper", "viscosity_Pa_s"), "damper.viscosity_Pa_s", "positive number"),
    (_drop("damper", "orifice_area_m2"), "damper.orifice_area_m2", "missing"),
    (_set(None, "sample_rate_Hz"), "sample_rate_Hz", "missing"),
    (_set("wave", "cases", 0, "waveform"), "cases.T01.waveform", "must be one of"),
    (_set("../T01", "cases", 0, "id"), "cases[0].id", "must be a string matching"),
    # a file name with a path refuses the whole manifest (hostile input; it used to quarantine the case)
    (_set("../T01.csv", "cases", 0, "file"), "cases.T01.file",
     "must be a bare file name inside the campaign folder, got '../T01.csv'"),
    (_set("sub/T01.csv", "cases", 0, "file"), "cases.T01.file",
     "must be a bare file name inside the campaign folder, got 'sub/T01.csv'"),
])
def test_broken_manifest_names_file_and_key(raw_campaign, edit, key, words):
    raw_campaign.edit_manifest(edit)
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert str(info.value).startswith(f"{MANIFEST_FILE}: key {key!r}: ")
    assert words in str(info.value)
    assert info.value.key == key


@pytest.mark.parametrize("text, words", [
    ("format_version: 1\ncampaign: demo\ncases: [\n  {id: T01\n", "invalid YAML at line"),
    ("- just\n- a list\n", "expected a mapping at the top level, got list"),
    ("", "got an empty file"),
    ("a: !!python/object:os.system ls\n", "invalid YAML at line 1"),  # safe_load only
])
def test_unparseable_manifest(raw_campaign, text, words):
    (raw_campaign.raw_dir / "campaign.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(ManifestError, match=words) as info:
        load_manifest(MANIFEST_FILE)
    assert str(info.value).startswith(f"{MANIFEST_FILE}: ")


def test_syntax_error_gives_line_and_column(raw_campaign):
    (raw_campaign.raw_dir / "campaign.yaml").write_text("format_version: 1\ncampaign: [demo\n", encoding="utf-8")
    with pytest.raises(ManifestError, match=r"line 3, column 1"):
        load_manifest(MANIFEST_FILE)


def _problems(m, case):
    return [(p.kind, p.column, p.message) for c in m.cases if c.id == case for p in c.problems]


@pytest.mark.parametrize("field, value, expected", [
    ("period_s", None, ("key", "period_s", "missing")),
    ("period_s", -4.0, ("key", "period_s", "must be a positive number, got -4.0")),
    ("amplitude_mm", "big", ("key", "amplitude_mm", "must be a positive number, got 'big'")),
    ("phase_rad", "north", ("key", "phase_rad", "must be a number, got 'north'")),
    ("sample_rate_Hz", 0, ("key", "sample_rate_Hz", "must be a positive number, got 0")),
    ("file", None, ("key", "file", "missing")),
    ("columns", {"force": {"unit": "lbf"}},
     ("column", "force_kN", "unknown unit 'lbf' for force; expected one of N, kN")),
    ("columns", {"force": {"invert": "yes"}}, ("key", "columns.force.invert", "must be true or false, got 'yes'")),
    ("columns", {"force": None}, ("key", "columns.force", "a required channel cannot be removed")),
])
def test_case_problems_stay_with_the_case(raw_campaign, field, value, expected):
    def edit(m):
        entry = m["cases"][0]
        if value is None:
            entry.pop(field)
        else:
            entry[field] = value
    raw_campaign.edit_manifest(edit)
    m = load_manifest(MANIFEST_FILE)
    assert _problems(m, "T01") == [expected]
    assert all(not c.problems for c in m.cases if c.id != "T01")


def test_campaign_unit_problem_reaches_every_case_naming_its_column(raw_campaign):
    raw_campaign.edit_manifest(_set("lbf", "columns", "force", "unit"))
    m = load_manifest(MANIFEST_FILE)
    columns = {c.id: [p.column for p in c.problems] for c in m.cases}
    assert columns == {"T01": ["force_kN"], "T02": ["force_kN"], "T03": ["force_inv_kN"],
                       "H01": ["force_kN"], "F01": ["force_kN"]}


def test_no_damper_numeric_strings_and_command_removal(raw_campaign):
    def edit(m):
        del m["damper"]
        m["sample_rate_Hz"] = "1e2"                    # PyYAML reads 1e2 as a string
        m["cases"][4]["columns"] = {"command": None}   # the free case has no command channel
        m["columns"]["humidity"] = {"name": "rh", "unit": "%"}
    raw_campaign.edit_manifest(edit)
    m = load_manifest(MANIFEST_FILE)
    assert m.damper is None and m.sample_rate_Hz == 100.0
    assert "command" not in m.cases[4].columns and "command" in m.cases[0].columns
    assert m.metadata["columns"] == {"humidity": {"name": "rh", "unit": "%"}}


def test_gas_force_is_optional_and_reaches_every_case(raw_campaign):
    assert load_manifest(MANIFEST_FILE).gas_force_N is None
    raw_campaign.edit_manifest(_set(-25.5, "gas_force_N"))
    m = load_manifest(MANIFEST_FILE)
    assert m.gas_force_N == -25.5
    assert [c.gas_force_N for c in m.cases] == [-25.5] * len(CASE_IDS)
    assert "gas_force_N" not in m.metadata                # a spec key (1.1), not carried as metadata


@pytest.mark.parametrize("value, words", [
    ("heavy", "must be a number, got 'heavy'"),
    (True, "must be a number, got True"),
    (float("nan"), "must be a number, got nan"),
    (2.0e6, "above the bound 1e+06 N"),
    (-2.0e6, "above the bound 1e+06 N"),
])
def test_bad_gas_force_fails_the_campaign(raw_campaign, value, words):
    raw_campaign.edit_manifest(_set(value, "gas_force_N"))
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert info.value.key == "gas_force_N"
    assert words in str(info.value)


def test_csv_block_is_optional_and_reaches_every_case(raw_campaign):
    m = load_manifest(MANIFEST_FILE)
    assert m.csv is None and {c.csv for c in m.cases} == {None}
    raw_campaign.edit_manifest(_set({"delimiter": ";", "decimal": ","}, "csv"))
    m = load_manifest(MANIFEST_FILE)
    assert m.csv == CsvDialect(delimiter=";", decimal=",")
    assert [c.csv for c in m.cases] == [m.csv] * len(CASE_IDS)
    assert "csv" not in m.metadata                        # a spec key (1.1), not carried as metadata


@pytest.mark.parametrize("block, dialect", [
    ({"delimiter": "\t"}, CsvDialect("\t", ".")),
    ({"delimiter": "\\t", "decimal": ","}, CsvDialect("\t", ",")),   # '\t' in single quotes: backslash and t
    ({"delimiter": "tab"}, CsvDialect("\t", ".")),
    ({"delimiter": "|", "decimal": ","}, CsvDialect("|", ",")),
    ({"delimiter": ";"}, CsvDialect(";", ".")),
    ({}, CsvDialect(",", ".")),
])
def test_csv_block_keys_default_to_the_format(raw_campaign, block, dialect):
    raw_campaign.edit_manifest(_set(block, "csv"))
    assert load_manifest(MANIFEST_FILE).csv == dialect


@pytest.mark.parametrize("block, key, words", [
    (";", "csv", "expected a mapping with keys delimiter and decimal, got ';'"),
    ({"delimiter": ";", "thousands": "."}, "csv.thousands", "unknown key: the csv block declares only delimiter"),
    ({"delimiter": ":"}, "csv.delimiter", "must be one of ',', ';', \"\\t\" (tab) or '|', got ':'"),
    ({"delimiter": [";"]}, "csv.delimiter", "got [';']"),
    ({"delimiter": None}, "csv.delimiter", "got None"),
    ({"delimiter": ";", "decimal": ";"}, "csv.decimal", "must be '.' or ',', got ';'"),
    ({"decimal": ","}, "csv", "delimiter and decimal mark are both ','"),
    ({"delimiter": ",", "decimal": ","}, "csv", "delimiter and decimal mark are both ','"),
])
def test_bad_csv_block_fails_the_campaign(raw_campaign, block, key, words):
    raw_campaign.edit_manifest(_set(block, "csv"))
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert info.value.key == key
    assert str(info.value).startswith(f"{MANIFEST_FILE}: key {key!r}: ")    # the campaign's folder and the key
    assert words in str(info.value)
