"""Sine bins' model means on the physics' grids (diagnosis.sine_model) against the sample-by-sample model and
against independent computations (scipy's quadrature and LTI simulation)."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, signal

from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.sine_model import low_pass, monomial_responses, reversals
from isokinetic.physics.damper import Effects
from isokinetic.physics.sine_drive import SineDrive


@pytest.fixture(scope="module")
def sine_campaign(tmp_path_factory):
    """(observations, damper) of a reference-rig sine campaign: 0.4 Hz at 500 Hz and 4 Hz at 2 kHz sampling,
    the second with a servo's second and third harmonics, some samples dropped."""
    from isokinetic.diagnosis.observations import build_observations
    from isokinetic.measurement.windows import WindowSpec
    from isokinetic.reference import campaign as rrc
    from isokinetic.reference import rig as rr
    from isokinetic.stages.blind_diagnose import process_raw_campaign
    from isokinetic.stages.diagnosis import load_campaign

    tmp = tmp_path_factory.mktemp("grid")
    cases = [rr.SineCase("S01", 0.4, 60e-6, 5, 500.0), rr.SineCase("S02", 4.0, 20e-6, 6, 2000.0, ((2, 0.03, 0.5),))]
    rig = rr.RigImperfections(force_noise_N=0.5, dropout_fraction=0.005)
    rrc.write_campaign(tmp / "raw" / "g", cases, rr.TABLE1, rr.TrueEffects(), rig=rig, seed=7, write_phase=False)
    root = process_raw_campaign(tmp / "raw" / "g", tmp / "work")
    campaign, damper, cases_df, char, _scales = load_campaign(root)
    obs = build_observations(campaign, cases_df, char, lambda row: pd.read_parquet(root / row["timeseries_file"]),
                             WindowSpec())
    assert obs.holes.size and all(isinstance(d, SineDrive) for d in obs.drives)
    return obs, damper


EFFECTS = [Effects(), Effects(leakage_conductance_m3_s_Pa=2e-12, asymmetry=0.05), Effects(air_volume_fraction=0.01)]


@pytest.mark.parametrize("effects", EFFECTS, ids=["nominal", "leakage", "air"])
def test_bin_means_on_the_grid_are_the_means_of_the_sampled_model(sine_campaign, effects):
    obs, damper = sine_campaign
    grid, samples = Evaluator(obs, damper), Evaluator(obs, damper, grid=False)
    expected = samples.predict(effects)
    assert np.max(np.abs(grid.predict(effects) - expected)) < 3e-5 * np.max(np.abs(expected))


@pytest.mark.parametrize("form", [0, 1, 2])
def test_the_force_channel_reads_the_grid_as_it_reads_the_samples(sine_campaign, form):
    # a delay: the same to the sample grid's interpolation; a low-pass: the analog prototype against its bilinear
    # transform at the sampling rate, within the warp (f/fs)^2 of the force's harmonics
    obs, damper = sine_campaign
    lags = [0.004, 0.03]
    grid = Evaluator(obs, damper).read(Effects(), form, lags)
    samples = Evaluator(obs, damper, grid=False).read(Effects(), form, lags)
    assert np.max(np.abs(grid - samples)) < 2e-3 * np.max(np.abs(samples))


def test_a_run_on_the_grid_costs_no_sample_by_sample_simulation(sine_campaign):
    obs, damper = sine_campaign
    ev = Evaluator(obs, damper)
    ev.predict(Effects(leakage_conductance_m3_s_Pa=1e-12))
    ev.read(Effects(leakage_conductance_m3_s_Pa=1e-12), 2, [0.01, 0.02])
    assert ev.calls == 1 and not ev._runs["forces"]


def test_the_monomial_responses_are_the_integrals_they_name():
    for pole in (complex(-3.0, 0.0), complex(-40.0, 40.0), complex(-0.01, 0.01)):
        h = 0.02
        got = monomial_responses(pole, h)
        for k in range(4):
            def part(t, k=k, pole=pole, h=h, take=np.real):
                return take(np.exp(pole * (h - t)) * (t / h) ** k)
            re = integrate.quad(part, 0, h, epsabs=1e-16)[0]
            im = integrate.quad(lambda t, k=k, pole=pole, h=h: part(t, k, pole, h, np.imag), 0, h, epsabs=1e-16)[0]
            assert abs(got[k] - complex(re, im)) < 1e-12 * h


@pytest.mark.parametrize("order", [1, 2])
def test_the_low_pass_is_the_butterworth_filter_of_the_signal(order):
    # scipy.signal.lsim of the analog Butterworth (corner c/L) on a finely sampled smooth signal
    h, n, lag = 0.01, 400, 0.05
    t = np.arange(n) * h
    p, f = np.sin(3.0 * t) + 0.3 * np.cos(7.0 * t), 3.0 * np.cos(3.0 * t) - 2.1 * np.sin(7.0 * t)
    y, slope = low_pass(p, f, h, order, lag)
    w = (1.0 if order == 1 else math.sqrt(2.0)) / lag
    fine = np.linspace(0.0, t[-1], 40 * (n - 1) + 1)
    _t, ref, _x = signal.lsim(signal.butter(order, w, analog=True), np.sin(3 * fine) + 0.3 * np.cos(7 * fine), fine)
    np.testing.assert_allclose(y, ref[::40], atol=2e-6)
    np.testing.assert_allclose(slope[1:-1], np.gradient(ref, fine)[::40][1:-1], atol=2e-3)


def test_reversals_are_where_a_distorted_motion_turns():
    drive = SineDrive(1e-3, 2.0, 0.0, 10, ((2, 2e-4, 0.7), (3, 1e-4, -0.2)))
    times, signs = reversals(drive, 1.0)
    fine = np.linspace(1e-6, 1.0, 400_001)
    v = drive.velocity(fine)
    turns = fine[1:][np.sign(v[1:]) != np.sign(v[:-1])]
    assert times[0] == 0.0 and signs[0] == np.sign(v[0])
    np.testing.assert_allclose(times[1:1 + turns.size], turns, atol=3e-6)
    assert np.all(signs[1:] == -signs[:-1])
