"""Rule virtual_rig (stages.virtual_rig): sensor model and determinism, config parsing, the ingested
campaign and the raw-campaign export, the export-virtual command."""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.__main__ import main
from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.physics import damper as dm
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import true_response
from isokinetic.physics.virtual_rig import Measurement, simulate_case
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign, write_campaign
from testconfig import TEST_CONFIG as CONFIG

UNIT_SI = {"s": 1.0, "mm": 1e-3, "kN": 1e3}      # raw-campaign-format units used by the export


@pytest.fixture(scope="module")
def config_mapping():
    return yaml.safe_load(CONFIG.read_text())["virtual_campaigns"]["paper-lag-damper"]


@pytest.fixture(scope="module")
def paper(config_mapping):
    return VirtualCampaign.from_config("paper-lag-damper", config_mapping)


def triangle(w_m_s=1.0e-3, period_s=20.0, rate_Hz=100.0, periods=2.0, case="T99"):
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=w_m_s * period_s / 4,
                    period_s=period_s, phase_rad=-math.pi / 2, duration_s=periods * period_s)


# ---------------------------------------------------------------------------------- measurement

def test_same_seed_gives_identical_records(paper):
    c = paper.case("T22")
    a = simulate_case(c, paper.damper, paper.effects, paper.measurement, paper.seed)
    b = simulate_case(c, paper.damper, paper.effects, paper.measurement, paper.seed)
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    other = simulate_case(c, paper.damper, paper.effects, paper.measurement, paper.seed + 1)
    assert not np.array_equal(a.force_N, other.force_N)


def test_record_covers_two_periods_with_schema(paper):
    c = paper.case("T22")
    df = simulate_case(c, paper.damper, paper.effects, paper.measurement, paper.seed)
    tables.validate_table(df, tables.TIMESERIES)
    assert list(df.columns) == ["row", "time_s", "displacement_m", "force_N", "command_m"]
    assert len(df) == int(c.duration_s * c.sample_rate_Hz) + 1
    assert df.time_s.iloc[-1] == c.duration_s and df.row.dtype == np.int64


def test_noise_has_the_stated_levels(paper):
    c = paper.case("T22")
    m = paper.measurement
    df = simulate_case(c, paper.damper, paper.effects, m, paper.seed)
    truth = true_response(c, paper.damper, paper.effects)
    expected = np.sqrt(m.force_noise_N**2 + (m.force_noise_rel * truth.force_N) ** 2)
    assert ((df.force_N - truth.force_N) / expected).std() == pytest.approx(1.0, abs=0.03)
    assert (df.displacement_m - truth.command_m).std() == pytest.approx(m.displacement_noise_m, rel=0.03)


def test_channels_are_quantised_to_the_stated_resolution(paper):
    m = paper.measurement
    df = simulate_case(paper.case("T22"), paper.damper, paper.effects, m, paper.seed)
    for col, res in (("force_N", m.force_resolution_N), ("displacement_m", m.displacement_resolution_m),
                     ("command_m", m.command_resolution_m)):
        counts = df[col] / res
        assert np.abs(counts - np.rint(counts)).max() < 1e-6, col


def test_cases_get_independent_noise(paper):
    m = Measurement(force_noise_N=5.0, force_resolution_N=0.0)
    a = simulate_case(triangle(case="T01"), TABLE_1, dm.NOMINAL, m, 1)
    b = simulate_case(triangle(case="T02"), TABLE_1, dm.NOMINAL, m, 1)
    ra = a.force_N - true_response(triangle(), TABLE_1).force_N
    rb = b.force_N - true_response(triangle(), TABLE_1).force_N
    assert abs(np.corrcoef(ra, rb)[0, 1]) < 0.1


# ---------------------------------------------------------------------------------- config

def test_from_config_converts_mm_to_m(paper, config_mapping):
    t01 = paper.case("T01")
    w = config_mapping["plan"]["triangle"]["velocities_mm_s"][0] * 1e-3
    assert t01.velocity_m_s == pytest.approx(w, rel=1e-12)
    assert paper.case("H04").amplitude_m == pytest.approx(0.64e-3, rel=1e-12)
    assert len(paper.cases) == 27 and paper.effects.asymmetry == 0.06


@pytest.mark.parametrize("mutate, key", [
    (lambda m: m.pop("seed"), "seed"),
    (lambda m: m["damper"].pop("orifice_area_m2"), "orifice_area_m2"),
    (lambda m: m["plan"]["triangle"].pop("periods_s"), "periods_s"),
    (lambda m: m["measurement"].update(bogus=1.0), "bogus"),
    (lambda m: m["effects"].update(magic={"x": 1.0}), "magic"),
    (lambda m: m.update(colour="red"), "colour"),
])
def test_from_config_errors_name_the_key(config_mapping, mutate, key):
    mapping = yaml.safe_load(yaml.safe_dump(config_mapping))
    mutate(mapping)
    with pytest.raises((KeyError, ValueError), match=key):
        VirtualCampaign.from_config("paper-lag-damper", mapping)


def test_a_virtual_campaign_may_declare_its_charge_pressure_and_its_air_follows_the_gas_law(config_mapping):
    mapping = yaml.safe_load(yaml.safe_dump(config_mapping))
    mapping["damper"]["charge_pressure_Pa"] = 1.0e7
    mapping["effects"] = {"air": {"volume_fraction": 3e-4}}
    mapping.get("measurement", {}).pop("servo_stiffness_N_m", None)
    vc = VirtualCampaign.from_config("paper-lag-damper", mapping)
    assert vc.damper.charge_pressure_Pa == 1.0e7 and vc.damper.to_dict()["charge_pressure_Pa"] == 1.0e7
    case = triangle(w_m_s=1.2e-3)
    with_gas = true_response(case, vc.damper, vc.effects)["force_N"].to_numpy()
    constant = true_response(case, dataclasses.replace(vc.damper, charge_pressure_Pa=None), vc.effects)
    assert np.max(np.abs(with_gas - constant["force_N"].to_numpy())) > 1e-3 * np.max(np.abs(with_gas))


# ---------------------------------------------------------------------------------- outputs

def small(paper) -> VirtualCampaign:
    keep = {"T22", "H01"}
    return dataclasses.replace(paper, cases=tuple(c for c in paper.cases if c.case in keep))


def test_export_is_byte_reproducible(paper, tmp_path):
    a = export_raw_campaign(paper, tmp_path / "a" / "lag", cases=["T22", "H01"], name="lag")
    b = export_raw_campaign(paper, tmp_path / "b" / "lag", cases=["T22", "H01"], name="lag")
    files = sorted(p.name for p in a.iterdir())
    assert files == ["H01.csv", "T22.csv", "campaign.yaml"]
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes()


def test_export_manifest_has_nominal_damper_and_provenance(paper, tmp_path):
    out = export_raw_campaign(paper, tmp_path / "lag", cases=["H01", "T22"], sample_rate_Hz=50.0, name="lag")
    manifest = yaml.safe_load((out / "campaign.yaml").read_text())
    assert manifest["format_version"] == 1 and manifest["source"] == "simulation" and manifest["campaign"] == "lag"
    assert manifest["damper"] == paper.damper.to_dict()
    assert manifest["columns"]["force"] == {"name": "force_kN", "unit": "kN"}
    assert manifest["generated_by"] == {"generator": "isokinetic.virtual_rig", "config_campaign": "paper-lag-damper",
                                        "seed": paper.seed, "cases": ["T22", "H01"], "sample_rate_Hz": 50.0}
    text = (out / "campaign.yaml").read_text()
    assert "effects" not in manifest and "coulomb" not in text and "conductance" not in text


def test_export_round_trips_the_simulated_series(paper, tmp_path):
    out = export_raw_campaign(paper, tmp_path / "lag", cases=["T22", "H01"], sample_rate_Hz=50.0, name="lag")
    manifest = yaml.safe_load((out / "campaign.yaml").read_text())
    for entry in manifest["cases"]:
        c = dataclasses.replace(paper.case(entry["id"]), sample_rate_Hz=50.0)
        sim = simulate_case(c, paper.damper, paper.effects, paper.measurement, paper.seed)
        raw = pd.read_csv(out / entry["file"])
        for channel, col in (("time", "time_s"), ("displacement", "displacement_m"), ("force", "force_N"),
                             ("command", "command_m")):
            spec = manifest["columns"][channel]
            back = raw[spec["name"]].to_numpy() * UNIT_SI[spec["unit"]]
            np.testing.assert_allclose(back, sim[col], rtol=1e-12, atol=0)
        assert entry["amplitude_mm"] * 1e-3 == pytest.approx(c.amplitude_m, rel=1e-12)


def test_export_refuses_non_empty_folder(paper, tmp_path):
    target = tmp_path / "lag"
    target.mkdir()
    (target / "keep.txt").write_text("x")
    with pytest.raises(FileExistsError):
        export_raw_campaign(paper, target, cases=["T22"], name="lag")
    assert sorted(p.name for p in target.iterdir()) == ["keep.txt"]


def test_write_campaign_ingest_has_nominal_damper_and_csv_hashes(paper, tmp_path):
    vc = small(paper)
    write_campaign(vc, tmp_path / "res")
    ing = CampaignFolder.at(tmp_path / "res")
    assert ing.meta.damper == paper.damper and ing.meta.source == "simulation"
    assert "coulomb" not in (tmp_path / "res" / "ingest" / "campaign.json").read_text()
    assert list(ing.ingested_cases().case) == ["T22", "H01"] and (ing.ingested_cases().status == "ok").all()
    assert ing.ingested_cases().raw_file.iloc[0] == "virtual_rig:paper-lag-damper/T22"
    raw = export_raw_campaign(vc, tmp_path / "raw" / "paper-lag-damper")
    for case, sha in zip(ing.ingested_cases().case, ing.ingested_cases().raw_sha256):
        assert sha == hashlib.sha256((raw / f"{case}.csv").read_bytes()).hexdigest()
    ts = ing.timeseries("T22")
    pd.testing.assert_frame_equal(ts, simulate_case(vc.case("T22"), vc.damper, vc.effects, vc.measurement, vc.seed))


def test_cli_exports_selected_cases_and_refuses_existing(tmp_path, capsys):
    out = tmp_path / "tiny"
    args = ["export-virtual", "--config", str(CONFIG), "--campaign", "paper-lag-damper", "--out", str(out),
            "--cases", "T22,H01", "--sample-rate-Hz", "50", "--name", "tiny"]
    assert main(args) == 0
    manifest = yaml.safe_load((out / "campaign.yaml").read_text())
    assert manifest["campaign"] == "tiny" and [c["id"] for c in manifest["cases"]] == ["T22", "H01"]
    assert manifest["sample_rate_Hz"] == 50.0
    assert main(args) == 1
    assert "non-empty" in capsys.readouterr().err
