"""Sensor or damper (isokinetic.diagnosis.verdict, issue 21): the force-lag hypothesis against the damper
effects, and the load-cell zero drift."""

from dataclasses import replace

import numpy as np
import pytest

from isokinetic.diagnosis import verdict as vd
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.physics.damper import NOMINAL


class _Obs:
    def __init__(self, force_N, sigma_N):
        self.force_N, self.sigma_N = force_N, sigma_N

    def __len__(self):
        return self.force_N.size


class _Fit:
    def __init__(self, prediction):
        self.prediction = self.measured_prediction = prediction


def drift_case(slope_N_s: float, seed: int = 4):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 500.0, 200))
    sigma = np.full(t.size, 0.5)
    force = 3.0 + slope_N_s * t + sigma * rng.standard_normal(t.size)
    return type("DG", (), {"obs": _Obs(force, sigma), "alpha": 1e-3})(), _Fit(np.zeros(t.size)), t


def test_a_zero_drift_is_the_slope_of_the_residuals_in_time():
    dg, fit, t = drift_case(0.01)
    drift = vd.zero_drift(dg, fit, t)
    assert drift["needed"] is True
    assert drift["estimate"] == pytest.approx(np.polyfit(t, dg.obs.force_N, 1)[0], rel=1e-9)


def test_no_drift_is_needed_where_the_residuals_are_level():
    dg, fit, t = drift_case(0.0)
    assert vd.zero_drift(dg, fit, t)["needed"] is False


def test_without_campaign_times_no_drift_is_tested():
    dg, fit, _t = drift_case(0.01)
    assert vd.zero_drift(dg, fit, None)["estimate"] is None


def test_a_drift_that_the_nominal_model_then_explains_is_taken_off(campaign):
    obs, damper = campaign
    t = np.linspace(0.0, 200.0, len(obs))
    dg = Diagnoser(replace(obs, force_N=Diagnoser(obs, damper).nominal + 0.05 * t), damper)
    compensated, drift = vd.drift_compensated(dg, dg.refit((), vd.INSTRUMENT), t)
    assert drift is not None and drift["estimate"] == pytest.approx(0.05, rel=0.05)  # the gain takes a little
    assert compensated.nominal_explains()


def test_a_lagging_force_channel_is_preferred_to_no_damper_candidate(campaign):
    obs, damper = campaign
    lagged = Evaluator(obs, damper).lagged(NOMINAL, [0.04])[0]
    dg = Diagnoser(replace(obs, force_N=lagged), damper)
    hyp = vd.sensor_hypothesis(dg, dg.refit((), vd.INSTRUMENT), [])
    assert hyp["preferred"] and hyp["lag_needed"]
    assert hyp["lag_s"] == pytest.approx(0.04, abs=5e-4)


def test_a_damper_candidate_that_beats_the_lag_by_the_margin_is_preferred(campaign):
    obs, damper = campaign
    lagged = Evaluator(obs, damper).lagged(NOMINAL, [0.04])[0]
    dg = Diagnoser(replace(obs, force_N=lagged), damper)
    sensor = vd.sensor_hypothesis(dg, dg.refit((), vd.INSTRUMENT), [])["candidate"]
    better = replace(sensor, effects=("air",), score=sensor.score - 2 * vd.SENSOR_MARGIN, explained=True)
    assert not vd.sensor_hypothesis(dg, dg.refit((), vd.INSTRUMENT), [better])["preferred"]
