"""The diagnosis.json document and its schema (isokinetic.diagnosis.result)."""

import jsonschema
import pytest

from isokinetic.diagnosis.result import diagnosis_schema, no_model, validate_diagnosis


def test_schema_rejects_an_unknown_effect_name():
    bad = no_model("x", "test") | {"verdict": ["temperature"]}
    with pytest.raises(jsonschema.ValidationError):
        validate_diagnosis(bad)


def test_campaign_without_damper_data_is_reported_not_diagnosed():
    out = no_model("raw-no-damper", "campaign.yaml has no damper block")
    validate_diagnosis(out)
    assert out["status"] == "not_diagnosed" and out["verdict"] == []


def test_schema_is_package_data():
    assert diagnosis_schema()["type"] == "object"


def test_the_schema_is_a_valid_json_schema():
    # validate_diagnosis builds its validator once and no longer checks the schema itself at every call
    import jsonschema

    from isokinetic.diagnosis.result import diagnosis_schema

    schema = diagnosis_schema()
    jsonschema.validators.validator_for(schema).check_schema(schema)
