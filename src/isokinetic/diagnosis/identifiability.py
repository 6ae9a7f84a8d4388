"""Identifiability of a verdict: standard errors and correlations of its effect parameters from the
Fisher information of its fit (the ``identifiability`` key of diagnosis.json)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from isokinetic.diagnosis.candidate import Candidate
from isokinetic.diagnosis.search import Diagnoser


def identifiability(dg: Diagnoser, candidate: Candidate) -> dict:
    """Standard errors (SI) and correlations of the effect parameters from the Fisher information JᵀJ.

    J (:func:`fit_jacobian`): derivatives of the fit residuals (period 1) with respect to every effect
    parameter and the free instrument terms, so the standard errors account for the instrument terms
    fitted alongside. Where the fit's χ² exceeds its degrees of freedom (a verdict that does not explain the
    data within noise), the standard errors are scaled by √(χ²/dof) (:func:`std_error_scale`, reported as
    ``std_error_scale``): the scatter the noise model did not describe widens them as it widens the residuals.
    """
    if not candidate.effects:
        return {"identifiable": True, "parameters": {}}
    jac = fit_jacobian(dg, candidate)
    try:
        cov = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        return {"identifiable": False, "reason": "singular Fisher information"}
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) < 0):
        return {"identifiable": False, "reason": "ill-conditioned Fisher information"}
    # the rows beyond the observations (a declared calibration's) count in χ² and its degrees of freedom too
    scale = std_error_scale(candidate.chi2_fit, jac.shape[0] - jac.shape[1])
    out: dict = {"identifiable": True, "parameters": {}, "std_error_scale": scale}
    for i, name in enumerate(candidate.effects):
        x, sx = float(candidate.x[i]), scale * float(math.sqrt(max(cov[i, i], 0.0)))
        key, value = dg.param.si(name, x)
        _, shifted = dg.param.si(name, x + sx)
        out["parameters"][key] = {"estimate": value, "std_error": abs(shifted - value),
                                  "relative_std_error": abs(shifted - value) / abs(value) if value else None}
    if len(candidate.effects) > 1:
        k = len(candidate.effects)
        d = np.sqrt(np.clip(np.diag(cov)[:k], 1e-300, None))
        corr = cov[:k, :k] / np.outer(d, d)
        out["correlation"] = {f"{a}~{b}": float(corr[i, j])
                              for (i, a), (j, b) in itertools.combinations(enumerate(candidate.effects), 2)}
    d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    if candidate.channel is not None:   # the lag's column follows the effects'
        k = len(candidate.effects)
        out["lag_correlation"] = {name: float(cov[i, k] / (d[i] * d[k])) for i, name in enumerate(candidate.effects)}
    if "force_drift" in candidate.instrument and dg.fit_time_s is not None:
        out["drift_correlation"] = {name: float(cov[i, -1] / (d[i] * d[-1]))
                                    for i, name in enumerate(candidate.effects)}
    return out


def std_error_scale(chi2: float, dof: int) -> float:
    """√(χ²/dof) where it exceeds 1 (the Birge ratio), else 1: the factor on standard errors from the Fisher
    information when the residuals scatter more than the noise model says (none without degrees of freedom)."""
    return math.sqrt(chi2 / dof) if dof > 0 and math.isfinite(chi2) and chi2 > dof else 1.0


def fit_jacobian(dg: Diagnoser, candidate: Candidate) -> np.ndarray:
    """Derivatives of the period-1 fit residuals: one column per effect parameter (optimiser units;
    friction analytic, the others by forward differences, through the candidate's force channel), then the
    free gain, offset and zero drift (last); with a declared load-cell calibration one more row, its residual
    (g - centre)/sd (:meth:`isokinetic.diagnosis.instrument.LinearTerms.prior_residuals`), whose only derivative
    is 1/sd by the gain."""
    fm = dg.fit_mask
    g = candidate.gain
    cols = []
    lag = None if candidate.channel is None else candidate.channel[1]
    sigma, sign = dg.obs.sigma_N[fm], dg.friction_signature(lag)[fm]   # friction as the force channel reads it
    nonlinear = [n for n in candidate.effects if n != "friction"]
    base = dict(zip(candidate.effects, candidate.x, strict=True))
    for name in candidate.effects:
        if name == "friction":
            cols.append(-g * sign * dg.param.force_ref_N / sigma)
            continue
        h = 1e-6 * max(1.0, abs(base[name]))
        shifted = dict(base, **{name: base[name] + h})
        m = dg.model(dg.param.effects(nonlinear, [shifted[n] for n in nonlinear]), lag=lag)[fm]
        m0 = candidate.prediction[fm] - base.get("friction", 0.0) * dg.param.force_ref_N * sign
        cols.append(-g * (m - m0) / h / sigma)
    if lag is not None:   # the force channel's group delay, fitted with the effects
        h = 1e-4
        values = [base[n] for n in nonlinear]
        m = dg.model(dg.param.effects(nonlinear, values), lag=lag + h)[fm]
        m0 = candidate.prediction[fm] - base.get("friction", 0.0) * dg.param.force_ref_N * sign
        cols.append(-g * (m - m0) / h / sigma)
    gain_column = len(cols)
    if "force_gain" in candidate.instrument:
        cols.append(-candidate.prediction[fm] / sigma)
    if "force_offset" in candidate.instrument:
        cols.append(-1.0 / sigma)
    if "force_drift" in candidate.instrument and dg.fit_time_s is not None:
        cols.append(-dg.fit_time_s / sigma)
    jac = np.column_stack(cols)
    terms = dg.terms(candidate.instrument)
    if terms.prior_residuals(candidate.gain).size:   # the calibration: one more observation, of the gain
        row = np.zeros(jac.shape[1])
        row[gain_column] = 1.0 / terms.gain_sd
        jac = np.vstack([jac, row])
    return jac
