"""Sensor or damper (isokinetic.diagnosis.verdict, issue 21): the force-lag hypothesis against the damper
effects, the force-channel lag and the load-cell zero drift fitted jointly with the effects."""

from dataclasses import replace

import numpy as np
import pytest

from isokinetic.diagnosis import verdict as vd
from isokinetic.diagnosis.candidate import Candidate, overdispersed_score
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.physics.damper import NOMINAL, Effects


def viscous(damper, factor: float = 1.25) -> Effects:
    return Effects(viscosity_Pa_s=factor * damper.viscosity_Pa_s)


def campaign_time(obs) -> np.ndarray:
    return np.linspace(0.0, 400.0, len(obs))


def test_a_drift_beside_an_effect_is_fitted_with_it_not_absorbed(campaign):
    obs, damper = campaign
    t = campaign_time(obs)
    force = Evaluator(obs, damper).predict(viscous(damper)) + 0.05 * (t - 150.0)
    dg = Diagnoser(replace(obs, force_N=force), damper, time_s=t, time_ref_s=200.0)
    fit = dg.refit(("viscosity",))
    assert fit.params["viscosity_Pa_s"] == pytest.approx(1.25 * damper.viscosity_Pa_s, rel=1e-3)
    assert fit.drift_N_s == pytest.approx(0.05, rel=1e-3)
    assert fit.offset_N == pytest.approx(0.05 * (200.0 - 150.0), abs=0.05)   # at the reference time


def test_the_nominal_model_with_a_drift_explains_a_drifting_campaign(campaign):
    obs, damper = campaign
    t = campaign_time(obs)
    drifting = replace(obs, force_N=Diagnoser(obs, damper).nominal + 0.05 * t)
    assert Diagnoser(drifting, damper, time_s=t).nominal_explains()
    assert not Diagnoser(drifting, damper).nominal_explains()   # without campaign times: no drift term


def test_a_lag_fitted_with_an_effect_recovers_both(campaign):
    obs, damper = campaign
    force = Evaluator(obs, damper).lagged(viscous(damper), [0.04])[0]
    dg = Diagnoser(replace(obs, force_N=force), damper).with_channel((0, 0.02))
    fit = dg.refit(("viscosity",))
    assert fit.channel == (0, pytest.approx(0.04, abs=2e-4))
    assert fit.params["viscosity_Pa_s"] == pytest.approx(1.25 * damper.viscosity_Pa_s, rel=1e-3)


@pytest.mark.slow
def test_an_effect_behind_a_lagging_channel_is_claimed_with_the_lag(campaign):
    obs, damper = campaign
    force = Evaluator(obs, damper).lagged(viscous(damper, 1.5), [0.04])[0]
    t = campaign_time(obs)
    result, _pred = vd.diagnose_observations(replace(obs, force_N=force), damper,
                                             sensor={"obs_time_s": t, "time_ref_s": 200.0})
    assert result["verdict"] == ["viscosity"]
    assert result["instrument"]["force_lag_s"] == pytest.approx(0.04, abs=1e-3)


def _cand(effects, explained, score):
    return type("C", (), {"effects": effects, "explained": explained, "score": score})()


def test_an_explaining_lag_candidate_beats_an_unexplaining_one_without():
    assert vd.lag_preferred(_cand(("viscosity",), True, 50.0), _cand(("viscosity", "air"), False, 10.0))


def test_of_two_explaining_candidates_the_smaller_set_is_preferred_whatever_the_score():
    assert not vd.lag_preferred(_cand(("viscosity", "air"), True, 10.0), _cand(("viscosity",), True, 50.0))


def test_where_neither_explains_the_lower_score_is_preferred():
    assert vd.lag_preferred(_cand(("asymmetry",), False, 130.0), _cand(("asymmetry", "air"), False, 1700.0))


def test_a_lagging_force_channel_is_preferred_to_no_damper_candidate(campaign):
    obs, damper = campaign
    lagged = Evaluator(obs, damper).lagged(NOMINAL, [0.04])[0]
    dg = Diagnoser(replace(obs, force_N=lagged), damper)
    hyp = vd.sensor_hypothesis(dg, dg.refit(()), [])
    assert hyp["preferred"] and hyp["lag_needed"]
    assert hyp["lag_s"] == pytest.approx(0.04, abs=5e-4)


def test_a_damper_candidate_that_beats_the_lag_by_the_margin_is_preferred(campaign):
    obs, damper = campaign
    lagged = Evaluator(obs, damper).lagged(NOMINAL, [0.04])[0]
    dg = Diagnoser(replace(obs, force_N=lagged), damper)
    sensor = vd.sensor_hypothesis(dg, dg.refit(()), [])["candidate"]
    better = replace(sensor, effects=("air",), score=sensor.score - 2 * vd.SENSOR_MARGIN, explained=True)
    assert not vd.sensor_hypothesis(dg, dg.refit(()), [better])["preferred"]


def friction_step(obs, chi2: float) -> float:
    """A Coulomb force whose period-1 χ² against the nominal model is about ``chi2`` (friction moves every mean
    by ±F_C)."""
    fit = obs.period == 1
    return float(np.sqrt(chi2 / np.sum(1.0 / obs.sigma_N[fit] ** 2)))


def test_an_effect_the_omnibus_test_misses_is_found_by_its_own_test(campaign):
    obs, damper = campaign
    coulomb = friction_step(obs, 20.0)
    force = Evaluator(obs, damper).predict(Effects(coulomb_force_N=coulomb))
    dg = Diagnoser(replace(obs, force_N=force), damper)
    assert dg.nominal_explains()   # the χ² of all observations alone sees nothing
    result, _pred = vd.diagnose_observations(replace(obs, force_N=force), damper)
    assert result["verdict"] == ["friction"]
    assert result["params"]["coulomb_force_N"] == pytest.approx(coulomb, rel=0.01)


def test_an_effect_the_held_out_period_does_not_confirm_is_not_claimed(campaign):
    obs, damper = campaign
    coulomb = friction_step(obs, 20.0)
    nominal = Evaluator(obs, damper).predict(NOMINAL)
    force = nominal + np.where(obs.period == 1, coulomb * obs.sign, 0.0)   # in the fitted period only
    result, _pred = vd.diagnose_observations(replace(obs, force_N=force), damper)
    assert result["effect_tests"]["friction"]["chi2_drop"] > result["effect_tests"]["friction"]["threshold"]
    assert result["verdict"] == []


def unexplained(effects, chi2_holdout):
    return Candidate(effects=effects, x=np.zeros(len(effects)), params={}, prediction=np.zeros(1), chi2_fit=200.0,
                     chi2_holdout=chi2_holdout, n_fit=100, n_holdout=100, gap_after=2.0, holdout_gap_after=2.0,
                     score=chi2_holdout, explained=False)


def test_of_partial_explanations_within_the_margin_the_smaller_set_is_chosen():
    small, large = unexplained(("air",), 400.0), unexplained(("path_asymmetry", "air"), 380.0)
    assert overdispersed_score(large, [small, large]) < overdispersed_score(small, [small, large])
    assert vd.parsimonious([small, large]) is small


def test_a_partial_explanation_better_by_more_than_the_margin_is_chosen_whatever_its_size():
    small, large = unexplained(("air",), 400.0), unexplained(("path_asymmetry", "air"), 300.0)
    assert vd.parsimonious([small, large]) is large


def test_an_unexplained_search_no_better_than_the_nominal_model_by_the_margin_names_no_effect():
    nominal, leakage, air = unexplained((), 400.0), unexplained(("leakage",), 396.0), unexplained(("air",), 397.0)
    assert vd.no_effect_earns(leakage, nominal, [leakage, air])


def test_an_unexplained_effect_better_than_the_nominal_model_by_more_than_the_margin_is_named():
    nominal, air = unexplained((), 400.0), unexplained(("air",), 300.0)
    assert not vd.no_effect_earns(air, nominal, [air])


def explaining(effects, score):
    return replace(unexplained(effects, score), explained=True, chi2_fit=score, score=score)


class Polisher:
    """A diagnoser whose polishing refit lowers each effect set's score (and χ²) by its ``gains``."""

    def __init__(self, gains):
        self.gains, self.refitted = gains, []

    def refit(self, effects, instrument, warm, tol):
        self.refitted.append(effects)
        gain = self.gains.get(effects, 0.0)
        return replace(warm, chi2_fit=warm.chi2_fit - gain, score=warm.score - gain)


def test_a_rival_whose_polished_fit_scores_better_is_the_verdict():
    # the leakage-beside-discharge campaign's search fits: 178.7 and 188.4, polished 171.4 and 159.6
    dv, ld = explaining(("discharge", "viscosity"), 178.7), explaining(("leakage", "discharge"), 188.4)
    best, candidates = vd.chosen_candidate(Polisher({dv.effects: 7.3, ld.effects: 28.8}), [dv, ld])
    assert best.effects == ld.effects and best.score == pytest.approx(159.6)
    assert [c.score for c in candidates] == [pytest.approx(171.4), pytest.approx(159.6)]   # polished, in place


def test_a_rival_polished_into_the_margin_is_listed_as_confounded():
    dv, ld = explaining(("discharge", "viscosity"), 178.7), explaining(("leakage", "discharge"), 188.4)
    best, candidates = vd.chosen_candidate(Polisher({dv.effects: 7.3, ld.effects: 10.0}), [dv, ld])
    assert best.effects == dv.effects
    rivals = [c for c in candidates if c.effects != best.effects and c.score - best.score < vd.CONFOUNDED_SCORE]
    assert [c.effects for c in rivals] == [ld.effects]   # 178.4 against 171.4 (unpolished 17 apart)


def test_rivals_beyond_the_reach_or_of_another_size_are_not_polished():
    best = explaining(("viscosity",), 100.0)
    far, larger = explaining(("discharge",), 100.0 + vd.RIVAL_REACH + 1.0), explaining(("leakage", "air"), 101.0)
    polisher = Polisher({})
    vd.chosen_candidate(polisher, [best, far, larger])
    assert polisher.refitted == [best.effects]


def confounding_of(lag_correlation, drift_correlation):
    out = {"instrument": {"force_gain": None, "force_lag_s": 0.04, "force_drift_N_s": 0.01},
           "identifiability": {"lag_correlation": lag_correlation, "drift_correlation": drift_correlation}}
    verdict = _cand(("air", "friction"), True, 0.0)
    vd.instrument_confounding(out, None, verdict, [], list(verdict.effects), None, {"estimate": 1.0})
    return out.get("confounded", [])


def test_an_effect_the_fit_cannot_tell_from_the_lag_or_the_drift_is_listed_with_it():
    groups = confounding_of({"air": -0.95, "friction": 0.1}, {"air": 0.0, "friction": 0.93})
    assert ["air", "force_lag"] in groups and ["friction", "force_drift"] in groups


def test_weakly_correlated_instrument_terms_are_not_listed():
    assert confounding_of({"air": -0.8, "friction": 0.1}, {"air": 0.0, "friction": 0.5}) == []


def test_friction_the_omnibus_test_misses_beside_an_explaining_effect_is_claimed(campaign):
    obs, damper = campaign
    coulomb = friction_step(obs, 60.0)
    effects = replace(viscous(damper, 1.5), coulomb_force_N=coulomb)
    force = replace(obs, force_N=Evaluator(obs, damper).predict(effects))
    alone = Diagnoser(force, damper).refit(("viscosity",))
    assert alone.explained   # the viscosity alone passes the χ² of all observations
    result, _pred = vd.diagnose_observations(force, damper)
    assert result["effect_tests"]["friction"]["against"] == ["viscosity"]
    assert result["verdict"] == ["friction", "viscosity"]
    assert result["params"]["coulomb_force_N"] == pytest.approx(coulomb, rel=0.01)


def test_friction_beside_an_explaining_effect_below_its_test_is_not_claimed(campaign):
    obs, damper = campaign
    effects = replace(viscous(damper, 1.5), coulomb_force_N=friction_step(obs, 30.0))
    result, _pred = vd.diagnose_observations(replace(obs, force_N=Evaluator(obs, damper).predict(effects)), damper)
    test = result["effect_tests"]["friction"]
    assert 0.0 < test["chi2_drop"] < test["threshold"]
    assert result["verdict"] == ["viscosity"]


def test_a_declared_calibration_the_data_contradict_is_said_in_the_calibration_note():
    tests = {"force_gain": {"estimate": 1.0, "calibration": {"gain": 1.0, "uncertainty_rel": 0.001, "reading": 1.015,
                                                            "z": 7.4, "agrees": False}},
             "displacement_scale": {"estimate": 1.012, "calibration": {"scale": 1.002, "uncertainty_rel": 0.001,
                                                                       "z": 9.9, "agrees": False}}}
    out = {"instrument_tests": tests}
    vd.calibration_keys(out)
    note = out["calibration_note"]
    assert "load cell's declared calibration (gain 1" in note and "1.015, +7.4 standard errors" in note
    assert "LVDT's declared calibration (scale 1.002" in note and "1.012, +9.9 standard errors" in note


def test_calibrations_that_agree_or_none_declared_add_no_note():
    agreeing = {"force_gain": {"estimate": 1.0, "calibration": {"gain": 1.0, "uncertainty_rel": 0.001,
                                                               "reading": 1.0004, "z": 0.4, "agrees": True}},
                "displacement_scale": {"estimate": None}}
    for tests in (agreeing, {}):
        out = {"instrument_tests": tests}
        vd.calibration_keys(out)
        assert "calibration_note" not in out
