"""The triangles' verdict checked on the campaign's sine records (the ``sine_check`` key of diagnosis.json).

Beside triangle windows the sine cases are left out of the search (a short record's phase bins share a slow-noise
error that their standard errors do not describe, and every model run would integrate them), but they are data
the verdict did not see: the verdict's effects, with the instrument terms and the force channel fitted on the
triangles, are driven by each sine record's measured motion (Eq. 1, :mod:`isokinetic.physics.sine_drive`) and
compared with its phase bins (:mod:`isokinetic.diagnosis.sine_observations`), nothing refitted. A verdict the
check fails is not explained, and the search is repeated on the triangles and the sine records together
(:mod:`isokinetic.diagnosis.joint`, called by :func:`isokinetic.stages.diagnosis.judge_on_all_records`): a force
channel fitted on the triangles' slow reversals need not carry over to a 10 Hz sine, so a right verdict can fail the
check and pass the joint search, which fits its effects and lag on both.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from isokinetic.diagnosis.candidate import ALPHA, consistent_with_noise
from isokinetic.diagnosis.instrument import LAG_FORM_NAMES
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.observations import Observations
from isokinetic.physics.damper import NOMINAL, Damper, Effects
from isokinetic.stats import chi2_sf

#: Force-channel forms by the names diagnosis.json gives them (``instrument_tests.force_lag.form``).
LAG_FORMS_BY_NAME = {name: form for form, name in LAG_FORM_NAMES.items()}


def verdict_effects(params: Mapping[str, float]) -> tuple[Effects, float]:
    """(the verdict's effects without friction, its Coulomb force [N]) from diagnosis.json's ``params``
    (the keys are :class:`isokinetic.physics.damper.Effects` fields)."""
    values = dict(params)
    coulomb = float(values.pop("coulomb_force_N", 0.0) or 0.0)
    return Effects(**values), coulomb


def load_cell_terms(result: Mapping) -> tuple[float, float, float]:
    """(gain, offset at the reference time [N], zero drift [N/s]) of the verdict's fit: the estimates of
    ``instrument_tests`` (fitted with the verdict, whether or not ``instrument`` reports them as needed), else
    ``instrument``'s, else none (1, 0, 0)."""
    tests, reported = result.get("instrument_tests") or {}, result.get("instrument") or {}

    def term(test: str, key: str, default: float) -> float:
        value = (tests.get(test) or {}).get("estimate")
        value = reported.get(key) if value is None else value
        return default if value is None else float(value)

    return term("force_gain", "force_gain", 1.0), term("force_offset", "force_offset_N", 0.0), \
        term("force_drift", "force_drift_N_s", 0.0)


def channel_of(result: Mapping) -> tuple[int, float] | None:
    """(form, group delay [s]) of the verdict's force channel, None for an ideal one."""
    lag = (result.get("instrument") or {}).get("force_lag_s")
    if not lag:
        return None
    form = ((result.get("instrument_tests") or {}).get("force_lag") or {}).get("form", "delay")
    return LAG_FORMS_BY_NAME.get(form, 0), float(lag)


def read_prediction(ev: Evaluator, effects: Effects, coulomb_N: float, channel: tuple[int, float] | None
                    ) -> np.ndarray:
    """The model's bin means of ``effects`` plus a Coulomb force, as the force channel reads them [N]."""
    if channel is None:
        return ev.predict(effects) + (coulomb_N * ev.friction_ideal() if coulomb_N else 0.0)
    form, lag = channel
    hydraulic = ev.read(effects, form, [lag])[0]
    return hydraulic + (coulomb_N * ev.friction_read(form, lag) if coulomb_N else 0.0)


def record_residuals(obs: Observations, model_N: np.ndarray) -> np.ndarray:
    """z = (F - M)/σ of every bin less, per record, its weighted least-squares even mode a + b·|M|: the error a
    short record shares in all its bins (noise slower than the record, additive and proportional), which the
    bins' standard errors do not describe. Both directions' forces are odd in the velocity, so the mode leaves
    the model's odd part to the test."""
    z = (obs.force_N - model_N) / obs.sigma_N
    out = z.copy()
    for case in dict.fromkeys(obs.case.tolist()):
        rows = obs.case == case
        design = np.column_stack([np.ones(rows.sum()), np.abs(model_N[rows])]) / obs.sigma_N[rows, None]
        coef, *_ = np.linalg.lstsq(design, z[rows], rcond=None)
        out[rows] = z[rows] - design @ coef
    return out


def sine_check(obs: Observations, damper: Damper, result: Mapping, time_s: np.ndarray | None,
               time_ref_s: float | None, alpha: float = ALPHA) -> dict:
    """χ² of the verdict of ``result`` and of the nominal model over the sine bins ``obs``, both read through
    the verdict's load cell (:func:`load_cell_terms`: gain, offset at ``time_ref_s``, zero drift at each bin's
    campaign time ``time_s``) and force channel, each record's even mode taken out (:func:`record_residuals`:
    two degrees of freedom a record); ``consistent``: the verdict's χ² passes the test at ``alpha``;
    ``improves_on_nominal``: its χ² is below the nominal model's (None for the verdict ``[]``)."""
    gain, offset, drift = load_cell_terms(result)
    zero = offset + (drift * (np.asarray(time_s) - time_ref_s) if drift and time_s is not None
                     and time_ref_s is not None else 0.0)
    ev = Evaluator(obs, damper)
    channel = channel_of(result)
    effects, coulomb = verdict_effects(result.get("params") or {})
    out = {"cases": ",".join(dict.fromkeys(obs.case.tolist())), "n_bins": len(obs), "alpha": alpha}
    dof = len(obs) - 2 * len(set(obs.case.tolist()))
    for name, eff, fc in (("verdict", effects, coulomb), ("nominal", NOMINAL, 0.0)):
        model = gain * read_prediction(ev, eff, fc, channel) + zero
        z = record_residuals(obs, model)
        chi2 = float(z @ z)
        out[name] = {"chi2": chi2, "rms_z": math.sqrt(chi2 / max(dof, 1)), "p_value": float(chi2_sf(chi2, dof))}
    out["dof"] = dof
    out["consistent"] = bool(consistent_with_noise(out["verdict"]["chi2"], dof, alpha))
    out["improves_on_nominal"] = bool(out["verdict"]["chi2"] < out["nominal"]["chi2"]) if result.get("verdict") \
        else None
    if not out["consistent"]:
        out["note"] = ("the verdict, fitted on the triangle cases, does not predict the sine records within their "
                       f"standard errors (rms_z {out['verdict']['rms_z']:.3g} over {dof} degrees of freedom, the "
                       f"nominal model {out['nominal']['rms_z']:.3g}): the verdict does not explain all the "
                       "campaign's records")
    return out
