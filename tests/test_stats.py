"""The statistical helpers defined once (isokinetic.stats), against scipy.stats and the normal quantile."""

from statistics import NormalDist

import numpy as np
import pytest
from scipy import stats

from isokinetic.stats import Z_95, chi2_isf, chi2_ppf, chi2_sf


@pytest.mark.parametrize("dof", [1, 2, 3, 7, 40, 2.5])
def test_chi2_helpers_give_scipy_stats_numbers_exactly(dof):
    x = np.concatenate([[-np.inf, -1.0, -0.0, 0.0, 5e-324, np.inf, np.nan], np.logspace(-300, 4, 500)])
    np.testing.assert_array_equal(chi2_sf(x, dof), stats.chi2.sf(x, dof))
    assert chi2_sf(3.0, dof) == stats.chi2.sf(3.0, dof) and np.ndim(chi2_sf(3.0, dof)) == 0
    q = np.concatenate([[0.0, 1.0, -0.1, 1.1, np.nan, 5e-324], np.logspace(-300, -1e-16, 500)])
    np.testing.assert_array_equal(chi2_isf(q, dof), stats.chi2.isf(q, dof))
    np.testing.assert_array_equal(chi2_ppf(q, dof), stats.chi2.ppf(q, dof))


def test_z_95_is_the_two_sided_95_percent_normal_quantile():
    assert pytest.approx(NormalDist().inv_cdf(0.975), rel=1e-15) == Z_95
