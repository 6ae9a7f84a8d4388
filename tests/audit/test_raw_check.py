"""raw_check: every raw file a processed campaign read still has the sha256 recorded at ingest."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from campaign_meta_fixture import write_campaign_meta
from conftest import CAMPAIGN
from fresh_imports import modules_loaded
from isokinetic.__main__ import main
from isokinetic.audit.raw_check import RawDataChanged, check_raw, raw_changes


def test_unchanged_campaign(raw_campaign, capsys):
    raw_campaign.run()
    assert raw_changes(raw_campaign.root) == []
    assert check_raw(raw_campaign.root, raw_campaign.root / "raw_check.json") == []
    record = json.loads((raw_campaign.root / "raw_check.json").read_text())
    assert (record["kind"], record["ok"], record["changes"]) == ("raw", True, [])
    assert main(["raw-check", str(raw_campaign.root)]) == 0 and capsys.readouterr().out == ""


def test_changed_and_missing_files(raw_campaign, capsys):
    raw_campaign.run()
    t01 = raw_campaign.raw_dir / "T01.csv"
    t01.write_bytes(t01.read_bytes().replace(b"0", b"1", 1))           # one digit
    (raw_campaign.raw_dir / "H01.csv").unlink()
    manifest = raw_campaign.raw_dir / "campaign.yaml"
    manifest.write_bytes(manifest.read_bytes() + b"\n")                 # even a trailing newline
    changes = raw_changes(raw_campaign.root)
    assert [(c["path"], c["role"], c["case"], c["problem"]) for c in changes] == [
        (f"data/raw/{CAMPAIGN}/campaign.yaml", "manifest", None, "changed"),
        (f"data/raw/{CAMPAIGN}/T01.csv", "case", "T01", "changed"),
        (f"data/raw/{CAMPAIGN}/H01.csv", "case", "H01", "missing"),
    ]
    assert all(len(c["sha256_recorded"]) == 64 for c in changes)
    with pytest.raises(RawDataChanged, match=r"campaign demo: raw file data/raw/demo/T01.csv has sha256 \w{12}\.\. "
                                             r"now, \w{12}\.\. recorded at ingest") as info:
        check_raw(raw_campaign.root, raw_campaign.root / "raw_check.json")
    assert "raw file data/raw/demo/H01.csv is missing" in str(info.value)
    record = json.loads((raw_campaign.root / "raw_check.json").read_text())
    assert record["ok"] is False and len(record["changes"]) == 3
    assert main(["raw-check", str(raw_campaign.root)]) == 1
    assert len(capsys.readouterr().out.splitlines()) == 3


def test_case_file_turned_into_a_symlink_out_of_the_folder_is_reported_unread(raw_campaign, tmp_path):
    raw_campaign.run()
    t01 = raw_campaign.raw_dir / "T01.csv"
    outside = tmp_path / "elsewhere.csv"
    outside.write_bytes(t01.read_bytes())      # same bytes: only not reading it tells the change
    t01.unlink()
    t01.symlink_to(outside.resolve())
    changes = raw_changes(raw_campaign.root)
    assert [(c["path"], c["problem"], c["sha256_now"]) for c in changes] == [
        (f"data/raw/{CAMPAIGN}/T01.csv", "outside", None)]
    with pytest.raises(RawDataChanged, match="T01.csv now leads outside the campaign folder: not read"):
        check_raw(raw_campaign.root)


def test_quarantined_case_without_hash_is_not_checked(raw_campaign):
    (raw_campaign.raw_dir / "F01.csv").unlink()     # quarantined at ingest: no sha256 recorded
    raw_campaign.run()
    assert raw_changes(raw_campaign.root) == []


def test_after_validate_only_ingest(raw_campaign):
    """Works on the ingest folder alone (before validate wrote cases.parquet)."""
    from isokinetic.stages.ingest import ingest_campaign
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    (raw_campaign.raw_dir / "T02.csv").write_text("tampered\n")
    assert [c["case"] for c in raw_changes(raw_campaign.root)] == ["T02"]


def test_simulated_campaign_has_nothing_on_disk(tmp_path):
    root = tmp_path / "results" / "sim"
    write_campaign_meta(root, "sim", lineage={"rule": "virtual_rig"})
    assert raw_changes(root) == []
    assert raw_changes(Path(tmp_path / "nothing")) == []


def test_simulated_campaign_is_recorded_as_nothing_to_check(tmp_path):
    root = tmp_path / "results" / "sim"
    write_campaign_meta(root, "sim", lineage={"rule": "virtual_rig"})
    assert check_raw(root, root / "raw_check.json") == []
    record = json.loads((root / "raw_check.json").read_text())
    assert (record["campaign"], record["kind"], record["ok"], record["changes"]) == ("sim", "simulation", True, [])


def test_help_lists_every_command_on_one_line(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for name in ("export-virtual", "trace", "raw-check"):
        assert [line for line in out.splitlines() if line.split()[:1] == [name] and len(line.split()) > 2], out


def test_the_raw_check_loads_no_pandas(raw_campaign):
    # the workflow's onsuccess/onerror check runs it in Snakemake's own process (issue 23)
    raw_campaign.run()
    code = ("import isokinetic.job; from isokinetic.audit.raw_check import raw_changes; "
            f"assert raw_changes({str(raw_campaign.root)!r}) == []")
    assert modules_loaded(code, "pandas") == []
