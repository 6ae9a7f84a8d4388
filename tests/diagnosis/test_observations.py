"""The observations a diagnosis compares with its model (isokinetic.diagnosis.observations and
sine_observations): triangle windows and sine phase bins against means computed here from the records,
the sine fit and the bins' noise model against known truths, and the model over mixed observations
against the independent reference rig."""

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import curve_fit

from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.observations import build_observations
from isokinetic.diagnosis.sine_observations import (
    between_case_scatter,
    bin_variance_model,
    fit_sine,
    periodic_motion,
    phase_bins,
)
from isokinetic.measurement.windows import WindowSpec
from isokinetic.physics.damper import NOMINAL, Effects
from isokinetic.physics.sine_drive import SineDrive
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.diagnosis import load_campaign, prepare

FRICTION_N = 5.0
CASES = [rr.TriangleCase("T01", 0.1e-3, 20.0, 50.0), rr.SineCase("H01", 0.5, 30e-6, 4, 200.0),
         rr.SineCase("H02", 5.0, 20e-6, 4, 1000.0)]


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """(observations, damper, root) of a nearly noise-free reference-rig campaign of a triangle and two sines
    (white force noise of 0.02 N: a constant record would read as saturated), through the real chain
    (ingest -> validate -> characteristic), built into observations of both kinds together (the diagnosis
    stage itself leaves a campaign's sines out beside triangle windows; the observations and the model take both)."""
    tmp = tmp_path_factory.mktemp("mixed")
    rig = rr.RigImperfections(force_noise_N=0.02, force_resolution_N=0.001)
    rrc.write_campaign(tmp / "raw" / "mixed", CASES, rr.TABLE1, rig=rig, seed=1, write_phase=False)
    root = process_raw_campaign(tmp / "raw" / "mixed", tmp / "work")
    campaign, damper, cases, char, _scales = load_campaign(root)

    def load(row):
        return pd.read_parquet(root / row["timeseries_file"])

    obs = build_observations(campaign, cases, char, load, WindowSpec())
    assert sorted(set(obs.case)) == ["H01", "H02", "T01"]
    return obs, damper, root


def series_of(root, case: str) -> tuple[pd.Series, pd.DataFrame]:
    cases = pd.read_parquet(root / "cases.parquet").set_index("case", drop=False)
    return cases.loc[case], pd.read_parquet(root / cases.loc[case, "timeseries_file"])


def test_a_triangle_window_is_the_mean_of_the_samples_in_its_plan_time_window(mixed):
    obs, _damper, root = mixed
    row, series = series_of(root, "T01")
    tau = series["time_s"].to_numpy() - float(row["motion_start_s"])
    half = CASES[0].period_s / 2
    windows = np.flatnonzero((obs.case == "T01") & obs.is_window)
    assert obs.segment[windows].tolist() == [1, 2, 3, 4]
    for i in windows:
        k = int(obs.segment[i]) - 1
        inside = (tau >= k * half + 0.45 * half) & (tau < k * half + 0.95 * half + 0.5 / 50.0)
        assert obs.force_N[i] == pytest.approx(series["force_N"].to_numpy()[inside].mean(), rel=1e-12)
        assert obs.period[i] == (k + 2) // 2 and obs.sign[i] == (1.0 if k % 2 == 0 else -1.0)


def test_a_triangles_transient_bins_are_the_means_of_four_equal_times_before_its_window(mixed):
    obs, _damper, root = mixed
    row, series = series_of(root, "T01")
    tau = series["time_s"].to_numpy() - float(row["motion_start_s"])
    half = CASES[0].period_s / 2
    for k in range(4):
        rows = np.flatnonzero((obs.case == "T01") & (obs.kind == "transient") & (obs.segment == k + 1))
        assert len(rows) == 4
        for j, i in enumerate(rows):
            a, b = k * half + 0.45 * half * j / 4, k * half + 0.45 * half * (j + 1) / 4
            inside = (tau >= a) & (tau < b)
            assert obs.force_N[i] == pytest.approx(series["force_N"].to_numpy()[inside].mean(), rel=1e-12)


@pytest.mark.parametrize("case", ["H01", "H02"])
def test_sine_bins_are_sample_means_over_phase_sixteenths_of_every_cycle_after_the_first(mixed, case):
    obs, _damper, root = mixed
    _row, series = series_of(root, case)
    t, force = series["time_s"].to_numpy(), series["force_N"].to_numpy()
    plan_index = int(obs.case_index[np.flatnonzero(obs.case == case)[0]])
    drive = obs.drives[plan_index]
    assert isinstance(drive, SineDrive)
    start = t[0] - drive.grid_start_s          # where the fitted sine starts its first cycle
    period = 1.0 / drive.frequency_Hz
    rows = np.flatnonzero(obs.case == case)
    assert len(rows) == 3 * 16                 # four cycles recorded, the first left out
    for n, i in enumerate(rows):
        m, j = 1 + n // 16, n % 16
        a, b = start + (m + j / 16) * period, start + (m + (j + 1) / 16) * period
        inside = (t >= a) & (t < b)
        assert obs.force_N[i] == pytest.approx(force[inside].mean(), rel=1e-12)
        centre = 2 * math.pi * (j + 0.5) / 16
        assert obs.sign[i] == np.sign(math.cos(centre))
        assert obs.kind[i] == ("window" if abs(math.cos(centre)) > 0.7 else "transient")
        assert obs.period[i] == 1 + (m - 1) % 2
        phase = np.linspace(a - start, b - start, 2001)
        speed = drive.amplitude_m * 2 * math.pi / period * np.abs(np.cos(2 * math.pi * phase / period))
        assert obs.speed_m_s[i] == pytest.approx(speed.mean(), rel=1e-5)


def test_the_sine_fit_agrees_with_scipys_curve_fit_on_a_noisy_record():
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 6.0, 0.002)
    truth = (3e-6, 25e-6, 1.01, -0.4)
    y = truth[0] + truth[1] * np.sin(2 * math.pi * truth[2] * t + truth[3]) + 1e-6 * rng.standard_normal(t.size)
    fit = fit_sine(t, y, 1.0)

    def model(t, c, amp, f, phi):
        return c + amp * np.sin(2 * math.pi * f * t + phi)

    ref, cov = curve_fit(model, t, y, p0=[0.0, 20e-6, 1.0, 0.0])
    assert fit.offset_m == pytest.approx(ref[0], abs=1e-10)
    assert fit.amplitude_m == pytest.approx(ref[1], rel=1e-7)
    assert fit.frequency_Hz == pytest.approx(ref[2], rel=1e-9)
    assert math.remainder(fit.phase_rad - ref[3], 2 * math.pi) == pytest.approx(0.0, abs=1e-7)
    assert fit.amplitude_rel_se == pytest.approx(math.sqrt(cov[1, 1]) / ref[1], rel=0.05)
    assert abs(fit.amplitude_m - truth[1]) < 5 * fit.amplitude_rel_se * truth[1]


def test_a_distorted_sines_harmonics_are_fitted_with_it_as_scipys_curve_fit_fits_them():
    # a servo's distortion: 3 % second and 1 % third harmonic, each of the fundamental's phase u
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 6.0, 0.002)
    c, amp, f, phi = 3e-6, 25e-6, 1.01, -0.4
    u = 2 * math.pi * f * t + phi
    harmonics = ((2, 0.03 * amp, 0.8), (3, 0.01 * amp, -2.0))
    y = c + amp * np.sin(u) + sum(a * np.sin(k * u + th) for k, a, th in harmonics) + 1e-6 * rng.standard_normal(t.size)
    fit = fit_sine(t, y, 1.0)
    kept = [k for k, _a, _th in fit.harmonics]
    assert {2, 3} <= set(kept)    # and, by chance (about 1 % each), a harmonic of the noise

    def model(t, c, amp, f, phi, *terms):
        u = 2 * math.pi * f * t + phi
        return c + amp * np.sin(u) + sum(a * np.sin(k * u + th) for k, a, th in zip(kept, terms[::2], terms[1::2]))

    ref, _cov = curve_fit(model, t, y, p0=[0.0, 20e-6, 1.0, 0.0] + [1e-7, 0.0] * len(kept))
    assert fit.amplitude_m == pytest.approx(ref[1], rel=1e-7)
    assert fit.frequency_Hz == pytest.approx(ref[2], rel=1e-9)
    for j, (_k, a_k, th_k) in enumerate(fit.harmonics):
        assert a_k == pytest.approx(abs(ref[4 + 2 * j]), rel=1e-6)
        flip = math.pi if ref[4 + 2 * j] < 0 else 0.0
        assert math.remainder(th_k - ref[5 + 2 * j] - flip, 2 * math.pi) == pytest.approx(0.0, abs=1e-5)
    true = {k: (a, th) for k, a, th in harmonics}
    for k, a_k, th_k in fit.harmonics:
        se = fit.harmonic_se_m[k - 2]
        a_true, th_true = true.get(k, (0.0, th_k))
        assert abs(a_k - a_true) < 5 * se
        if a_true:
            assert abs(math.remainder(th_k - th_true, 2 * math.pi)) < 5 * se / a_true


def test_a_pure_sine_in_white_noise_rarely_gets_a_harmonic():
    # 3 standard errors on each of the two harmonics fitted: about 2 % of records get one by chance
    rng = np.random.default_rng(6)
    t = np.arange(0.0, 3.0, 0.002)
    draws = [fit_sine(t, 20e-6 * np.sin(2 * math.pi * t + 0.3) + 1e-6 * rng.standard_normal(t.size), 1.0)
             for _ in range(200)]
    with_any = sum(bool(fit.harmonics) for fit in draws)
    assert with_any <= 12
    assert all(len(fit.harmonic_se_m) == 2 for fit in draws)


def test_a_cranks_free_record_is_periodic_and_a_two_tone_or_sweeping_one_is_not():
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 5.0, 0.001)
    noise = 1e-6 * rng.standard_normal(t.size)
    r, rod = 100e-6, 400e-6                       # a slider crank at 1 Hz, its rod four times its radius
    theta = 2 * math.pi * 1.0 * t
    crank = r * np.cos(theta) + np.sqrt(rod**2 - (r * np.sin(theta)) ** 2) - rod
    fit, unexplained = periodic_motion(t, crank + noise)
    assert fit.frequency_Hz == pytest.approx(1.0, rel=1e-4) and unexplained < 0.005
    assert [k for k, _a, _th in fit.harmonics][:1] == [2]
    assert fit.harmonics[0][1] / fit.amplitude_m == pytest.approx(r / (4 * rod), rel=0.05)   # r/4l
    two_tone = 100e-6 * np.sin(2 * math.pi * t) + 30e-6 * np.sin(2 * math.pi * 1.37 * t)
    sweep = 100e-6 * np.sin(2 * math.pi * (0.8 * t + 0.05 * t**2))
    for record in (two_tone, sweep):
        assert periodic_motion(t, record + noise)[1] > 0.005
    assert periodic_motion(t[:2000], crank[:2000])[0] is None       # two cycles: too short


def test_phase_bins_never_straddle_a_reversal():
    bins = phase_bins(16)
    edges = {round(b[0], 12) for b in bins}
    assert {0.25, 0.75} <= edges
    assert [b[2] for b in bins] == [1.0] * 4 + [-1.0] * 8 + [1.0] * 4
    assert sum(b[3] == "window" for b in bins) == 8
    with pytest.raises(ValueError):
        phase_bins(10)


def test_the_bin_variance_model_recovers_the_variance_of_white_and_proportional_noise():
    # bins of a/n + b F² with a modelled cycle-to-cycle convergence (taken off): the fitted variance of every
    # bin mean within 20 % of the truth (a and b alone are less sharp: both rise with the force's bins)
    rng = np.random.default_rng(9)
    n_bins, n_cycles = 64, 12
    level = np.tile(np.linspace(-500.0, 500.0, n_bins), n_cycles)
    n = np.tile(rng.integers(5, 50, n_bins), n_cycles).astype(float)
    a, b = 1000.0, 4e-4
    drift = np.repeat(np.linspace(0.0, 300.0, n_cycles), n_bins)
    true = level + drift
    force = true + np.sqrt(a / n + b * true**2) * rng.standard_normal(level.size)
    key = np.tile(np.arange(n_bins), n_cycles).astype(str)
    cycle = np.repeat(np.arange(n_cycles), n_bins)
    fa, fb = bin_variance_model(key, cycle, force, n, np.ones(level.size, bool), true)
    ratio = (fa / n + fb * true**2) / (a / n + b * true**2)
    assert np.all(np.abs(ratio - 1.0) < 0.2)
    wa, wb = bin_variance_model(key, cycle, force, n, np.ones(level.size, bool))   # the convergence read as noise
    assert np.all(wa / n + wb * true**2 > 1.2 * (fa / n + fb * true**2))



def test_a_convergence_the_model_lacks_is_not_read_as_bin_noise():
    # a damper whose effects the model lacks converges from rest in its own way over the first cycles (here by
    # 300 N, decaying by half a cycle): the bins' variance comes from the later, converged cycles
    rng = np.random.default_rng(10)
    n_bins, n_cycles = 16, 10
    level = np.tile(np.linspace(-2000.0, 2000.0, n_bins), n_cycles)
    n = np.full(level.size, 60.0)
    a = 60.0 * 25.0   # 5 N per bin mean
    convergence = np.repeat(300.0 * 0.5 ** np.arange(n_cycles), n_bins)
    force = level + convergence + np.sqrt(a / n) * rng.standard_normal(level.size)
    key = np.tile(np.arange(n_bins), n_cycles).astype(str)
    cycle = np.repeat(np.arange(n_cycles), n_bins)
    fa, fb = bin_variance_model(key, cycle, force, n, np.ones(level.size, bool), level)
    variance = fa / n + fb * level**2
    assert np.all((variance > 0.5 * a / n) & (variance < 2.0 * a / n))


def test_a_sine_only_campaign_with_unmodelled_effects_keeps_its_noise_model(tmp_path):
    # leakage and an asymmetric orifice shift the mean pressure over the first cycles of a record started from
    # rest; neither that nor the cycle-to-cycle difference of the first two cycles is noise or between-period
    # scatter (it made a sine-only campaign's bin errors 20 times too large, and its verdict miss two effects)
    rig = rr.RigImperfections(force_noise_N=5.0, force_resolution_N=0.01)
    effects = rr.TrueEffects(asymmetry=0.06, coulomb_force_N=90.0,
                             leakage_gap_m=rrc.leakage_gap_from_conductance(2.2e-12, rr.TABLE1))
    rrc.write_campaign(tmp_path / "raw" / "converging", [rr.SineCase("H01", 1.75, 230e-6, 10, 1000.0)], rr.TABLE1,
                       effects, rig=rig, seed=5, write_phase=False)
    root = process_raw_campaign(tmp_path / "raw" / "converging", tmp_path / "work")
    _c, _damper, _cases, obs, reason = prepare(root)
    assert obs is not None, reason
    assert obs.noise["sine"]["white_var_N2"] < 10.0 * 5.0**2    # 68 600 N² before (the rig's: 25 N²)
    assert obs.noise["between_period_rel"] < 0.005             # 0.059 before


def even_and_odd_residuals(rng, n_cases: int, common_rel: float, odd_N: float):
    """Bins of n_cases two-direction cycles: model M (odd), bin noise of 1 % and, per case, one common even error
    common_rel·|M| drawn anew for every case, plus an odd residual ``odd_N``·sign (a friction the model lacks)."""
    phase = 2 * math.pi * (np.arange(32) + 0.5) / 32
    model = np.concatenate([rng.uniform(100.0, 1000.0) * np.cos(phase) for _ in range(n_cases)])
    case = np.repeat(np.arange(n_cases).astype(str), 32)
    var = (0.01 * model) ** 2 + 1.0
    common = np.repeat(common_rel * rng.standard_normal(n_cases), 32)
    residual = common * np.abs(model) + odd_N * np.sign(model) + np.sqrt(var) * rng.standard_normal(model.size)
    return case, residual, model, var


def test_a_common_even_error_per_case_is_measured_as_between_case_scatter():
    rng = np.random.default_rng(3)
    estimates = [between_case_scatter(*even_and_odd_residuals(rng, 12, 0.02, 0.0)) for _ in range(20)]
    assert np.median(estimates) == pytest.approx(0.02, rel=0.2)


def test_odd_residuals_and_bin_noise_alone_give_no_between_case_scatter():
    rng = np.random.default_rng(5)
    estimates = [between_case_scatter(*even_and_odd_residuals(rng, 12, 0.0, 15.0)) for _ in range(20)]
    assert np.median(estimates) < 0.002


def test_the_model_over_mixed_observations_matches_the_reference_rig(mixed):
    # nearly noise-free records: every mean, triangle window or sine bin, is the rig's own (independent) force
    obs, damper, _root = mixed
    predicted = Evaluator(obs, damper).predict(NOMINAL)
    scale = np.abs(obs.force_N).max()
    assert np.max(np.abs(predicted - obs.force_N)) < 2e-4 * scale


@pytest.mark.parametrize("effects", [NOMINAL, Effects(coulomb_force_N=5.0)], ids=["sums", "sample-grid"])
def test_sine_cases_leave_the_triangle_models_means_unchanged(mixed, effects):
    # without friction the triangles keep their closed-form sums; with it every case runs on one sample grid
    obs, damper, _root = mixed
    triangle = obs.case == "T01"
    alone = Evaluator(obs.subset(triangle), damper).predict(effects)
    together = Evaluator(obs, damper).predict(effects)[triangle]
    assert np.allclose(together, alone, rtol=1e-9, atol=1e-9 * np.abs(alone).max())


@pytest.fixture(scope="module")
def dropped(tmp_path_factory):
    """(observations, damper) of the ``mixed`` campaign's triangle case, its damper with 5 N of Coulomb friction,
    1.5 % of its samples dropped by the rig's logger (nearly noise-free: every mean is the rig's own force over the
    samples the record kept)."""
    tmp = tmp_path_factory.mktemp("dropped")
    rig = rr.RigImperfections(force_noise_N=0.02, force_resolution_N=0.001, dropout_fraction=0.015)
    rrc.write_campaign(tmp / "raw" / "dropped", CASES[:1], rr.TABLE1, rr.TrueEffects(coulomb_force_N=FRICTION_N),
                       rig=rig, seed=3, write_phase=False)
    root = process_raw_campaign(tmp / "raw" / "dropped", tmp / "work")
    campaign, damper, cases, char, _scales = load_campaign(root)
    obs = build_observations(campaign, cases, char, lambda row: pd.read_parquet(root / row["timeseries_file"]),
                             WindowSpec())
    return obs, damper


def test_the_samples_a_record_dropped_are_named_as_holes_in_the_model_ranges(dropped):
    obs, _damper = dropped
    n_model = obs.stop - obs.start
    per_row = np.bincount(obs.holes[:, 0], minlength=len(obs))
    assert 0 < obs.holes.shape[0] < 0.06 * n_model.sum()
    rows, at = obs.holes[:, 0], obs.holes[:, 1]
    assert np.all((at >= obs.start[rows]) & (at < obs.stop[rows]))
    assert np.all(per_row < n_model)


def test_the_model_leaves_out_the_samples_a_record_dropped(dropped):
    # a dropped sample inside a reversal's transient moves the bin's mean by a large share of the force's swing:
    # the model's mean must be over the same samples; without friction from the closed-form sums (friction added
    # as its constant step), with it on the sample grid
    obs, damper = dropped
    ev = Evaluator(obs, damper)
    tol = 2e-4 * np.abs(obs.force_N).max()
    assert np.max(np.abs(ev.predict(NOMINAL) + FRICTION_N * obs.sign - obs.force_N)) < tol
    assert np.max(np.abs(ev.predict(Effects(coulomb_force_N=FRICTION_N)) - obs.force_N)) < tol


def test_a_lagging_channels_model_means_leave_out_the_dropped_samples_at_their_places(dropped):
    # an independent reduction: per observation, the model force shifted by whole samples, masked where dropped
    obs, damper = dropped
    ev = Evaluator(obs, damper)
    force = ev.forces(NOMINAL)[0]
    fs = obs.plans[0].sample_rate_Hz
    shift = 7
    lagged = ev.lagged(NOMINAL, [shift / fs])[0]
    padded = np.concatenate([np.zeros(shift), force])   # the model is at rest before its first sample
    for i in range(len(obs)):
        keep = np.ones(obs.stop[i] - obs.start[i], dtype=bool)
        keep[obs.holes[obs.holes[:, 0] == i, 1] - obs.start[i]] = False
        expected = padded[obs.start[i]:obs.stop[i]][keep].mean()
        assert lagged[i] == pytest.approx(expected, rel=1e-9, abs=1e-9 * np.abs(force).max())


def spiked_window(root):
    """(T01's series, the samples of its window 2, the one spiked there (+10 kN), a loader giving the spiked
    series for T01, the campaign's (name, cases, characteristic))."""
    row, series = series_of(root, "T01")
    tau = series["time_s"].to_numpy() - float(row["motion_start_s"])
    half = CASES[0].period_s / 2
    inside = np.flatnonzero((tau >= 1.45 * half) & (tau < 1.95 * half + 0.5 / 50.0))      # window 2
    spike = int(inside[inside.size // 2])
    spiked = series.copy()
    spiked.loc[spike, "force_N"] += 10_000.0
    campaign, _damper, cases, char, _scales = load_campaign(root)

    def load(r):
        return spiked if r["case"] == "T01" else pd.read_parquet(root / r["timeseries_file"])

    return series, inside, spike, load, (campaign, cases, char)


def test_a_spike_in_a_window_is_left_out_of_its_mean_of_the_models_and_of_the_noise_model(mixed):
    obs, damper, root = mixed
    series, inside, spike, load, (campaign, cases, char) = spiked_window(root)
    dirty = build_observations(campaign, cases, char, load, WindowSpec())
    i = int(np.flatnonzero((dirty.case == "T01") & dirty.is_window & (dirty.segment == 2))[0])
    kept = np.setdiff1d(inside, [spike])
    assert dirty.force_N[i] == pytest.approx(series["force_N"].to_numpy()[kept].mean(), rel=1e-12)
    assert dirty.holes[dirty.holes[:, 0] == i].shape == (1, 2) and obs.holes[obs.holes[:, 0] == i].size == 0
    np.testing.assert_allclose(Evaluator(dirty, damper).predict(NOMINAL), Evaluator(obs, damper).predict(NOMINAL),
                               rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(dirty.sigma_N, obs.sigma_N, rtol=0.05)


def test_a_windows_parts_leave_out_the_samples_their_window_leaves_out(mixed):
    # a spike found on the whole window is left out of the part that holds it, and only of that one
    _obs, _damper, root = mixed
    _series, _inside, _spike, load, (campaign, cases, char) = spiked_window(root)
    parts = build_observations(campaign, cases, char, load, WindowSpec()).subwindows
    rows = np.flatnonzero((parts.case == "T01") & (parts.segment == 2))
    holed = [i for i in rows if (parts.holes[:, 0] == i).any()]
    assert len(holed) == 1
    clean = build_observations(campaign, cases, char, lambda r: pd.read_parquet(root / r["timeseries_file"]),
                               WindowSpec()).subwindows
    np.testing.assert_allclose(parts.force_N[rows], clean.force_N[rows], rtol=0.02)   # the spike gone from its part


def test_a_subset_carries_the_load_cells_declared_calibration(mixed):
    obs = replace(mixed[0], force_calibration=(1.012, 0.001))
    assert obs.subset(obs.case == "H01").force_calibration == (1.012, 0.001)
