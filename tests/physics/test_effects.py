"""The effect registry (isokinetic.physics.effects) walked through every consumer: the model (Effects, its config
group, the config schema), the diagnosis' search and parametrisation, the diagnosis schema, the report's units and
the blind suite's draws on the reference rig. Each test runs once per record, so that a record missing anywhere
fails a test named for the consumer and the effect."""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from isokinetic.blind import generate as gen
from isokinetic.contracts import scenarios
from isokinetic.diagnosis import joint, search, verdict
from isokinetic.diagnosis.parametrisation import TRANSFORMS, Parametrisation
from isokinetic.diagnosis.result import diagnosis_schema
from isokinetic.physics.damper import TABLE_1, Effects
from isokinetic.physics.effects import BLIND_EFFECTS, CATALOGUE, REGISTRY, effect
from isokinetic.physics.plan import CasePlan
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.report import diagnosis_section
from isokinetic.report.sources import Source

ROOT = Path(__file__).resolve().parents[2]
FITTED = [e for e in REGISTRY if e.fit is not None]
DRAWN = [e for e in REGISTRY if e.blind is not None]
#: A damper that is not Table 1 (so that a record reading the damper's own value is seen to read it).
DAMPER = dataclasses.replace(TABLE_1, discharge_coefficient=0.7, viscosity_Pa_s=0.045, oil_compressibility_1_Pa=5e-9)
#: Two triangle cases, slow and fast, at 50 Hz: where every catalogue effect moves the window means.
CASES = (CasePlan("T01", "triangle", 50.0, amplitude_m=0.4e-3, period_s=40.0, duration_s=80.0),
         CasePlan("T02", "triangle", 50.0, amplitude_m=2.0e-3, period_s=10.0, duration_s=20.0))
RIG = rr.RigImperfections(force_noise_N=3.0, force_noise_rel=0.005, noise_corner_Hz=2.0)


def ids(records):
    return [e.name for e in records]


def away_from_default(field: str) -> float:
    """A value of an Effects field other than its default (a nominal-scale value where the default is None)."""
    default = {f.name: f.default for f in dataclasses.fields(Effects)}[field]
    return 0.5 if default is None else default + 0.1 * max(abs(default), 1e-3)


@pytest.fixture(scope="module")
def model():
    """The model's window means of CASES (the blind suite's detection problem, no rig in the loop)."""
    return gen.DetectionProblem.of("walk", CASES, DAMPER, RIG)


# ------------------------------------------------------------------------------------------ the registry

def test_records_have_unique_names_and_fields():
    assert len({e.name for e in REGISTRY}) == len(REGISTRY)
    assert len({e.field for e in REGISTRY}) == len(REGISTRY)
    assert effect("air").field == "air_volume_fraction"
    with pytest.raises(KeyError, match="unknown effect 'nope'"):
        effect("nope")


def test_catalogue_and_suite_effects_are_the_registry_in_its_order():
    assert tuple(e.name for e in FITTED) == CATALOGUE
    assert scenarios.CATALOGUE == search.CATALOGUE == verdict.CATALOGUE == joint.CATALOGUE == CATALOGUE
    assert scenarios.EFFECTS == BLIND_EFFECTS == tuple(e.name for e in DRAWN)
    assert set(BLIND_EFFECTS) <= set(CATALOGUE)


def test_the_blind_suite_draws_every_catalogue_effect_but_path_asymmetry():
    # path_asymmetry (issue 21) has no blind-suite draw yet; a new catalogue effect must come with one
    assert [e.name for e in FITTED if e.blind is None] == ["path_asymmetry"]


# ------------------------------------------------------------------------------------------ the model

def test_every_effects_field_belongs_to_one_records_config_group():
    fields = [field for e in REGISTRY for _key, field in e.config]
    assert sorted(fields) == sorted(f.name for f in dataclasses.fields(Effects))
    assert len(fields) == len(set(fields))


@pytest.mark.parametrize("record", REGISTRY, ids=ids(REGISTRY))
def test_model_sees_each_record_active_alone(record):
    assert record.field in record.config_keys.values()
    assert set(record.active_fields) <= set(record.config_keys.values())
    for field in record.active_fields:
        assert Effects(**{field: away_from_default(field)}).active() == [record.name]


@pytest.mark.parametrize("record", REGISTRY, ids=ids(REGISTRY))
def test_config_group_of_each_record_sets_its_fields(record):
    values = {key: away_from_default(field) for key, field in record.config}
    built = Effects.from_config({record.name: values})
    assert {field: getattr(built, field) for _key, field in record.config} == \
        {field: values[key] for key, field in record.config}


def test_config_schema_lists_each_records_group_and_keys():
    schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text(encoding="utf-8"))
    groups = schema["$defs"]["virtual_campaign"]["properties"]["effects"]["properties"]
    assert {g: set(v["properties"]) for g, v in groups.items()} == \
        {e.name: set(e.config_keys) for e in REGISTRY}


# ------------------------------------------------------------------------------ the search's parametrisation

@pytest.mark.parametrize("record", FITTED, ids=ids(FITTED))
def test_parametrisation_bounds_starts_and_maps_each_catalogue_record(record):
    p = Parametrisation(DAMPER, force_ref_N=500.0)
    lo, hi = p.bounds(record.name)
    assert math.isfinite(lo) and math.isfinite(hi) and lo < hi
    assert all(lo < x < hi for x in p.starts(record.name))
    transform = TRANSFORMS[record.fit.transform]
    for x in (*p.starts(record.name), lo, hi):
        name, value = p.si(record.name, x)
        assert name == record.field and math.isfinite(value)
        assert transform.from_si(p, record.field, value) == pytest.approx(x, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("record", FITTED, ids=ids(FITTED))
def test_each_catalogue_record_moves_the_model_it_is_fitted_to(record, model):
    p = Parametrisation(DAMPER, force_ref_N=500.0)
    x = max(p.starts(record.name), key=abs)
    effects = p.effects((record.name,), (x,))
    assert effects.active() == [record.name]
    assert np.max(np.abs(model.forces(effects) - model.nominal_N)) > 1e-6


def test_parametrisation_refuses_an_effect_outside_the_catalogue():
    with pytest.raises(KeyError, match="unknown effect 'backlash'"):
        Parametrisation(DAMPER, force_ref_N=500.0).si("backlash", 0.0)


# --------------------------------------------------------------------------- the diagnosis schema, the report

def test_diagnosis_schema_names_the_catalogue():
    assert diagnosis_schema()["$defs"]["effect"]["enum"] == list(CATALOGUE)


@pytest.mark.parametrize("record", FITTED, ids=ids(FITTED))
def test_report_shows_each_catalogue_parameter_in_its_unit(record):
    assert diagnosis_section.EFFECT_PARAM_UNITS[record.field] == record.unit
    source = Source(Path("results/c/diagnosis.json"), "results/c/diagnosis.json", False)
    (row,) = diagnosis_section._params({"params": {record.field: 1.5}}, source).rows
    assert row.cells[0].html == f"{record.display_name} <code>{record.field}</code>"
    assert row.cells[-1].html == diagnosis_section.formula(record.unit) != ""


# ------------------------------------------------------------------------------------------ the blind suite

@pytest.mark.parametrize("record", DRAWN, ids=ids(DRAWN))
def test_blind_suite_draws_each_record_within_its_bound(record, model):
    assert gen.BOUNDS[record.name] == record.blind.bound > 0
    assert gen.UNITS[record.name] == record.blind.unit
    assert gen.PARAM_KEYS[record.name] == record.field
    assert (record.name in gen.SIGNED) == record.blind.signed
    level = gen.detection_level(model, record.name)
    assert level is not None and level < record.blind.bound
    fields = gen.effect_fields(record.name, level, -1.0, DAMPER)
    assert list(fields) == [record.field] and Effects(**fields).active() == [record.name]


@pytest.mark.parametrize("record", FITTED, ids=ids(FITTED))
def test_reference_rig_has_each_catalogue_records_field(record):
    assert record.rig is not None and record.rig.field in {f.name for f in dataclasses.fields(rr.TrueEffects)}
    assert record.rig.conversion == "" or record.rig.conversion in gen.RIG_CONVERSIONS
    assert record.field in rrc.catalogue_equivalent(DAMPER, rr.TrueEffects())


@pytest.mark.parametrize("record", DRAWN, ids=ids(DRAWN))
def test_blind_suite_puts_each_record_on_the_reference_rig_and_reads_it_back(record):
    """The rig mapping against the rig's own reading of its physics in the catalogue's form."""
    magnitude = 0.01 * record.blind.bound
    (value,) = gen.effect_fields(record.name, magnitude, -1.0, DAMPER).values()
    truth = gen.physical_effects(DAMPER, {record.name: magnitude}, {record.name: -1.0}, charge_Pa=8.0e6)
    assert getattr(truth, record.rig.field) != getattr(rr.TrueEffects(), record.rig.field)
    assert rrc.catalogue_equivalent(DAMPER, truth)[record.field] == pytest.approx(value, rel=1e-9)
