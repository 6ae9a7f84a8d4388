"""The diagnosis' model over the observations (diagnosis.model): its means against the simulated samples."""

import numpy as np
import pandas as pd
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


FRICTION_N = 20.0


@pytest.fixture(scope="module")
def filtered_friction(tmp_path_factory):
    """(observations, damper, group delay) of a nearly noise-free reference-rig campaign of two sine cases (0.5
    and 5 Hz, at 200 and 1000 Hz sampling) with FRICTION_N of Coulomb friction, read through a 4 Hz first-order
    force low-pass (group delay 1/(2π·4 Hz) = 40 ms)."""
    from isokinetic.diagnosis.observations import build_observations
    from isokinetic.measurement.windows import WindowSpec
    from isokinetic.reference import campaign as rrc
    from isokinetic.reference import rig as rr
    from isokinetic.stages.blind_diagnose import process_raw_campaign
    from isokinetic.stages.diagnosis import load_campaign

    tmp = tmp_path_factory.mktemp("filtered_friction")
    cases = [rr.SineCase("H01", 0.5, 30e-6, 4, 200.0), rr.SineCase("H02", 5.0, 20e-6, 4, 1000.0)]
    rig = rr.RigImperfections(force_noise_N=0.02, force_resolution_N=0.001, force_filter_Hz=4.0,
                              force_filter_order=1)
    rrc.write_campaign(tmp / "raw" / "ff", cases, rr.TABLE1, rr.TrueEffects(coulomb_force_N=FRICTION_N), rig=rig,
                       seed=4, write_phase=False)
    root = process_raw_campaign(tmp / "raw" / "ff", tmp / "work")
    campaign, damper, cases_df, char, _scales = load_campaign(root)
    obs = build_observations(campaign, cases_df, char, lambda row: pd.read_parquet(root / row["timeseries_file"]),
                             WindowSpec())
    return obs, damper, 1.0 / (2.0 * np.pi * 4.0)


def test_a_profiled_friction_is_read_through_the_force_channel_as_the_hydraulic_force_is(filtered_friction):
    # near each reversal a low-passed channel still reads the friction of the other direction: the friction's
    # column is sign(v) through the channel, not the bin's direction
    obs, damper, lag = filtered_friction
    ev = Evaluator(obs, damper)
    hydraulic = ev.filtered(Effects(), [lag], 1)[0]
    through = hydraulic + FRICTION_N * ev.friction_read(1, lag)
    direct = hydraulic + FRICTION_N * obs.sign
    tol = 0.05 * FRICTION_N   # the model's low-pass (bilinear) is not the rig's (exact): 0.8 N at most here
    assert np.max(np.abs(through - obs.force_N)) < tol < np.max(np.abs(direct - obs.force_N))
    # and it is sign(v) through the channel as the sample-by-sample digital filter (bilinear, at each case's rate)
    # reads it, to within the sample grid's quantisation of a reversal (5 ms at 200 Hz, an eighth of the delay)
    samples = Evaluator(obs, damper, grid=False).friction_read(1, lag)
    assert np.max(np.abs(ev.friction_read(1, lag) - samples)) < 0.05
