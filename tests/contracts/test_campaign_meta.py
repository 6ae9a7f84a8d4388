"""The typed campaign metadata record (isokinetic.contracts.campaign_meta) and its schema."""

import dataclasses
import json

import jsonschema
import pytest

from conftest import CAMPAIGN, MANIFEST
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.campaign_meta import (
    CAMPAIGN_KEYS,
    OPTIONAL_KEYS,
    CampaignMeta,
    CampaignMetaError,
    campaign_schema,
    schema_problems,
)
from isokinetic.physics.damper import TABLE_1
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign
from testconfig import paper_campaign

SIMULATED = {"format_version": 1, "campaign": "sim", "source": "simulation", "description": "d",
             "temperature_C": 40.0, "damper": TABLE_1.to_dict(), "manifest_file": "", "manifest_sha256": "",
             "metadata": {"generated_by": {"seed": 3}}}


@pytest.fixture
def raw_meta_file(raw_campaign):
    ingest_campaign(raw_campaign.raw_dir, raw_campaign.root)
    return CampaignFolder.at(raw_campaign.root).ingest_path("meta")


def test_a_raw_ingests_file_reads_typed_and_writes_back_unchanged(raw_meta_file):
    written = json.loads(raw_meta_file.read_text())
    meta = CampaignMeta.from_mapping(written)
    assert (meta.campaign, meta.source, meta.temperature_C) == (CAMPAIGN, "rig", 40.0)
    assert meta.damper.piston_area_m2 == MANIFEST["damper"]["piston_area_m2"]
    assert meta.warnings == () and meta.gas_force_N is None and meta.metadata["operator"] == "fixture"
    assert meta.present == {"viscosity_law", "gas_force_N", "csv", "warnings", "force_calibration",
                            "displacement_calibration"}
    assert written["force_calibration"] is None and meta.calibration is None
    assert written["displacement_calibration"] is None and meta.lvdt_calibration is None
    assert meta.to_mapping() == written


def test_a_simulated_campaigns_file_has_no_raw_ingest_keys(tmp_path):
    paper = VirtualCampaign.from_config("paper-lag-damper", paper_campaign())
    write_campaign(dataclasses.replace(paper, cases=paper.cases[:1]), tmp_path / "sim")
    written = json.loads(CampaignFolder.at(tmp_path / "sim").ingest_path("meta").read_text())
    assert set(written) == set(CAMPAIGN_KEYS)
    meta = CampaignMeta.from_mapping(written)
    assert meta.present == frozenset() and meta.generated_by["seed"] == paper.seed
    assert meta.to_mapping() == written


def test_unknown_keys_are_kept_and_written_back():
    meta = CampaignMeta.from_mapping({**SIMULATED, "rig_operator": "ab", "lineage": {"rule": "virtual_rig"}})
    assert meta.extra == {"rig_operator": "ab"} and meta.lineage == {"rule": "virtual_rig"}
    assert meta.to_mapping() == {**SIMULATED, "rig_operator": "ab", "lineage": {"rule": "virtual_rig"}}


@pytest.mark.parametrize(("change", "words"), [
    ({"campaign": None}, "key 'campaign' must be string, got None"),
    ({"temperature_C": "40"}, "key 'temperature_C' must be ['number', 'null'], got '40'"),
    ({"format_version": True}, "key 'format_version' must be integer, got True"),
    ({"warnings": ["ok", 3]}, "key 'warnings' item 1 must be string, got 3"),
])
def test_a_key_of_the_wrong_type_is_refused_naming_file_and_key(change, words):
    with pytest.raises(CampaignMetaError, match="^results/c/ingest/campaign.json: ") as err:
        CampaignMeta.from_mapping({**SIMULATED, **change}, where="results/c/ingest/campaign.json")
    assert words in str(err.value)


def test_a_missing_key_or_an_unusable_damper_block_is_refused():
    partial = {k: v for k, v in SIMULATED.items() if k != "manifest_sha256"}
    with pytest.raises(CampaignMetaError, match="missing key 'manifest_sha256'"):
        CampaignMeta.from_mapping(partial)
    with pytest.raises(CampaignMetaError, match="density_kg_m3"):
        CampaignMeta.from_mapping({**SIMULATED, "damper": {**TABLE_1.to_dict(), "density_kg_m3": -1.0}})


def test_a_declared_force_calibration_reads_as_gain_and_uncertainty_and_writes_back():
    written = {**SIMULATED, "force_calibration": {"gain": 1.012, "uncertainty_rel": 0.001}}
    meta = CampaignMeta.from_mapping(written)
    assert meta.calibration == (1.012, 0.001)
    assert meta.to_mapping() == written


@pytest.mark.parametrize("calibration", [{"gain": 1.01}, {"gain": "1.01", "uncertainty_rel": 0.001}, {}])
def test_a_force_calibration_without_its_two_numbers_is_refused(calibration):
    with pytest.raises(CampaignMetaError, match="^c.json: key 'force_calibration' must hold the numbers"):
        CampaignMeta.from_mapping({**SIMULATED, "force_calibration": calibration}, where="c.json")


def test_a_declared_lvdt_calibration_reads_as_scale_and_uncertainty_and_writes_back():
    written = {**SIMULATED, "displacement_calibration": {"scale": 1.012, "uncertainty_rel": 0.001}}
    meta = CampaignMeta.from_mapping(written)
    assert (meta.lvdt_calibration, meta.calibration) == ((1.012, 0.001), None)
    assert meta.to_mapping() == written


@pytest.mark.parametrize("calibration", [{"scale": 1.01}, {"gain": 1.01, "uncertainty_rel": 0.001},
                                         {"scale": None, "uncertainty_rel": 0.001}])
def test_an_lvdt_calibration_without_its_two_numbers_is_refused(calibration):
    with pytest.raises(CampaignMetaError, match="^c.json: key 'displacement_calibration' must hold the numbers "
                                                "scale and uncertainty_rel"):
        CampaignMeta.from_mapping({**SIMULATED, "displacement_calibration": calibration}, where="c.json")


def test_the_viscosity_law_needs_the_damper_block():
    law = {"kind": "walther", "points": [[40.0, 0.03], [100.0, 0.006]]}
    with_law = CampaignMeta.from_mapping({**SIMULATED, "viscosity_law": law})
    assert with_law.viscosity_law().viscosity_Pa_s(40.0) == pytest.approx(0.03)
    assert CampaignMeta.from_mapping({**SIMULATED, "viscosity_law": law, "damper": None}).viscosity_law() is None


def test_the_schema_is_a_valid_schema_using_only_the_keywords_checked_here():
    schema = campaign_schema()
    jsonschema.validators.validator_for(schema).check_schema(schema)
    assert set(schema["required"]) == set(CAMPAIGN_KEYS) and set(OPTIONAL_KEYS) <= set(schema["properties"])
    for spec in schema["properties"].values():
        assert set(spec) <= {"type", "items", "description"}


@pytest.mark.parametrize("mapping", [
    SIMULATED, {**SIMULATED, "source": None}, {**SIMULATED, "format_version": 1.5},
    {**SIMULATED, "metadata": []}, {**SIMULATED, "warnings": "slip"}, {**SIMULATED, "gas_force_N": False},
    {k: v for k, v in SIMULATED.items() if k != "damper"}, {**SIMULATED, "extra": {"any": 1}},
])
def test_jsonschema_agrees_with_the_check_here(mapping):
    agrees = jsonschema.validators.validator_for(campaign_schema())(campaign_schema()).is_valid(mapping)
    assert agrees == (schema_problems(mapping) == [])
