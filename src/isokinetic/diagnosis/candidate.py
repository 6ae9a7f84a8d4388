"""A fitted candidate (a set of damper effects), the gap metric and the χ² tests that judge it.

Gap metric ``rms_z``. Root mean square over the characteristic points (windows) of
z = (F_measured - F_model)/σ. A model that explains the data to within noise gives rms_z ≈ 1.

A candidate is fitted on the period-1 observations and scored on period 2, which the fit did not
see: ``score`` = χ²(period 2) + k·ln(n_fit) (lower is better; k parameters, instrument terms
included). It *explains* the gap when its fit χ² (n_fit - k degrees of freedom), its holdout χ²
(n_holdout) and the χ² of the windows alone (the characteristic, both periods) are consistent with
noise at level ``alpha`` (:func:`consistent_with_noise`). When none explains, candidates are
ranked by :func:`overdispersed_score`, and :func:`parsimonious` chooses among them (the verdict, and where the
search stops extending its sets).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from isokinetic.diagnosis.instrument import INSTRUMENT
from isokinetic.measurement.noise import scaled_chi2_sf
from isokinetic.stats import ALPHA  # the significance level, defined once

#: Score difference (χ² units) within which two candidates count as confounded (explaining ones), or cannot be
#: told apart (:func:`parsimonious`, where none explains).
CONFOUNDED_SCORE = 10.0


@dataclass(frozen=True)
class Candidate:
    effects: tuple[str, ...]
    x: np.ndarray                   # optimiser values in ``effects`` order (friction: F_C / F_ref)
    params: dict
    prediction: np.ndarray          # the damper model, before the instrument terms
    chi2_fit: float
    chi2_holdout: float
    n_fit: int
    n_holdout: int
    gap_after: float
    holdout_gap_after: float
    score: float
    explained: bool
    instrument: tuple[str, ...] = INSTRUMENT   # instrument terms free in the fit
    gain: float = 1.0
    offset_N: float = 0.0                      # at the diagnoser's reference time (time_ref_s)
    drift_N_s: float = 0.0                     # load-cell zero drift (0 unless "force_drift" is free)
    drift_N: np.ndarray | float = 0.0          # the drift's force at each observation
    channel: tuple[int, float] | None = None   # the force channel's (form, lag [s]) the model is read through

    @property
    def k(self) -> int:
        """Fitted parameters: damper effects plus free instrument terms (the channel's lag among them)."""
        return len(self.effects) + len(self.instrument) + (self.channel is not None)

    @property
    def measured_prediction(self) -> np.ndarray:
        """What the load cell would read: gain·F_model + offset + drift."""
        return self.gain * self.prediction + self.offset_N + self.drift_N

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "params": self.params, "gap_after": self.gap_after,
                "holdout_gap_after": self.holdout_gap_after, "score": self.score, "explained": self.explained,
                "chi2_fit": self.chi2_fit, "chi2_holdout": self.chi2_holdout, "n_fit": self.n_fit,
                "n_holdout": self.n_holdout,
                "instrument": {"force_gain": self.gain if "force_gain" in self.instrument else None,
                               "force_offset_N": self.offset_N if "force_offset" in self.instrument else None,
                               "force_drift_N_s": self.drift_N_s if "force_drift" in self.instrument else None,
                               "force_lag_s": None if self.channel is None else self.channel[1]}}


def rms(z: np.ndarray) -> float:
    """Root mean square (the gap metric ``rms_z`` of a set of z); NaN when empty."""
    return float(np.sqrt(np.mean(np.square(z)))) if z.size else float("nan")


def consistent_with_noise(chi2: float, dof: int, alpha: float = ALPHA, scale_rel_sd: float = 0.0) -> bool:
    """χ² test: True when a χ² this large has probability >= alpha under noise alone.

    ``scale_rel_sd``: relative uncertainty of the noise model's variance scale, common to all the
    z in the sum (:func:`isokinetic.measurement.noise.scaled_chi2_sf`); 0 for a plain χ² test.
    """
    return dof > 0 and math.isfinite(chi2) and scaled_chi2_sf(chi2, dof, scale_rel_sd) >= alpha


def overdispersed_score(candidate: Candidate, candidates: Sequence[Candidate]) -> float:
    """Quasi-likelihood score when nothing fits within noise: χ²_holdout / ŝ² + k ln n_fit.

    ŝ² = min over candidates of χ²_fit/(n_fit - k), the noise inflation that the best model needs.
    """
    s2 = min(c.chi2_fit / max(c.n_fit - c.k, 1) for c in candidates)
    return candidate.chi2_holdout / max(s2, 1.0) + candidate.k * math.log(candidate.n_fit)


def parsimonious(candidates: Sequence[Candidate]) -> Candidate:
    """Of candidates none of which explains the data: the smallest effect set (then the best score) among
    those whose overdispersed score (:func:`overdispersed_score`) is within
    CONFOUNDED_SCORE of the best. Scores that close cannot be told apart, and an effect added to a partial
    explanation must earn its place by that margin."""
    scores = {id(c): overdispersed_score(c, candidates) for c in candidates}
    best = min(scores.values())
    close = [c for c in candidates if scores[id(c)] <= best + CONFOUNDED_SCORE]
    return min(close, key=lambda c: (len(c.effects), scores[id(c)]))
