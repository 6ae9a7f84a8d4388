"""The sim-to-real gap diagnosis, checked on virtual campaigns whose truth the diagnosis never sees."""

import json
import math

import jsonschema
import numpy as np
import pandas as pd
import pytest

from isokinetic import diagnosis as dg
from isokinetic.characteristic import assemble
from isokinetic.damper import Damper, Effects
from isokinetic.io import write_parquet
from isokinetic.plan import CasePlan
from isokinetic.repeatability import repeatability
from isokinetic.validate import write_validated
from isokinetic.virtual_rig import Measurement, VirtualCampaign, write_campaign
from isokinetic.windows import windows_stage

TABLE1 = Damper(piston_area_m2=4.0e-3, chamber_volume_1_m3=3.0e-4, chamber_volume_2_m3=3.0e-4,
                orifice_area_m2=6.0e-8, orifice_length_m=5.0e-4, discharge_coefficient=0.6,
                density_kg_m3=815.0, viscosity_Pa_s=0.03, oil_compressibility_1_Pa=3.8e-9)
# speeds [mm/s] and periods [s]: across the laminar-turbulent transition, the fast ones short
PLAN = [(0.01, 80.0), (0.05, 80.0), (0.2, 20.0), (0.5, 20.0), (1.0, 20.0), (1.5, 20.0)]


def process(tmp_path, effects: Effects, seed: int = 3):
    """Simulate a small campaign and run the real stage chain up to the characteristic."""
    cases = tuple(CasePlan(case=f"T{i:02d}", waveform="triangle", sample_rate_Hz=20.0, amplitude_m=w * 1e-3 * t / 4,
                           period_s=t, duration_s=2 * t) for i, (w, t) in enumerate(PLAN, start=1))
    vc = VirtualCampaign(name="virt", description="", seed=seed, temperature_C=40.0, damper=TABLE1, effects=effects,
                         measurement=Measurement(force_noise_N=5.0, force_noise_rel=0.01, displacement_noise_m=1e-6),
                         cases=cases)
    root = tmp_path / "virt"
    write_campaign(vc, root)
    write_validated(root)
    win = windows_stage(root)
    rep = repeatability(win, 0.05)
    write_parquet(assemble(win, rep), root / "characteristic.parquet")
    return root


def test_nominal_damper_gets_an_empty_verdict(tmp_path):
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects()))
    assert result["verdict"] == [] and result["nominal_explains"]
    assert 0.5 < result["gap_before"] < 2.0  # noise only: rms_z about 1
    assert result["where"] == []


def test_leakage_is_attributed_and_its_conductance_recovered(tmp_path):
    truth = 1.5e-12
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects(leakage_conductance_m3_s_Pa=truth)))
    assert result["verdict"] == ["leakage"] and result["explained"]
    assert result["params"]["leakage_conductance_m3_s_Pa"] == pytest.approx(truth, rel=0.02)
    assert result["gap_after"] < 2.0 and result["holdout_gap_after"] < 2.0
    assert result["shrink"] == pytest.approx(result["gap_before"] / result["gap_after"])
    # leakage weakens the damper everywhere: every significant band has a negative relative error
    assert result["where"] and all(b["mean_rel_error"] < 0 for b in result["where"])


def test_air_is_told_apart_from_leakage_by_the_transients(tmp_path):
    result, _obs, _pred = dg.diagnose(process(tmp_path, Effects(air_volume_fraction=0.002)))
    assert result["verdict"] == ["air"]
    assert result["params"]["air_volume_fraction"] == pytest.approx(0.002, rel=0.05)
    leak = next(c for c in result["candidates"] if c["effects"] == ["leakage"])
    assert not leak["explained"]


def test_diagnosis_json_validates_against_the_repository_schema(tmp_path):
    root = process(tmp_path, Effects(coulomb_force_N=20.0))
    out = dg.write_diagnosis(root, tmp_path / "diagnosis.json", tmp_path / "gap.png")
    written = json.loads((tmp_path / "diagnosis.json").read_text())
    assert written["verdict"] == ["friction"] == out["verdict"]
    assert (tmp_path / "gap.png").stat().st_size > 0
    dg.validate_diagnosis(written)
    for key in ("format_version", "campaign", "metric", "gap_before", "where", "candidates", "verdict",
                "gap_after", "holdout_gap_after", "shrink"):
        assert key in written
    scores = [c["score"] for c in written["candidates"] if c["explained"] and len(c["effects"]) == 1]
    assert scores == sorted(scores)


def test_schema_rejects_an_unknown_effect_name():
    bad = dg.no_model("x", "test") | {"verdict": ["temperature"]}
    with pytest.raises(jsonschema.ValidationError):
        dg.validate_diagnosis(bad)


def test_campaign_without_damper_data_is_reported_not_diagnosed():
    out = dg.no_model("raw-no-damper", "campaign.yaml has no damper block")
    dg.validate_diagnosis(out)
    assert out["status"] == "not_diagnosed" and out["verdict"] == []


def test_rms_z_is_one_for_unit_noise():
    z = np.random.default_rng(1).standard_normal(200_000)
    assert dg.rms(z) == pytest.approx(1.0, abs=0.01)


def test_parametrisation_maps_optimiser_units_to_si():
    p = dg.Parametrisation(TABLE1, force_ref_N=1000.0)
    c1 = 8 * math.pi * 0.03 * 5e-4 / 6e-8**2
    assert p.si("friction", 0.05) == ("coulomb_force_N", pytest.approx(50.0))
    assert p.si("leakage", 0.2) == ("leakage_conductance_m3_s_Pa", pytest.approx(0.2 / c1))
    assert p.si("discharge", math.log(1.5)) == ("discharge_coefficient", pytest.approx(0.9))
    assert p.si("viscosity", 0.0) == ("viscosity_Pa_s", pytest.approx(0.03))
    assert p.si("air", 2.0) == ("air_volume_fraction", pytest.approx(2.0 * 3.8e-9 / 9.9e-6))
    assert p.effects(("friction", "asymmetry"), (0.05, 0.1)) == Effects(coulomb_force_N=50.0, asymmetry=0.1)


def test_gap_bands_group_contiguous_points_of_equal_significance_and_sign():
    n = 6
    obs = dg.Observations(
        campaign="c", plans=(), case=np.array([f"T{i}" for i in range(n)], dtype=object),
        case_index=np.arange(n), kind=np.array(["window"] * n, dtype=object), segment=np.ones(n, dtype=np.int64),
        period=np.ones(n, dtype=np.int64), sign=np.ones(n), speed_m_s=np.arange(1, n + 1) * 1e-4,
        start=np.zeros(n, dtype=np.int64), stop=np.ones(n, dtype=np.int64),
        force_N=np.full(n, 100.0), sigma_N=np.ones(n), rep_rel=0.0)
    model = np.array([100.0, 100.5, 110.0, 112.0, 100.0, 90.0])  # z = 0, -0.5, -10, -12, 0, +10
    bands = dg.gap_bands(obs, model)
    got = [(b["v_min_m_s"], b["v_max_m_s"], b["significant"]) for b in bands]
    assert got == [(pytest.approx(1e-4), pytest.approx(2e-4), False), (pytest.approx(3e-4), pytest.approx(4e-4), True),
                   (pytest.approx(5e-4), pytest.approx(5e-4), False), (pytest.approx(6e-4), pytest.approx(6e-4), True)]
    assert bands[1]["mean_rel_error"] == pytest.approx(-0.11)  # damper 11 % weaker than the model
    assert bands[3]["mean_rel_error"] == pytest.approx(0.10)


def test_parametrisation_never_overflows_at_any_bound():
    p = dg.Parametrisation(TABLE1, force_ref_N=1000.0)
    for effect in dg.EFFECTS:
        lo, hi = p.bounds(effect)
        for x in (lo, hi, hi + 1e6, lo - 1e6):
            name, value = p.si(effect, x)
            assert math.isfinite(value), (effect, x, name)
