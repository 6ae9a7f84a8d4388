"""Rules characteristic and analysis: one job runs its stages in order, and writes what each stage would."""

from __future__ import annotations

import shutil

import numpy as np
import pandas as pd
import pytest

from isokinetic.contracts.outputs import RULE_STAGES, campaign_path, rule_figures, rule_outputs_of
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.analysis import write_analysis
from isokinetic.stages.characteristic import (
    assemble,
    paired_repeatability,
    records_stage,
    windows_stage,
    write_characteristic,
)
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign

#: Three short triangle cases and a sine case (the fewest the model fit accepts, and a harmonic record).
SPEC = {
    "description": "three short triangle cases and a sine", "seed": 11, "temperature_C": 40.0,
    "damper": {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
               "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
               "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9},
    "effects": {"friction": {"coulomb_force_N": 90.0}},
    "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
    "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8], "sample_rate_Hz": 20.0},
             "sine": {"frequency_Hz": 1.75, "amplitudes_mm": [0.3], "periods": 6, "sample_rate_Hz": 200.0}},
}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """results/<campaign>/ with the simulated campaign, its characteristic and its analysis."""
    root = tmp_path_factory.mktemp("results") / "small"
    write_campaign(VirtualCampaign.from_config("small", SPEC), root)
    write_characteristic(root, repeatability_tolerance=0.05)
    write_analysis(root)
    return root


def files_of(rule: str, root) -> list:
    paths = list(rule_outputs_of(rule).values()) + [f.path for f in rule_figures(rule)]
    return [root / p for p in paths]


def test_rules_run_their_stages_in_method_order():
    assert RULE_STAGES["characteristic"] == ("validate", "windows", "repeatability", "characteristic")
    assert RULE_STAGES["analysis"][-1] == "figures"          # figures read the others' tables
    assert RULE_STAGES["analysis"].index("nominal") < RULE_STAGES["analysis"].index("models")
    assert campaign_path("c", rule_outputs_of("characteristic")["windows"]) == "results/c/windows.parquet"


@pytest.mark.slow
@pytest.mark.parametrize("rule", ["characteristic", "analysis"])
def test_job_writes_every_output_of_its_stages(campaign, rule):
    missing = [p for p in files_of(rule, campaign) if not p.is_file() or p.stat().st_size == 0]
    assert not missing


@pytest.mark.slow
def test_characteristic_job_equals_its_stages_run_one_by_one(campaign):
    spec = WindowSpec()
    windows = windows_stage(campaign, spec)
    records, energy = records_stage(campaign)
    rep = paired_repeatability(windows, records, 0.05)
    pd.testing.assert_frame_equal(pd.read_parquet(campaign / "windows.parquet"), windows)
    pd.testing.assert_frame_equal(pd.read_parquet(campaign / "repeatability.parquet"), rep)
    pd.testing.assert_frame_equal(pd.read_parquet(campaign / "characteristic.parquet"), assemble(windows, rep, records))
    pd.testing.assert_frame_equal(pd.read_parquet(campaign / "energy.parquet"), energy)


@pytest.mark.slow
def test_analysis_job_reads_the_characteristic_job_outputs_only(campaign, tmp_path):
    # a folder with only what rule analysis takes as input gives the same tables
    copy = tmp_path / "small"
    shutil.copytree(campaign / "ingest", copy / "ingest")
    for name in ("cases.parquet", "windows.parquet", "characteristic.parquet"):
        shutil.copy(campaign / name, copy / name)
    written = write_analysis(copy)
    for rel in rule_outputs_of("analysis").values():
        assert copy / rel in written
        if rel.endswith(".csv"):
            assert (copy / rel).read_bytes() == (campaign / rel).read_bytes()
        else:
            pd.testing.assert_frame_equal(pd.read_parquet(copy / rel), pd.read_parquet(campaign / rel))


@pytest.mark.slow
def test_analysis_job_writes_the_static_force_of_the_campaign(campaign):
    # the simulated damper has friction but no static force: the interval holds 0
    table = pd.read_parquet(campaign / rule_outputs_of("analysis")["static_force"])
    row = table.iloc[0]
    assert (len(table), row["campaign"], row["source"], row["n_matched"]) == (1, "small", "characteristic", 3)
    assert row["ci_low_N"] <= 0.0 <= row["ci_high_N"]
    assert RULE_STAGES["analysis"].index("harmonic") < RULE_STAGES["analysis"].index("static_force")


@pytest.mark.slow
@pytest.mark.parametrize("table", ["characteristic", "models"])
def test_analysis_job_exports_the_characteristic_and_models_as_csv(campaign, table):
    # the CSV holds its Parquet table's numbers bit for bit, under a units row
    parquet = {"characteristic": "characteristic.parquet", "models": rule_outputs_of("analysis")["models"]}[table]
    csv_file = campaign / rule_outputs_of("analysis")[f"{table}_csv"]
    source = pd.read_parquet(campaign / parquet)
    back = pd.read_csv(csv_file, skiprows=[1], float_precision="round_trip")
    assert list(back.columns) == list(source.columns) and len(back) == len(source) > 0
    for col in source.select_dtypes(["float", "integer", "bool"]).columns:
        assert np.array_equal(back[col].to_numpy(), source[col].to_numpy(), equal_nan=source[col].dtype.kind == "f")
    units = dict(zip(source.columns, csv_file.read_text(encoding="utf-8").split("\n")[1].split(","), strict=True))
    assert units["force_N" if table == "characteristic" else "rms_residual_N"] == "N"
