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
    (_set(-5e6, "damper", "charge_pressure_Pa"), "damper.charge_pressure_Pa", "positive number"),
    (_set(None, "sample_rate_Hz"), "sample_rate_Hz", "missing"),
    (_set("wave", "cases", 0, "waveform"), "cases.T01.waveform", "must be one of"),
    (_set("../T01", "cases", 0, "id"), "cases[0].id", "must be a string matching"),
    # a file name with a path refuses the whole manifest (hostile input; it used to quarantine the case)
    (_set("../T01.csv", "cases", 0, "file"), "cases.T01.file",
     "must be a bare file name inside the campaign folder, got '../T01.csv'"),
    (_set("sub/../T01.csv", "cases", 0, "file"), "cases.T01.file",
     "must be a bare file name inside the campaign folder, got 'sub/../T01.csv'"),
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
    ("columns", {"force": {"unit": "ton"}},
     ("column", "force_kN", "unit 'ton' is a mass unit (ton), not a force unit; nearest known force units: newton, "
                            "pond, ton_force")),
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
    raw_campaign.edit_manifest(_set("ton", "columns", "force", "unit"))
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


def test_the_damper_may_declare_its_charge_pressure(raw_campaign):
    assert load_manifest(MANIFEST_FILE).damper.charge_pressure_Pa is None
    raw_campaign.edit_manifest(_set(1.3e7, "damper", "charge_pressure_Pa"))
    m = load_manifest(MANIFEST_FILE)
    assert m.damper.charge_pressure_Pa == 1.3e7
    assert "charge_pressure_Pa" not in m.metadata.get("damper", {})   # a spec key (1.3), not carried as metadata


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


def test_a_force_calibration_is_optional_and_read_as_declared(raw_campaign):
    assert load_manifest(MANIFEST_FILE).force_calibration is None
    raw_campaign.edit_manifest(_set({"gain": 1.012, "uncertainty_rel": "1e-3"}, "columns", "force", "calibration"))
    m = load_manifest(MANIFEST_FILE)
    assert m.force_calibration == {"gain": 1.012, "uncertainty_rel": 0.001}   # 1e-3: a string to PyYAML
    assert m.columns["force"].unit == "kN"   # the column itself unchanged


def test_a_force_calibrations_gain_defaults_to_one(raw_campaign):
    raw_campaign.edit_manifest(_set({"uncertainty_rel": 0.002}, "columns", "force", "calibration"))
    assert load_manifest(MANIFEST_FILE).force_calibration == {"gain": 1.0, "uncertainty_rel": 0.002}


def _case_force_calibration(m):
    m["cases"][0]["columns"] = {"force": {"calibration": {"gain": 1.01, "uncertainty_rel": 0.001}}}


@pytest.mark.parametrize("edit, key, words", [
    (_set({"gain": 0.85, "uncertainty_rel": 0.001}, "columns", "force", "calibration"),
     "columns.force.calibration.gain", "within [0.9, 1.1]"),
    (_set({"gain": 1.15, "uncertainty_rel": 0.001}, "columns", "force", "calibration"),
     "columns.force.calibration.gain", "within [0.9, 1.1]"),
    (_set({"gain": "heavy", "uncertainty_rel": 0.001}, "columns", "force", "calibration"),
     "columns.force.calibration.gain", "got 'heavy'"),
    (_set({"gain": True, "uncertainty_rel": 0.001}, "columns", "force", "calibration"),
     "columns.force.calibration.gain", "got True"),
    (_set({"gain": 1.01, "uncertainty_rel": 0.0}, "columns", "force", "calibration"),
     "columns.force.calibration.uncertainty_rel", "> 0 and <= 0.02"),
    (_set({"gain": 1.01, "uncertainty_rel": -0.001}, "columns", "force", "calibration"),
     "columns.force.calibration.uncertainty_rel", "> 0 and <= 0.02"),
    (_set({"gain": 1.01, "uncertainty_rel": 0.03}, "columns", "force", "calibration"),
     "columns.force.calibration.uncertainty_rel", "> 0 and <= 0.02"),
    (_set({"gain": 1.01, "uncertainty_rel": float("nan")}, "columns", "force", "calibration"),
     "columns.force.calibration.uncertainty_rel", "got nan"),
    (_set({"gain": 1.01}, "columns", "force", "calibration"), "columns.force.calibration.uncertainty_rel",
     "missing"),
    (_set({"gain": 1.01, "uncertainty_rel": 0.001, "sigma": 1}, "columns", "force", "calibration"),
     "columns.force.calibration.sigma", "not a key of the calibration"),
    (_set(1.01, "columns", "force", "calibration"), "columns.force.calibration", "expected a mapping"),
    (_set({"gain": 1.01, "uncertainty_rel": 0.001}, "columns", "command", "calibration"),
     "columns.command.calibration", "only the force and displacement columns"),
    (_case_force_calibration, "cases.T01.columns.force.calibration", "declared once on the campaign's force column"),
])
def test_a_bad_force_calibration_fails_the_campaign_naming_the_key(raw_campaign, edit, key, words):
    raw_campaign.edit_manifest(edit)
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert str(info.value).startswith(f"{MANIFEST_FILE}: key {key!r}: ")   # the file names the campaign's folder
    assert words in str(info.value)


def test_an_lvdt_calibration_is_optional_and_read_as_declared(raw_campaign):
    assert load_manifest(MANIFEST_FILE).displacement_calibration is None
    raw_campaign.edit_manifest(_set({"scale": 1.012, "uncertainty_rel": "1e-3"}, "columns", "displacement",
                                    "calibration"))
    m = load_manifest(MANIFEST_FILE)
    assert m.displacement_calibration == {"scale": 1.012, "uncertainty_rel": 0.001}
    assert m.force_calibration is None and m.columns["displacement"].unit == "mm"   # the column itself unchanged


def test_an_lvdt_calibrations_scale_defaults_to_one(raw_campaign):
    raw_campaign.edit_manifest(_set({"uncertainty_rel": 0.002}, "columns", "displacement", "calibration"))
    assert load_manifest(MANIFEST_FILE).displacement_calibration == {"scale": 1.0, "uncertainty_rel": 0.002}


def test_both_calibrations_are_read_side_by_side(raw_campaign):
    raw_campaign.edit_manifest(_set({"scale": 0.995, "uncertainty_rel": 0.0005}, "columns", "displacement",
                                    "calibration"))
    raw_campaign.edit_manifest(_set({"gain": 1.004, "uncertainty_rel": 0.001}, "columns", "force", "calibration"))
    m = load_manifest(MANIFEST_FILE)
    assert (m.displacement_calibration, m.force_calibration) == ({"scale": 0.995, "uncertainty_rel": 0.0005},
                                                                  {"gain": 1.004, "uncertainty_rel": 0.001})


def _case_lvdt_calibration(m):
    m["cases"][0]["columns"] = {"displacement": {"calibration": {"scale": 1.01, "uncertainty_rel": 0.001}}}


def _lvdt(calibration):
    return _set(calibration, "columns", "displacement", "calibration")


@pytest.mark.parametrize("edit, key, words", [
    (_lvdt({"scale": 0.85, "uncertainty_rel": 0.001}), "columns.displacement.calibration.scale", "within [0.9, 1.1]"),
    (_lvdt({"scale": 1.15, "uncertainty_rel": 0.001}), "columns.displacement.calibration.scale", "within [0.9, 1.1]"),
    (_lvdt({"scale": float("inf"), "uncertainty_rel": 0.001}), "columns.displacement.calibration.scale", "got inf"),
    (_lvdt({"scale": "long", "uncertainty_rel": 0.001}), "columns.displacement.calibration.scale", "got 'long'"),
    (_lvdt({"scale": True, "uncertainty_rel": 0.001}), "columns.displacement.calibration.scale", "got True"),
    (_lvdt({"scale": 1.01, "uncertainty_rel": 0.0}), "columns.displacement.calibration.uncertainty_rel",
     "> 0 and <= 0.02"),
    (_lvdt({"scale": 1.01, "uncertainty_rel": 0.021}), "columns.displacement.calibration.uncertainty_rel",
     "> 0 and <= 0.02"),
    (_lvdt({"scale": 1.01, "uncertainty_rel": "tight"}), "columns.displacement.calibration.uncertainty_rel",
     "got 'tight'"),
    (_lvdt({"scale": 1.01}), "columns.displacement.calibration.uncertainty_rel", "missing"),
    (_lvdt({"gain": 1.01, "uncertainty_rel": 0.001}), "columns.displacement.calibration.gain",
     "not a key of the calibration (keys: scale, uncertainty_rel)"),
    (_lvdt([1.01, 0.001]), "columns.displacement.calibration", "expected a mapping {scale, uncertainty_rel}"),
    (_case_lvdt_calibration, "cases.T01.columns.displacement.calibration",
     "declared once on the campaign's displacement column"),
])
def test_a_bad_lvdt_calibration_fails_the_campaign_naming_the_key(raw_campaign, edit, key, words):
    raw_campaign.edit_manifest(edit)
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert str(info.value).startswith(f"{MANIFEST_FILE}: key {key!r}: ")   # the file names the campaign's folder
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
    ({"delimiter": "\t"}, CsvDialect(delimiter="\t", decimal=".")),
    # '\t' in single quotes: backslash and t
    ({"delimiter": "\\t", "decimal": ","}, CsvDialect(delimiter="\t", decimal=",")),
    ({"delimiter": "tab"}, CsvDialect(delimiter="\t", decimal=".")),
    ({"delimiter": "|", "decimal": ","}, CsvDialect(delimiter="|", decimal=",")),
    ({"delimiter": ";"}, CsvDialect(delimiter=";", decimal=".")),
    ({}, CsvDialect(delimiter=",", decimal=".")),
    ({"delimiter": ";", "decimal": ",", "thousands": "."},                                  # 1.5
     CsvDialect(delimiter=";", decimal=",", thousands=".")),
    ({"thousands": "space"}, CsvDialect(thousands=" ")),
    ({"timezone": "Europe/Berlin"}, CsvDialect(timezone="Europe/Berlin")),
])
def test_csv_block_keys_default_to_the_format(raw_campaign, block, dialect):
    raw_campaign.edit_manifest(_set(block, "csv"))
    assert load_manifest(MANIFEST_FILE).csv == dialect


@pytest.mark.parametrize("block, key, words", [
    (";", "csv", "expected a mapping with keys format, delimiter, decimal, encoding, units_row, header, sheet, "
                 "thousands, timezone, got ';'"),
    ({"delimiter": ";", "thousand": "."}, "csv.thousand",
     "unknown key: the csv block declares only format, delimiter"),
    ({"delimiter": ";", "decimal": ",", "thousands": ","}, "csv.thousands", "',' is the decimal mark"),
    ({"thousands": ","}, "csv.thousands", "',' is the delimiter"),
    ({"thousands": "_"}, "csv.thousands", "must be one of '.', ',', space or \"'\", got '_'"),
    ({"timezone": "Europe/Atlantis"}, "csv.timezone", "unknown time zone 'Europe/Atlantis'"),
    ({"delimiter": ":"}, "csv.delimiter", "must be one of ',', ';', \"\\t\" (tab), '|' or whitespace, got ':'"),
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


# --- format 1.2 additions ------------------------------------------------------------------------

@pytest.mark.parametrize("block, dialect", [
    ({"format": "mts793"}, CsvDialect(delimiter="\t", units_row=True, format="mts793")),
    ({"format": "mts793", "delimiter": "whitespace", "encoding": "cp1252"},
     CsvDialect(delimiter="whitespace", encoding="cp1252", units_row=True, format="mts793")),
    ({"delimiter": "whitespace", "units_row": True}, CsvDialect(delimiter="whitespace", units_row=True)),
    ({"encoding": "latin-1", "delimiter": ";", "decimal": ","},
     CsvDialect(delimiter=";", decimal=",", encoding="latin-1")),
])
def test_csv_block_format_encoding_and_units_row(raw_campaign, block, dialect):
    raw_campaign.edit_manifest(_set(block, "csv"))
    assert load_manifest(MANIFEST_FILE).csv == dialect


@pytest.mark.parametrize("block, key, words", [
    ({"encoding": "klingon"}, "csv.encoding", "unknown encoding 'klingon'"),
    ({"encoding": "base64"}, "csv.encoding", "'base64' is not a text encoding"),
    ({"encoding": 1252}, "csv.encoding", "must be a text encoding name"),
    ({"units_row": "yes"}, "csv.units_row", "must be true or false, got 'yes'"),
    ({"format": "xls"}, "csv.format", "must be one of delimited, mts793, xlsx, got 'xls'"),
    ({"format": "mts793", "delimiter": ";"}, "csv.delimiter", "an mts793 export is tab or whitespace separated"),
    ({"format": "mts793", "units_row": False}, "csv.units_row", "an mts793 export always has a units row"),
    ({"encodng": "cp1252"}, "csv.encodng", "did you mean 'encoding'?"),
])
def test_bad_csv_block_1_2_keys_fail_the_campaign(raw_campaign, block, key, words):
    raw_campaign.edit_manifest(_set(block, "csv"))
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    assert info.value.key == key and words in str(info.value)


def test_vendor_units_are_accepted_and_sec_means_seconds(raw_campaign):
    def edit(m):
        m["columns"]["time"]["unit"] = "Sec"
        m["columns"]["displacement"]["unit"] = "in"
        m["columns"]["force"]["unit"] = "lbf"
        m["cases"][1]["columns"] = {"force": {"unit": "kgf"}}
    raw_campaign.edit_manifest(edit)
    m = load_manifest(MANIFEST_FILE)
    assert all(not c.problems for c in m.cases)
    assert (m.columns["time"].unit, m.columns["displacement"].unit, m.columns["force"].unit) == ("s", "in", "lbf")
    assert m.cases[1].columns["force"].unit == "kgf"


@pytest.mark.parametrize("keys, time_range, rows", [
    ({"time_range_s": [40.0, 52.5]}, (40.0, 52.5), None),
    ({"time_range_s": ["0", 7.5]}, (0.0, 7.5), None),
    ({"rows": [4000, 5200]}, None, (4000, 5200)),
])
def test_case_slice_keys(raw_campaign, keys, time_range, rows):
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(keys))
    t01 = load_manifest(MANIFEST_FILE).cases[0]
    assert (t01.time_range_s, t01.rows, t01.problems) == (time_range, rows, ())


@pytest.mark.parametrize("keys, key, words", [
    ({"time_range_s": [5.0, 5.0]}, "time_range_s", "must be [start, end) in seconds"),
    ({"time_range_s": [-1.0, 5.0]}, "time_range_s", "0 <= start < end"),
    ({"time_range_s": [0.0, 2e6]}, "time_range_s", "end <= 1e+06"),
    ({"time_range_s": 5.0}, "time_range_s", "got 5.0"),
    ({"rows": [10, 5]}, "rows", "must be [first, stop) of 0-based data rows"),
    ({"rows": [0.5, 5]}, "rows", "integers"),
    ({"rows": [0, 10**12]}, "rows", "stop <= 1000000000"),
    ({"rows": [0, 5], "time_range_s": [0.0, 1.0]}, "rows", "give time_range_s or rows, not both"),
])
def test_bad_case_slice_is_the_case_problem(raw_campaign, keys, key, words):
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(keys))
    m = load_manifest(MANIFEST_FILE)
    [(kind, column, message)] = _problems(m, "T01")
    assert (kind, column) == ("key", key) and words in message
    assert all(not c.problems for c in m.cases[1:])


def test_standstill_case_has_no_motion_keys(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["cases"].extend([
        {"id": "Z01", "waveform": "standstill", "file": "F01.csv", "time_range_s": [0.0, 2.0]},
        {"id": "Z02", "waveform": "standstill", "file": "F01.csv", "amplitude_mm": 1.0}]))
    m = load_manifest(MANIFEST_FILE)
    z01 = m.cases[-2]
    assert z01.waveform == "standstill" and z01.problems == () and math.isnan(z01.plan.amplitude_m)
    assert _problems(m, "Z02") == [("key", "amplitude_mm", "a standstill case has no motion: leave the key out")]


def test_case_gas_force_overrides_the_campaign(raw_campaign):
    def edit(m):
        m["gas_force_N"] = 100.0
        m["cases"][1]["gas_force_N"] = 150.0
        m["cases"][2]["gas_force_N"] = "lots"
    raw_campaign.edit_manifest(edit)
    m = load_manifest(MANIFEST_FILE)
    assert [c.gas_force_N for c in m.cases[:2]] == [100.0, 150.0]
    assert (m.cases[0].case_gas_force_N, m.cases[1].case_gas_force_N) == (None, 150.0)
    assert _problems(m, "T03") == [("key", "gas_force_N", "must be a number (N), got 'lots'")]
    assert "gas_force_N" not in m.metadata.get("cases", {}).get("T02", {})


def test_keys_far_from_any_known_key_give_no_warning(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(rig_operator="A. Smith", frequency_hz=1.0))
    m = load_manifest(MANIFEST_FILE)
    assert len(m.warnings) == 1 and "'cases.T01.frequency_hz'" in m.warnings[0] and "'frequency_Hz'" in m.warnings[0]


def test_full_scale_is_read_per_channel_and_merged_into_a_case(raw_campaign):
    """Issue 20 (1.2): columns.<channel>.full_scale, in the column's unit; a case's own columns may set it."""
    raw_campaign.edit_manifest(lambda m: (m["columns"]["force"].update(full_scale=10),
                                          raw_campaign.case_entry(m, "T02").update(
                                              columns={"displacement": {"full_scale": "2.5"}})))
    manifest = load_manifest(raw_campaign.raw_dir / "campaign.yaml")
    cases = {c.id: c for c in manifest.cases}
    assert manifest.columns["force"].full_scale == 10.0 and manifest.columns["time"].full_scale is None
    assert cases["T02"].columns["displacement"].full_scale == 2.5 and cases["T02"].columns["force"].full_scale == 10.0
    assert cases["T01"].columns["displacement"].full_scale is None


@pytest.mark.parametrize("channel, value, words", [("force", 0, "must be a positive number"),
                                                   ("force", "ten", "must be a positive number"),
                                                   ("time", 10, "applies to displacement, force, command only")])
def test_bad_full_scale_fails_the_campaign(raw_campaign, channel, value, words):
    raw_campaign.edit_manifest(lambda m: m["columns"][channel].update(full_scale=value))
    with pytest.raises(ManifestError) as info:
        load_manifest(raw_campaign.raw_dir / "campaign.yaml")
    assert info.value.key == f"columns.{channel}.full_scale" and words in info.value.problem
