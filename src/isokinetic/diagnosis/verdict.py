"""The verdict of a diagnosis, its instrument terms and confoundings, and the diagnosis dict.

The verdict is the smallest explaining set with the best score (:mod:`isokinetic.diagnosis.search`);
``[]`` when the nominal model (with the instrument terms) already explains all observations.
Explaining candidates of the verdict's size whose score is within ``CONFOUNDED_SCORE`` of the best
are listed as ``confounded``, and so is a load-cell gain that discharge and viscosity together
explain as well (or the reverse). When no candidate explains the gap, the verdict is the candidate
with the best overdispersed score (:func:`isokinetic.diagnosis.candidate.overdispersed_score`),
``explained`` is false and a note says the gap lies outside the catalogue. An instrument term is
reported (non-null) only where a likelihood-ratio test at ``alpha`` needs it. A fit that fails is
listed under ``failed_fits`` with its reason.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence

import numpy as np

from isokinetic.contracts.scenarios import EFFECTS
from isokinetic.diagnosis.candidate import ALPHA, Candidate, overdispersed_score, rms
from isokinetic.diagnosis.gap import gap_bands
from isokinetic.diagnosis.identifiability import identifiability
from isokinetic.diagnosis.instrument import GAIN_BOUND, INSTRUMENT
from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.result import CONTRACT_VERSION, FORMAT_VERSION, METRIC, json_safe
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.measurement.noise import chi2_isf
from isokinetic.physics.damper import Damper

#: Score difference (χ² units) within which two explaining candidates count as confounded.
CONFOUNDED_SCORE = 10.0
#: Tolerance of the verdict's final (polishing) fit, whose parameters are reported.
POLISH_TOL = 1e-6

NOMINAL_NOTE = "the nominal model with the instrument terms explains the data: no effect searched"
NO_FIT_NOTE = "no candidate fit succeeded (see failed_fits)"
UNEXPLAINED_NOTE = (
    "no candidate of the catalogue explains the gap within noise: the verdict is the candidate "
    "with the best overdispersed score (χ² divided by the smallest achievable χ²/dof, plus "
    "k ln n); the remaining gap points to an effect outside the catalogue (for example backlash, "
    "fixture or servo compliance, or a flow path of another form)")
GAIN_CONFOUNDED_NOTE = (
    "a load-cell gain error and a change of discharge coefficient plus viscosity explain the data "
    "alike: the data cannot tell an instrument gain from these damper effects; calibrate the load cell "
    "to decide")


def diagnose_observations(obs: Observations, damper: Damper, alpha: float = ALPHA,
                          delays: Mapping | None = None) -> tuple[dict, dict]:
    """The diagnosis dict of the contract, and the predictions (nominal, verdict) for figures."""
    started = time.perf_counter()
    delays = dict(delays or {"delay_s": None})
    dg = Diagnoser(obs, damper, alpha)
    out = gap_before_keys(dg, alpha)
    nominal_fit = dg.refit((), INSTRUMENT)
    out["nominal_p_value"] = dg.nominal_p_value()
    nominal_ok = out["nominal_p_value"] >= alpha
    candidates = [] if nominal_ok else dg.search()
    out["candidates"] = [c.to_dict() for c in candidates]
    if nominal_ok or not candidates:
        best = nominal_fit
        verdict = []
        out.update(nominal_verdict_keys(best, nominal_ok, out["gap_before"]))
    else:
        best = chosen_candidate(dg, candidates)
        verdict = list(best.effects)
        out.update(verdict_keys(dg, best, candidates, out["gap_before"]))
    instrument, tests = instrument_report(dg, best, delays.get("delay_s"))
    out["instrument"] = instrument
    out["instrument_tests"] = {**tests, "delay": {k: v for k, v in delays.items() if k != "delay_s"},
                               "bounds": {"force_gain": [1.0 - GAIN_BOUND, 1.0 + GAIN_BOUND],
                                          "force_offset_N": [-dg.linear.offset_bound_N,
                                                             dg.linear.offset_bound_N]}}
    group = gain_confounding(dg, best, candidates, instrument["force_gain"] is not None)
    if group:
        out.setdefault("confounded", []).append(group)
        out["confounded_instrument_note"] = GAIN_CONFOUNDED_NOTE
    if dg.failed:
        out["failed_fits"] = dg.failed
    out["nominal_explains"] = nominal_ok
    out["model_evaluations"] = dg.evaluator.calls + dg.fit_evaluator.calls
    out["seconds"] = round(time.perf_counter() - started, 3)
    predictions = {"nominal": dg.nominal,
                   "verdict": None if best is None or not verdict else best.measured_prediction}
    return json_safe(out), predictions


def gap_before_keys(dg: Diagnoser, alpha: float) -> dict:
    """The contract's header, the gap of the nominal model (``gap_before``, ``where``,
    ``rms_rel_before``) and the noise summary."""
    obs = dg.obs
    win = obs.is_window
    z_nom = dg.z(dg.nominal)
    return {"format_version": FORMAT_VERSION, "contract_version": CONTRACT_VERSION, "campaign": obs.campaign,
            "status": "ok", "metric": METRIC,
            "gap_before": rms(z_nom[win]), "where": [b for b in gap_bands(obs, dg.nominal) if b["significant"]],
            "noise": {**{k: v for k, v in obs.noise.items() if k != "objects"}, "repeatability_rel": obs.rep_rel,
                      "n_windows": int(win.sum()), "n_transient_bins": int((~win).sum()), "alpha": alpha},
            "rms_rel_before": rms(((obs.force_N - dg.nominal) / np.abs(obs.force_N))[win])}


def shrink(gap_before: float, gap_after: float) -> float | None:
    """How far the gap shrinks: gap_before / gap_after (None when the gap after is 0)."""
    return gap_before / gap_after if gap_after > 0 else None


def nominal_verdict_keys(best: Candidate, nominal_ok: bool, gap_before: float) -> dict:
    """The empty verdict: the nominal model explains the data, or no candidate fit succeeded."""
    keys = {"search_note": NOMINAL_NOTE} if nominal_ok else {"unexplained_note": NO_FIT_NOTE}
    keys.update(verdict=[], explained=bool(nominal_ok), gap_after=best.gap_after,
                holdout_gap_after=best.holdout_gap_after, shrink=shrink(gap_before, best.gap_after))
    return keys


def chosen_candidate(dg: Diagnoser, candidates: Sequence[Candidate]) -> Candidate:
    """The best explaining candidate (else the best overdispersed score), polished at POLISH_TOL."""
    explaining = [c for c in candidates if c.explained]
    best = explaining[0] if explaining else min(candidates, key=lambda c: overdispersed_score(c, candidates))
    polished = dg.refit(best.effects, best.instrument, best, POLISH_TOL)
    if polished is not None and polished.chi2_fit <= best.chi2_fit:
        best = polished
    return best


def verdict_keys(dg: Diagnoser, best: Candidate, candidates: Sequence[Candidate], gap_before: float) -> dict:
    """The verdict ``best`` of a search: its fit, gap, identifiability and same-size rivals."""
    obs = dg.obs
    explaining = [c for c in candidates if c.explained]
    keys = {} if explaining else {"unexplained_note": UNEXPLAINED_NOTE}
    keys.update(verdict=list(best.effects), explained=best.explained, gap_after=best.gap_after,
                holdout_gap_after=best.holdout_gap_after, params=best.params,
                shrink=shrink(gap_before, best.gap_after),
                rms_rel_after=rms(((obs.force_N - best.measured_prediction) / np.abs(obs.force_N))[obs.is_window]),
                identifiability=identifiability(dg, best))
    rivals = [c for c in explaining if len(c.effects) == len(best.effects) and c.effects != best.effects
              and c.score - best.score < CONFOUNDED_SCORE]
    if rivals:
        keys["confounded"] = [sorted({e for c in [best, *rivals] for e in c.effects})] if len(best.effects) > 1 \
            else [[best.effects[0], *(c.effects[0] for c in rivals)]]
        keys["confounded_note"] = (f"{len(rivals)} other candidate(s) of the same size also explain the gap "
                                   f"within noise with a score less than {CONFOUNDED_SCORE:g} worse; the verdict "
                                   "holds the best-scoring one")
    return keys


def instrument_report(dg: Diagnoser, best: Candidate, delay_s: float | None) -> tuple[dict, dict]:
    """The ``instrument`` key and its test details: each load-cell term refitted as fixed (gain 1,
    offset 0) and kept where the fit χ² rises beyond the χ²₁ quantile at 1 - alpha."""
    needed = {}
    tests = {}
    threshold = float(chi2_isf(dg.alpha, 1))
    for term in INSTRUMENT:
        reduced = tuple(t for t in best.instrument if t != term)
        if term not in best.instrument:
            needed[term] = False
            continue
        alt = dg.refit(best.effects, reduced, best)
        rise = math.inf if alt is None else alt.chi2_fit - best.chi2_fit
        needed[term] = bool(rise > threshold)
        tests[term] = {"estimate": best.gain if term == "force_gain" else best.offset_N,
                       "chi2_rise_if_fixed": rise, "threshold": threshold, "needed": needed[term]}
    return ({"delay_s": delay_s,
             "force_offset_N": best.offset_N if needed["force_offset"] else None,
             "force_gain": best.gain if needed["force_gain"] else None}, tests)


def gain_confounding(dg: Diagnoser, best: Candidate, candidates: Sequence[Candidate],
                     gain_needed: bool) -> list[str] | None:
    """The group [force_gain, discharge, viscosity] when a load-cell gain and discharge plus viscosity
    explain the data alike (within CONFOUNDED_SCORE), else None.

    A gain scales every force; discharge and viscosity together scale the turbulent and laminar parts,
    so a gain error of a few per cent can be mistaken for them, and the reverse, unless the transient
    bins (which a gain scales but does not reshape) tell them apart.
    """
    physics = ("discharge", "viscosity")
    if gain_needed:
        names = tuple(e for e in EFFECTS if e in best.effects or e in physics)
        alt = dg.refit(names, tuple(t for t in best.instrument if t != "force_gain"), best)
    elif any(e in best.effects for e in physics):
        rest = tuple(e for e in best.effects if e not in physics)
        alt = next((c for c in candidates if c.effects == rest and "force_gain" in c.instrument), None) if rest \
            else dg.refit((), INSTRUMENT)
    else:
        return None
    if alt is not None and alt.explained and abs(alt.score - best.score) < CONFOUNDED_SCORE:
        return ["force_gain", *[e for e in physics if e in best.effects or e in alt.effects]]
    return None
