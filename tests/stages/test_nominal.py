"""Nominal model through the test plan (isokinetic.stages.nominal): converged windows against the closed
form Eq. (31), the convergence deficit of fast short cases, and agreement with the independent path
virtual_rig.simulate_case -> windows.extract_windows."""

from __future__ import annotations

import json
import logging
import math
import shutil

import numpy as np
import pandas as pd
import pytest

from isokinetic.contracts import tables
from isokinetic.measurement.model_windows import ModelPlan, model_windows
from isokinetic.measurement.windows import WindowSpec, extract_windows
from isokinetic.physics import damper as dm
from isokinetic.physics.damper import NOMINAL
from isokinetic.physics.damper import TABLE_1 as TABLE1
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.virtual_rig import Measurement, simulate_case
from isokinetic.stages.nominal import nominal_stage
from isokinetic.stages.validate import write_validated
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign

#: The paper's window, [0.45, 0.95] T/2 (the configuration's default)
PAPER = WindowSpec()


def tri(case: str, w_m_s: float, period_s: float, rate_Hz: float = 100.0, periods: float = 2.0) -> CasePlan:
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=w_m_s * period_s / 4,
                    period_s=period_s, phase_rad=-math.pi / 2, duration_s=periods * period_s)


def cases_table(plans: list[CasePlan], campaign: str = "unit", extra: list[dict] | None = None) -> pd.DataFrame:
    """A validated-style cases table of status-ok cases (plus raw rows in ``extra``)."""
    rows = [{"campaign": campaign, "case": p.case, "waveform": p.waveform, "sample_rate_Hz": p.sample_rate_Hz,
             "amplitude_m": p.amplitude_m, "period_s": p.period_s, "frequency_Hz": p.frequency_Hz,
             "phase_rad": p.phase_rad, "duration_s": p.duration_s, "raw_file": f"sim/{p.case}",
             "raw_sha256": "x", "timeseries_file": f"ingest/timeseries/{p.case}.parquet",
             "n_samples": int(round(p.duration_s * p.sample_rate_Hz)) + 1, "status": "ok"} for p in plans]
    return pd.DataFrame(rows + (extra or []))


# ------------------------------------------------------------------------ against Eq. (31)

def test_converged_windows_equal_incompressible_eq31():
    # 0.1 mm/s over T = 80 s: the compressibility transient (~0.1 s) is long over at 0.45 T/2 = 18 s
    out = model_windows("unit", cases_table([tri("T01", 1.0e-4, 80.0)]), TABLE1, NOMINAL, PAPER)
    assert len(out) == 4
    eq31 = dm.nominal_force(out["velocity_m_s"].to_numpy(), TABLE1)
    np.testing.assert_allclose(out["force_N"].to_numpy(), eq31, rtol=1e-4)
    assert out["velocity_m_s"].tolist() == pytest.approx([1e-4, -1e-4, 1e-4, -1e-4], rel=1e-9)


def test_fast_short_case_falls_below_eq31():
    # 1.5 mm/s over T = 20 s (paper case 23): turbulent relaxation of ~2 s is not over at 4.5 s
    out = model_windows("unit", cases_table([tri("T23", 1.5e-3, 20.0)]), TABLE1, NOMINAL, PAPER)
    eq31 = dm.nominal_force(out["velocity_m_s"].to_numpy(), TABLE1)
    ratio = out["force_N"].to_numpy() / eq31
    assert np.all(ratio < 0.99), ratio          # every window short of the steady force by > 1 %
    assert np.all(ratio > 0.5), ratio           # ... but a converging force, not nonsense
    assert np.all(out["force_std_N"] > 1e-3 * np.abs(out["force_N"]))   # still drifting in the window


def test_each_case_at_its_own_viscosity_follows_eq31_at_that_viscosity():
    # two converged cases, one at the damper's viscosity, one with the oil at 0.4 of it (a warm case)
    cases = cases_table([tri("T01", 1.0e-4, 80.0), tri("T02", 1.0e-4, 80.0)])
    out = model_windows("unit", cases, TABLE1, NOMINAL, PAPER, viscosity_scales={"T02": 0.4})
    thin = dm.Damper(**{**TABLE1.to_dict(), "viscosity_Pa_s": 0.4 * TABLE1.viscosity_Pa_s})
    for case, damper in (("T01", TABLE1), ("T02", thin)):
        w = out[out["case"] == case]
        eq31 = dm.nominal_force(w["velocity_m_s"].to_numpy(), damper)
        np.testing.assert_allclose(w["force_N"].to_numpy(), eq31, rtol=1e-4)


# ------------------------------------------------------- same as the rig's independent path

EFFECTS = dm.Effects(coulomb_force_N=60.0, leakage_conductance_m3_s_Pa=1e-12, asymmetry=0.08,
                     discharge_coefficient=0.7, backlash_m=2e-6)


def test_model_windows_match_simulated_records_through_extract_windows():
    plans = [tri("T01", 2e-5, 80.0, rate_Hz=50.0),
             tri("T02", 3e-4, 40.0, periods=2.3),          # longer record than the plan needs
             tri("T03", 1.2e-3, 20.0)]
    cases = cases_table(plans, extra=[{"campaign": "unit", "case": "H01", "waveform": "sine",
                                       "sample_rate_Hz": 1000.0, "amplitude_m": 2e-4, "period_s": math.nan,
                                       "frequency_Hz": 1.75, "phase_rad": 0.0, "duration_s": 2.0,
                                       "raw_file": "sim/H01", "raw_sha256": "x", "timeseries_file": "",
                                       "n_samples": 2001, "status": "ok"}])
    ours = model_windows("unit", cases, TABLE1, EFFECTS, WindowSpec(0.4, 0.9))
    series = {p.case: simulate_case(p, TABLE1, EFFECTS, Measurement.ideal(), seed=1) for p in plans}
    ref = extract_windows(cases, lambda row: series[row["case"]], WindowSpec(0.4, 0.9))
    assert len(ours) == len(ref) == 12
    exact = ["case", "segment", "direction", "period", "n_samples", "row_start", "row_stop", "window_start_s",
             "window_end_s", "campaign"]
    pd.testing.assert_frame_equal(ours[exact].reset_index(drop=True), ref[exact].reset_index(drop=True))
    for col in ("planned_velocity_m_s", "velocity_m_s", "force_N"):
        np.testing.assert_allclose(ours[col], ref[col], rtol=1e-9, err_msg=col)
    np.testing.assert_allclose(ours["force_std_N"], ref["force_std_N"], rtol=1e-6, atol=1e-9)
    assert set(ours["raw_file"]) == {"model:friction+leakage+asymmetry+discharge+backlash"}
    assert set(ours["raw_sha256"]) == {""}


def test_unknown_record_length_falls_back_to_sample_count():
    plan = tri("T01", 2e-4, 40.0)
    known = cases_table([plan])
    unknown = known.assign(duration_s=math.nan)
    pd.testing.assert_frame_equal(model_windows("unit", unknown, TABLE1, NOMINAL, PAPER),
                                  model_windows("unit", known, TABLE1, NOMINAL, PAPER))
    short = unknown.assign(n_samples=int(1.9 * 40.0 * 100))      # 1.9 T recorded: segment 4 incomplete
    assert model_windows("unit", short, TABLE1, NOMINAL, PAPER)["segment"].tolist() == [1, 2, 3]


def test_quarantined_and_sine_cases_are_skipped():
    cases = cases_table([tri("T01", 2e-4, 40.0), tri("T02", 3e-4, 40.0)])
    cases.loc[cases["case"] == "T02", "status"] = "quarantined"
    out = model_windows("unit", cases, TABLE1, NOMINAL, PAPER)
    assert set(out["case"]) == {"T01"}


def test_model_plan_reused_with_other_effects_matches_one_shot():
    cases = cases_table([tri("T01", 2e-4, 40.0), tri("T02", 8e-4, 20.0)])
    mp = ModelPlan.from_cases("unit", cases, PAPER)
    mp.forces(TABLE1)                                 # a first run must not leak into the next
    force, std = mp.forces(TABLE1, EFFECTS)
    ref = model_windows("unit", cases, TABLE1, EFFECTS, PAPER)
    np.testing.assert_array_equal(force, ref["force_N"].to_numpy())
    np.testing.assert_array_equal(std, ref["force_std_N"].to_numpy())


# ----------------------------------------------------------------------------- the stage

@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory):
    """A validated virtual campaign folder results/<campaign> with two triangle cases and one sine."""
    vc = VirtualCampaign.from_config("mini", {
        "seed": 3, "temperature_C": 40.0, "damper": TABLE1.to_dict(),
        "effects": {"friction": {"coulomb_force_N": 50.0}},
        "measurement": {"force_noise_N": 2.0},
        "plan": {"triangle": {"velocities_mm_s": [0.05, 0.8], "periods_s": [40, 20], "sample_rate_Hz": 20.0},
                 "sine": {"frequency_Hz": 1.75, "amplitudes_mm": [0.3], "periods": 2, "sample_rate_Hz": 200.0}},
    })
    root = tmp_path_factory.mktemp("results") / "mini"
    write_campaign(vc, root)
    write_validated(root)
    return root


def test_nominal_stage_simulates_the_validated_plan(small_campaign):
    out = nominal_stage(small_campaign, PAPER)
    tables.validate_table(out, tables.WINDOWS)
    assert sorted(set(out["case"])) == ["T01", "T02"] and len(out) == 8
    assert set(out["raw_file"]) == {"model:nominal"} and set(out["campaign"]) == {"mini"}
    measured = extract_windows(pd.read_parquet(small_campaign / "cases.parquet"),
                               lambda row: pd.read_parquet(small_campaign / row["timeseries_file"]), PAPER)
    # same windows as measured (rows, velocity); the nominal force lacks the 50 N friction
    assert out["row_start"].tolist() == measured["row_start"].tolist()
    np.testing.assert_allclose(out["velocity_m_s"], measured["velocity_m_s"], rtol=1e-3)
    slow = out["case"] == "T01"
    gap = (measured["force_N"].to_numpy() - out["force_N"].to_numpy()) * np.sign(out["velocity_m_s"].to_numpy())
    assert gap[slow.to_numpy()] == pytest.approx(50.0, abs=3.0)


def test_nominal_stage_uses_measured_length_when_duration_is_unknown(small_campaign, tmp_path):
    root = tmp_path / "mini"
    shutil.copytree(small_campaign, root)
    cases = pd.read_parquet(root / "cases.parquet")
    cases["duration_s"] = math.nan
    cases["n_samples"] = 0                               # force the measured series to be read
    cases.to_parquet(root / "cases.parquet", index=False)
    pd.testing.assert_frame_equal(nominal_stage(root, PAPER), nominal_stage(small_campaign, PAPER))


def test_nominal_stage_without_damper_block_is_empty(small_campaign, tmp_path, caplog):
    root = tmp_path / "mini"
    shutil.copytree(small_campaign, root)
    meta_path = root / "ingest" / "campaign.json"
    meta = json.loads(meta_path.read_text())
    meta["damper"] = None
    meta_path.write_text(json.dumps(meta))
    with caplog.at_level(logging.INFO, logger="isokinetic"):
        out = nominal_stage(root, PAPER)
    assert out.empty and list(out.columns) == list(tables.empty(tables.WINDOWS).columns)
    assert "no damper block" in caplog.text
