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
    fitted alongside.
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
    out: dict = {"identifiable": True, "parameters": {}}
    for i, name in enumerate(candidate.effects):
        x, sx = float(candidate.x[i]), float(math.sqrt(max(cov[i, i], 0.0)))
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
    return out


def fit_jacobian(dg: Diagnoser, candidate: Candidate) -> np.ndarray:
    """Derivatives of the period-1 fit residuals: one column per effect parameter (optimiser units;
    friction analytic, the others by forward differences), then the free gain and offset."""
    fm = dg.fit_mask
    sigma, sign = dg.obs.sigma_N[fm], dg.obs.sign[fm]
    g = candidate.gain
    cols = []
    nonlinear = [n for n in candidate.effects if n != "friction"]
    base = dict(zip(candidate.effects, candidate.x, strict=True))
    for name in candidate.effects:
        if name == "friction":
            cols.append(-g * sign * dg.param.force_ref_N / sigma)
            continue
        h = 1e-6 * max(1.0, abs(base[name]))
        shifted = dict(base, **{name: base[name] + h})
        m = dg.evaluator.predict(dg.param.effects(nonlinear, [shifted[n] for n in nonlinear]))[fm]
        m0 = candidate.prediction[fm] - base.get("friction", 0.0) * dg.param.force_ref_N * sign
        cols.append(-g * (m - m0) / h / sigma)
    if "force_gain" in candidate.instrument:
        cols.append(-candidate.prediction[fm] / sigma)
    if "force_offset" in candidate.instrument:
        cols.append(-1.0 / sigma)
    return np.column_stack(cols)
