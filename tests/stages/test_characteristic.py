"""The characteristic job on sine and free records (issue 19): peak-velocity points, free bins, the energy
per cycle, and the consumers (models, static force, diagnosis) on a campaign without triangle cases.

References come from the virtual rig's noise-free truth (physics.responses.true_response), not from the
method under test; the triangle tables are checked against the windows joined by hand."""

from __future__ import annotations

import copy
import io
import math
import shutil

import numpy as np
import pandas as pd
import pytest

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import timeseries_relpath
from isokinetic.io import write_parquet
from isokinetic.measurement.model_fit import fit_models
from isokinetic.measurement.repeatability import repeatability
from isokinetic.physics.responses import true_response
from isokinetic.stages.characteristic import assemble, record_points, write_characteristic
from isokinetic.stages.diagnosis import prepare
from isokinetic.stages.exports import csv_text
from isokinetic.stages.figures import write_campaign_figures
from isokinetic.stages.static_force import write_static_force
from isokinetic.stages.virtual_rig import VirtualCampaign, write_campaign
from rigfiles import dropout_rows

DAMPER = {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
          "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
          "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9}
#: Four sine steps of the paper's harmonic tests, 12 periods each, noisy sensors.
SINE = {
    "description": "sine steps only", "seed": 5, "temperature_C": 40.0, "damper": DAMPER,
    "effects": {"friction": {"coulomb_force_N": 90.0}, "leakage": {"conductance_m3_s_Pa": 2.2e-12}},
    "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
    "plan": {"sine": {"frequency_Hz": 1.75, "amplitudes_mm": [0.23, 0.38, 0.64], "periods": 12,
                      "sample_rate_Hz": 1000.0}},
}
TRIANGLE = {**SINE, "description": "triangle cases only",
            "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8],
                                  "sample_rate_Hz": 50.0}}}


def make(tmp_path_factory, name: str, spec: dict):
    root = tmp_path_factory.mktemp(name) / name
    vc = VirtualCampaign.from_config(name, spec)
    write_campaign(vc, root)
    return vc, root


@pytest.fixture(scope="module")
def sine_campaign(tmp_path_factory):
    vc, root = make(tmp_path_factory, "sines", SINE)
    write_characteristic(root)
    return vc, root


def truth_at_peak_velocity(vc: VirtualCampaign, case: str, skip_s: float) -> dict[str, float]:
    """Mean noise-free force at the velocity peaks after ``skip_s`` (parabola through the three samples
    around each peak, force interpolated at its vertex), per direction."""
    truth = true_response(vc.case(case), vc.damper, vc.effects)
    t, v, f = (truth[c].to_numpy(float) for c in ("time_s", "piston_velocity_m_s", "force_N"))
    out = {}
    for sign, d in ((1.0, "+"), (-1.0, "-")):
        sv = sign * v
        peaks = np.flatnonzero((sv[1:-1] > sv[:-2]) & (sv[1:-1] >= sv[2:]) & (sv[1:-1] > 0.5 * sv.max())) + 1
        peaks = peaks[t[peaks] > skip_s]
        forces = []
        for i in peaks:
            y0, y1, y2 = sv[i - 1:i + 2]
            shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
            forces.append(np.interp(t[i] + shift * (t[1] - t[0]), t, f))
        out[d] = float(np.mean(forces))
    return out


def test_sine_only_campaign_gives_peak_velocity_points(sine_campaign):
    _vc, root = sine_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    assert len(char) > 0 and set(char["method"]) == {"sine_peak"}
    assert set(char["case"]) == {"H01", "H02", "H03"}
    # two periods (halves of the steady cycles) per direction, so repeatability has a row per direction
    assert sorted(char.groupby("case").size().unique()) == [4]
    rep = pd.read_parquet(root / "repeatability.parquet")
    assert len(rep) == 6


def test_peak_velocity_force_matches_the_noise_free_force_within_1_percent(sine_campaign):
    vc, root = sine_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    for case, rows in char.groupby("case"):
        start = rows["window_start_s"].min()
        truth = truth_at_peak_velocity(vc, case, start)
        for d, g in rows.groupby("direction"):
            measured = np.average(g["force_N"], weights=g["n_samples"])
            assert measured == pytest.approx(truth[d], rel=0.01), (case, d)


def test_sine_point_standard_error_is_the_cycle_scatter(sine_campaign):
    _vc, root = sine_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    assert (char["n_samples"] >= 2).all()
    # period 1 and period 2 agree within a few standard errors of their difference
    for (_case, _d), g in char.groupby(["case", "direction"]):
        se = np.hypot(*(g["force_std_N"] / np.sqrt(g["n_samples"])))
        assert abs(g["force_N"].iloc[0] - g["force_N"].iloc[1]) < 5.0 * se + 0.005 * g["force_N"].abs().max()


def test_energy_per_cycle_matches_the_noise_free_loop_area(sine_campaign):
    vc, root = sine_campaign
    energy = pd.read_parquet(root / "energy.parquet")
    assert list(energy["case"]) == ["H01", "H02", "H03"]
    for row in energy.itertuples():
        truth = true_response(vc.case(row.case), vc.damper, vc.effects)
        t, x, f = (truth[c].to_numpy(float) for c in ("time_s", "actuator_m", "force_N"))
        period = 1.0 / row.frequency_Hz
        last = (t >= t[-1] - 4 * period)
        area = float(np.sum(0.5 * (f[last][1:] + f[last][:-1]) * np.diff(x[last]))) / 4.0   # 4 whole periods
        assert row.energy_J == pytest.approx(area, rel=0.01)
        assert row.energy_se_J < 0.01 * row.energy_J


def test_models_fit_a_sine_only_characteristic(sine_campaign):
    _vc, root = sine_campaign
    models, residuals = fit_models(pd.read_parquet(root / "characteristic.parquet"))
    wall = models[(models["model"] == "wallaschek") & (models["kind"] == "fitted")]
    assert set(wall["parameter"]) == {"F_C", "D_L", "D_Q"}
    assert np.isfinite(wall["estimate"]).all()
    assert len(residuals[residuals["model"] == "wallaschek"]) == 12


def test_static_force_uses_the_sine_points_without_triangle_cases(sine_campaign, tmp_path):
    _vc, root = sine_campaign
    work = tmp_path / "c"
    shutil.copytree(root, work)
    write_static_force(work)
    sf = pd.read_parquet(work / "static_force.parquet").iloc[0]
    assert sf["source"] == "characteristic" and sf["n_matched"] == 3


def test_a_sine_only_campaign_is_diagnosed_from_its_phase_bins(sine_campaign):
    _vc, root = sine_campaign
    _c, _d, cases, obs, reason = prepare(root)
    assert obs is not None, reason
    sines = cases.loc[(cases["status"] == "ok") & (cases["waveform"] == "sine"), "case"]
    assert set(obs.case) == set(sines) and len(sines) > 0
    assert {obs.plans[i].waveform for i in obs.case_index} == {"sine"}


def drop_rows(series: pd.DataFrame, fraction: float, seed: int) -> pd.DataFrame:
    """The series with ``fraction`` of its rows gone, in singles and bursts of 5-40 (:func:`rigfiles.dropout_rows`)."""
    return series.drop(index=series.index[dropout_rows(len(series), fraction, seed)]).reset_index(drop=True)


def test_dropped_samples_give_the_same_characteristic_within_its_standard_errors(sine_campaign, tmp_path):
    _vc, root = sine_campaign
    full = pd.read_parquet(root / "characteristic.parquet")
    work = tmp_path / "dropped"
    shutil.copytree(root / "ingest", work / "ingest")
    for case in full["case"].unique():
        path = work / timeseries_relpath(case)
        write_parquet(drop_rows(pd.read_parquet(path), 0.01, seed=len(case) + int(case[1:])), path)
    thin = write_characteristic(work)
    cases = pd.read_parquet(work / "cases.parquet")
    assert (cases["status"] == "ok").all()
    keys = ["case", "segment"]
    both = full.merge(thin, on=keys, suffixes=("", "_thin"), validate="one_to_one")
    assert len(both) == len(full)
    se = np.hypot(both["force_std_N"] / np.sqrt(both["n_samples"]),
                  both["force_std_N_thin"] / np.sqrt(both["n_samples_thin"]))
    assert (np.abs(both["force_N"] - both["force_N_thin"]) <= 3.0 * se).all()


@pytest.fixture(scope="module")
def triangle_campaign(tmp_path_factory):
    vc, root = make(tmp_path_factory, "tri", TRIANGLE)
    write_characteristic(root)
    return vc, root


def test_triangle_campaign_table_is_the_windows_with_their_flag_and_method(triangle_campaign):
    _vc, root = triangle_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    windows = pd.read_parquet(root / "windows.parquet")
    rep = pd.read_parquet(root / "repeatability.parquet")
    pd.testing.assert_frame_equal(rep, repeatability(windows, 0.05))
    keys = ["campaign", "case", "direction"]
    by_hand = windows.merge(rep[keys + ["flagged"]].rename(columns={"flagged": "repeatability_flagged"}), on=keys)
    by_hand = by_hand.sort_values(["velocity_m_s", "case", "segment"], ignore_index=True)
    assert list(char.columns) == [*windows.columns, "repeatability_flagged", "method", "force_se_N"]
    pd.testing.assert_frame_equal(char.drop(columns=["method", "force_se_N"]), by_hand)
    np.testing.assert_allclose(char["force_se_N"], char["force_std_N"] / np.sqrt(char["n_samples"]))
    assert set(char["method"]) == {"triangle_window"}
    assert pd.read_parquet(root / "energy.parquet").empty


def test_free_record_gives_velocity_bins_with_their_standard_error():
    t = np.arange(0.0, 8.0, 1e-3)
    x = 0.01 * np.sin(2 * math.pi * 1.3 * t) + 0.004 * np.sin(2 * math.pi * 3.1 * t + 0.4)
    v = np.gradient(x, t)
    f = 2000.0 * v + 30000.0 * v * np.abs(v) + np.random.default_rng(3).normal(0.0, 2.0, t.size)
    series = pd.DataFrame({"row": np.arange(t.size, dtype=np.int64), "time_s": t, "displacement_m": x, "force_N": f})
    cases = pd.DataFrame([{"campaign": "c", "case": "F01", "waveform": "free", "status": "ok", "raw_file": "F01.csv",
                           "raw_sha256": "0" * 64, "frequency_Hz": math.nan, "amplitude_m": math.nan}])
    points, energy, notes = record_points(cases, lambda _case: series)
    assert not notes and energy.empty
    assert set(points["method"]) == {"free_bin"} and (points["period"] == 1).all()
    assert list(points["segment"]) == list(range(1, len(points) + 1))
    expected = 2000.0 * points["velocity_m_s"] + 30000.0 * points["velocity_m_s"] * points["velocity_m_s"].abs()
    np.testing.assert_allclose(points["force_N"], expected, rtol=0.05, atol=3.0)
    char = assemble(tables.empty(tables.WINDOWS), tables.empty(tables.REPEATABILITY), points)
    assert len(char) == len(points) and not char["repeatability_flagged"].any()


def test_a_two_cycle_sine_step_gives_a_point_per_direction():
    # issue 33: a 0.2 Hz or 1 Hz step of a sweep holds 2 cycles; settling is measured, not a fixed skip
    spec = copy.deepcopy(SINE)
    spec["plan"]["sine"].update(periods=2, amplitudes_mm=[0.3])
    vc = VirtualCampaign.from_config("short", spec)
    from isokinetic.physics.virtual_rig import simulate_case
    series = simulate_case(vc.cases[0], vc.damper, vc.effects, vc.measurement, vc.seed)
    cases = pd.DataFrame([{"campaign": "short", "case": vc.cases[0].case, "waveform": "sine", "status": "ok",
                           "raw_file": "x", "raw_sha256": "0" * 64, "frequency_Hz": 1.75, "amplitude_m": 3e-4}])
    points, _energy, notes = record_points(cases, lambda _case: series)
    assert sorted(points["direction"]) == ["+", "-"] and set(points["period"]) == {1}
    truth = truth_at_peak_velocity(vc, vc.cases[0].case, points["window_start_s"].min())
    for row in points.itertuples():
        assert row.force_N == pytest.approx(truth[row.direction], rel=0.02), row.direction
    char = assemble(tables.empty(tables.WINDOWS), tables.empty(tables.REPEATABILITY), points)
    one = char["n_samples"] == 1
    assert char.loc[one, "force_se_N"].isna().all() and char.loc[~one, "force_se_N"].notna().all()
    assert points.loc[points["n_samples"] == 1, "quality"].str.contains("one steady cycle").all()
    assert bool(one.any()) == ("H01" in notes)


def test_csv_export_carries_the_sine_points_and_their_method(sine_campaign):
    _vc, root = sine_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    back = pd.read_csv(io.StringIO(csv_text(char)), skiprows=[1], float_precision="round_trip")
    assert len(back) == len(char) and set(back["method"]) == {"sine_peak"}
    np.testing.assert_array_equal(back["force_N"], char["force_N"])


@pytest.mark.slow
def test_figures_of_a_sine_only_campaign_show_its_characteristic(sine_campaign, tmp_path):
    _vc, root = sine_campaign
    import matplotlib.image

    from isokinetic.plots import figures

    char = pd.read_parquet(root / "characteristic.parquet")
    fig = figures.characteristic(char)
    assert sum(len(ln.get_xdata()) for ln in fig.axes[0].get_lines() if ln.get_gid() == "sine_peak") == 6
    paths = write_campaign_figures(root, tmp_path)
    assert all(matplotlib.image.imread(p).size for p in paths)
    cases = pd.read_parquet(root / "cases.parquet")
    assert figures.applies("fig07_time_and_loops", cases) is not None
    assert figures.applies("fig09_characteristic", cases) is None


def test_a_short_steady_step_keeps_its_first_period():
    # a slice of a sweep: 2.6 periods of a settled sine starting at its top, F = c v + noise
    t = np.arange(0.0, 2.6, 1e-3)
    x = 0.01 * np.cos(2 * math.pi * t)
    v = -0.02 * math.pi * np.sin(2 * math.pi * t)
    f = 3000.0 * v + np.random.default_rng(8).normal(0.0, 1.0, t.size)
    series = pd.DataFrame({"row": np.arange(t.size, dtype=np.int64), "time_s": t, "displacement_m": x, "force_N": f})
    cases = pd.DataFrame([{"campaign": "c", "case": "S01", "waveform": "sine", "status": "ok", "raw_file": "s.txt",
                           "raw_sha256": "0" * 64, "frequency_Hz": 1.0, "amplitude_m": 0.01}])
    points, energy, notes = record_points(cases, lambda _case: series)
    assert not notes
    # + peaks at 0.75 and 1.75 s, - peaks at 0.25, 1.25 and 2.25 s: every one counts, no fixed skip
    assert list(points.sort_values("direction")["n_samples"]) == [2, 3] and set(points["period"]) == {1}
    np.testing.assert_allclose(points["force_N"].abs(), 3000.0 * 0.02 * math.pi, rtol=0.01)
    assert energy["n_cycles"].tolist() == [2]      # between the three - peaks
    assert energy["energy_J"].iloc[0] == pytest.approx(math.pi * 3000.0 * 2 * math.pi * 0.01 ** 2, rel=0.01)


def test_compare_and_static_force_take_a_free_records_bins_as_no_case_point(sine_campaign):
    from isokinetic.measurement.comparison import campaign_points
    from isokinetic.measurement.static_force_fit import branch_points

    _vc, root = sine_campaign
    char = pd.read_parquet(root / "characteristic.parquet")
    bins = char[char["case"] == "H01"].assign(case="F01", method="free_bin", segment=[1, 2, 3, 4], period=1)
    both = pd.concat([char, bins], ignore_index=True)
    assert set(campaign_points(both)["case"]) == {"H01", "H02", "H03"}
    pd.testing.assert_frame_equal(campaign_points(both), campaign_points(char))
    assert set(branch_points(both)["case"]) == {"H01", "H02", "H03"}


@pytest.mark.slow
def test_trace_rederives_a_sine_point_from_the_raw_file(tmp_path):
    import subprocess
    import sys

    import yaml

    from isokinetic.stages.ingest import ingest_campaign
    from isokinetic.stages.virtual_rig import export_raw_campaign

    folder = tmp_path / "data" / "raw" / "sines"
    export_raw_campaign(VirtualCampaign.from_config("sines", SINE), folder)
    ingest_campaign(folder, tmp_path / "results" / "sines")
    write_characteristic(tmp_path / "results" / "sines")
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"windows": {"start_fraction": 0.45, "end_fraction": 0.95},
                                      "repeatability": {"tolerance": 0.05},
                                      "validation": {"sample_rate_tolerance": 0.05}}), encoding="utf-8")
    run = subprocess.run([sys.executable, "-m", "isokinetic", "trace", "results/sines/characteristic.parquet",
                          "case=H02,segment=3", "--config", str(config)], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    assert "sine_peak point re-derived" in run.stdout and run.stdout.rstrip().endswith("MATCH")


def test_models_of_a_campaign_with_triangle_cases_fit_its_windows_only(sine_campaign, triangle_campaign):
    # sine peak-velocity forces lie below the steady characteristic (compressibility): not fitted with it
    tri = pd.read_parquet(triangle_campaign[1] / "characteristic.parquet")
    sine = pd.read_parquet(sine_campaign[1] / "characteristic.parquet").assign(campaign=tri["campaign"].iloc[0])
    mixed = pd.concat([tri, sine], ignore_index=True)
    models_mixed, residuals_mixed = fit_models(mixed)
    models_tri, residuals_tri = fit_models(tri)
    pd.testing.assert_frame_equal(models_mixed, models_tri)
    pd.testing.assert_frame_equal(residuals_mixed, residuals_tri)


# --------------------------------------------------------------------------------------------
# issue 33: the method follows the record's physics, not its manifest label
# --------------------------------------------------------------------------------------------

def free_case(case: str = "F01") -> pd.DataFrame:
    return pd.DataFrame([{"campaign": "c", "case": case, "waveform": "free", "status": "ok", "raw_file": "F.csv",
                          "raw_sha256": "0" * 64, "frequency_Hz": math.nan, "amplitude_m": math.nan}])


def test_a_distorted_sine_drafted_free_gives_the_force_at_its_velocity_extremum():
    # the servo's 3 % third harmonic: x = X sin(wt) + 0.03 X sin(3wt + phi), F = c1 v + c2 v|v| (noise free);
    # reference: the analytic velocity's extremum on a fine grid and the force there
    c1, c2, amp, w, phi = 200.0, 3000.0, 0.0127, 2 * math.pi * 5.0, 1.1
    def motion(tt):
        return (amp * (np.sin(w * tt) + 0.03 * np.sin(3 * w * tt + phi)),
                amp * w * (np.cos(w * tt) + 0.09 * np.cos(3 * w * tt + phi)))
    t = np.arange(0.0, 0.6, 1.0 / 1024.0)                     # three cycles
    x, v = motion(t)
    series = pd.DataFrame({"row": np.arange(t.size, dtype=np.int64), "time_s": t, "displacement_m": x,
                           "force_N": c1 * v + c2 * v * np.abs(v)})
    points, energy, notes = record_points(free_case(), lambda _case: series)
    grid = motion(np.linspace(0.0, 0.2, 1_000_001))[1]
    assert not notes and set(points["method"]) == {"sine_peak"} and len(energy) == 1
    for d, vref in (("+", grid.max()), ("-", grid.min())):
        row = points[points["direction"] == d].iloc[0]
        assert row["velocity_m_s"] == pytest.approx(vref, rel=1e-3)
        assert row["force_N"] == pytest.approx(c1 * vref + c2 * vref * abs(vref), rel=2e-3)
    # energy: the loop area, F v integrated over the whole cycles analytically sampled
    tt = np.linspace(0.0, 0.2, 200_001)
    vv = motion(tt)[1]
    assert energy["energy_J"].iloc[0] == pytest.approx(np.trapezoid((c1 * vv + c2 * vv * np.abs(vv)) * vv, tt),
                                                       rel=2e-3)


def lagged_two_tone(tau_s: float) -> pd.DataFrame:
    """A random-like two-tone record (not periodic) on F = c v behind a first-order lag (exact discrete filter)."""
    t = np.arange(0.0, 8.0, 1e-3)
    x = 0.01 * np.sin(2 * math.pi * 1.3 * t) + 0.004 * np.sin(2 * math.pi * 3.1 * t + 0.4)
    v = 0.01 * 2 * math.pi * 1.3 * np.cos(2 * math.pi * 1.3 * t) \
        + 0.004 * 2 * math.pi * 3.1 * np.cos(2 * math.pi * 3.1 * t + 0.4)
    target = 3000.0 * v
    f = np.empty_like(target)
    f[0], a = target[0], math.exp(-1e-3 / tau_s)
    for i in range(1, t.size):
        f[i] = a * f[i - 1] + (1 - a) * target[i]
    f += np.random.default_rng(4).normal(0.0, 1.0, t.size)
    return pd.DataFrame({"row": np.arange(t.size, dtype=np.int64), "time_s": t, "displacement_m": x, "force_N": f})


def test_a_dynamic_free_record_gives_no_bin_and_says_why(tmp_path):
    points, energy, notes = record_points(free_case(), lambda _case: lagged_two_tone(0.01))
    assert points.empty and energy.empty
    assert notes["F01"].startswith("not quasi-static") and "harmonic/" in notes["F01"]
    # the page's cases table reads the reason from cases.parquet's quality
    from isokinetic.stages.characteristic import note_cases
    cases = free_case().assign(sample_rate_Hz=1000.0, amplitude_m=math.nan, period_s=math.nan, phase_rad=math.nan,
                               duration_s=8.0, timeseries_file="ingest/timeseries/F01.parquet", n_samples=8000,
                               quality="ok")
    write_parquet(tables.validate_table(cases, tables.CASES), tmp_path / "cases.parquet")
    note_cases(tmp_path, notes)
    quality = pd.read_parquet(tmp_path / "cases.parquet")["quality"].iloc[0]
    assert quality == f"characteristic: {notes['F01']}"


# --- spikes (issue 34): one electrical spike in a window, and too many ------------------------------------------

def spiked_copy(root, tmp_path, spikes: dict[tuple[str, int], list[float]]):
    """A copy of an ingested campaign with force spikes added, {(case, raw row): [offsets N]}, and its characteristic
    written."""
    work = tmp_path / "spiked"
    shutil.copytree(root / "ingest", work / "ingest")
    for case in {c for c, _row in spikes}:
        path = work / timeseries_relpath(case)
        series = pd.read_parquet(path)
        for (c, row), offsets in spikes.items():
            if c == case:
                series.loc[series["row"] == row, "force_N"] += offsets[0]
        write_parquet(series, path)
    return work, write_characteristic(work)


def test_a_spike_in_a_triangle_window_gives_the_clean_point_within_its_standard_error_counted_and_flagged(
        triangle_campaign, tmp_path):
    _vc, root = triangle_campaign
    clean = pd.read_parquet(root / "characteristic.parquet").set_index(["case", "segment"])
    w = clean.loc[("T02", 3)]
    middle = (int(w["row_start"]) + int(w["row_stop"])) // 2
    work, char = spiked_copy(root, tmp_path, {("T02", middle): [10_000.0]})
    char = char.set_index(["case", "segment"])
    assert abs(char.loc[("T02", 3), "force_N"] - w["force_N"]) < w["force_se_N"]
    assert char.loc[("T02", 3), "force_std_N"] == pytest.approx(w["force_std_N"], rel=0.1)
    assert char.loc[("T02", 3), "spikes_excluded"] == 1
    others = char.drop(index=("T02", 3))
    assert (others["spikes_excluded"] == 0).all()
    pd.testing.assert_frame_equal(others[["force_N", "force_std_N", "n_samples"]],
                                  clean.drop(index=("T02", 3))[["force_N", "force_std_N", "n_samples"]])
    quality = pd.read_parquet(work / "cases.parquet").set_index("case")["quality"]
    assert "1 spike sample excluded" in quality["T02"] and "spike" not in quality["T01"]


def test_too_many_spikes_set_a_triangle_window_aside_and_the_case_says_why(triangle_campaign, tmp_path):
    _vc, root = triangle_campaign
    w = pd.read_parquet(root / "windows.parquet").set_index(["case", "segment"]).loc[("T03", 2)]
    rows = range(int(w["row_start"]) + 10, int(w["row_stop"]) - 10, 20)          # 5 spikes in 101 samples
    work, char = spiked_copy(root, tmp_path, {("T03", r): [-7000.0] for r in rows})
    assert ("T03", 2) not in set(zip(char["case"], char["segment"], strict=True))
    assert len(char) == len(pd.read_parquet(root / "characteristic.parquet")) - 1
    quality = pd.read_parquet(work / "cases.parquet").set_index("case")["quality"]
    assert f"window 2 (-, period 1): {len(rows)} spike samples of {int(w['n_samples'])}" in quality["T03"]
    assert "set aside" in quality["T03"]


def test_a_spike_at_a_sine_peak_gives_the_clean_point_within_its_standard_error_counted(sine_campaign, tmp_path):
    _vc, root = sine_campaign
    clean = pd.read_parquet(root / "characteristic.parquet").set_index(["case", "segment"])
    series = pd.read_parquet(root / timeseries_relpath("H02"))
    t, x, f = (series[c].to_numpy(float) for c in ("time_s", "displacement_m", "force_N"))
    from isokinetic.measurement.peak_velocity import peak_points
    peaks = peak_points(t, x, f, 1.0 / 1.75)
    last = peaks[peaks["direction"] == "+"].iloc[-1]                 # a '+' peak of period 2 (segment 3)
    at = int(series["row"].iloc[int(np.argmin(np.abs(t - last["time_s"])))])
    work, char = spiked_copy(root, tmp_path, {("H02", at): [10_000.0]})
    char = char.set_index(["case", "segment"])
    p, c = char.loc[("H02", 3)], clean.loc[("H02", 3)]
    assert p["spikes_excluded"] == 1 and abs(p["force_N"] - c["force_N"]) < c["force_se_N"]
    assert "spike" in pd.read_parquet(work / "cases.parquet").set_index("case").loc["H02", "quality"]


def test_spikes_in_a_free_record_leave_its_velocity_bins_within_their_standard_errors_counted():
    t = np.arange(0.0, 8.0, 1e-3)
    x = 0.01 * np.sin(2 * math.pi * 1.3 * t) + 0.004 * np.sin(2 * math.pi * 3.1 * t + 0.4)
    v = np.gradient(x, t)
    f = 2000.0 * v + 30000.0 * v * np.abs(v) + np.random.default_rng(3).normal(0.0, 2.0, t.size)
    clean = pd.DataFrame({"row": np.arange(t.size, dtype=np.int64), "time_s": t, "displacement_m": x, "force_N": f})
    spiked = clean.copy()
    spiked.loc[[1500, 3200, 5100], "force_N"] += [10_000.0, -10_000.0, 10_000.0]
    cases = pd.DataFrame([{"campaign": "c", "case": "F01", "waveform": "free", "status": "ok", "raw_file": "F01.csv",
                           "raw_sha256": "0" * 64, "frequency_Hz": math.nan, "amplitude_m": math.nan}])
    before, _e, notes_before = record_points(cases, lambda _case: clean)
    after, _e, notes = record_points(cases, lambda _case: spiked)
    assert not notes_before and "3 spike samples excluded from the velocity bins" in notes["F01"]
    assert len(after) == len(before) and int(after["spikes_excluded"].sum()) == 3
    se = before["force_std_N"] / np.sqrt(before["n_samples"])
    assert (np.abs(after["force_N"] - before["force_N"]) < se).all()
