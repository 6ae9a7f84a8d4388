"""Fitting candidate effect sets to a campaign's observations, and the search over the catalogue.

Candidates. Each effect of the catalogue (:data:`isokinetic.contracts.scenarios.CATALOGUE`) alone
(one parameter each), every pair, then, while nothing explains, the :data:`BEAM` best candidates of
the largest size extended by one more effect; a size is tried only while no smaller set explains
(none when the nominal model does) and until :data:`STABLE_SIZES` sizes in a row have left the choice
among unexplained candidates (:func:`isokinetic.diagnosis.candidate.parsimonious`) where it was: an
out-of-catalogue campaign stops there instead of fitting every set up to the whole catalogue. Coulomb
friction, like the load-cell terms (gain, offset and, where each observation's campaign time is known,
the zero drift), is linear in the means and profiled in closed form
(:class:`isokinetic.diagnosis.instrument.LinearTerms`); a force channel's lag, where the diagnoser has one, is
fitted with the effects as one more nonlinear parameter (:meth:`Diagnoser.model`); the other
effects are fitted with bounded least squares (scipy ``least_squares``, 'trf') on the period-1
observations (segments 1-2, windows and transient bins) and scored on period 2 (segments 3-4)
(:mod:`isokinetic.diagnosis.candidate`). A fit that fails is recorded in ``Diagnoser.failed`` with
its reason. The search's fits take their Jacobian by forward differences at the start and by
Broyden's update after each step (:class:`SecantJacobian`: one model run per iteration, about 40 %
fewer runs in all); the verdict's polish (a tighter tolerance) uses forward differences throughout.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from scipy import optimize

from isokinetic.contracts.scenarios import CATALOGUE
from isokinetic.diagnosis.candidate import ALPHA, Candidate, consistent_with_noise, parsimonious, rms
from isokinetic.diagnosis.instrument import DRIFT, INSTRUMENT, LAG_MAX_S, LinearTerms, offset_bound_N
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.parametrisation import Parametrisation
from isokinetic.measurement.noise import scaled_chi2_sf
from isokinetic.physics.damper import NOMINAL, Damper

log = logging.getLogger(__name__)

#: Relative tolerance on cost and parameters at which a search fit stops: 1e-3 of a χ² or of a
#: parameter is far below what ranks candidates or matters against the parameter's uncertainty.
FIT_TOL = 1e-3
#: Candidates of each size extended by one more effect while nothing explains the gap.
BEAM = 3
#: Sizes in a row that must leave the unexplained search's choice (:func:`isokinetic.diagnosis.candidate.parsimonious`)
#: where it was before the extension stops: one is not enough (on the benchmark suite a set of four effects beat
#: the pair that sets of three had left in place), two changed no choice on the default and benchmark suites.
STABLE_SIZES = 2
#: What a fit may raise on a pathological parameter set (overflow, a singular system).
FIT_ERRORS = (ValueError, FloatingPointError, ArithmeticError, np.linalg.LinAlgError)


#: Bounds of a fitted force-channel group delay [s] per form (a low-pass needs a positive one).
LAG_BOUNDS_S = {0: (0.0, LAG_MAX_S), 1: (1e-3, LAG_MAX_S), 2: (1e-3, LAG_MAX_S)}
#: Relative step of the forward-difference Jacobian (scipy's ``diff_step``).
DIFF_STEP = 1e-6


class SecantJacobian:
    """Residuals ``fun`` and their Jacobian for ``least_squares``: forward differences (relative step
    DIFF_STEP, one-sided away from a bound, as scipy's '2-point') at the first point, then Broyden's
    rank-one update J += (Δf - JΔx)Δxᵀ/ΔxᵀΔx from each accepted step (Dennis & Schnabel, Numerical
    Methods for Unconstrained Optimization, §8.1): one model run per iteration instead of 1 + n.
    Used by the search's fits at FIT_TOL; tighter fits (the verdict's polish) use plain differences."""

    def __init__(self, fun, lower, upper):
        self.fun = fun
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.last: tuple[np.ndarray, np.ndarray] | None = None   # the latest evaluation (x, f)
        self.at: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None   # the latest Jacobian (x, f, J)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        f = np.asarray(self.fun(x), dtype=float)
        self.last = (np.array(x, dtype=float), f)
        return f

    def _value(self, x: np.ndarray) -> np.ndarray:
        if self.last is not None and np.array_equal(self.last[0], x):
            return self.last[1]
        return self(x)

    def jac(self, x: np.ndarray) -> np.ndarray:
        x = np.array(x, dtype=float)
        f = self._value(x)
        if self.at is None:
            jac = self._differences(x, f)
        else:
            x_prev, f_prev, jac = self.at
            dx = x - x_prev
            step2 = float(dx @ dx)
            jac = jac + np.outer(f - f_prev - jac @ dx, dx / step2) if step2 > 0.0 else jac
        self.at = (x, f, jac)
        return jac

    def _differences(self, x: np.ndarray, f: np.ndarray) -> np.ndarray:
        h = DIFF_STEP * np.where(x >= 0.0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        h = np.where((x + h > self.upper) & (x - h >= self.lower), -h, h)
        cols = []
        for j in range(x.size):
            xj = x.copy()
            xj[j] += h[j]
            cols.append((np.asarray(self.fun(xj), dtype=float) - f) / (xj[j] - x[j]))
        return np.column_stack(cols)


class Diagnoser:
    """Fits and scores candidate effect sets on one campaign's observations.

    ``time_s``: each observation's campaign time [s] (None: unknown; then no zero drift is fitted),
    ``time_ref_s`` the reference time at which the load-cell offset is reported (default the middle of
    the observations' span). ``channel``: the force channel's dynamics (form of
    :data:`isokinetic.diagnosis.instrument.LAG_FORMS`, starting group delay [s]) every model prediction is
    read through, its group delay fitted with the effects in every fit (one more parameter, bounds
    LAG_BOUNDS_S; starts: the given one and ``lag_starts``); None: an ideal channel."""

    def __init__(self, obs: Observations, damper: Damper, alpha: float = ALPHA, time_s: np.ndarray | None = None,
                 time_ref_s: float | None = None, channel: tuple[int, float] | None = None,
                 lag_starts: Sequence[float] = (), evaluators: tuple[Evaluator, Evaluator] | None = None):
        self.obs = obs
        # an ideal force channel (``model`` applies ``channel``); period 1 alone (simulated only up to its last
        # sample); ``evaluators``: those of a diagnoser of the same observations, shared with their remembered runs
        self.fit_mask = obs.period == 1
        self.fit_obs = obs.subset(self.fit_mask)
        if evaluators is None:
            evaluators = (Evaluator(obs, damper), Evaluator(self.fit_obs, damper))
            evaluators[1].share_forces(evaluators[0])   # a sine-only campaign: the same runs
        self.evaluator, self.fit_evaluator = evaluators
        self.alpha = alpha
        self.channel = channel
        self.lag_starts = () if channel is None else (channel[1], *(s for s in lag_starts if s != channel[1]))
        windows = np.abs(obs.force_N[obs.is_window])
        self.param = Parametrisation(damper, float(np.median(windows)) if windows.size else 1.0)
        offset_bound = offset_bound_N(obs.force_N, obs.is_window,
                                      bool(len(obs)) and all(p.waveform == "sine" for p in obs.plans))
        self.time_s, self.time_ref_s = None, None
        if time_s is not None and len(time_s) == len(obs) and np.ptp(time_s) > 0:
            t = np.asarray(time_s, dtype=float)
            self.time_ref_s = float(0.5 * (t.min() + t.max()) if time_ref_s is None else time_ref_s)
            self.time_s = t - self.time_ref_s
        drift_bound = offset_bound / float(np.max(np.abs(self.time_s))) if self.time_s is not None else 0.0
        self.instrument = INSTRUMENT + ((DRIFT,) if self.time_s is not None else ())
        # a declared load-cell calibration (gain, relative uncertainty) centres the gain and observes it once more
        centre, rel = obs.force_calibration or (1.0, None)
        self.linear = LinearTerms(offset_bound_N=offset_bound, drift_bound_N_s=drift_bound,
                                  friction_bound_N=self.param.bounds("friction")[1] * self.param.force_ref_N,
                                  gain_centre=centre, gain_sd=None if rel is None else rel * centre)
        self.weight = 1.0 / obs.sigma_N**2
        self.hold_mask = obs.period == 2
        self.fit_time_s = None if self.time_s is None else self.time_s[self.fit_mask]
        self.nominal = self.model(NOMINAL)
        self.scale_rel_sd = float(obs.noise.get("scale_rel_sd", 0.0))
        self.failed: list[dict] = []

    def with_channel(self, channel: tuple[int, float] | None, lag_starts: Sequence[float] = ()) -> Diagnoser:
        """The same diagnoser with every model prediction read through the force channel ``channel`` (the same
        evaluators: model runs are shared, and counted once in ``calls``)."""
        t = None if self.time_s is None else self.time_s + self.time_ref_s
        return Diagnoser(self.obs, self.evaluator.damper, self.alpha, t, self.time_ref_s, channel, lag_starts,
                         (self.evaluator, self.fit_evaluator))

    def model(self, effects, fit: bool = False, lag: float | None = None) -> np.ndarray:
        """The model force of every observation (``fit``: of period 1) as the force channel reads it (its
        group delay ``lag``, default the channel's starting one)."""
        ev = self.fit_evaluator if fit else self.evaluator
        if self.channel is None:
            return ev.predict(effects)
        return ev.read(effects, self.channel[0], [self.channel[1] if lag is None else lag])[0]

    def _split(self, nonlinear: Sequence[str], x) -> tuple[np.ndarray, float | None]:
        """(effect values, the channel's lag or None) of an optimiser vector."""
        x = np.asarray(x, dtype=float)
        return (x[:-1], float(x[-1])) if self.channel is not None else (x, None)

    @property
    def calls(self) -> int:
        """Model runs so far (of these evaluators: shared with the diagnosers made by :meth:`with_channel`)."""
        return self.evaluator.calls + self.fit_evaluator.calls

    def friction_signature(self, lag: float | None = None, fit: bool = False) -> np.ndarray:
        """The column of a profiled Coulomb friction per observation (``fit``: of period 1): its direction
        through an ideal channel (:meth:`isokinetic.diagnosis.model.Evaluator.friction_ideal`), else sign(v) as
        the force channel of group delay ``lag`` (default the channel's starting one) reads it
        (:meth:`isokinetic.diagnosis.model.Evaluator.friction_read`)."""
        ev = self.fit_evaluator if fit else self.evaluator
        if self.channel is None:
            return ev.friction_ideal()
        return ev.friction_read(self.channel[0], self.channel[1] if lag is None else lag)

    def z(self, prediction: np.ndarray) -> np.ndarray:
        return (self.obs.force_N - prediction) / self.obs.sigma_N

    def terms(self, instrument: Sequence[str] | None = None) -> LinearTerms:
        return replace(self.linear, free=tuple(self.instrument if instrument is None else instrument))

    def drift(self, rate_N_s: float, fit: bool = False) -> np.ndarray | float:
        """The zero drift's force at each observation (``fit``: of period 1) [N] for a rate [N/s]."""
        t = self.fit_time_s if fit else self.time_s
        return 0.0 if t is None else rate_N_s * t

    def _residuals(self, nonlinear: Sequence[str], friction: bool, terms: LinearTerms):
        obs, w = self.fit_obs, 1.0 / self.fit_obs.sigma_N**2

        def fun(x):
            eff, lag = self._split(nonlinear, x)
            m = self.model(self.param.effects(nonlinear, eff), fit=True, lag=lag)
            s = self.friction_signature(lag, fit=True) if friction else obs.sign
            g, fc, o, r = terms.solve(obs.force_N, m, s, w, friction, self.fit_time_s)
            z = (obs.force_N - g * (m + fc * s) - o - self.drift(r, True)) / obs.sigma_N
            prior = terms.prior_residuals(g)   # a declared calibration of the gain: one more residual
            return np.concatenate([z, prior]) if prior.size else z
        return fun

    def fit(self, names: Sequence[str], starts: Sequence[Sequence[float]],
            instrument: Sequence[str] | None = None, tol: float = FIT_TOL,
            lag_starts: Sequence[float] | None = None) -> Candidate | None:
        """Best of bounded least-squares fits of the nonlinear effects from the given starting points
        (one value per effect of ``names`` other than friction, which is profiled with the instrument
        terms; with a force channel, each start once per lag of ``lag_starts``, default ``self.lag_starts``);
        None (and a record in ``failed``) when no fit succeeds."""
        names = tuple(names)
        terms = self.terms(instrument)
        instrument = terms.free
        nonlinear = tuple(n for n in names if n != "friction")
        friction = "friction" in names
        bounds = [self.param.bounds(n) for n in nonlinear]
        if self.channel is not None:
            bounds.append(LAG_BOUNDS_S[self.channel[0]])
            starts = [[*x0, lag] for x0 in starts for lag in (lag_starts or self.lag_starts)]
        if not bounds:
            return self._guarded(names, nonlinear, np.empty(0), terms)
        lower, upper = zip(*bounds, strict=True)
        fun = self._residuals(nonlinear, friction, terms)
        best, errors = None, []
        for x0 in starts:
            x0 = np.clip(np.asarray(x0, dtype=float), np.asarray(lower) + 1e-12, np.asarray(upper) - 1e-12)
            secant = SecantJacobian(fun, lower, upper) if tol >= FIT_TOL else None
            try:
                with np.errstate(over="raise", invalid="raise", divide="raise"):
                    res = optimize.least_squares(secant or fun, x0, jac=secant.jac if secant else "2-point",
                                                 bounds=(lower, upper), method="trf", x_scale="jac",
                                                 diff_step=DIFF_STEP, ftol=tol, xtol=tol,
                                                 max_nfev=40 * len(bounds))
            except FIT_ERRORS as exc:
                errors.append(f"from {np.round(x0, 6).tolist()}: {type(exc).__name__}: {exc}")
                continue
            if not np.all(np.isfinite(res.fun)):
                errors.append(f"from {np.round(x0, 6).tolist()}: non-finite residuals")
                continue
            if best is None or res.cost < best.cost:
                best = res
        if best is None:
            log.warning("campaign %s: no fit of %s converged: %s", self.obs.campaign, list(names), "; ".join(errors))
            self.failed.append({"effects": list(names), "instrument": list(instrument),
                                "reason": "; ".join(errors) or "no starting point"})
            return None
        return self._guarded(names, nonlinear, best.x, terms)

    def _guarded(self, names, nonlinear, x, terms) -> Candidate | None:
        try:
            with np.errstate(over="raise", invalid="raise", divide="raise"):
                return self._score(names, nonlinear, x, terms)
        except FIT_ERRORS as exc:
            self.failed.append({"effects": list(names), "instrument": list(terms.free),
                                "reason": f"scoring failed: {type(exc).__name__}: {exc}"})
            return None

    def score_prediction(self, hydraulic: np.ndarray, instrument: Sequence[str] | None = None,
                         extra_k: int = 0) -> Candidate:
        """The candidate of no damper effect for a given model prediction ``hydraulic`` (for example the
        nominal model as a lagging force channel reads it), scored like any candidate with ``extra_k``
        more fitted parameters (the instrument terms measured to make it)."""
        return self._score((), (), np.empty(0), self.terms(instrument), hydraulic, extra_k)

    def _score(self, names: tuple[str, ...], nonlinear: tuple[str, ...], x: np.ndarray,
               terms: LinearTerms, hydraulic: np.ndarray | None = None, extra_k: int = 0) -> Candidate:
        """The candidate of fitted values ``x``: instrument terms and friction profiled on period 1,
        χ² of fit, holdout and windows, the explained test and the score."""
        x, lag = self._split(nonlinear, x)
        if hydraulic is None:
            hydraulic = self.model(self.param.effects(nonlinear, x), lag=lag) if nonlinear or lag is not None \
                else self.nominal
        fm = self.fit_mask
        sign = self.friction_signature(lag) if "friction" in names else self.obs.sign
        g, fc, o, r = terms.solve(self.obs.force_N[fm], hydraulic[fm], sign[fm], self.weight[fm], "friction" in names,
                                  self.fit_time_s)
        pred = hydraulic + fc * sign
        z = self.z(g * pred + o + self.drift(r))
        win = self.obs.is_window
        prior = terms.prior_residuals(g)   # a declared calibration: one more observation (of the gain) in the fit
        chi2_fit = float(np.sum(z[fm] ** 2) + np.sum(prior**2))
        chi2_hold = float(np.sum(z[self.hold_mask] ** 2))
        n_fit, n_hold = int(fm.sum()), int(self.hold_mask.sum())
        k = len(names) + len(terms.free) + extra_k + (self.channel is not None)
        eps = self.scale_rel_sd
        chi2_win = float(np.sum(z[win] ** 2))
        explained = (consistent_with_noise(chi2_fit, n_fit + prior.size - k, self.alpha, eps)
                     and consistent_with_noise(chi2_hold, n_hold, self.alpha, eps)
                     and consistent_with_noise(chi2_win, int(win.sum()) - k, self.alpha, eps))
        values = dict(zip(nonlinear, np.asarray(x, dtype=float), strict=True))
        values["friction"] = fc / self.param.force_ref_N
        full_x = np.array([values[n] for n in names], dtype=float)
        params = dict(self.param.si(n, v) for n, v in zip(names, full_x, strict=True))
        return Candidate(effects=names, x=full_x, params=params,
                         prediction=pred, chi2_fit=chi2_fit, chi2_holdout=chi2_hold, n_fit=n_fit, n_holdout=n_hold,
                         gap_after=rms(z[win & fm]), holdout_gap_after=rms(z[win & self.hold_mask]),
                         score=chi2_hold + k * math.log(n_fit), explained=explained,
                         instrument=tuple(terms.free), gain=g, offset_N=o, drift_N_s=r,
                         drift_N=np.broadcast_to(self.drift(r), pred.shape).copy(),
                         channel=None if lag is None else (self.channel[0], lag))

    def refit(self, names: Sequence[str], instrument: Sequence[str] | None = None, warm: Candidate | None = None,
              tol: float = FIT_TOL) -> Candidate | None:
        """Fit ``names`` with the instrument terms ``instrument``, warm-started from ``warm``."""
        nonlinear = [n for n in names if n != "friction"]
        x0 = [warm.x[warm.effects.index(n)] if warm is not None and n in warm.effects else self.param.starts(n)[0]
              for n in nonlinear]
        lags = [warm.channel[1]] if warm is not None and warm.channel is not None else None
        return self.fit(tuple(names), [x0], instrument, tol, lags)

    def nominal_p_value(self, instrument: Sequence[str] | None = None) -> float:
        """p-value of the χ² tests of the nominal model with the instrument terms (fitted on all
        observations), over all observations and over the windows (the characteristic) alone:
        twice the smaller p-value (Bonferroni), the probability of such a χ² from noise alone."""
        terms = self.terms(instrument)
        g, _fc, o, r = terms.solve(self.obs.force_N, self.nominal, self.obs.sign, self.weight, False, self.time_s)
        z = self.z(g * self.nominal + o + self.drift(r))
        win = self.obs.is_window
        k = len(terms.free) + (self.channel is not None)
        tests = [(float(np.sum(z**2)), len(z) - k), (float(np.sum(z[win] ** 2)), int(win.sum()) - k)]
        if any(dof <= 0 for _, dof in tests):
            return 0.0
        # the smaller of the two p-values, Bonferroni-corrected: the test of both at once
        return min(1.0, 2.0 * min(scaled_chi2_sf(c, dof, self.scale_rel_sd) for c, dof in tests))

    def nominal_explains(self, instrument: Sequence[str] | None = None) -> bool:
        """The nominal model with the instrument terms is within noise at level ``alpha``."""
        return self.nominal_p_value(instrument) >= self.alpha

    def singles(self) -> dict[str, Candidate | None]:
        """Each catalogue effect alone, fitted from its starting points."""
        return {e: self.fit((e,), [[s] for s in self.param.starts(e)] if e != "friction" else [[]])
                for e in CATALOGUE}

    def search(self, max_size: int | None = None) -> list[Candidate]:
        """Singles, then pairs (warm-started from the singles), then greedy extension of the BEAM best of
        the largest size, each size only while no smaller set explains the gap (the verdict is the
        smallest explaining set, so larger ones cannot change it) and until STABLE_SIZES larger sizes in a row
        have not moved the choice among the unexplained candidates (:func:`parsimonious`); no set larger than
        ``max_size`` (a rival search against a verdict of that size that explains: a larger set cannot win)."""
        limit = len(CATALOGUE) if max_size is None else max_size
        singles = self.singles()
        found = [c for c in singles.values() if c is not None]
        start = {e: (c.x[0] if c is not None else self.param.starts(e)[0]) for e, c in singles.items()}
        if limit >= 2 and not any(c.explained for c in found):
            for pair in itertools.combinations(CATALOGUE, 2):
                c = self.fit(pair, _warm_start(pair, start))
                if c is not None:
                    found.append(c)
        size, stable = 2, 0
        pick = parsimonious(found).effects if found else ()
        while found and not any(c.explained for c in found) and size < limit and stable < STABLE_SIZES:
            found += self._extend(found, size, start)
            size += 1
            now = parsimonious(found).effects
            stable, pick = (stable + 1 if now == pick else 0), now
        return sorted(found, key=lambda c: (not c.explained, len(c.effects) if c.explained else 0, c.score))

    def _extend(self, found: Sequence[Candidate], size: int, start: dict[str, float]) -> list[Candidate]:
        """The BEAM best candidates of ``size`` effects, each extended by one more effect."""
        bases = sorted((c for c in found if len(c.effects) == size), key=lambda c: c.score)[:BEAM]
        tried, out = set(), []
        for base in bases:
            for e in CATALOGUE:
                names = tuple(n for n in CATALOGUE if n in base.effects or n == e)
                if e in base.effects or names in tried:
                    continue
                tried.add(names)
                c = self.fit(names, _warm_start(names, start, base))
                if c is not None:
                    out.append(c)
        return out


def _warm_start(names: Sequence[str], start: dict[str, float], source: Candidate | None = None) -> list[list[float]]:
    """One starting point for the nonlinear effects of ``names``: the values of ``source`` where it
    has them, else each effect's single fit (``start``)."""
    return [[(source.x[source.effects.index(n)] if source is not None and n in source.effects else start[n])
             for n in names if n != "friction"]]
