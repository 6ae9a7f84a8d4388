"""Instrument terms of the sensor chain (isokinetic.diagnosis.instrument, issue 21): the LVDT's scale against
the command channel, and the force channel's lag fitted on the nominal model."""

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from isokinetic.diagnosis import instrument as ins
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.physics.damper import NOMINAL, Effects
from isokinetic.reference import rig as rr


def triangle_series(scale: float, delay_s: float, with_command: bool = True) -> pd.DataFrame:
    t = np.arange(0.0, 40.0, 0.02)
    c = rr.triangle_command(t, 5e-3, 20.0)
    x = scale * rr.triangle_command(t - delay_s, 5e-3, 20.0)
    frame = pd.DataFrame({"time_s": t, "displacement_m": x, "force_N": np.zeros_like(t)})
    if with_command:
        frame["command_m"] = c
    return frame


def test_the_speed_ratio_of_the_lvdt_to_the_command_is_its_scale():
    assert ins.case_speed_ratio(triangle_series(1.012, 0.05), 20.0, 0.05) == pytest.approx(1.012, rel=1e-9)


def test_without_a_command_channel_the_speed_ratio_is_not_a_number():
    assert np.isnan(ins.case_speed_ratio(triangle_series(1.012, 0.05, with_command=False), 20.0, 0.05))


def test_a_scale_departing_from_one_beyond_its_error_is_applied():
    ratios = np.array([1.0119, 1.0121, 1.0120, 1.0122, 1.0118])
    scale = ins.displacement_scale(ratios)
    assert scale["estimate"] == pytest.approx(np.median(ratios))
    assert scale["applied"] is True


def test_a_scale_within_a_tenth_of_a_percent_is_not_applied():
    scale = ins.displacement_scale(np.array([1.0004, 1.0005, 1.0006, 1.0005]))
    assert scale["applied"] is False


def test_a_command_far_from_the_lvdt_is_no_measure_of_its_scale():
    scale = ins.displacement_scale(np.array([1.2, 1.2001, 1.1999]))
    assert scale["applied"] is False


def test_no_command_channel_gives_no_scale():
    scale = ins.displacement_scale(np.array([np.nan, np.nan]))
    assert scale["estimate"] is None and scale["applied"] is False


def test_without_a_command_channel_a_declared_lvdt_calibration_is_the_scale():
    scale = ins.calibrated_scale(ins.displacement_scale(np.array([np.nan])), (1.012, 0.001))
    assert scale == {"estimate": 1.012, "std_error": pytest.approx(1.012e-3), "uncertainty_rel": 0.001,
                     "n_cases": 0, "applied": True, "source": "calibration",
                     "calibration": {"scale": 1.012, "uncertainty_rel": 0.001}}
    assert ins.scale_measured(scale)


def test_a_declared_lvdt_scale_of_one_is_measured_and_not_applied():
    scale = ins.calibrated_scale(ins.displacement_scale(np.array([])), (1.0, 0.001))
    assert (scale["estimate"], scale["applied"], scale["source"]) == (1.0, False, "calibration")
    assert ins.scale_measured(scale)


def test_a_looser_lvdt_calibration_is_applied_but_does_not_measure_the_scale():
    # a scale error within ±0.5 % would still read as a load-cell gain plus C_D·√k: the confounding stays listed
    scale = ins.calibrated_scale(ins.displacement_scale(np.array([])), (1.012, 0.005))
    assert (scale["estimate"], scale["applied"]) == (1.012, True)
    assert not ins.scale_measured(scale)
    assert ins.scale_measured({**scale, "uncertainty_rel": ins.SCALE_MIN_DEPARTURE})


def test_a_command_channels_measured_scale_stands_beside_a_declared_calibration_that_it_contradicts():
    measured = ins.displacement_scale(np.array([1.0119, 1.0121, 1.0120, 1.0122, 1.0118]))
    scale = ins.calibrated_scale(measured, (1.005, 0.001))
    z = (measured["estimate"] - 1.005) / np.hypot(measured["std_error"], 1.005 * 0.001)
    assert scale == {**measured, "calibration": {"scale": 1.005, "uncertainty_rel": 0.001, "z": pytest.approx(z),
                                                 "agrees": False}}
    assert z > 6.0


def test_a_declared_calibration_within_its_uncertainty_of_the_command_channels_scale_agrees():
    measured = ins.displacement_scale(np.array([1.0119, 1.0121, 1.0120, 1.0122, 1.0118]))
    assert ins.calibrated_scale(measured, (1.0135, 0.001))["calibration"]["agrees"] is True


def test_the_gain_the_data_read_beside_a_calibration_is_their_own_least_squares_gain_and_its_error():
    # the calibration's row left out: the plain weighted least squares in (gain, offset), and its standard error
    # from their covariance, computed here independently
    model, w, force = _calibrated_rig(9)
    terms = ins.LinearTerms(offset_bound_N=50.0, gain_centre=1.0, gain_sd=0.001)
    g, se = ins.gain_reading(terms, force, model, np.sign(model), w)
    a = np.column_stack([model, np.ones_like(model)]) * np.sqrt(w)[:, None]
    ref = np.linalg.lstsq(a, force * np.sqrt(w), rcond=None)[0]
    cov = np.linalg.inv(a.T @ a)
    assert g == pytest.approx(ref[0], rel=1e-10)
    assert se == pytest.approx(np.sqrt(cov[0, 0]), rel=1e-6)
    z = ins.calibration_z(g, se, 1.0, 0.001)
    assert abs(z) > ins.CALIBRATION_Z   # the rig's 1.3 % against a calibration of 1.000 ± 0.1 %


def test_a_command_far_from_the_lvdt_gives_way_to_a_declared_calibration():
    rejected = ins.displacement_scale(np.array([1.2, 1.2001, 1.1999]))
    assert not ins.scale_measured(rejected)
    scale = ins.calibrated_scale(rejected, (1.01, 0.001))
    assert (scale["estimate"], scale["source"], scale["command"]) == (1.01, "calibration", rejected)
    assert "note" not in scale


def test_without_a_declared_calibration_the_scale_is_unchanged():
    unmeasured = ins.displacement_scale(np.array([]))
    assert ins.calibrated_scale(unmeasured, None) is unmeasured and not ins.scale_measured(unmeasured)


def test_rescaled_drives_divide_every_measured_speed(campaign):
    obs, _damper = campaign
    scaled = ins.rescaled_drives(obs, 1.02)
    for before, after in zip(obs.drives, scaled.drives, strict=True):
        assert np.allclose(np.array(after.speeds_m_s) * 1.02, before.speeds_m_s)


@pytest.mark.parametrize("effects", [NOMINAL, Effects(leakage_conductance_m3_s_Pa=2e-12, air_volume_fraction=0.01)],
                         ids=["nominal", "leakage-air"])
@pytest.mark.parametrize("samples", [3.0, 7.4])
def test_lagged_model_means_are_the_means_of_the_model_force_shifted_back(campaign, effects, samples):
    """lagged (from the running sums of Δp, :class:`PressureSums`) against the model force sample by sample
    (Evaluator.forces), shifted back by whole samples at the plan's 50 Hz and interpolated linearly between them."""
    obs, damper = campaign
    ev = Evaluator(obs, damper)
    forces = ev.forces(effects)
    lagged = ev.lagged(effects, [samples / 50.0])[0]
    k, frac = int(samples), samples - int(samples)
    by_hand = []
    for case, lo, hi in zip(obs.case_index, obs.start, obs.stop, strict=True):
        f = np.concatenate([np.zeros(k + 1), forces[case]])  # at rest before the record
        by_hand.append((1.0 - frac) * f[lo + 1:hi + 1].mean() + frac * f[lo:hi].mean())
    scale = max(np.abs(by_hand))
    assert np.allclose(lagged, by_hand, rtol=1e-11, atol=1e-9 * scale)


def test_a_low_pass_moves_the_steady_windows_like_a_delay_of_its_group_delay(campaign):
    obs, damper = campaign
    ev = Evaluator(obs, damper)
    win = obs.is_window
    filtered = ev.filtered(NOMINAL, [0.045], 2)[0][win]
    delayed = ev.lagged(NOMINAL, [0.045])[0][win]
    assert np.allclose(filtered, delayed, rtol=1e-3)


@pytest.mark.parametrize("form", [0, 2])
def test_the_force_lag_of_a_lagging_channel_is_recovered(campaign, form):
    obs, damper = campaign
    ev = Evaluator(obs, damper)
    truth = ev.lagged(NOMINAL, [0.03])[0] if form == 0 else ev.filtered(NOMINAL, [0.03], form)[0]
    dg = Diagnoser(replace(obs, force_N=truth), damper)
    lag, fitted_form, _pred = ins.fit_force_lag(dg)
    assert fitted_form == form
    assert lag == pytest.approx(0.03, abs=5e-4)


def test_linear_terms_give_the_offset_at_the_reference_time_and_the_drift():
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 600.0, 80))
    model = rng.uniform(-500.0, 500.0, t.size)
    force = 1.01 * model + 4.0 + 0.02 * (t - 300.0)
    terms = ins.LinearTerms(free=(*ins.INSTRUMENT, ins.DRIFT), offset_bound_N=50.0, drift_bound_N_s=1.0)
    g, _fc, offset, drift = terms.solve(force, model, np.sign(model), np.ones(t.size), False, t - 300.0)
    assert (g, offset, drift) == pytest.approx((1.01, 4.0, 0.02), rel=1e-9)


def test_without_campaign_times_no_drift_is_fitted():
    terms = ins.LinearTerms(free=(*ins.INSTRUMENT, ins.DRIFT), offset_bound_N=50.0, drift_bound_N_s=1.0)
    model = np.linspace(-100.0, 100.0, 20)
    *_rest, drift = terms.solve(model + 3.0, model, np.sign(model), np.ones(20), False, None)
    assert drift == 0.0


def test_the_force_lag_is_profiled_on_a_candidates_effects(campaign):
    obs, damper = campaign
    effects = Effects(viscosity_Pa_s=1.3 * damper.viscosity_Pa_s)
    truth = Evaluator(obs, damper).lagged(effects, [0.03])[0]
    dg = Diagnoser(replace(obs, force_N=truth), damper)
    lag, form, _pred = ins.fit_force_lag(dg, (0,), effects=effects)
    assert (form, lag) == (0, pytest.approx(0.03, abs=5e-4))


SWEEP_HZ_MM_S = [(0.2, 0.05), (0.5, 0.1), (1.0, 0.2), (2.0, 0.4), (5.0, 0.8), (10.0, 1.2)]


def sine_responses(rig: rr.RigImperfections, with_command: bool = True) -> list[tuple[float, float, float]]:
    """case_sine_response of each case of a reference-rig sweep (four cycles at 1 kHz)."""
    from isokinetic.reference import campaign as rrc

    out = []
    for i, (f, v) in enumerate(SWEEP_HZ_MM_S):
        case = rr.SineCase(f"H{i}", f, v * 1e-3 / (2 * np.pi * f), 4, 1000.0)
        s = rrc.simulate_case(case, rig=rig, seed=3, case_index=i, rtol=1e-6)
        series = pd.DataFrame({"time_s": s["time_s"], "displacement_m": s["displacement_meas_m"]})
        if with_command:
            series["command_m"] = s["command_meas_m"]
        out.append(ins.case_sine_response(series, f))
    return out


def test_a_sine_sweeps_lvdt_scale_and_delay_are_measured_against_its_command():
    rig = rr.RigImperfections(delay_s=0.012, servo_lag_s=0.006, displacement_gain=1.012, displacement_noise_m=1e-6)
    scale, delays = ins.sine_servo_terms(*zip(*sine_responses(rig), strict=True))
    assert scale["estimate"] == pytest.approx(1.012, abs=3e-4)
    assert scale["applied"] is True
    assert delays["delay_s"] == pytest.approx(0.018, abs=5e-4)   # a ramp's delay: dead time plus servo lag
    assert delays["servo_lag_s"] == pytest.approx(0.006, abs=5e-4)


def test_a_sine_sweep_with_a_true_lvdt_gets_no_scale_applied():
    rig = rr.RigImperfections(delay_s=0.012, servo_lag_s=0.006, displacement_noise_m=1e-6)
    scale, _delays = ins.sine_servo_terms(*zip(*sine_responses(rig), strict=True))
    assert scale["applied"] is False


def test_a_sine_sweep_without_a_command_channel_gives_no_scale_and_no_delay():
    rig = rr.RigImperfections(delay_s=0.012, servo_lag_s=0.006, displacement_gain=1.012)
    scale, delays = ins.sine_servo_terms(*zip(*sine_responses(rig, with_command=False), strict=True))
    assert scale["estimate"] is None and scale["source"] == "no command channel"
    assert delays["delay_s"] is None


def test_sine_cases_all_at_one_frequency_give_no_applied_scale_and_no_delay():
    # one point of the amplitude response: the LVDT scale and the servo lag's amplitude loss are one unknown
    scale, delays = ins.sine_servo_terms([2.0, 2.0, 2.0], [1.011, 1.012, 1.010], [0.15, 0.15, 0.16], [1e-4] * 3)
    assert scale["applied"] is False and scale["estimate"] == pytest.approx(1.011)
    assert delays["delay_s"] is None


def test_a_sine_only_campaigns_offset_bound_does_not_grow_with_the_offset():
    force = np.sin(np.linspace(0.0, 2 * np.pi, 32, endpoint=False)) * 900.0
    window = np.abs(force) > 600.0
    assert ins.offset_bound_N(force - 142.0, window, True) == pytest.approx(ins.offset_bound_N(force, window, True))
    assert ins.offset_bound_N(force - 142.0, window, True) > 142.0   # a sweep's offset of 16 % of its peak force


def test_a_triangle_campaigns_offset_bound_is_a_fraction_of_its_largest_window_force():
    force = np.array([-900.0, -300.0, 20.0, 310.0, 880.0])
    window = np.array([True, True, False, True, True])
    assert ins.offset_bound_N(force, window, False) == pytest.approx(ins.OFFSET_BOUND_REL * 900.0)


def test_linear_terms_inside_and_at_their_bounds_are_the_bounded_least_squares():
    """Within the bounds the closed-form solution is scipy's bounded one; with the gain beyond its 2 % bound it is
    held at the bound and the offset is the weighted mean of what remains (an independent computation)."""
    from scipy.optimize import lsq_linear

    rng = np.random.default_rng(11)
    model = rng.uniform(-800.0, 800.0, 60)
    w = rng.uniform(0.5, 2.0, model.size)
    terms = ins.LinearTerms(offset_bound_N=50.0)
    force = 1.008 * model + 3.0 + rng.normal(0.0, 1.0, model.size)
    g, _fc, offset, _r = terms.solve(force, model, np.sign(model), w, False)
    a = np.column_stack([model, np.ones_like(model)]) * np.sqrt(w)[:, None]
    ref = lsq_linear(a, force * np.sqrt(w), bounds=([0.98, -50.0], [1.02, 50.0]), method="bvls").x
    assert (g, offset) == pytest.approx(tuple(ref), rel=1e-10)
    force = 1.05 * model + 3.0 + rng.normal(0.0, 1.0, model.size)
    g, _fc, offset, _r = terms.solve(force, model, np.sign(model), w, False)
    assert g == pytest.approx(1.02, rel=1e-12)
    assert offset == pytest.approx(np.sum(w * (force - 1.02 * model)) / np.sum(w), rel=1e-9)


def _calibrated_rig(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(model, weights, force) of a load cell of gain 1.013 with an offset of 2 N and noise."""
    rng = np.random.default_rng(seed)
    model = rng.uniform(-800.0, 800.0, 60)
    w = rng.uniform(0.5, 2.0, model.size)
    return model, w, 1.013 * model + 2.0 + rng.normal(0.0, 1.0, model.size) / np.sqrt(w)


def test_a_calibrated_free_gain_is_the_weighted_mean_of_the_data_and_the_calibration():
    model, w, force = _calibrated_rig(5)
    centre, sd = 1.01, 0.0005
    terms = ins.LinearTerms(free=("force_gain",), gain_centre=centre, gain_sd=sd)
    g, *_rest = terms.solve(force, model, np.sign(model), w, False)
    closed_form = (np.sum(w * model * force) + centre / sd**2) / (np.sum(w * model**2) + 1.0 / sd**2)
    assert g == pytest.approx(closed_form, rel=1e-12)
    assert centre < g < 1.013   # pulled from the data's gain towards the calibration


def test_a_gain_not_fitted_is_the_calibrated_gain():
    model, w, force = _calibrated_rig(6)
    terms = ins.LinearTerms(free=("force_offset",), offset_bound_N=50.0, gain_centre=1.013, gain_sd=0.001)
    g, _fc, offset, _r = terms.solve(force, model, np.sign(model), w, False)
    assert g == 1.013
    assert offset == pytest.approx(np.sum(w * (force - 1.013 * model)) / np.sum(w), rel=1e-9)


def test_without_a_calibration_the_gain_is_the_plain_weighted_least_squares():
    model, w, force = _calibrated_rig(7)
    g, _fc, offset, _r = ins.LinearTerms(offset_bound_N=50.0).solve(force, model, np.sign(model), w, False)
    a = np.column_stack([model, np.ones_like(model)]) * np.sqrt(w)[:, None]
    ref = np.linalg.lstsq(a, force * np.sqrt(w), rcond=None)[0]
    assert (g, offset) == pytest.approx(tuple(ref), rel=1e-10)
    assert ins.LinearTerms(free=()).solve(force, model, np.sign(model), w, False)[0] == 1.0


def test_a_calibrated_gain_is_bounded_around_its_centre():
    model, w, force = _calibrated_rig(8)
    terms = ins.LinearTerms(free=("force_gain",), gain_centre=1.09)   # the data's 1.013 lies below 1.09 - 0.02
    assert terms.solve(force, model, np.sign(model), w, False)[0] == pytest.approx(1.09 - ins.GAIN_BOUND, rel=1e-12)
