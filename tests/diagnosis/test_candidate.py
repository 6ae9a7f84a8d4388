"""The gap metric and the χ² tests of a candidate (isokinetic.diagnosis.candidate)."""

import numpy as np
import pytest

from isokinetic.diagnosis.candidate import consistent_with_noise, rms


def test_rms_z_is_one_for_unit_noise():
    z = np.random.default_rng(1).standard_normal(200_000)
    assert rms(z) == pytest.approx(1.0, abs=0.01)


def test_a_chi2_of_noise_is_consistent_and_a_large_one_is_not():
    assert consistent_with_noise(100.0, 100)
    assert not consistent_with_noise(300.0, 100)
    assert not consistent_with_noise(1.0, 0)  # no degrees of freedom: nothing is shown
