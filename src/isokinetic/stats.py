"""The statistical constants and χ² helpers every layer shares, defined once.

``chi2_sf``/``chi2_isf``/``chi2_ppf`` are scipy.stats.chi2's functions from ``scipy.special`` alone
(importing scipy.stats costs a job ~0.4 s), imported when first called: a job that
uses only the constants (the report's) loads no scipy. ``ALPHA`` is the significance level of the diagnosis'
χ² tests (a smaller p-value is not noise); ``Z_95`` the two-sided 95 % normal quantile of the
comparison bars and bands.
"""

from __future__ import annotations

import numpy as np

#: Significance level: a χ² with a smaller p-value is not noise (diagnosis, static-force check).
ALPHA = 1e-3

#: Two-sided 95 % quantile of the normal distribution (bars and bands are +-Z_95 SE).
Z_95 = 1.959963984540054


def chi2_sf(x, dof):
    """``scipy.stats.chi2.sf(x, dof)``, the same numbers from ``scipy.special`` alone: ``chdtrc``,
    and 1 at x <= 0 where ``chdtrc`` gives NaN."""
    from scipy import special

    x = np.asarray(x, dtype=float)
    out = np.where(x <= 0.0, 1.0, special.chdtrc(dof, x))
    return out[()] if out.ndim == 0 else out


def chi2_isf(q, dof):
    """``scipy.stats.chi2.isf(q, dof)``: its very function, ``scipy.special.chdtri``."""
    from scipy import special

    return special.chdtri(dof, q)


def chi2_ppf(p, dof):
    """``scipy.stats.chi2.ppf(p, dof)``: its very function, 2 ``gammaincinv(dof / 2, p)``."""
    from scipy import special

    return 2 * special.gammaincinv(dof / 2, p)
