"""raw_folder: only the manifest and the files it names reach Snakemake; the rest is listed by name only."""

from __future__ import annotations

import os

import pytest
import yaml

from conftest import CAMPAIGN
from isokinetic.audit.raw_folder import folder_problem, manifest_files, plain_path, snakemake_inputs, unused_entries


def name_file(raw_dir, case, file):
    """Point one case of the manifest at ``file``."""
    doc = yaml.safe_load((raw_dir / "campaign.yaml").read_text(encoding="utf-8"))
    next(c for c in doc["cases"] if c["id"] == case)["file"] = file
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return doc


def test_only_the_manifest_and_the_case_files_it_names_are_inputs(raw_campaign):
    (raw_campaign.raw_dir / "notes {old}.txt").write_text("x", encoding="utf-8")
    (raw_campaign.raw_dir / "notes <old>.txt").write_text("x", encoding="utf-8")
    doc = yaml.safe_load((raw_campaign.raw_dir / "campaign.yaml").read_text(encoding="utf-8"))
    expected = ["campaign.yaml"] + list(dict.fromkeys(c["file"] for c in doc["cases"]))
    assert manifest_files(raw_campaign.raw_dir) == expected
    inputs = snakemake_inputs(raw_campaign.raw_dir)
    assert inputs.paths == tuple((raw_campaign.raw_dir / n).as_posix() for n in expected)
    assert inputs.fingerprints == () and all(plain_path(p) for p in inputs.paths)


def test_a_named_file_with_pattern_characters_is_fingerprinted_not_given_as_a_path(raw_campaign):
    (raw_campaign.raw_dir / "T01.csv").rename(raw_campaign.raw_dir / "T{01}.csv")
    name_file(raw_campaign.raw_dir, "T01", "T{01}.csv")
    inputs = snakemake_inputs(raw_campaign.raw_dir)
    assert all("{" not in p for p in inputs.paths)
    st = (raw_campaign.raw_dir / "T{01}.csv").stat()
    assert inputs.fingerprints == (f"T{{01}}.csv {st.st_size} {st.st_mtime_ns}",)


def test_a_subfolder_case_file_is_an_input(raw_campaign):
    (raw_campaign.raw_dir / "run1").mkdir()
    (raw_campaign.raw_dir / "T01.csv").rename(raw_campaign.raw_dir / "run1" / "T01.csv")
    name_file(raw_campaign.raw_dir, "T01", "run1/T01.csv")
    assert "run1/T01.csv" in manifest_files(raw_campaign.raw_dir)


def test_a_broken_manifest_leaves_only_the_manifest(raw_campaign):
    (raw_campaign.raw_dir / "campaign.yaml").write_text("format_version: [", encoding="utf-8")
    assert manifest_files(raw_campaign.raw_dir) == ["campaign.yaml"]


def test_a_manifest_symlink_leading_out_is_no_input(raw_campaign, tmp_path_factory):
    outside = tmp_path_factory.mktemp("elsewhere") / "campaign.yaml"
    (raw_campaign.raw_dir / "campaign.yaml").rename(outside)
    (raw_campaign.raw_dir / "campaign.yaml").symlink_to(outside)
    assert manifest_files(raw_campaign.raw_dir) == []


def test_unused_entries_are_listed_by_name_and_outside_symlinks_marked(raw_campaign, tmp_path_factory):
    outside = tmp_path_factory.mktemp("elsewhere")
    (outside / "secret").write_text("s", encoding="utf-8")
    (raw_campaign.raw_dir / "passwd.csv").symlink_to(outside / "secret")
    (raw_campaign.raw_dir / "linked_dir").symlink_to(outside)
    (raw_campaign.raw_dir / "sub").mkdir()
    (raw_campaign.raw_dir / "sub" / "a.csv").write_text("a", encoding="utf-8")
    os.mkfifo(raw_campaign.raw_dir / "pipe")
    got = {e["path"]: e for e in unused_entries(raw_campaign.raw_dir, manifest_files(raw_campaign.raw_dir))}
    assert set(got) == {"passwd.csv", "linked_dir", "sub/a.csv", "pipe"}
    assert got["passwd.csv"]["kind"] == "symlink" and "outside" in got["passwd.csv"]["note"]
    assert "outside" in got["linked_dir"]["note"]
    assert got["sub/a.csv"]["kind"] == "file" and got["pipe"]["kind"] == "other"


def test_unused_entries_are_capped_with_a_count(raw_campaign):
    for i in range(7):
        (raw_campaign.raw_dir / f"extra{i}.txt").write_text("x", encoding="utf-8")
    got = unused_entries(raw_campaign.raw_dir, manifest_files(raw_campaign.raw_dir), limit=5)
    assert len(got) == 6 and got[-1]["note"] == "and 2 more entries not listed"


@pytest.mark.parametrize("inside_raw", [True, False])
def test_a_campaign_folder_resolving_outside_the_raw_folder_is_refused(raw_campaign, tmp_path_factory, inside_raw):
    raw = raw_campaign.raw_dir.parent
    target = raw / "elsewhere" if inside_raw else tmp_path_factory.mktemp("outside") / "elsewhere"
    raw_campaign.raw_dir.rename(target)
    raw_campaign.raw_dir.symlink_to(target.resolve())
    problem = folder_problem(raw_campaign.raw_dir, raw)
    if inside_raw:
        assert problem is None
    else:
        assert problem.startswith(f"campaign folder data/raw/{CAMPAIGN} is a symlink leading outside data/raw/")
