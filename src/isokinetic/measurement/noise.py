"""Pooled force-noise model of a campaign and honest standard errors of window means.

Model
    A force sample is x_i = F_i + n_i with n_i = w_i + c_i: w white, variance s_w^2 + s_q^2 F^2, and
    c a first-order (AR(1)) coloured process, autocorrelation exp(-|lag| / tau_c), variance
    s_c^2 = s_a^2 + s_r^2 F^2; each has an additive and a force-proportional part (s_q = 0 gives the
    white + coloured model of the rig; the virtual rig's sensor noise is s_w and s_q alone). The
    correlation per sample is rho = exp(-1 / (fs tau_c)); a corner frequency f_c corresponds to
    tau_c = 1 / (2 pi f_c).

Variance of a mean of n consecutive samples (exact under the model)
    var = (s_w^2 + s_q^2 F^2) / n + s_c^2 g(n, rho), g = (1/n^2) sum_{i,j} rho^|i-j|
        = [n (1 + rho)/(1 - rho) - 2 rho (1 - rho^n)/(1 - rho)^2] / n^2,
    which is 1/n for white noise and tends to 1 when tau_c is long against the window.

Fit (:func:`fit_noise_model`)
    Steady windows are pooled through their empirical variograms V(k) = mean_i (r_{i+k} - r_i)^2 / 2
    at the lags k = 1, 2, 3, 5, 8, ... <= n/2 (no mean to remove, so no demeaning bias); r is the
    window with its least-squares line removed (a drift b of the true force would add (b k)^2 / 2
    and read as slow noise). The line also removes part of the noise, so the fit uses the exact
    expected detrended variogram, white variance times A_k(n) plus s_c^2 B_k(n, tau_c), and stays
    unbiased. For each tau_c on a log grid (16 a decade, one sample interval to 10 s), the
    unknowns (s_w^2, s_q^2, s_a^2, s_r^2) >= 0 solve a generalised non-negative least squares
    problem. Its weight is the inverse of the covariance of each window's variogram points under
    the current model (Gaussian increments): every window is scaled to its own noise level, so
    5 N and 7 kN windows count alike, and the sum of squares is a chi-square. The best tau_c is
    refined by a parabola, and the weights are re-derived from the fit (a fixed number of passes;
    deterministic). Then, by backward elimination, each of s_q, s_a, s_r whose removal raises the
    chi-square by less than 3.84 (chi2(1) 0.95) is dropped, the last coloured one (with tau_c) if
    it costs less than 7.68, and the kept ones are refitted with their own weights. A component
    below the detection limit would otherwise sit at a noisy positive value, and its effect on
    slow means is large; the pure-white case is exactly that.

Uncertainty
    The generalised least squares information gives a covariance of (s_w^2, s_q^2, s_a^2, s_r^2,
    ln tau_c) (``NoiseModel.param_cov``), and :meth:`NoiseModel.mean_variance_rel_sd` the resulting
    relative uncertainty of a mean's variance. That uncertainty is common to all the means of a
    campaign, so it scales a chi-square of many z as a whole; :func:`scaled_chi2_isf` gives the
    threshold that allows for it.

Limits
    Within-window data see the coloured part on time scales up to half the longest windows. When
    the windows are not much longer than tau_c (e.g. a 0.1 Hz corner, tau_c = 1.6 s, and windows of
    5-20 s), the sill and tau_c trade off along a ridge. The variance of a window mean is then
    uncertain by 15-65 % (``mean_variance_rel_sd``), with the error roughly log-symmetric: unbiased
    in the median, biased high in the mean. A noise component constant over a whole window cannot be
    seen here at all and belongs to the between-period scatter (:func:`between_period_scatter`). An
    additive coloured part far below the white noise is not detectable but can still matter for long
    means of small forces. A corner above about fs / (2 pi) (tau_c below one sample) cannot be told
    from white noise; the grid starts at one sample interval.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isokinetic.stats import chi2_isf, chi2_ppf, chi2_sf

#: Median of the chi-square distribution with one degree of freedom (0.454936...).
MEDIAN_CHI2_1 = float(chi2_ppf(0.5, 1))

#: Windows shorter than this are ignored by :func:`fit_noise_model`.
MIN_FIT_SAMPLES = 6

#: Default upper end of the tau_c grid [s].
TAU_MAX_S = 10.0

_TAU_PER_DECADE = 16
_N_PASSES = 2
_LAG_DIVISOR = 2


@dataclass(frozen=True)
class NoiseModel:
    """Force-noise model: white plus first-order coloured noise, each additive plus proportional.

    Attributes
    ----------
    white_var_N2 : float
        Additive variance s_w^2 of the white part [N^2].
    coloured_var_N2 : float
        Additive variance s_a^2 of the coloured part [N^2].
    coloured_rel_var : float
        Relative variance s_r^2 of the coloured part (s_r a fraction of the force) [-].
    tau_c_s : float
        Correlation time of the coloured part, autocorrelation exp(-|lag| / tau_c) [s].
    fs_Hz : float
        Sample rate [Hz].
    white_rel_var : float, optional
        Relative variance s_q^2 of a force-proportional white part [-] (the virtual rig's
        ``force_noise_rel``); 0 by default.
    param_cov : tuple of tuples, optional
        Covariance (5 x 5) of the fitted (s_w^2, s_q^2, s_a^2, s_r^2, ln tau_c), zero rows for
        parameters fixed at zero; set by :func:`fit_noise_model`, None for a model given by hand.
    """

    white_var_N2: float
    coloured_var_N2: float
    coloured_rel_var: float
    tau_c_s: float
    fs_Hz: float
    white_rel_var: float = 0.0
    param_cov: tuple[tuple[float, ...], ...] | None = None

    def __post_init__(self):
        for name in ("white_var_N2", "white_rel_var", "coloured_var_N2", "coloured_rel_var"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {v!r}")
        for name in ("tau_c_s", "fs_Hz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        if self.param_cov is not None and np.shape(self.param_cov) != (5, 5):
            raise ValueError(f"param_cov must be 5 x 5, got shape {np.shape(self.param_cov)}")

    def to_dict(self) -> dict:
        """The plain (JSON-ready) form: the fields, ``corner_Hz``, and ``param_cov`` as nested lists."""
        out = {name: float(getattr(self, name)) for name in ("white_var_N2", "white_rel_var", "coloured_var_N2",
                                                             "coloured_rel_var", "tau_c_s", "fs_Hz")}
        out["corner_Hz"] = self.corner_Hz
        out["param_cov"] = None if self.param_cov is None else [list(row) for row in self.param_cov]
        return out

    @property
    def corner_Hz(self) -> float:
        """Corner frequency 1 / (2 pi tau_c) of the coloured part [Hz]."""
        return 1.0 / (2.0 * math.pi * self.tau_c_s)

    @property
    def rho(self) -> float:
        """The correlation of the coloured part between neighbouring samples, exp(-1 / (fs tau_c)) [-]."""
        return math.exp(-1.0 / (self.fs_Hz * self.tau_c_s))

    def white_variance_N2(self, mean_square_force_N2):
        """Variance s_w^2 + s_q^2 F^2 of the white part at mean square force F^2 [N^2]."""
        return self.white_var_N2 + self.white_rel_var * np.asarray(mean_square_force_N2, dtype=float)

    def coloured_variance_N2(self, mean_square_force_N2):
        """Variance s_a^2 + s_r^2 F^2 of the coloured part at mean square force F^2 [N^2]."""
        return self.coloured_var_N2 + self.coloured_rel_var * np.asarray(mean_square_force_N2, dtype=float)

    def sample_variance_N2(self, mean_square_force_N2):
        """Variance of one sample, white plus coloured [N^2]."""
        return self.white_variance_N2(mean_square_force_N2) + self.coloured_variance_N2(mean_square_force_N2)

    def mean_variance(self, n_samples, mean_square_force_N2):
        """Variance of the mean of ``n_samples`` consecutive samples [N^2].

        Parameters
        ----------
        n_samples : array_like of int
            Samples in the mean (>= 1).
        mean_square_force_N2 : array_like
            Mean over those samples of the squared true force F^2 [N^2] (for a steady window the
            squared mean force; for a transient bin the mean of F^2, an approximation there).

        Returns
        -------
        ndarray or float
            (s_w^2 + s_q^2 F^2) / n + (s_a^2 + s_r^2 F^2) g(n, rho), broadcast over both arguments
            (g from :func:`ar1_mean_factor`).
        """
        n = np.asarray(n_samples, dtype=float)
        if np.any(~np.isfinite(n)) or np.any(n < 1):
            raise ValueError("n_samples must be finite and >= 1")
        f2 = np.asarray(mean_square_force_N2, dtype=float)
        if np.any(~np.isfinite(f2)) or np.any(f2 < 0):
            raise ValueError("mean_square_force_N2 must be finite and >= 0")
        a = 1.0 / (self.fs_Hz * self.tau_c_s)
        out = self.white_variance_N2(f2) / n + self.coloured_variance_N2(f2) * ar1_mean_factor(n, a)
        return out if out.ndim else float(out)

    def mean_se(self, n_samples, mean_square_force_N2):
        """Standard error of the mean of ``n_samples`` samples, sqrt(:meth:`mean_variance`) [N]."""
        return np.sqrt(self.mean_variance(n_samples, mean_square_force_N2))

    def mean_variance_rel_sd(self, n_samples, mean_square_force_N2):
        """Relative standard deviation of :meth:`mean_variance` from the fit's own uncertainty [-].

        First order in ``param_cov``; a value above about 0.3 means the model cannot be trusted
        for such a mean. The errors of all means of a campaign are strongly correlated, so a
        chi-square of many z = (mean - F) / se scales with them as a whole (:func:`scaled_chi2_isf`).

        Raises
        ------
        ValueError
            When the model carries no ``param_cov``.
        """
        if self.param_cov is None:
            raise ValueError("the model carries no parameter covariance (not fitted)")
        total = self.mean_variance(n_samples, mean_square_force_N2)
        n = np.asarray(n_samples, dtype=float)
        f2 = np.asarray(mean_square_force_N2, dtype=float)
        a = 1.0 / (self.fs_Hz * self.tau_c_s)
        h = 1e-4
        g = ar1_mean_factor(n, a)
        dg = (ar1_mean_factor(n, a * math.exp(-h)) - ar1_mean_factor(n, a * math.exp(h))) / (2.0 * h)  # d/d ln tau
        grad = np.stack(np.broadcast_arrays(1.0 / n, f2 / n, g, f2 * g, self.coloured_variance_N2(f2) * dg), axis=-1)
        var = np.einsum("...i,ij,...j->...", grad, np.asarray(self.param_cov, dtype=float), grad)
        out = np.sqrt(np.clip(var, 0.0, None)) / np.where(total > 0, total, 1.0)
        return out if out.ndim else float(out)


def ar1_mean_factor(n_samples, a):
    """g(n) = (1/n^2) sum_{i,j<n} exp(-a |i - j|) [-]: variance of a mean of n unit-variance AR(1) samples.

    ``a`` = 1 / (fs tau_c) > 0 (samples^-1); vectorised over ``n_samples`` (>= 1). Uses a series in
    a n where the closed form would cancel.
    """
    n = np.asarray(n_samples, dtype=float)
    a = float(a)
    if not a > 0.0:
        raise ValueError(f"a must be > 0, got {a!r}")
    x = a * n
    small = x < 1e-3
    om = -math.expm1(-a)                                    # 1 - rho, no cancellation
    rho = 1.0 - om
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        exact = (n * (1.0 + rho) / om + 2.0 * rho * np.expm1(-x) / om**2) / (n * n)
    series = 1.0 - a * (n * n - 1.0) / (3.0 * n) + a * a * (n * n - 1.0) / 12.0
    out = np.where(small, series, exact)
    return np.clip(out, 1.0 / n, 1.0)


def variogram_lags(n_samples: int) -> np.ndarray:
    """Lags 1, 2, 3, 5, 8, 13, ... (Fibonacci) up to n // 2 (at least lag 1) [samples]."""
    top = max(1, int(n_samples) // _LAG_DIVISOR)
    lags = [1]
    a, b = 2, 3
    while a <= top:
        lags.append(a)
        a, b = b, a + b
    return np.asarray(lags, dtype=np.int64)


def _white_design(n: int, lags: np.ndarray, detrend: bool) -> np.ndarray:
    """Expected (detrended) variogram of unit white noise at ``lags``: 1 - 6 k^2 / (n (n^2 - 1))."""
    k = lags.astype(float)
    if not detrend:
        return np.ones_like(k)
    return 1.0 - 6.0 * k * k / (n * (n * n - 1.0))


def _coloured_design(n: int, lags: np.ndarray, a: np.ndarray, detrend: bool) -> np.ndarray:
    """Expected (detrended) variogram of unit AR(1) noise, shape (len(a), len(lags)).

    Without detrending 1 - rho^k. With it, for residuals r = M x (M removes the least-squares line,
    u the centred sample index, c^2 = 12 / (n (n^2 - 1)), W = R u with R_ij = rho^|i-j|):
    E V(k) = 1 - rho^k + 2 k c^2 P_k / (n - k) + k^2 c^4 u'W / 2, P_k = sum_{i<k} W_i. W has the
    closed form u_i (1 + rho)/(1 - rho) + K (rho^(i+1) - rho^(n-i)), K = ((m+1)(1-rho) + rho)/(1-rho)^2,
    m = (n-1)/2; it cancels badly for a n small, where W comes from the exact recursion instead.
    """
    k = lags.astype(float)[None, :]
    a = np.asarray(a, dtype=float)[:, None]
    base = -np.expm1(-a * k)
    if not detrend:
        return base
    m = 0.5 * (n - 1.0)
    c2 = 12.0 / (n * (n * n - 1.0))
    p = np.empty((a.shape[0], k.shape[1]))
    g = np.empty((a.shape[0], 1))
    closed = (a[:, 0] * n) >= 2.0
    if np.any(closed):
        ac = a[closed]
        rho = np.exp(-ac)
        om = -np.expm1(-ac)
        kk = ((m + 1.0) * om + rho) / om**2
        p[closed] = ((1.0 + rho) / om * (k * (k - 1.0) / 2.0 - k * m)
                     + kk * (-np.expm1(-ac * k)) * (rho - np.exp(-ac * (n - k + 1.0))) / om)
        sum_i_rho = rho * (1.0 - n * np.exp(-ac * (n - 1.0)) + (n - 1.0) * np.exp(-ac * n)) / om**2
        g[closed] = ((1.0 + rho) / om * n * (n * n - 1.0) / 12.0
                     + 2.0 * kk * rho * (sum_i_rho - m * (-np.expm1(-ac * n)) / om))
    if not np.all(closed):
        u = np.arange(n, dtype=float) - m
        idx = lags.astype(np.int64)
        # the AR(1) recursion y_i = u_i + rho y_(i-1), both ways, as rho^i cumsum(rho^-j u_j): a n < 2 here,
        # so rho^-j <= e^2 and the sums neither overflow nor cancel
        open_ = np.flatnonzero(~closed)
        decay = np.exp(-a[open_] * np.arange(n, dtype=float)[None, :])                  # rho^i, (J, n)
        forward = decay * np.cumsum(u / decay, axis=1)
        backward = (decay * np.cumsum(u[::-1] / decay, axis=1))[:, ::-1]
        w = forward + backward - u
        cs = np.concatenate([np.zeros((open_.size, 1)), np.cumsum(w, axis=1)], axis=1)
        p[open_] = cs[:, idx]
        g[open_, 0] = w @ u
    return base + 2.0 * k * c2 * p / (n - k) + k * k * c2 * c2 * g / 2.0


@dataclass(frozen=True)
class _Group:
    """Windows with the same number of variogram lags (hence the same lags)."""

    lags: np.ndarray          # (L,) lags [samples]
    n: np.ndarray             # (B,) samples per window
    value_N2: np.ndarray      # (B, L) empirical variograms
    f2_N2: np.ndarray         # (B,) mean square forces
    white: np.ndarray         # (B, L) expected variogram of unit white noise
    level_N2: np.ndarray      # (B,) mean of each window's variogram (fallback noise scale)


def _window_variogram(x: np.ndarray, detrend: bool):
    """(variogram at :func:`variogram_lags`, mean square force) of one window."""
    n = x.size
    mean = float(x.mean())
    r = x - mean
    f2 = mean * mean
    if detrend:
        t = np.arange(n, dtype=float) - 0.5 * (n - 1.0)
        slope = float(t @ r) / float(t @ t)
        r = r - slope * t
        f2 += slope * slope * float(t @ t) / n
    v = np.array([0.5 * float(np.mean(np.square(r[k:] - r[:-k]))) for k in variogram_lags(n)])
    return v, f2


def _collect(windows, detrend: bool) -> list[_Group]:
    """Variograms of the usable windows, grouped by their lag sets."""
    by_size: dict[int, list] = {}
    for j, w in enumerate(windows):
        x = np.asarray(w, dtype=float)
        if x.ndim != 1:
            raise ValueError(f"window {j} is not one-dimensional (shape {x.shape})")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"window {j} holds non-finite samples")
        if x.size < MIN_FIT_SAMPLES or np.all(x == x[0]):
            continue            # too short, or constant (quantised): no information on the noise
        v, f2 = _window_variogram(x, detrend)
        if not np.any(v > 0.0):
            continue            # an exact straight line once detrended
        by_size.setdefault(v.size, []).append((x.size, v, f2))
    groups = []
    for size in sorted(by_size):
        items = by_size[size]
        n = np.array([it[0] for it in items], dtype=np.int64)
        lags = variogram_lags(int(n[0]))
        value = np.stack([it[1] for it in items])
        groups.append(_Group(lags=lags, n=n, value_N2=value, f2_N2=np.array([it[2] for it in items]),
                             white=np.stack([_white_design(int(m), lags, detrend) for m in n]),
                             level_N2=value.mean(axis=1)))
    return groups


def _group_columns(g: _Group, a: np.ndarray, detrend: bool) -> np.ndarray:
    """Expected unit coloured variogram of each window of ``g`` for each a, shape (T, B, L)."""
    if not detrend:
        return np.broadcast_to(_coloured_design(int(g.n[0]), g.lags, a, False)[:, None, :],
                               (a.size, g.n.size, g.lags.size))
    out = np.empty((a.size, g.n.size, g.lags.size))
    for m in np.unique(g.n):
        out[:, g.n == m, :] = _coloured_design(int(m), g.lags, a, True)[:, None, :]
    return out


def _variogram_covariance(g: _Group, white_var: np.ndarray, coloured_var: np.ndarray, a: float) -> np.ndarray:
    """Approximate covariance of each window's empirical variogram (Gaussian noise), (B, L, L).

    Increments d = x_{i+k} - x_i are Gaussian, so cov(V(k1), V(k2)) = sum_{i,j} C(i - j)^2 / (2 N1 N2)
    with C(m) = g(m + k1 - k2) - g(m + k1) - g(m - k2) + g(m), g the autocovariance. With the
    stationary sum over all m (and sqrt(N1 N2) for the overlap, which keeps the matrix positive
    semi-definite) sum_m C^2 = sum_{p,q} alpha_p alpha_q G(p - q), G(D) = sum_m g(m) g(m + D) =
    s_w^4 [D = 0] + 2 s_w^2 s_c^2 rho^|D| + s_c^4 rho^|D| (|D| + (1 + rho^2)/(1 - rho^2)).
    Detrending is ignored here (it only shapes the weights).
    """
    k = g.lags.astype(float)
    k1, k2 = k[:, None], k[None, :]
    zero = 0.0 * k1 * k2
    shifts = np.stack([k2 - k1, -k1 + zero, k2 + zero, zero], axis=-1)                  # (L, L, 4)
    alpha = np.array([1.0, -1.0, -1.0, 1.0])
    aa = alpha[:, None] * alpha[None, :]
    dd = np.abs(shifts[..., :, None] - shifts[..., None, :])                             # (L, L, 4, 4)
    rd = np.exp(-a * dd)
    q = (1.0 + math.exp(-2.0 * a)) / -math.expm1(-2.0 * a)
    m0 = np.einsum("pq,ijpq->ij", aa, (dd == 0).astype(float))
    m1 = np.einsum("pq,ijpq->ij", aa, rd)
    m2 = np.einsum("pq,ijpq->ij", aa, rd * (dd + q))
    sw = white_var[:, None, None]
    sc = coloured_var[:, None, None]
    npairs = (g.n[:, None] - g.lags[None, :]).astype(float)
    return (sw * sw * m0 + 2.0 * sw * sc * m1 + sc * sc * m2) / (2.0 * np.sqrt(npairs[:, :, None] * npairs[:, None, :]))


@dataclass(frozen=True)
class _Weighted:
    """A group with its weight (inverse covariance) matrices and the fixed products."""

    group: _Group
    precision: np.ndarray     # (B, L, L)
    pa: np.ndarray            # precision @ white   (B, L)
    py: np.ndarray            # precision @ value   (B, L)
    aa: np.ndarray            # white' P white per window (B,)
    ay: np.ndarray            # white' P value per window (B,)
    yy: float                 # sum value' P value


def _weigh(groups: list[_Group], beta, a: float) -> list[_Weighted]:
    """Weight matrices of every group under the model beta = (s_w^2, s_q^2, s_a^2, s_r^2) and a.

    ``beta`` None weighs every window as white noise at its own level (the first pass); a window
    the model leaves (nearly) noiseless is weighed that way too.
    """
    out = []
    for g in groups:
        if beta is None:
            sw, sc = g.level_N2.copy(), np.zeros(g.n.size)
        else:
            sw = beta[0] + beta[1] * g.f2_N2
            sc = beta[2] + beta[3] * g.f2_N2
            quiet = sw + sc < 1e-6 * g.level_N2
            sw[quiet], sc[quiet] = g.level_N2[quiet], 0.0
        cov = _variogram_covariance(g, sw, sc, a)
        w, v = np.linalg.eigh(cov)
        w = np.maximum(w, 1e-10 * w[:, -1:])
        prec = np.einsum("bil,bl,bjl->bij", v, 1.0 / w, v)
        pa = np.einsum("bij,bj->bi", prec, g.white)
        py = np.einsum("bij,bj->bi", prec, g.value_N2)
        out.append(_Weighted(group=g, precision=prec, pa=pa, py=py, aa=np.sum(pa * g.white, axis=1),
                             ay=np.sum(pa * g.value_N2, axis=1), yy=float(np.sum(py * g.value_N2))))
    return out


#: Unknowns: s_w^2, s_q^2 (white), s_a^2, s_r^2 (coloured).
_ALL = (0, 1, 2, 3)
_COLOURED = (2, 3)


def _nnls(gram: np.ndarray, rhs: np.ndarray, yy: float, free: tuple[int, ...] = _ALL):
    """Non-negative least squares with a few unknowns for a batch of normal equations.

    ``gram`` (T, p, p), ``rhs`` (T, p), ``yy`` = y'y; only the unknowns ``free`` may be non-zero.
    Returns (beta (T, p), SSE (T,)). The optimum is the unconstrained optimum on its own support,
    so the feasible support solution of least SSE (over all supports within ``free`` and beta = 0)
    is the answer.
    """
    t, p = rhs.shape
    scale = np.sqrt(np.clip(np.einsum("tii->ti", gram), 1e-300, None))
    g = gram / scale[:, :, None] / scale[:, None, :]
    h = rhs / scale
    best_beta = np.zeros((t, p))
    best_sse = np.full(t, float(yy))
    for mask in range(1, 2**p):
        s = [i for i in range(p) if mask >> i & 1]
        if not set(s) <= set(free):
            continue
        gs = g[:, s][:, :, s] + 1e-12 * np.eye(len(s))
        bs = np.linalg.solve(gs, h[:, s][:, :, None])[:, :, 0]
        feasible = np.all(bs >= 0.0, axis=1)
        sse = yy - 2.0 * np.einsum("ti,ti->t", bs, h[:, s]) + np.einsum("ti,tij,tj->t", bs, gs, bs)
        better = feasible & (sse < best_sse)
        if np.any(better):
            beta = np.zeros((t, p))
            beta[:, s] = bs
            best_beta[better] = beta[better]
            best_sse[better] = sse[better]
    return best_beta / scale, np.maximum(best_sse, 0.0)


def _fit_for_taus(weighted: list[_Weighted], a: np.ndarray, detrend: bool, free: tuple[int, ...] = _ALL,
                  columns: list[np.ndarray] | None = None):
    """Generalised NNLS of (s_w^2, s_q^2, s_a^2, s_r^2) for each a; returns (beta (T, 4), SSE (T,)).

    Columns per window: the unit white variogram w, F^2 w, the unit coloured variogram c and F^2 c;
    with P the window's precision the normal equations need only w'Pw, w'Py, c'Pc, c'Pw and c'Py.
    ``columns``: c of each group for these a, if already at hand.
    """
    gram = np.zeros((a.size, 4, 4))
    rhs = np.zeros((a.size, 4))
    yy = 0.0
    for k, wg in enumerate(weighted):
        g = wg.group
        f2 = g.f2_N2
        f4 = f2 * f2
        c = _group_columns(g, a, detrend) if columns is None else columns[k]     # (T, B, L)
        cc = np.einsum("tbl,blm,tbm->tb", c, wg.precision, c)
        ca = np.einsum("tbl,bl->tb", c, wg.pa)
        cy = np.einsum("tbl,bl->tb", c, wg.py)
        gram[:, 0, 0] += wg.aa.sum()
        gram[:, 0, 1] += wg.aa @ f2
        gram[:, 1, 1] += wg.aa @ f4
        gram[:, 0, 2] += ca.sum(axis=1)
        gram[:, 0, 3] += ca @ f2
        gram[:, 1, 2] += ca @ f2
        gram[:, 1, 3] += ca @ f4
        gram[:, 2, 2] += cc.sum(axis=1)
        gram[:, 2, 3] += cc @ f2
        gram[:, 3, 3] += cc @ f4
        rhs[:, 0] += wg.ay.sum()
        rhs[:, 1] += wg.ay @ f2
        rhs[:, 2] += cy.sum(axis=1)
        rhs[:, 3] += cy @ f2
        yy += wg.yy
    iu = np.triu_indices(4, 1)
    gram[:, iu[1], iu[0]] = gram[:, iu[0], iu[1]]
    return _nnls(gram, rhs, yy, free)


def _profile_tau(weighted, log_tau: np.ndarray, fs: float, detrend: bool, free: tuple[int, ...],
                 grid_columns: list[np.ndarray]):
    """Best (beta, log tau, SSE) over the grid, refined by a parabola through the best three points.

    ``grid_columns``: the coloured columns of each group on the grid. Without a coloured unknown in
    ``free`` tau plays no part: one evaluation, at the grid's low end.
    """
    if not set(free) & set(_COLOURED):
        b, s = _fit_for_taus(weighted, 1.0 / (fs * np.exp(log_tau[:1])), detrend, free, [c[:1] for c in grid_columns])
        return b[0], float(log_tau[0]), float(s[0])
    betas, sse = _fit_for_taus(weighted, 1.0 / (fs * np.exp(log_tau)), detrend, free, grid_columns)
    i = int(np.argmin(sse))
    beta, lt, best = betas[i], float(log_tau[i]), float(sse[i])
    if 0 < i < log_tau.size - 1:
        s0, s1, s2 = sse[i - 1], sse[i], sse[i + 1]
        curvature = s0 - 2.0 * s1 + s2
        if curvature > 0.0:
            x = float(log_tau[i] + 0.5 * (log_tau[i + 1] - log_tau[i]) * (s0 - s2) / curvature)
            b, s = _fit_for_taus(weighted, np.array([1.0 / (fs * math.exp(x))]), detrend, free)
            if s[0] < best:
                beta, lt, best = b[0], x, float(s[0])
    return beta, lt, best


def _param_cov(weighted, beta: np.ndarray, lt: float, fs: float, detrend: bool) -> np.ndarray:
    """Covariance of (s_w^2, s_q^2, s_a^2, s_r^2, ln tau) from the generalised least squares information.

    Parameters at zero (dropped, or on the bound) are held fixed (zero rows and columns); so is
    ln tau when there is no coloured part.
    """
    active = [b > 0.0 for b in beta] + [beta[2] > 0.0 or beta[3] > 0.0]
    info = np.zeros((5, 5))
    h = 1e-4
    a = 1.0 / (fs * math.exp(lt))
    for wg in weighted:
        g = wg.group
        f2 = g.f2_N2[:, None]
        c = _group_columns(g, np.array([a]), detrend)[0]
        dc = (_group_columns(g, np.array([a * math.exp(-h)]), detrend)[0]
              - _group_columns(g, np.array([a * math.exp(h)]), detrend)[0]) / (2.0 * h)
        jac = np.stack([g.white, g.white * f2, c, c * f2, (beta[2] + beta[3] * f2) * dc], axis=-1)   # (B, L, 5)
        info += np.einsum("bli,blm,bmj->ij", jac, wg.precision, jac)
    idx = np.flatnonzero(active)
    cov = np.zeros((5, 5))
    if idx.size:
        sub = info[np.ix_(idx, idx)]
        d = np.sqrt(np.clip(np.diag(sub), 1e-300, None))
        cov[np.ix_(idx, idx)] = np.linalg.pinv(sub / d[:, None] / d[None, :], rcond=1e-12) / d[:, None] / d[None, :]
    return cov


#: Increase of the generalised SSE (a chi-square under the model) below which a component is
#: dropped as not supported by the data: the chi2(1 dof) 0.95 quantile per parameter.
_DROP_THRESHOLD = float(chi2_ppf(0.95, 1))


def _select(weighted, log_tau, fs, detrend, grid_columns):
    """Backward elimination of s_q^2, s_a^2, s_r^2: drop the cheapest while it costs < threshold.

    Dropping the last coloured component also drops tau_c, so it is allowed twice the threshold.
    Returns the free unknowns kept.
    """
    free = _ALL
    best = _profile_tau(weighted, log_tau, fs, detrend, free, grid_columns)[2]
    while True:
        trials = []
        for drop in (1, 2, 3):
            if drop not in free:
                continue
            cand = tuple(i for i in free if i != drop)
            cost = _profile_tau(weighted, log_tau, fs, detrend, cand, grid_columns)[2] - best
            limit = (2.0 if not set(cand) & set(_COLOURED) and set(free) & set(_COLOURED) else 1.0) * _DROP_THRESHOLD
            trials.append((cost / limit, cost, cand))
        if not trials:
            return free
        ratio, cost, cand = min(trials)
        if ratio >= 1.0:
            return free
        free, best = cand, best + cost


def fit_noise_model(windows: Sequence, fs_Hz: float, *, detrend: bool = True,
                    tau_range_s: tuple[float | None, float | None] = (None, TAU_MAX_S)) -> NoiseModel:
    """Pooled white + coloured force-noise model of steady windows.

    Parameters
    ----------
    windows : sequence of 1-D array_like
        Force samples [N] of steady windows (true force constant, or with a slow linear trend if
        ``detrend``), all at ``fs_Hz``. Windows shorter than :data:`MIN_FIT_SAMPLES` or of constant
        samples (quantised, below the resolution) are ignored.
    fs_Hz : float
        Sample rate [Hz].
    detrend : bool, optional
        Remove each window's least-squares line before its variogram (default); the fit then uses
        the exact expected variogram of detrended noise. Without it, a drift of 0.2 % of F across
        a window reads as slow noise wherever the coloured noise is weak (measured: var(mean) up to
        15x too large). The cost is precision on noise slower than the windows: False is better
        only when every window is shorter than about 5 tau_c and the true force is known to be flat.
    tau_range_s : (float or None, float or None), optional
        Range of the correlation time searched [s]; None below means one sample interval 1/fs,
        None above :data:`TAU_MAX_S`.

    Returns
    -------
    NoiseModel
        With ``param_cov``. Components the data do not support are zero (a model without coloured
        part carries the low end of the tau range); all variances are zero when every window is
        constant. With a single force level additive and proportional parts cannot be told apart
        and the additive ones are kept.

    Raises
    ------
    ValueError
        For a bad sample rate or range, non-finite samples, a window that is not 1-D, or no window
        of at least :data:`MIN_FIT_SAMPLES` samples.
    """
    fs = float(fs_Hz)
    if not (math.isfinite(fs) and fs > 0.0):
        raise ValueError(f"fs_Hz must be finite and > 0, got {fs_Hz!r}")
    lo = 1.0 / fs if tau_range_s[0] is None else float(tau_range_s[0])
    hi = max(TAU_MAX_S, lo) if tau_range_s[1] is None else float(tau_range_s[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo <= hi):
        raise ValueError(f"tau_range_s must satisfy 0 < low <= high, got {tau_range_s!r}")
    windows = list(windows)
    if not any(np.asarray(w).size >= MIN_FIT_SAMPLES for w in windows):
        raise ValueError(f"no window of at least {MIN_FIT_SAMPLES} samples")
    groups = _collect(windows, detrend)
    if not groups:
        return NoiseModel(0.0, 0.0, 0.0, lo, fs, param_cov=tuple((0.0,) * 5 for _ in range(5)))

    n_grid = int(math.ceil(_TAU_PER_DECADE * math.log10(hi / lo))) + 1 if hi > lo else 1
    log_tau = np.linspace(math.log(lo), math.log(hi), n_grid)
    columns = [_group_columns(g, 1.0 / (fs * np.exp(log_tau)), detrend) for g in groups]
    weighted = _weigh(groups, None, 1.0)
    for _ in range(_N_PASSES):
        beta, lt, _sse = _profile_tau(weighted, log_tau, fs, detrend, _ALL, columns)
        weighted = _weigh(groups, beta, 1.0 / (fs * math.exp(lt)))
    free = _select(weighted, log_tau, fs, detrend, columns)
    # Refit the kept components with weights from their own model (no weights fitted to noise
    # that was dropped), once to settle the weights and once for the estimate.
    for _ in range(2):
        beta, lt, _sse = _profile_tau(weighted, log_tau, fs, detrend, free, columns)
        weighted = _weigh(groups, beta, 1.0 / (fs * math.exp(lt)))
    beta, lt, _sse = _profile_tau(weighted, log_tau, fs, detrend, free, columns)
    if beta[2] == 0.0 and beta[3] == 0.0:
        lt = float(log_tau[0])
    cov = _param_cov(weighted, beta, lt, fs, detrend)
    return NoiseModel(white_var_N2=float(beta[0]), coloured_var_N2=float(beta[2]), coloured_rel_var=float(beta[3]),
                      tau_c_s=float(math.exp(lt)), fs_Hz=fs, white_rel_var=float(beta[1]),
                      param_cov=tuple(tuple(float(v) for v in row) for row in cov))


def scaled_chi2_isf(alpha: float, dof: int, scale_rel_sd: float) -> float:
    """The upper ``alpha`` quantile of c X, X ~ chi-square(``dof``), ln c ~ N(0, ``scale_rel_sd``^2).

    The threshold for a sum of ``dof`` squared z whose common variance scale is known only to a
    relative standard deviation ``scale_rel_sd`` (e.g. the mean of
    :meth:`NoiseModel.mean_variance_rel_sd` over the means in the sum); equals
    ``chi2.isf(alpha, dof)`` for 0. Gauss-Hermite quadrature over ln c.
    """
    alpha, eps = float(alpha), float(scale_rel_sd)
    if not 0.0 < alpha < 1.0 or dof < 1 or not (math.isfinite(eps) and eps >= 0.0):
        raise ValueError(f"need 0 < alpha < 1, dof >= 1, scale_rel_sd >= 0; got {alpha}, {dof}, {eps}")
    q0 = float(chi2_isf(alpha, dof))
    if eps == 0.0:
        return q0
    x, w = _gauss_hermite()
    scale = np.exp(eps * x)

    def excess(log_q: float) -> float:
        return float(np.sum(w * chi2_sf(math.exp(log_q) / scale, dof))) - alpha

    hi = math.log(q0) + 10.0 * eps
    while excess(hi) > 0.0:
        hi += 10.0 * eps
    from scipy.optimize import brentq

    return float(math.exp(brentq(excess, math.log(q0), hi, xtol=1e-10)))


def scaled_chi2_sf(x: float, dof: int, scale_rel_sd: float) -> float:
    """The p-value P(c X > x), X ~ chi-square(``dof``), ln c ~ N(0, ``scale_rel_sd``^2): the p-value that goes with
    :func:`scaled_chi2_isf` (equals ``chi2.sf(x, dof)`` for 0). Gauss-Hermite quadrature over ln c."""
    eps = float(scale_rel_sd)
    if dof < 1 or not (math.isfinite(eps) and eps >= 0.0):
        raise ValueError(f"need dof >= 1, scale_rel_sd >= 0; got {dof}, {eps}")
    if eps == 0.0:
        return float(chi2_sf(x, dof))
    z, w = _gauss_hermite()
    return float(np.sum(w * chi2_sf(x / np.exp(eps * z), dof)))


@functools.cache
def _gauss_hermite(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """The n-point Gauss-Hermite rule of the standard normal (nodes, weights summing to 1), computed once (an
    eigenproblem: a diagnosis asks for it at every χ² test, over a thousand times on the blind suite)."""
    x, w = np.polynomial.hermite_e.hermegauss(n)
    w = w / w.sum()
    x.flags.writeable = w.flags.writeable = False
    return x, w


def between_period_scatter(d_N, base_var_N2, mean_force_N) -> float:
    """Relative between-period scatter r, a consistent median estimate.

    Parameters
    ----------
    d_N : array_like
        Differences of paired window means, period 2 minus period 1 (same case and direction) [N].
    base_var_N2 : array_like
        Variance of each difference from the noise model alone (sum of the two means' variances)
        [N^2].
    mean_force_N : array_like
        Mean force magnitude Fbar of each pair, (|F1| + |F2|) / 2 [N].

    Returns
    -------
    float
        r >= 0 with median_i d_i^2 / (base_i + 2 r^2 Fbar_i^2) = :data:`MEDIAN_CHI2_1`, the median
        of chi-square with one degree of freedom, so that r^2 is consistent (the raw median of
        d^2 would be 0.455 of the variance). 0 when the median at r = 0 is already at or below
        that, inf when no finite r reaches it (pairs with Fbar = 0 hold the median up); 0 for no
        pairs.
    """
    d = np.asarray(d_N, dtype=float).ravel()
    base = np.asarray(base_var_N2, dtype=float).ravel()
    fbar = np.abs(np.asarray(mean_force_N, dtype=float).ravel())
    if not (d.size == base.size == fbar.size):
        raise ValueError("d_N, base_var_N2 and mean_force_N must have the same size")
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(base)) and np.all(np.isfinite(fbar))):
        raise ValueError("inputs must be finite")
    if np.any(base < 0):
        raise ValueError("base_var_N2 must be >= 0")
    if d.size == 0:
        return 0.0
    d2 = d * d
    f2 = 2.0 * fbar * fbar

    def median_q(s: float) -> float:
        den = base + s * f2
        q = np.divide(d2, den, out=np.where(d2 > 0, np.inf, 0.0), where=den > 0)
        return float(np.median(q))

    if median_q(0.0) <= MEDIAN_CHI2_1:
        return 0.0
    pos = f2 > 0
    # q_i falls to the target at s_i; beyond the largest s_i every q_i with Fbar > 0 is below it.
    s_i = (d2[pos] / MEDIAN_CHI2_1 - base[pos]) / f2[pos]
    hi = float(s_i.max()) if s_i.size else 0.0
    if hi <= 0.0 or median_q(hi) > MEDIAN_CHI2_1:
        return math.inf
    from scipy.optimize import brentq

    s = brentq(lambda s: median_q(s) - MEDIAN_CHI2_1, 0.0, hi, xtol=1e-14 * hi, rtol=1e-12)
    return float(math.sqrt(s))
