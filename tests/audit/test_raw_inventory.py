"""raw_inventory: every folder under data/raw/ is a campaign or is listed with why and the fix; results of a
campaign whose input is gone are orphaned."""

from __future__ import annotations

from pathlib import Path

import pytest

from campaign_meta_fixture import write_campaign_meta
from isokinetic.audit.raw_inventory import orphaned_results, suggested_id, unusable_folders


def _folder(path: Path, manifest: bool) -> Path:
    path.mkdir(parents=True)
    (path / "T01.csv").write_text("t,x,F\n", encoding="utf-8")
    if manifest:
        (path / "campaign.yaml").write_text("format_version: 1\n", encoding="utf-8")
    return path


def _results(root: Path, name: str, manifest_file: str) -> Path:
    folder = root / name
    write_campaign_meta(folder, name, manifest_file=manifest_file)
    (folder / "report.html").write_text("Provenance checks pass", encoding="utf-8")
    return folder


def test_a_folder_without_a_manifest_is_listed_with_the_init_campaign_fix(tmp_path):
    raw = tmp_path / "data" / "raw"
    _folder(raw / "good", manifest=True)
    _folder(raw / "bench4", manifest=False)
    [issue] = unusable_folders(raw)
    assert issue.folder == (raw / "bench4").as_posix()
    assert issue.reason == "no campaign.yaml"
    assert f"init-campaign {(raw / 'bench4').as_posix()}" in issue.fix
    assert issue.line().startswith(f"{(raw / 'bench4').as_posix()}/: not built: no campaign.yaml; ")


def test_a_folder_whose_name_is_no_campaign_id_is_listed_with_a_name_to_rename_it_to(tmp_path):
    raw = tmp_path / "raw"
    _folder(raw / "Bench 3", manifest=True)
    _folder(raw / "Old Rig", manifest=False)
    issues = {Path(i.folder).name: i for i in unusable_folders(raw)}
    assert sorted(issues) == ["Bench 3", "Old Rig"]
    assert "'Bench 3' is not a campaign id" in issues["Bench 3"].reason
    assert "rename it to bench-3" in issues["Bench 3"].fix and "`campaign: bench-3`" in issues["Bench 3"].fix
    assert "no campaign.yaml" in issues["Old Rig"].reason
    assert "rename it to old-rig" in issues["Old Rig"].fix and "init-campaign" in issues["Old Rig"].fix


@pytest.mark.parametrize("name, expected", [("Bench 3", "bench-3"), ("  Rig__A  ", "rig__a"), ("a..b", "a-b"),
                                            ("Ärger", "arger"), ("___", None), ("日本", None)])
def test_suggested_ids_are_campaign_ids(name, expected):
    assert suggested_id(name) == expected


def test_hidden_folders_plain_files_and_campaigns_are_not_listed(tmp_path):
    raw = tmp_path / "raw"
    _folder(raw / "good", manifest=True)
    _folder(raw / ".ipynb_checkpoints", manifest=False)
    (raw / "README.txt").write_text("notes", encoding="utf-8")
    assert unusable_folders(raw) == []
    assert unusable_folders(tmp_path / "missing") == []


def test_results_of_a_deleted_raw_folder_are_orphaned_and_say_so(tmp_path):
    raw, results = tmp_path / "data/raw", tmp_path / "results"
    _folder(raw / "kept", manifest=True)
    _folder(raw / "emptied", manifest=False)
    _results(results, "kept", "data/raw/kept/campaign.yaml")
    _results(results, "gone", "data/raw/gone/campaign.yaml")
    _results(results, "emptied", "data/raw/emptied/campaign.yaml")
    _results(results, "sim", "")                         # a virtual campaign, still in the config
    _results(results, "dropped-sim", "")                 # a virtual campaign taken out of the config
    out = orphaned_results(results, ["kept", "sim"], raw)
    assert sorted(out) == ["dropped-sim", "emptied", "gone"]
    assert out["gone"].startswith(f"orphaned: raw folder missing: {(raw / 'gone').as_posix()}/ is gone")
    assert out["emptied"].startswith("orphaned: raw folder missing: ") and "has no campaign.yaml" in out["emptied"]
    assert "virtual campaign 'dropped-sim' is not in the config" in out["dropped-sim"]
    for reason in out.values():
        assert "checks pass" not in reason and "delete " in reason


def test_the_blind_suite_comparisons_design_summary_and_other_folders_are_no_orphans(tmp_path):
    results = tmp_path / "results"
    for name in ("blind", "compare", "design"):
        _results(results, name, "")
    (results / "scratch").mkdir()                        # no campaign's results: left alone
    (results / "scratch" / "notes.txt").write_text("mine", encoding="utf-8")
    (results / "index.html").write_text("index", encoding="utf-8")
    assert orphaned_results(results, [], tmp_path / "data/raw") == {}
    assert orphaned_results(tmp_path / "missing", [], tmp_path / "data/raw") == {}


def test_a_comparison_or_blind_suite_the_config_no_longer_asks_for_is_orphaned(tmp_path):
    results = tmp_path / "results"
    for name in ("kept", "dropped"):
        (results / "compare" / name).mkdir(parents=True)
        (results / "compare" / name / "compare.json").write_text("{}", encoding="utf-8")
    (results / "blind").mkdir()
    (results / "blind" / "summary.json").write_text("{}", encoding="utf-8")
    out = orphaned_results(results, [], tmp_path / "data/raw", comparisons=["kept"], blind=False)
    assert sorted(out) == ["blind", "compare/dropped"]
    assert out["compare/dropped"].startswith("orphaned: comparison 'dropped' is not in the config (comparisons)")
    assert out["blind"].startswith("orphaned: the blind suite is not in the config (blind)")
    assert orphaned_results(results, [], tmp_path / "data/raw", comparisons=["kept", "dropped"], blind=True) == {}
