"""The blind suite drawn (isokinetic.blind.generate): scenario generation on the reference rig, detection levels,
truth-free export."""

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from isokinetic.blind import generate as gen
from isokinetic.blind.generate import BOUNDS, effect_fields, generate_scenarios, magnitude_bin, write_suite
from isokinetic.contracts.scenarios import EFFECTS, EXPECTED_COST_S, balanced_chunks, kind_name
from isokinetic.measurement.windows import case_windows
from isokinetic.physics.damper import TABLE_1, Effects
from isokinetic.physics.virtual_rig import Measurement, simulate_cases
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

SEED = 11
SUITE = {"n_per_effect": 1, "n_pairs": 2, "n_none": 1, "n_out": 3}


@pytest.fixture(scope="module")
def suite():
    return generate_scenarios(SEED, **SUITE)


def tree_hashes(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------------------------
# generation
# --------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_generation_is_deterministic_and_composed_as_asked(suite):
    assert generate_scenarios(SEED, **SUITE) == suite
    assert generate_scenarios(SEED + 1, **SUITE) != suite
    assert [s.name for s in suite] == [f"blind-{k:03d}" for k in range(12)]
    sizes = sorted(len(s.truth) for s in suite)
    assert sizes == [0] * 4 + [1] * 6 + [2] * 2
    assert sorted(s.out_of_catalogue for s in suite if s.out_of_catalogue) == sorted(gen.OUT_OF_CATALOGUE[:3])
    assert all(not s.truth for s in suite if s.out_of_catalogue)
    assert sorted(s.truth[0] for s in suite if len(s.truth) == 1) == sorted(EFFECTS)
    assert len({s.truth for s in suite if len(s.truth) == 2}) == 2  # distinct pairs
    for s in suite:
        assert s.truth == tuple(e for e in EFFECTS if e in s.truth)
        for name in gen.GEOMETRY_FIELDS:
            assert 0.7 <= getattr(s.damper, name) / getattr(TABLE_1, name) <= 1.3
        speeds = [c.velocity_m_s * 1e3 for c in s.cases]
        assert 8 <= len(speeds) <= 12 and min(speeds) >= 0.005 and max(speeds) <= 1.5
        assert speeds != sorted(speeds)  # tested in a random order, not by speed
        for c in s.cases:
            assert 0.3e-3 * (1 - 1e-9) <= c.amplitude_m <= 8e-3 and c.period_s in (20.0, 80.0, 240.0)
            shorter = [t for t in (20.0, 80.0, 240.0) if t < c.period_s]
            assert all(c.velocity_m_s * t / 4 < 0.3e-3 for t in shorter)  # shortest period above the floor
            assert c.sample_rate_Hz == 50.0 and c.duration_s == 2 * c.period_s
        r, ranges = s.rig, gen.RIG_RANGES  # nuisances in every scenario
        assert ranges["delay_s"][0] <= r.delay_s <= ranges["delay_s"][1] and r.servo_lag_s > 0
        assert 2 <= r.force_noise_N <= 10 and 0.005 <= r.force_noise_rel <= 0.015
        assert 0.1 <= r.noise_corner_Hz <= 5.0 and abs(r.force_gain - 1) <= 0.01 and r.force_offset_N != 0
        assert abs(r.force_offset_N) <= 0.02 * gen.full_scale_N(s.damper, s.cases)


def test_sensor_chain_nuisances_are_drawn_in_every_scenario(suite):
    lo, hi = gen.SENSOR_RANGES["force_filter_Hz"]
    filtered = [s for s in suite if s.rig.force_filter_Hz > 0]
    assert 0 < len(filtered) < len(suite)  # a low-pass in some scenarios, none in others
    for s in suite:
        r = s.rig
        assert r.force_filter_Hz == 0 or (lo <= r.force_filter_Hz <= hi and r.force_filter_order in (1, 2))
        assert 0 < abs(r.displacement_gain - 1) <= 0.015
        duration = sum(c.duration_s + 1 / c.sample_rate_Hz for c in s.cases)
        assert 0 < abs(r.force_drift_N_s) * duration <= 0.002 * gen.full_scale_N(s.damper, s.cases) * (1 + 1e-3)
        assert 0 <= r.dropout_fraction <= 0.01


def test_without_the_sensor_chain_the_same_scenarios_have_an_ideal_one(suite):
    ideal = generate_scenarios(SEED, **SUITE, sensor_chain=False)
    chain = {"force_filter_Hz": 0.0, "force_filter_order": 2, "displacement_gain": 1.0, "force_drift_N_s": 0.0,
             "dropout_fraction": 0.0}
    assert ideal == [dataclasses.replace(s, rig=dataclasses.replace(s.rig, **chain)) for s in suite]


def test_truth_records_each_sensor_chain_nuisance(suite):
    for s in suite:
        inst, r = s.truth_record()["instrument"], s.rig
        order = 1.0 if r.force_filter_order == 1 else math.sqrt(2.0)
        lag = 0.0 if r.force_filter_Hz == 0 else order / (2 * math.pi * r.force_filter_Hz)
        assert inst["force_lag_s"] == pytest.approx(lag, rel=1e-12, abs=0.0)
        assert inst["displacement_scale"] == r.displacement_gain and inst["force_drift_N_s"] == r.force_drift_N_s
        middle = sum(c.duration_s + 1 / c.sample_rate_Hz for c in s.cases) / 2  # the offset a campaign fit sees
        assert inst["force_offset_N"] == pytest.approx(r.force_offset_N + r.force_drift_N_s * middle, rel=1e-12)
        assert s.truth_record()["rig"]["dropout_fraction"] == r.dropout_fraction


def test_magnitudes_lie_between_1_and_5_detection_levels(suite):
    for s in suite:
        assert set(s.multiple) == set(s.detection_level) == set(s.magnitude) == set(s.truth)
        for e in s.truth:
            assert 1.0 <= s.multiple[e] <= 5.0
            assert s.magnitude[e] == pytest.approx(s.multiple[e] * s.detection_level[e], rel=1e-12)
            assert 5.0 * s.detection_level[e] <= BOUNDS[e]
        if s.truth:
            assert s.magnitude_x_detection == min(s.multiple.values())
        else:
            assert math.isnan(s.magnitude_x_detection)


def test_physical_effects_have_the_drawn_catalogue_magnitudes(suite):
    for s in suite:
        params = s.truth_params()
        for e in s.truth:
            key = gen.PARAM_KEYS[e]
            want = effect_fields(e, s.magnitude[e], s.sign[e], s.damper)
            expected = next(iter(want.values()))
            assert params[key] == pytest.approx(expected, rel=1e-6), (s.name, e)


def _independent_rms_z(scenario, effects: Effects) -> float:
    """rms_z of the noise-free effect against the nominal, from the virtual rig's time series, the
    window extraction and the rig's exact noise of a window mean."""
    ideal = Measurement.ideal()
    with_effect = simulate_cases(scenario.cases, scenario.damper, effects, ideal, 0)
    nominal = simulate_cases(scenario.cases, scenario.damper, Effects(), ideal, 0)
    z = []
    for c in scenario.cases:
        for we, w0 in zip(case_windows(c, with_effect[c.case]), case_windows(c, nominal[c.case]), strict=True):
            f = we["force_N"]
            se = math.sqrt(rrc.mean_noise_variance(we["n_samples"], f, scenario.rig, c.sample_rate_Hz))
            z.append((f - w0["force_N"]) / se)
    return float(np.sqrt(np.mean(np.square(z))))


def test_detection_level_gives_rms_z_3_checked_independently(suite):
    seen = set()
    for s in suite:
        for e in s.truth:
            if e in seen:
                continue
            seen.add(e)
            def at(k, s=s, e=e):
                return Effects(**effect_fields(e, k * s.detection_level[e], s.sign[e], s.damper))
            assert _independent_rms_z(s, at(1.0)) == pytest.approx(3.0, rel=1e-4), (s.name, e)
            assert _independent_rms_z(s, at(0.5)) < 3.0  # the smallest magnitude reaching 3
    assert seen == set(EFFECTS)


def test_undetectable_effect_gives_no_detection_level(suite):
    s = next(s for s in suite if not s.truth)
    problem = gen.DetectionProblem.of(s.name, s.cases, s.damper, s.rig)
    assert gen.detection_level(problem, "friction", bound=1e-3) is None
    assert gen.detection_level(problem, "friction") == pytest.approx(
        gen.detection_level(problem, "friction", bound=10 * BOUNDS["friction"]), rel=1e-5)


# --------------------------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_export_holds_no_truth_and_is_byte_reproducible(suite, tmp_path):
    write_suite(suite, tmp_path / "a" / "raw", tmp_path / "a" / "truth")
    write_suite(generate_scenarios(SEED, **SUITE), tmp_path / "b" / "raw", tmp_path / "b" / "truth")
    assert tree_hashes(tmp_path / "a") == tree_hashes(tmp_path / "b")
    raw = tmp_path / "a" / "raw"
    assert sorted(p.name for p in raw.iterdir()) == [s.name for s in suite]
    for s in suite:
        folder = raw / s.name
        assert sorted(p.name for p in folder.iterdir()) == sorted(["campaign.yaml"] + [f"{c.case}.csv"
                                                                                      for c in s.cases])
        header = (folder / f"{s.cases[0].case}.csv").read_text(encoding="utf-8").splitlines()[0]
        assert "command_um" in header.split(",")  # the command channel that makes the LVDT gain measurable
        text = (folder / "campaign.yaml").read_text(encoding="utf-8")
        manifest = yaml.safe_load(text)
        # the damper block is the nominal design data (checked below); everything else names no effect
        lowered = yaml.safe_dump({k: v for k, v in manifest.items() if k != "damper"}).lower()
        for word in EFFECTS + gen.OUT_OF_CATALOGUE + ("effects:", "seed", "truth", "coulomb", "conductance",
                                                         "volume_fraction", "multiple", "detection", "offset", "gain"):
            assert word not in lowered, (s.name, word)
        for value in s.magnitude.values():
            assert repr(value) not in text and f"{value:.6g}" not in text
        assert manifest["source"] == "simulation" and manifest["campaign"] == s.name
        assert manifest["description"] == gen.DESCRIPTION
        # nominal: no off-nominal C_D or viscosity; the charge pressure is design data (air follows the gas law)
        assert manifest["damper"] == {**s.damper.to_dict(), "charge_pressure_Pa": s.effects.charge_pressure_Pa}
        truth = json.loads((tmp_path / "a" / "truth" / f"{s.name}.json").read_text(encoding="utf-8"))
        assert truth["truth"] == list(s.truth) and truth["multiple"] == s.multiple
        assert truth["out_of_catalogue"] == s.out_of_catalogue
        assert truth["magnitude_bin"] == magnitude_bin(s.magnitude_x_detection)


# --------------------------------------------------------------------------------------------
# composition, chunks and sine-only scenarios (issues 21 and 23)
# --------------------------------------------------------------------------------------------

def test_sine_scenarios_follow_the_same_triangle_suite_and_take_none_then_each_effect_in_turn():
    triangles = gen.suite_composition(SEED, **SUITE)
    composed = gen.suite_composition(SEED, **SUITE, n_sine=9)
    assert composed[:len(triangles)] == triangles and {k[3] for k in triangles} == {"triangle"}
    sines = composed[len(triangles):]
    assert [k[3] for k in sines] == ["sine"] * 9 and not any(k[2] for k in sines)
    expected = [()] + [(e,) for e in EFFECTS] + [(), ("friction",)]
    assert sorted(k[0] for k in sines) == sorted(expected)
    assert all(set(k[1]) == set(k[0]) and all(1.0 <= m <= 5.0 for m in k[1].values()) for k in sines)


def test_chunks_hold_every_scenario_once_balanced_within_one_scenarios_cost():
    kinds = gen.suite_composition(SEED, 2, 3, 3, 3, n_sine=5)
    for n_chunks in (1, 2, 3):
        chunks = balanced_chunks(kinds, n_chunks)
        assert sorted(i for c in chunks for i in c) == list(range(len(kinds)))
        assert all(c == sorted(c) for c in chunks)
        loads = [sum(EXPECTED_COST_S[kind_name(kinds[i])] for i in c) for c in chunks]
        assert max(loads) - min(loads) <= max(EXPECTED_COST_S.values())


@pytest.fixture(scope="module")
def sine_suite():
    return generate_scenarios(SEED, 0, 0, 0, 0, n_sine=3)


def test_a_chunk_is_generated_as_in_the_whole_suite(sine_suite):
    assert generate_scenarios(SEED, 0, 0, 0, 0, n_sine=3, names=["blind-002"]) == [sine_suite[2]]
    with pytest.raises(ValueError, match="not in the suite"):
        generate_scenarios(SEED, 0, 0, 0, 0, n_sine=3, names=["blind-003"])


def test_sine_scenarios_are_sweeps_of_0_2_to_10_hz_behind_the_same_nuisances(sine_suite):
    assert sorted(s.truth for s in sine_suite) == sorted([(), ("friction",), ("leakage",)])
    for s in sine_suite:
        assert s.waveform == "sine" and s.truth_record()["waveform"] == "sine"
        freqs = sorted(c.frequency_Hz for c in s.cases)
        assert 5 <= len(freqs) <= 7 and freqs[0] == 0.2 and freqs[-1] == 10.0
        assert [c.frequency_Hz for c in s.cases] != freqs  # tested in a random order
        for c in s.cases:
            assert c.sample_rate_Hz == 1000.0 and c.duration_s * c.frequency_Hz == pytest.approx(4.0)
            assert 0.03e-3 <= 2 * math.pi * c.frequency_Hz * c.amplitude_m <= 1.5e-3 * (1 + 1e-3)
        assert abs(s.rig.force_offset_N) > 0 and 0 < abs(s.rig.displacement_gain - 1) <= 0.015


def _reference_bins(case, force_N, time_s):
    """Phase-bin means of one sine record: 16 bins per cycle, every whole cycle after the first."""
    cycle = np.asarray(time_s) * case.frequency_Hz
    k = np.floor((cycle - 1.0) * 16 + 1e-9).astype(int)
    used = (cycle >= 1.0 - 1e-12) & (k < 3 * 16)
    n = np.bincount(k[used])
    return np.bincount(k[used], weights=np.asarray(force_N)[used]) / n, n


def _reference_rms_z(scenario, effects) -> float:
    """rms_z of the noise-free effect against the nominal on the reference rig (ideal rig, exact catalogue
    forms of friction and viscosity), binned here, with the rig's exact noise of a bin mean."""
    z = []
    for rc, c in zip(scenario.rig_cases(), scenario.cases, strict=True):
        design = rr.DamperDesign.from_mapping(scenario.damper.to_dict())
        eff = rr.true_series(rc, design, effects)
        nom = rr.true_series(rc, design, gen.physical_effects(scenario.damper, {}, {}))
        fe, n = _reference_bins(c, eff["force_N"], eff["time_s"])
        f0, _ = _reference_bins(c, nom["force_N"], nom["time_s"])
        se = np.sqrt([rrc.mean_noise_variance(int(k), float(f), scenario.rig, c.sample_rate_Hz)
                      for k, f in zip(n, fe, strict=True)])
        z.extend((fe - f0) / se)
    return float(np.sqrt(np.mean(np.square(z))))


def test_sine_detection_level_gives_rms_z_3_checked_on_the_reference_rig(sine_suite):
    # the level is the planned sine's: the servo's distortion (which moves it by about a tenth) left out here
    s = dataclasses.replace(next(s for s in sine_suite if s.truth == ("friction",)), sine_harmonics=())
    level = s.detection_level["friction"]
    at = lambda k: gen.physical_effects(s.damper, {"friction": k * level}, {})  # noqa: E731
    assert _reference_rms_z(s, at(1.0)) == pytest.approx(3.0, rel=2e-3)
    assert _reference_rms_z(s, at(0.5)) < 3.0


def test_a_sine_scenarios_load_cell_offset_stays_within_5_percent_of_its_largest_force(sine_suite):
    # the full scale follows the force the sweep reaches (compressibility holds a stiff damper's force at a few
    # Hz far below the steady force at the same peak speed), not the steady force
    for s in sine_suite:
        design = rr.DamperDesign.from_mapping(s.damper.to_dict())
        peak = max(float(np.abs(rr.true_series(rc, design)["force_N"]).max()) for rc in s.rig_cases())
        assert abs(s.rig.force_offset_N) <= 0.05 * peak
