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

The sensor chain (contract 1.2, issue 21): when the nominal model fails, it is also read through a
lagging force channel (:func:`sensor_hypothesis`); when the steady windows pass that way and no damper
candidate beats it by ``SENSOR_MARGIN``, the verdict is ``[]`` with the lag (sensor or damper). A
load-cell zero drift linear in campaign time is taken off where the nominal model then explains the
data (:func:`drift_compensated`), else tested on the verdict's residuals (:func:`zero_drift`). The
LVDT's scale comes from the stage (measured against the command channel); without one, a verdict
with discharge or viscosity, or a reported load-cell gain, states its confounding with it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from isokinetic.contracts.scenarios import CATALOGUE
from isokinetic.diagnosis.candidate import ALPHA, Candidate, consistent_with_noise, overdispersed_score, rms
from isokinetic.diagnosis.gap import gap_bands
from isokinetic.diagnosis.identifiability import identifiability
from isokinetic.diagnosis.instrument import GAIN_BOUND, INSTRUMENT, displacement_scale, fit_force_lag
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
#: The zero drift is tested at alpha times this: it is tested after the verdict, on its residuals, where
#: a slow drift of the oil's viscosity over the campaign also leaves a small slope in time.
DRIFT_ALPHA_FACTOR = 0.01
#: Names of the force channel's fitted dynamics (:data:`isokinetic.diagnosis.instrument.LAG_FORMS`).
LAG_FORM_NAMES = {0: "delay", 1: "low-pass, 1st order", 2: "low-pass, 2nd order"}
#: Score margin (χ² units) by which a damper effect must beat the sensor terms (the nominal model seen
#: through a lagging force channel) before it is claimed, when the steady windows already pass.
SENSOR_MARGIN = 10.0
#: The low-pass forms of the force channel are fitted only when the windows' rms_z with a pure delay is
#: below this (a lag moves the steady windows little: far above it, no sensor dynamics explain them).
SENSOR_GATE_RMS_Z = 2.0
SENSOR_NOTE = (
    "steady characteristic explained; the transient mismatch is consistent with sensor dynamics or "
    "compliance: no damper effect explains the windows and the transients better than the sensor terms "
    "(a force-channel lag) by the stated margin")
SCALE_CONFOUNDED_NOTE = (
    "no command channel: the LVDT's scale k cannot be measured (where the servo closes on the LVDT the "
    "record shows the command whatever k is), and inside the model a displacement scale k is a load-cell "
    "gain 1/k plus C_D·√k (displacement scale ≡ load-cell gain + C_D·√k): the discharge and viscosity "
    "effects claimed, or the load-cell gain reported, may be an LVDT scale error; calibrate the LVDT or record "
    "the command to decide")


def instrument_confounding(out: dict, dg: Diagnoser, best, candidates, verdict: list[str], hyp: dict | None,
                           scale: Mapping) -> None:
    """The instrument terms the verdict cannot be told apart from, added to ``out['confounded']`` with their
    notes: a load-cell gain against discharge + viscosity; a force-channel lag scoring within SENSOR_MARGIN of
    the verdict; an unmeasured displacement scale (no command channel) against a gain, discharge or viscosity."""
    gain = out["instrument"]["force_gain"] is not None
    group = gain_confounding(dg, best, candidates, gain)
    if group:
        out.setdefault("confounded", []).append(group)
        out["confounded_instrument_note"] = GAIN_CONFOUNDED_NOTE
    if hyp is not None and not hyp["preferred"] and verdict and hyp["lag_needed"] \
            and best.score - hyp["candidate"].score > -SENSOR_MARGIN:
        out.setdefault("confounded", []).append([*verdict, "force_lag"])
        out["confounded_sensor_note"] = (f"the nominal model through a force-channel lag of {hyp['lag_s']:.4g} s "
                                         f"scores within {SENSOR_MARGIN:g} of the verdict")
    physics = [e for e in verdict if e in ("discharge", "viscosity")]
    unmeasured = scale["estimate"] is None or "note" in scale  # no command channel, or none that follows the LVDT
    if (physics or gain) and unmeasured:
        out.setdefault("confounded", []).append(["displacement_scale", "force_gain", *physics])
        out["confounded_scale_note"] = SCALE_CONFOUNDED_NOTE


def diagnose_observations(obs: Observations, damper: Damper, alpha: float = ALPHA,
                          delays: Mapping | None = None, sensor: Mapping | None = None) -> tuple[dict, dict]:
    """The diagnosis dict of the contract, and the predictions (nominal, verdict) for figures.

    ``sensor`` (from the stage): ``displacement_scale`` (:func:`isokinetic.diagnosis.instrument.displacement_scale`,
    already applied to ``obs``' drives where ``applied``) and ``obs_time_s`` (each observation's campaign time,
    for the load-cell zero drift); absent: no command channel, no drift test."""
    started = time.perf_counter()
    delays = dict(delays or {"delay_s": None})
    sensor = dict(sensor or {})
    dg = Diagnoser(obs, damper, alpha)
    out = gap_before_keys(dg, alpha)
    nominal_fit = dg.refit((), INSTRUMENT)
    out["nominal_p_value"] = dg.nominal_p_value()
    nominal_ok = out["nominal_p_value"] >= alpha
    drift_removed = None
    if not nominal_ok and nominal_fit is not None:
        dg, drift_removed = drift_compensated(dg, nominal_fit, sensor.get("obs_time_s"))
        if drift_removed is not None:
            nominal_fit = dg.refit((), INSTRUMENT)
            nominal_ok = True
    candidates = [] if nominal_ok else dg.search()
    out["candidates"] = [c.to_dict() for c in candidates]
    hyp = None if nominal_ok or nominal_fit is None else sensor_hypothesis(dg, nominal_fit, candidates)
    lagged = None
    if hyp is not None and hyp["preferred"]:
        best = hyp["candidate"]
        lagged = hyp["prediction"]
        verdict = []
        out.update(nominal_verdict_keys(best, best.explained, out["gap_before"]))
        out.pop("search_note", None)
        out.pop("unexplained_note", None)
        out["sensor_note"] = SENSOR_NOTE
    elif nominal_ok or not candidates:
        best = nominal_fit
        verdict = []
        out.update(nominal_verdict_keys(best, nominal_ok, out["gap_before"]))
    else:
        best = chosen_candidate(dg, candidates)
        verdict = list(best.effects)
        out.update(verdict_keys(dg, best, candidates, out["gap_before"]))
    instrument, tests = instrument_report(dg, best, delays.get("delay_s"), lagged)
    instrument["force_lag_s"] = hyp["lag_s"] if hyp is not None and hyp["preferred"] and hyp["lag_needed"] else None
    scale = dict(sensor.get("displacement_scale") or displacement_scale([]))
    instrument["displacement_scale"] = scale["estimate"] if scale["applied"] else None
    drift = drift_removed or zero_drift(dg, best, sensor.get("obs_time_s"))
    if drift.get("needed") and not out["explained"]:  # residuals of a model that misfits are no drift measure
        drift = {**drift, "needed": False, "reason": "not reported: the verdict does not explain the data"}
    instrument["force_drift_N_s"] = drift["estimate"] if drift.get("needed") else None
    if drift_removed is not None:
        out["drift_note"] = ("the nominal model explains the data once a load-cell zero drift linear in campaign "
                             "time is taken off the forces (force_drift_N_s)")
    out["instrument"] = instrument
    out["instrument_tests"] = {**tests, "delay": {k: v for k, v in delays.items() if k != "delay_s"},
                               "force_lag": None if hyp is None else hyp["report"],
                               "displacement_scale": scale, "force_drift": drift,
                               "bounds": {"force_gain": [1.0 - GAIN_BOUND, 1.0 + GAIN_BOUND],
                                          "force_offset_N": [-dg.linear.offset_bound_N,
                                                             dg.linear.offset_bound_N]}}
    instrument_confounding(out, dg, best, candidates, verdict, hyp, scale)
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


def instrument_report(dg: Diagnoser, best: Candidate, delay_s: float | None,
                      lagged: np.ndarray | None = None) -> tuple[dict, dict]:
    """The ``instrument`` key and its test details: each load-cell term refitted as fixed (gain 1,
    offset 0) and kept where the fit χ² rises beyond the χ²₁ quantile at 1 - alpha. ``lagged``: the
    verdict is the nominal model seen through a lagging force channel (this prediction), refitted as such."""
    needed = {}
    tests = {}
    threshold = float(chi2_isf(dg.alpha, 1))
    for term in INSTRUMENT:
        reduced = tuple(t for t in best.instrument if t != term)
        if term not in best.instrument:
            needed[term] = False
            continue
        alt = dg.refit(best.effects, reduced, best) if lagged is None else dg.score_prediction(lagged, reduced, 1)
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
        names = tuple(e for e in CATALOGUE if e in best.effects or e in physics)
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


def sensor_hypothesis(dg: Diagnoser, nominal_fit: Candidate, candidates: Sequence[Candidate]) -> dict:
    """The sensor terms against the damper effects (issue 21's "sensor or damper").

    The sensor candidate is the nominal model seen through a force channel lagging by a fitted delay,
    or (where the windows' rms_z is below SENSOR_GATE_RMS_Z) a fitted first- or second-order low-pass,
    whichever fits best (:func:`isokinetic.diagnosis.instrument.fit_force_lag`), scored like any
    candidate (one more parameter). It is ``preferred`` (the verdict is then ``[]``) when the steady
    windows pass with the sensor terms (χ² of the windows alone; the lag moves the windows little, the
    transients much) and no explaining damper candidate scores better than it by SENSOR_MARGIN. The
    lag is ``lag_needed`` when the fit χ² falls by more than the χ²₁ quantile at 1 - alpha against no lag.
    """
    lag, form, pred = fit_force_lag(dg, (0,))
    cand = dg.score_prediction(pred, INSTRUMENT, extra_k=1)
    win = dg.obs.is_window
    if rms(dg.z(cand.measured_prediction)[win]) < SENSOR_GATE_RMS_Z:  # the low-passes: only where plausible
        lag, form, pred = fit_force_lag(dg)
        cand = dg.score_prediction(pred, INSTRUMENT, extra_k=1)
    threshold = float(chi2_isf(dg.alpha, 1))
    drop = nominal_fit.chi2_fit - cand.chi2_fit
    k = len(INSTRUMENT) + 1
    chi2_win = float(np.sum(dg.z(cand.measured_prediction)[win] ** 2))
    windows_ok = bool(consistent_with_noise(chi2_win, int(win.sum()) - k, dg.alpha, dg.scale_rel_sd))
    explaining = [c for c in candidates if c.explained]
    best_damper = min(explaining, key=lambda c: c.score) if explaining else None
    damper_wins = best_damper is not None and best_damper.score < cand.score - SENSOR_MARGIN
    preferred = windows_ok and not damper_wins
    report = {"estimate_s": lag, "form": LAG_FORM_NAMES[form], "chi2_drop": drop, "threshold": threshold,
              "needed": bool(drop > threshold),
              "steady_windows_pass": windows_ok, "sensor_score": cand.score, "sensor_explains": cand.explained,
              "best_damper_score": None if best_damper is None else best_damper.score,
              "best_damper_effects": None if best_damper is None else list(best_damper.effects),
              "margin": SENSOR_MARGIN, "chosen": "sensor" if preferred else "damper"}
    return {"lag_s": lag, "prediction": pred, "candidate": cand, "lag_needed": bool(drop > threshold),
            "preferred": preferred, "report": report}


def zero_drift(dg: Diagnoser, best: Candidate, obs_time_s: np.ndarray | None) -> dict:
    """The load-cell zero drift, linear in campaign time: the slope r [N/s] of F = g·F_model + F_0 + r·t,
    weighted least squares with the gain and offset refitted alongside (a drift over cases ordered by
    speed would otherwise partly hide in the gain), ``needed`` when its χ² drop exceeds the χ²₁ quantile
    at 1 - alpha·DRIFT_ALPHA_FACTOR. Not refitted into the verdict."""
    if obs_time_s is None or len(obs_time_s) != len(dg.obs):
        return {"estimate": None, "needed": False, "reason": "no campaign time per observation"}
    t = np.asarray(obs_time_s, dtype=float)
    if np.ptp(t) <= 0:
        return {"estimate": None, "needed": False, "reason": "all observations at one time"}
    sigma = dg.obs.sigma_N
    y = dg.obs.force_N / sigma
    model = np.asarray(getattr(best, "prediction", np.zeros(len(t))), dtype=float)
    a = np.column_stack([model / sigma, 1.0 / sigma, (t - t.mean()) / sigma])

    def ssr(cols: np.ndarray) -> tuple[float, np.ndarray]:
        coef, *_ = np.linalg.lstsq(cols, y, rcond=None)
        return float(np.sum((y - cols @ coef) ** 2)), coef

    without, _ = ssr(a[:, :2])
    with_drift, coef = ssr(a)
    drop = without - with_drift
    cov = np.linalg.pinv(a.T @ a)
    threshold = float(chi2_isf(dg.alpha * DRIFT_ALPHA_FACTOR, 1))
    return {"estimate": float(coef[2]), "std_error": float(math.sqrt(max(cov[2, 2], 0.0))), "chi2_drop": drop,
            "threshold": threshold, "needed": bool(drop > threshold), "span_s": float(np.ptp(t))}


def drift_compensated(dg: Diagnoser, nominal_fit: Candidate, obs_time_s: np.ndarray | None
                      ) -> tuple[Diagnoser, dict | None]:
    """(diagnoser, drift) with the load-cell zero drift taken off the forces, when the nominal model's
    residuals need one (:func:`zero_drift`) and the nominal model then explains the data within noise;
    else the diagnoser unchanged and None (a drift beside damper effects is only reported)."""
    drift = zero_drift(dg, nominal_fit, obs_time_s)
    if not drift.get("needed"):
        return dg, None
    t = np.asarray(obs_time_s, dtype=float)
    obs = replace(dg.obs, force_N=dg.obs.force_N - drift["estimate"] * (t - t.mean()))
    compensated = Diagnoser(obs, dg.evaluator.damper, dg.alpha)
    if compensated.nominal_p_value() < dg.alpha:
        return dg, None
    return compensated, {**drift, "removed": True}
