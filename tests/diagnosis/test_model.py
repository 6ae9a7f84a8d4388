"""The diagnosis' model over the observations (diagnosis.model): its means against the simulated samples."""

import numpy as np
import pytest

from isokinetic.diagnosis.model import Evaluator
from isokinetic.physics.damper import Effects


@pytest.mark.parametrize("effects", [Effects(), Effects(leakage_conductance_m3_s_Pa=2e-12, asymmetry=0.05),
                                     Effects(air_volume_fraction=0.01), Effects(coulomb_force_N=40.0)],
                         ids=["nominal", "leakage", "air", "friction"])
def test_predicted_means_are_the_means_of_the_simulated_samples(campaign, effects):
    """predict (Δp* summed in closed form where the model is steady) gives each observation's mean of
    the model force sample by sample (Evaluator.forces)."""
    obs, damper = campaign
    ev = Evaluator(obs, damper)
    forces = ev.forces(effects)
    expected = np.array([forces[c][a:b].mean() for c, a, b in zip(obs.case_index, obs.start, obs.stop)])
    np.testing.assert_allclose(ev.predict(effects), expected, rtol=1e-11, atol=1e-9 * np.abs(expected).max())


def test_a_remembered_run_gives_the_same_means_without_simulating_again(campaign):
    obs, damper = campaign
    ev = Evaluator(obs, damper)
    effects = Effects(leakage_conductance_m3_s_Pa=2e-12)
    first = ev.predict(effects)
    first[:] = 0.0   # the caller's copy: what is remembered stays as simulated
    again = ev.predict(effects)
    assert ev.calls == 1
    np.testing.assert_array_equal(again, Evaluator(obs, damper).predict(effects))
