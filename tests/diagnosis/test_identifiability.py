"""Standard errors of a verdict's parameters (isokinetic.diagnosis.identifiability) against the scatter of the
estimates over noise realisations."""

from dataclasses import replace

import numpy as np
import pytest

from isokinetic.diagnosis.identifiability import identifiability, std_error_scale
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.physics.damper import Effects

REALISATIONS = 40


def estimates_and_errors(obs, damper, noise_factor: float, seed: int = 11):
    """Viscosity estimates and their reported standard errors over REALISATIONS noise draws of ``noise_factor``
    times the observations' own standard errors around a model of 1.2 × the nominal viscosity."""
    truth = Evaluator(obs, damper).predict(Effects(viscosity_Pa_s=1.2 * damper.viscosity_Pa_s))
    rng = np.random.default_rng(seed)
    values, errors, scales = [], [], []
    for _ in range(REALISATIONS):
        noisy = replace(obs, force_N=truth + noise_factor * obs.sigma_N * rng.standard_normal(len(obs)))
        dg = Diagnoser(noisy, damper)
        fit = dg.refit(("viscosity",), instrument=())
        ident = identifiability(dg, fit)
        values.append(fit.params["viscosity_Pa_s"])
        errors.append(ident["parameters"]["viscosity_Pa_s"]["std_error"])
        scales.append(ident["std_error_scale"])
    return np.array(values), np.array(errors), np.array(scales)


@pytest.mark.parametrize("noise_factor", [1.0, 3.0], ids=["noise-as-modelled", "three-times-the-noise"])
def test_reported_standard_errors_match_the_scatter_of_the_estimates(campaign, noise_factor):
    # with three times the noise the standard errors assume, the fit's χ² is about nine times its degrees of
    # freedom: the Fisher errors alone would be three times too small; scaled by √(χ²/dof) they are right
    obs, damper = campaign
    values, errors, scales = estimates_and_errors(obs, damper, noise_factor)
    scatter = np.std(values, ddof=1)
    assert np.median(errors) == pytest.approx(scatter, rel=0.3)
    assert np.median(scales) == pytest.approx(max(noise_factor, 1.0), rel=0.2)


def test_the_scale_is_one_where_the_fit_is_within_its_degrees_of_freedom():
    assert std_error_scale(90.0, 100) == 1.0 and std_error_scale(400.0, 100) == pytest.approx(2.0)
    assert std_error_scale(5.0, 0) == 1.0


def fisher_error(dg, fit, name: str) -> float:
    """A parameter's standard error from the Fisher information alone (the reported one without its Birge
    scale: with eight observations χ²/dof scatters widely)."""
    ident = identifiability(dg, fit)
    return ident["parameters"][name]["std_error"] / ident["std_error_scale"]


def test_with_a_declared_calibration_the_standard_errors_match_the_scatter_of_the_estimates(campaign):
    # the calibration is one more observation of the gain: each realisation draws it with its uncertainty too,
    # and the errors from the Fisher information (the calibration's row in it) must match the scatter. On the
    # steady windows alone a gain beside discharge and viscosity is what only the calibration pins (issue 37)
    obs, damper = campaign
    obs = obs.subset(obs.is_window)
    truth = Evaluator(obs, damper).predict(Effects(discharge_coefficient=0.9 * damper.discharge_coefficient))
    rng, u = np.random.default_rng(5), 0.002
    values, errors, without = [], [], []
    for _ in range(REALISATIONS):
        noisy = replace(obs, force_N=truth + obs.sigma_N * rng.standard_normal(len(obs)),
                        force_calibration=(1.0 + u * rng.standard_normal(), u))
        dg = Diagnoser(noisy, damper)
        fit = dg.refit(("discharge", "viscosity"), instrument=("force_gain",))
        values.append(fit.params["discharge_coefficient"])
        errors.append(fisher_error(dg, fit, "discharge_coefficient"))
        plain = Diagnoser(replace(noisy, force_calibration=None), damper)
        without.append(fisher_error(plain, plain.refit(("discharge", "viscosity"), instrument=("force_gain",)),
                                    "discharge_coefficient"))
    assert np.mean(errors) == pytest.approx(np.std(values, ddof=1), rel=0.3)
    assert np.mean(errors) < 0.2 * np.mean(without)   # without its row the gain is free: C_D is all but unknown
