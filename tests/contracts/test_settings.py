"""The method's settings as one record from the validated config (isokinetic.contracts.settings)."""

import copy
import dataclasses
import shutil
from pathlib import Path

import pytest
import yaml

from isokinetic.contracts.settings import (
    CONFIG_FILE,
    CONFIG_KEYS,
    DEFAULTS,
    RULE_SETTINGS,
    SCHEMA_FILE,
    Settings,
    flat_settings,
    load_settings,
    rule_settings,
    with_defaults,
)

ROOT = Path(__file__).resolve().parents[2]
#: Every config key a setting reads, with a changed value, and the flat setting it must reach.
CHANGES = [(("windows", "start_fraction"), 0.5, "start_fraction", 0.5),
           (("windows", "end_fraction"), 0.9, "end_fraction", 0.9),
           (("repeatability", "tolerance"), 0.08, "repeatability_tolerance", 0.08),
           (("validation", "sample_rate_tolerance"), 0.02, "sample_rate_tolerance", 0.02),
           (("validation", "max_missing_fraction"), 0.1, "max_missing_fraction", 0.1),
           (("validation", "max_gap_s"), 0.3, "max_gap_s", 0.3),
           (("ingest", "max_case_file_MB"), 64, "max_case_file_MB", 64.0),
           (("design", "convergence_fraction"), 0.99, "phi", 0.99),
           (("design", "max_amplitude_mm"), 20.0, "max_amplitude_m", 0.02),
           (("design", "min_amplitude_mm"), 0.5, "min_amplitude_m", 0.0005)]


def project(tmp_path: Path, config: dict) -> Path:
    (tmp_path / SCHEMA_FILE).parent.mkdir(parents=True)
    shutil.copy(ROOT / SCHEMA_FILE, tmp_path / SCHEMA_FILE)
    (tmp_path / CONFIG_FILE).parent.mkdir(parents=True)
    (tmp_path / CONFIG_FILE).write_text(yaml.safe_dump(config), encoding="utf-8")
    return tmp_path


def base_config() -> dict:
    return yaml.safe_load((ROOT / CONFIG_FILE).read_text(encoding="utf-8"))


def test_defaults_come_from_the_schema_where_the_config_leaves_them_out(tmp_path):
    config = base_config()
    del config["ingest"]
    del config["validation"]["max_gap_s"]
    schema = yaml.safe_load((ROOT / SCHEMA_FILE).read_text(encoding="utf-8"))
    filled = with_defaults(config, schema)
    assert filled["ingest"]["max_case_file_MB"] == schema["properties"]["ingest"]["properties"]["max_case_file_MB"][
        "default"]
    assert filled["validation"]["max_gap_s"] == schema["properties"]["validation"]["properties"]["max_gap_s"][
        "default"]
    assert "ingest" not in config   # the config itself is left as it is
    settings = load_settings(project(tmp_path, config))
    assert settings.max_case_file_MB == filled["ingest"]["max_case_file_MB"]


@pytest.mark.parametrize(("keys", "value", "flat", "expected"), CHANGES)
def test_each_config_key_reaches_its_setting_and_the_rules_that_read_it_only(tmp_path, keys, value, flat, expected):
    before = load_settings(project(tmp_path / "a", base_config()))
    config = copy.deepcopy(base_config())
    config.setdefault(keys[0], {})[keys[1]] = value
    after = load_settings(project(tmp_path / "b", config))
    assert flat_settings(after)[flat] == pytest.approx(expected)
    changed = {name for name in flat_settings(before) if flat_settings(before)[name] != flat_settings(after)[name]}
    assert changed == {flat}
    for rule in RULE_SETTINGS:   # a rule's params change exactly where it reads the setting
        assert (rule_settings(before, rule) != rule_settings(after, rule)) == (flat in rule_settings(after, rule))


def test_every_setting_has_a_flat_name_and_every_rule_reads_existing_settings():
    fields = {f.name for f in dataclasses.fields(Settings)}
    assert {field for names in RULE_SETTINGS.values() for field in names} <= fields
    settings = load_settings(ROOT)
    assert set(flat_settings(settings)) == {c[2] for c in CHANGES}


def test_a_config_the_schema_refuses_is_refused(tmp_path):
    config = base_config()
    config["windows"]["start_fraction"] = 1.5
    with pytest.raises(Exception, match="1.5"):
        load_settings(project(tmp_path, config))


def test_an_optional_block_that_asks_for_something_is_never_created_by_its_defaults():
    # the blind block's presence asks for the blind suite; its n_sine default must not create it
    config = base_config()
    del config["blind"]
    schema = yaml.safe_load((ROOT / SCHEMA_FILE).read_text(encoding="utf-8"))
    assert "blind" not in with_defaults(config, schema)


def test_every_settings_default_is_the_schemas_key_by_key():
    # one source: the schema's default of every config key a setting reads is the record's own (DEFAULTS)
    schema = yaml.safe_load((ROOT / SCHEMA_FILE).read_text(encoding="utf-8"))["properties"]
    defaults = flat_settings(DEFAULTS)
    assert set(CONFIG_KEYS) == set(defaults)
    for name, ((block, key), factor) in CONFIG_KEYS.items():
        assert schema[block]["properties"][key]["default"] * factor == pytest.approx(defaults[name], rel=1e-15), name


def test_a_config_with_only_its_raw_folder_gets_the_defaults(tmp_path):
    assert load_settings(project(tmp_path, {"raw_dir": "data/raw"})) == DEFAULTS


def test_the_project_is_found_from_a_folder_below_it(tmp_path, monkeypatch):
    root = project(tmp_path / "p", base_config())
    (root / "benchmark").mkdir()
    monkeypatch.chdir(root / "benchmark")
    assert load_settings() == load_settings(root)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match="no project"):
        load_settings()


@pytest.mark.parametrize(("keys", "value", "flat", "expected"), CHANGES)
def test_each_config_key_reaches_trace_and_init_campaign(tmp_path, keys, value, flat, expected):
    # the build's rules: test_each_config_key_reaches_its_setting_and_the_rules_that_read_it_only; the blind
    # suite's chain: tests/stages/test_blind_diagnose.py; here trace's rebuild (a file without a lineage record of
    # the setting) and
    # init-campaign (a raw folder inside the project, run from elsewhere)
    from isokinetic.audit.trace_core import Context, recorded_settings
    from isokinetic.contracts.settings import project_settings

    config = copy.deepcopy(base_config())
    config.setdefault(keys[0], {})[keys[1]] = value
    root = project(tmp_path, config)
    raw = root / "data" / "raw" / "c1"
    raw.mkdir(parents=True)
    ctx = Context(table=root / "results" / "c1" / "windows.parquet", root=root, config_path=root / CONFIG_FILE,
                  report=None, scratch=tmp_path / "scratch")
    assert flat_settings(recorded_settings(ctx, [ctx.table]))[flat] == pytest.approx(expected)
    assert flat_settings(project_settings(raw))[flat] == pytest.approx(expected)


def test_init_campaign_outside_any_project_applies_the_defaults(tmp_path, monkeypatch):
    from isokinetic.contracts.settings import project_settings

    monkeypatch.chdir(tmp_path)
    assert project_settings(tmp_path) == DEFAULTS
