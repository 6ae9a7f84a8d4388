"""The search's fits (diagnosis.search): the secant Jacobian against forward differences and the
secant equation, and fits with it against fits with scipy's own differences."""

from dataclasses import replace

import numpy as np
import pytest
from scipy import optimize

from isokinetic.diagnosis.search import DIFF_STEP, FIT_TOL, Diagnoser, SecantJacobian


def residuals(x):
    """A small nonlinear least-squares problem (exponential decay) with its exact minimum near (2, 0.7)."""
    t = np.linspace(0.0, 3.0, 25)
    return x[0] * np.exp(-x[1] * t) - 2.0 * np.exp(-0.7 * t) - 0.01 * np.sin(7.0 * t)


def test_first_jacobian_is_the_forward_difference():
    """The first Jacobian: forward differences of relative step DIFF_STEP, one-sided away from the upper bound."""
    x = np.array([1.5, 0.4])
    sj = SecantJacobian(residuals, [0.0, 0.0], [10.0, 0.4 + 1e-9])
    f = sj(x)
    got = sj.jac(x)
    h0 = (1.5 + DIFF_STEP * 1.5) - 1.5
    h1 = (0.4 - DIFF_STEP * 1.0) - 0.4   # x + h would leave the bounds: the step goes down
    expected = np.column_stack([(residuals(x + [h0, 0.0]) - f) / h0, (residuals(x + [0.0, h1]) - f) / h1])
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_update_satisfies_the_secant_equation():
    """After a step Δx the updated Jacobian maps Δx onto the change of the residuals (Broyden's update)."""
    sj = SecantJacobian(residuals, [0.0, 0.0], [10.0, 5.0])
    a, b = np.array([1.5, 0.4]), np.array([1.8, 0.55])
    sj(a)
    j0 = sj.jac(a)
    sj(b)
    j1 = sj.jac(b)
    np.testing.assert_allclose(j1 @ (b - a), residuals(b) - residuals(a), rtol=1e-12, atol=1e-14)
    v = np.array([-(b - a)[1], (b - a)[0]])  # orthogonal to the step: unchanged
    np.testing.assert_allclose(j1 @ v, j0 @ v, rtol=1e-12, atol=1e-14)


def test_fit_with_the_secant_jacobian_finds_the_same_minimum():
    """least_squares with the secant Jacobian stops within the search's tolerance of scipy's own '2-point'
    fit to the end (the cost within FIT_TOL, the parameters within √FIT_TOL), with fewer evaluations."""
    calls = {"n": 0}

    def counted(x):
        calls["n"] += 1
        return residuals(x)

    bounds = ([0.0, 0.0], [10.0, 5.0])
    ref = optimize.least_squares(counted, [1.0, 0.2], bounds=bounds, method="trf", x_scale="jac",
                                 diff_step=DIFF_STEP, ftol=1e-12, xtol=1e-12)
    calls["n"] = 0
    optimize.least_squares(counted, [1.0, 0.2], bounds=bounds, method="trf", x_scale="jac", diff_step=DIFF_STEP,
                           ftol=FIT_TOL, xtol=FIT_TOL)
    n_ref, calls["n"] = calls["n"], 0
    sj = SecantJacobian(counted, *bounds)
    got = optimize.least_squares(sj, [1.0, 0.2], jac=sj.jac, bounds=bounds, method="trf", x_scale="jac",
                                 ftol=FIT_TOL, xtol=FIT_TOL)
    assert got.cost <= ref.cost * (1.0 + FIT_TOL)
    np.testing.assert_allclose(got.x, ref.x, rtol=FIT_TOL**0.5)
    assert calls["n"] < n_ref


class _Starts:
    def starts(self, effect):
        return [0.1]


def searched_sizes(holdout_of_size) -> list[int]:
    """The sizes of the effect sets a search fits when no candidate explains and a set's holdout χ² is
    ``holdout_of_size(size)`` (the fits stubbed: a Diagnoser with only ``fit`` and its parametrisation)."""
    from isokinetic.diagnosis.candidate import Candidate
    from isokinetic.diagnosis.search import Diagnoser

    sizes = []

    def fit(names, starts):
        sizes.append(len(names))
        return Candidate(effects=tuple(names), x=np.zeros(len(names)), params={}, prediction=np.zeros(1),
                         chi2_fit=150.0, chi2_holdout=holdout_of_size(len(names)), n_fit=100, n_holdout=100,
                         gap_after=2.0, holdout_gap_after=2.0, score=0.0, explained=False)

    dg = object.__new__(Diagnoser)
    dg.param, dg.fit = _Starts(), fit
    dg.search()
    return sizes


def test_an_unexplained_search_stops_where_two_larger_sizes_leave_its_choice():
    """Pairs beat the singles by far more than the margin; triples and sets of four earn less than it: the pair
    stays the choice over two sizes, and no set of five or more is fitted."""
    sizes = searched_sizes(lambda n: {1: 1000.0, 2: 500.0}.get(n, 495.0))
    assert max(sizes) == 4 and sizes.count(3) > 0 and sizes.count(4) > 0


def test_an_unexplained_search_goes_on_while_larger_sets_change_its_choice():
    """Every size beats the one before by more than the margin: the search extends up to the whole catalogue."""
    sizes = searched_sizes(lambda n: 1000.0 - 100.0 * n)
    assert max(sizes) == 7


def test_the_diagnoser_holds_the_gain_to_the_observations_calibration(campaign):
    obs, damper = campaign
    linear = Diagnoser(replace(obs, force_calibration=(1.02, 0.001)), damper).linear
    assert (linear.gain_centre, linear.gain_sd) == pytest.approx((1.02, 0.00102))
    plain = Diagnoser(obs, damper).linear
    assert (plain.gain_centre, plain.gain_sd) == (1.0, None)


def test_a_declared_calibration_counts_as_one_more_observation_in_the_fits_chi2(campaign):
    obs, damper = campaign
    forced = replace(obs, force_N=1.004 * Diagnoser(obs, damper).nominal, force_calibration=(1.0, 0.001))
    dg = Diagnoser(forced, damper)
    fit = dg.refit(())
    assert 1.0 < fit.gain < 1.004   # the data pull the gain away from the calibration, the calibration holds it
    z = (forced.force_N - fit.measured_prediction) / forced.sigma_N
    chi2_obs = float(np.sum(z[dg.fit_mask] ** 2))
    assert fit.chi2_fit == pytest.approx(chi2_obs + ((fit.gain - 1.0) / 0.001) ** 2, rel=1e-9)
    plain = Diagnoser(replace(forced, force_calibration=None), damper).refit(())
    assert plain.gain == pytest.approx(1.004, rel=1e-6) and plain.chi2_fit == pytest.approx(0.0, abs=1e-6)
