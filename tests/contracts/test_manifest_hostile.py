"""Hostile manifests are refused as a whole, before any case file is read or any YAML object built.

Each refusal is a ManifestError whose message starts with the manifest's path and names the key
(``key 'cases.T01.file': ...``), or the file itself where no key is involved (size, symlink).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from conftest import CAMPAIGN
from isokinetic.contracts import manifest_yaml as manifest_module
from isokinetic.contracts.manifest import (
    MAX_CASES,
    MAX_MANIFEST_BYTES,
    MAX_PLANNED_SAMPLES,
    ManifestError,
    check_yaml_events,
    load_manifest,
)
from isokinetic.stages.ingest import ingest_campaign

MANIFEST_FILE = f"data/raw/{CAMPAIGN}/campaign.yaml"


def _refused(key, *words) -> ManifestError:
    with pytest.raises(ManifestError) as info:
        load_manifest(MANIFEST_FILE)
    err = info.value
    assert err.key == key, str(err)
    prefix = f"{MANIFEST_FILE}: key {key!r}: " if key else f"{MANIFEST_FILE}: "
    assert str(err).startswith(prefix), str(err)
    for w in words:
        assert w in str(err), str(err)
    return err


def _append_text(raw_campaign, text: str) -> None:
    path = raw_campaign.raw_dir / "campaign.yaml"
    path.write_text(path.read_text(encoding="utf-8") + text, encoding="utf-8")


def _no_case_file_read(raw_campaign, monkeypatch) -> None:
    """Make any attempt to open a case CSV fail the test."""
    real_open = open

    def guarded(file, *args, **kwargs):
        if str(file).endswith(".csv"):
            raise AssertionError(f"case file opened: {file}")
        return real_open(file, *args, **kwargs)
    monkeypatch.setattr("builtins.open", guarded)


# --- file names and symlinks -------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../T01.csv", "sub/../../T01.csv", "/etc/passwd", "sub\\T01.csv", "C:T01.csv",
                                  "..", "T01.csv\0", 5, "sub//T01.csv", "sub/", "./T01.csv"])
def test_file_name_with_a_path_refuses_the_manifest(raw_campaign, monkeypatch, name):
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(file=name))
    _no_case_file_read(raw_campaign, monkeypatch)
    _refused("cases.T01.file", f"must be a bare file name inside the campaign folder, got {name!r}")
    with pytest.raises(ManifestError):
        ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    assert not raw_campaign.root.exists()


def test_symlink_leading_outside_refuses_the_manifest(raw_campaign, monkeypatch, tmp_path):
    secret = tmp_path / "outside.csv"
    secret.write_text("time_s,disp_mm,force_kN\n0,0,0\n", encoding="utf-8")
    link = raw_campaign.raw_dir / "T02.csv"
    link.unlink()
    link.symlink_to(secret)
    _no_case_file_read(raw_campaign, monkeypatch)
    _refused("cases.T02.file", "'T02.csv' is a symlink to", "outside the campaign folder")


def test_subfolder_symlink_leading_outside_refuses_the_manifest(raw_campaign, monkeypatch, tmp_path):
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "T01.csv").write_bytes((raw_campaign.raw_dir / "T01.csv").read_bytes())
    (raw_campaign.raw_dir / "run1").symlink_to(tmp_path / "elsewhere")
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(file="run1/T01.csv"))
    _no_case_file_read(raw_campaign, monkeypatch)
    _refused("cases.T01.file", "'run1/T01.csv' is a symlink to", "outside the campaign folder")


def test_case_file_in_a_subfolder_is_accepted(raw_campaign):
    (raw_campaign.raw_dir / "run1").mkdir()
    (raw_campaign.raw_dir / "T01.csv").rename(raw_campaign.raw_dir / "run1" / "T01.csv")
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(file="run1/T01.csv"))
    assert load_manifest(MANIFEST_FILE).cases[0].file == "run1/T01.csv"


def test_dangling_symlink_outside_and_symlink_inside(raw_campaign):
    link = raw_campaign.raw_dir / "T02.csv"
    link.unlink()
    link.symlink_to("/nonexistent/T02.csv")
    _refused("cases.T02.file", "outside the campaign folder")
    link.unlink()
    (raw_campaign.raw_dir / "T01.csv").rename(raw_campaign.raw_dir / "real.csv")
    (raw_campaign.raw_dir / "T01.csv").symlink_to("real.csv")      # stays inside: accepted
    link.symlink_to(Path("..", CAMPAIGN, "real.csv"))             # out and back in: accepted
    assert [c.file for c in load_manifest(MANIFEST_FILE).cases][:2] == ["T01.csv", "T02.csv"]


def test_manifest_symlink_leading_outside(raw_campaign, tmp_path):
    target = tmp_path / "elsewhere.yaml"
    target.write_bytes((raw_campaign.raw_dir / "campaign.yaml").read_bytes())
    (raw_campaign.raw_dir / "campaign.yaml").unlink()
    (raw_campaign.raw_dir / "campaign.yaml").symlink_to(target)
    _refused(None, "is a symlink to", "outside the campaign folder")


# --- YAML hostility ----------------------------------------------------------------------------

@pytest.mark.parametrize("text, key, words", [
    ("evil: !!python/object/apply:os.system [echo hi]\n", "evil",
     "tag '!!python/object/apply:os.system' is not allowed"),
    ("evil: !!python/name:os.system ''\n", "evil", "tag '!!python/name:os.system' is not allowed"),
    ("evil: !!binary aGk=\n", "evil", "tag '!!binary' is not allowed"),
    ("evil: !local x\n", "evil", "tag '!local' is not allowed"),
    ("evil: !!set {a: null}\n", "evil", "tag '!!set' is not allowed"),
])
def test_tags_that_construct_objects(raw_campaign, text, key, words):
    _append_text(raw_campaign, text)
    err = _refused(key, words, "invalid YAML at line")
    assert "only plain values" in str(err)


def test_plain_yaml_tags_are_accepted(raw_campaign):
    _append_text(raw_campaign, "note: !!str 12\nlevel: !!float 3\n")
    assert load_manifest(MANIFEST_FILE).metadata["note"] == "12"


def test_object_tag_inside_a_case(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["cases"][1].update(period_s="TAG"))
    path = raw_campaign.raw_dir / "campaign.yaml"
    path.write_text(path.read_text(encoding="utf-8").replace("TAG", "!!python/object:os.system ls"),
                    encoding="utf-8")
    _refused("cases[1].period_s", "tag '!!python/object:os.system'")


BILLION_LAUGHS = """lol: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]
lol2: &b [*a,*a,*a,*a,*a,*a,*a,*a,*a]
lol3: &c [*b,*b,*b,*b,*b,*b,*b,*b,*b]
lol4: &d [*c,*c,*c,*c,*c,*c,*c,*c,*c]
lol5: &e [*d,*d,*d,*d,*d,*d,*d,*d,*d]
lol6: &f [*e,*e,*e,*e,*e,*e,*e,*e,*e]
lol7: &g [*f,*f,*f,*f,*f,*f,*f,*f,*f]
lol8: &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]
lol9: &i [*h,*h,*h,*h,*h,*h,*h,*h,*h]
"""


def test_alias_bomb_is_refused_before_expansion(raw_campaign, monkeypatch):
    _append_text(raw_campaign, BILLION_LAUGHS)
    monkeypatch.setattr(manifest_module.yaml, "load", lambda *a, **k: pytest.fail("YAML objects built"))
    start = time.perf_counter()
    _refused("lol", "anchor &a is not allowed", "line")
    assert time.perf_counter() - start < 1.0


@pytest.mark.parametrize("text, key, words", [
    ("shared: &cols {name: x}\n", "shared", "anchor &cols is not allowed"),
    ("other: *nothing\n", "other", "alias *nothing is not allowed"),
    ("extra:\n  <<: {description: merged}\n", "extra.<<", "merge keys '<<' are not allowed"),
])
def test_anchors_aliases_and_merge_keys(raw_campaign, text, key, words):
    _append_text(raw_campaign, text)
    _refused(key, words)


@pytest.mark.parametrize("text, key", [
    ("campaign: other\n", "campaign"),                          # a second top-level 'campaign'
    ("'sample_rate_Hz': 5000.0\n", "sample_rate_Hz"),           # quoting does not make it another key
])
def test_duplicate_top_level_keys(raw_campaign, text, key):
    _append_text(raw_campaign, text)
    _refused(key, "duplicate key (YAML would silently keep the last value)")


def test_duplicate_key_inside_a_case(raw_campaign):
    path = raw_campaign.raw_dir / "campaign.yaml"
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("  period_s: 2.0\n", "  period_s: 2.0\n  period_s: 200.0\n", 1), encoding="utf-8")
    _refused("cases[1].period_s", "duplicate key")


def test_duplicate_key_in_a_column_mapping(raw_campaign):
    path = raw_campaign.raw_dir / "campaign.yaml"
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("    unit: kN\n", "    unit: kN\n    unit: N\n", 1), encoding="utf-8")
    _refused("columns.force.unit", "duplicate key")


def test_complex_key_and_deep_nesting(raw_campaign):
    good = (raw_campaign.raw_dir / "campaign.yaml").read_bytes()
    _append_text(raw_campaign, "? [a, b]\n: 1\n")
    _refused(None, "mapping keys must be plain values, got a sequence")
    (raw_campaign.raw_dir / "campaign.yaml").write_bytes(good)
    _append_text(raw_campaign, "deep: " + "[" * 40 + "]" * 40 + "\n")
    _refused("deep" + "[0]" * 31, "nested deeper than 32 levels")


def test_huge_integer_and_overflow(raw_campaign):
    good = (raw_campaign.raw_dir / "campaign.yaml").read_bytes()
    _append_text(raw_campaign, "big: " + "9" * 5000 + "\n")
    _refused(None, "invalid YAML: Exceeds the limit (4300 digits)")
    (raw_campaign.raw_dir / "campaign.yaml").write_bytes(good)
    raw_campaign.edit_manifest(lambda m: m.update(sample_rate_Hz=10 ** 400))
    _refused("sample_rate_Hz", "must be a positive number")


def test_check_yaml_events_accepts_the_good_manifest(raw_campaign):
    check_yaml_events((raw_campaign.raw_dir / "campaign.yaml").read_bytes(), "x")


# --- sizes -------------------------------------------------------------------------------------

def test_manifest_file_too_large(raw_campaign, monkeypatch):
    path = raw_campaign.raw_dir / "campaign.yaml"
    _append_text(raw_campaign, "# " + "x" * MAX_MANIFEST_BYTES + "\n")
    monkeypatch.setattr(manifest_module.yaml, "parse", lambda *a, **k: pytest.fail("parsed"))
    _refused(None, f"{path.stat().st_size} bytes, more than the {MAX_MANIFEST_BYTES} bytes a manifest may have")


def test_manifest_not_a_regular_file(raw_campaign):
    path = raw_campaign.raw_dir / "campaign.yaml"
    path.unlink()
    os.mkfifo(path)       # reading it would block forever
    _refused(None, "not a regular file")


@pytest.mark.parametrize("edit, key, words", [
    (lambda m: m.update(sample_rate_Hz=5e6), "sample_rate_Hz", "5e+06 is above the bound 1e+06"),
    (lambda m: m["cases"][1].update(sample_rate_Hz=2e7), "cases.T02.sample_rate_Hz", "2e+07 is above the bound 1e+06"),
    (lambda m: m["cases"][0].update(period_s=1e9), "cases.T01.period_s", "1e+09 is above the bound 100000"),
    (lambda m: m["cases"][0].update(amplitude_mm=3e4), "cases.T01.amplitude_mm", "30000 is above the bound 1000"),
    (lambda m: m["cases"][3].update(frequency_Hz=1e6), "cases.H01.frequency_Hz", "1e+06 is above the bound 10000"),
    (lambda m: m["cases"][4].update(duration_s=1e7), "cases.F01.duration_s", "1e+07 is above the bound 1e+06"),
    # each value within its bound, but the record would need too many samples
    (lambda m: m["cases"][0].update(period_s=9e4, sample_rate_Hz=1e5), "cases.T01.period_s",
     f"the record would need 1.8e+10 samples (180000 s at 100000 Hz), more than the {MAX_PLANNED_SAMPLES:.0e}"),
    (lambda m: m["cases"][3].update(frequency_Hz=1e-5), "cases.H01.frequency_Hz",
     "the record would need 2e+07 samples (100000 s at 200 Hz)"),
    (lambda m: m["cases"][4].update(duration_s=9e5, sample_rate_Hz=1e3), "cases.F01.duration_s",
     "the record would need 9e+08 samples"),
    (lambda m: m.update(cases=[dict(m["cases"][4], id=f"C{k}") for k in range(MAX_CASES + 1)]), "cases",
     f"{MAX_CASES + 1} cases, more than the {MAX_CASES} a campaign may have"),
])
def test_absurd_sizes(raw_campaign, edit, key, words):
    raw_campaign.edit_manifest(edit)
    _refused(key, words)


def test_bounds_leave_the_good_plans_alone(raw_campaign):
    raw_campaign.edit_manifest(lambda m: m["cases"][0].update(period_s=240.0, sample_rate_Hz=1000.0))
    assert load_manifest(MANIFEST_FILE).cases[0].plan.period_s == 240.0
