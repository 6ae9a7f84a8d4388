"""One reader of a campaign's results folder (isokinetic.contracts.campaign_folder)."""

import pandas as pd
import pytest

from conftest import CAMPAIGN, CASE_IDS, MANIFEST
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.validate import write_validated


@pytest.fixture
def ingested(raw_campaign):
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    return CampaignFolder.at(raw_campaign.root)


def test_paths_come_from_the_output_registry(tmp_path):
    folder = CampaignFolder.at(tmp_path / "results" / "c")
    assert folder.path("windows", "windows") == tmp_path / "results" / "c" / "windows.parquet"
    assert folder.path("models", "models") == tmp_path / "results" / "c" / "models" / "models.parquet"
    assert folder.ingest_dir == tmp_path / "results" / "c" / "ingest"
    with pytest.raises(KeyError):
        folder.path("windows", "no-such-table")


def test_meta_names_the_campaign_and_its_damper(ingested):
    assert ingested.campaign == CAMPAIGN == ingested.meta.campaign
    assert ingested.damper.piston_area_m2 == MANIFEST["damper"]["piston_area_m2"]


def test_meta_is_read_once(ingested):
    first = ingested.meta
    ingested.ingest_path("meta").unlink()
    assert ingested.meta is first and CampaignFolder.at(ingested.root).has_meta() is False


def test_a_folder_without_campaign_json_is_named_after_itself_and_has_no_cases(tmp_path):
    folder = CampaignFolder.at(tmp_path / "results" / "c")
    assert folder.campaign == "c" and folder.cases_if_any() is None
    with pytest.raises(FileNotFoundError):
        _ = folder.meta


def test_ingests_tables_and_a_cases_series_by_id(ingested):
    assert sorted(ingested.ingested_cases()["case"]) == sorted(CASE_IDS)
    assert ingested.ingested_quarantine().empty
    row = ingested.ingested_cases().set_index("case", drop=False).loc["T01"]
    pd.testing.assert_frame_equal(ingested.timeseries("T01"), ingested.timeseries(row))


def test_documents_are_read_when_present(ingested):
    assert ingested.document("diagnosis", "json") is None
    ingested.path("diagnosis", "json").write_text('{"verdict": "x"}', encoding="utf-8")
    assert ingested.document("diagnosis", "json") == {"verdict": "x"}


def test_before_validation_the_cases_are_ingests_and_there_is_no_validated_table(ingested):
    assert ingested.table("validate", "cases") is None
    pd.testing.assert_frame_equal(ingested.cases(), ingested.ingested_cases())
    with pytest.raises(FileNotFoundError):
        ingested.validated_cases()


def test_after_validation_the_cases_are_validates(ingested):
    written, _quarantine = write_validated(ingested.root)
    validated = ingested.validated_cases()
    pd.testing.assert_frame_equal(validated, written)
    pd.testing.assert_frame_equal(ingested.cases(), validated)
    assert sorted(validated["case"]) == sorted(ingested.ingested_cases()["case"]) == sorted(CASE_IDS)
    assert "motion_start_s" in validated and "motion_start_s" not in ingested.ingested_cases()


def test_timeseries_reads_a_cases_own_file(ingested):
    row = ingested.ingested_cases().set_index("case", drop=False).loc["T01"]
    series = ingested.timeseries(row, ["time_s"])
    assert list(series.columns) == ["time_s"]
    pd.testing.assert_frame_equal(series, pd.read_parquet(ingested.root / row["timeseries_file"], columns=["time_s"]))
