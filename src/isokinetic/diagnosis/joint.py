"""A mixed campaign judged on all its records: the search repeated on the triangles and the sine records together.

Beside triangle windows a campaign's sine records are first left out of the search and only check the triangles'
verdict (:mod:`isokinetic.diagnosis.sine_check`). Where they fail it, the search is run again on both
(:class:`JointDiagnoser`), each record with honest errors: a triangle window or transient bin with its own
standard error, as in the triangles' search; a sine record's phase bins with theirs, less the even mode
a + b·|M| of each of its steady cycles (:func:`isokinetic.diagnosis.sine_check.record_residuals` over
:func:`cycle_blocks`: two linear parameters a cycle). That mode is the block noise a cycle's bins share (noise
slower than a cycle, additive and proportional): profiled out as a nuisance, it is the limit of a block covariance
σ²I + s_a²11ᵀ + s_b²|M||M|ᵀ per cycle whose common variances are unknown, so no estimate of their size enters the
test; a symmetric damper's force and every symmetric effect (friction, air's lag, a discharge or viscosity change)
are odd over a cycle and stay in the residuals. Each candidate's effects (and the force channel's lag, where the
triangles' verdict has one) are fitted on both, period 1 of each; the load-cell terms and Coulomb friction are
profiled on the triangles (:class:`isokinetic.diagnosis.search.Diagnoser`) and read into the sines. A candidate
explains where the triangles' tests pass (fit, held-out period, windows) and the sines' χ² passes on both periods;
its score is the triangles' plus the sines' held-out χ².
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy import optimize

from isokinetic.contracts.scenarios import CATALOGUE
from isokinetic.diagnosis.candidate import Candidate, consistent_with_noise
from isokinetic.diagnosis.instrument import LAG_FORM_NAMES, LAG_FORMS
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.search import BEAM, DIFF_STEP, FIT_ERRORS, FIT_TOL, LAG_BOUNDS_S, Diagnoser, SecantJacobian
from isokinetic.diagnosis.sine_check import record_residuals
from isokinetic.physics.damper import Damper, Effects

#: The joint search stops at sets of this many effects (the catalogue's largest credible combination; each size
#: costs BEAM x len(CATALOGUE) fits driven through every sine record).
MAX_JOINT_SIZE = 4

@dataclass(frozen=True)
class JointCandidate:
    """An effect set fitted on triangles and sine records together: ``triangles`` its triangles' part (a
    :class:`~isokinetic.diagnosis.candidate.Candidate`: fit, held-out period, windows, instrument terms), the sine
    records' χ² (each record's even mode taken out) on period 1 (fitted) and period 2 (held out) and their
    degrees of freedom."""

    triangles: Candidate
    sine_chi2_fit: float
    sine_dof_fit: int
    sine_chi2_hold: float
    sine_dof_hold: int
    sines_pass: bool

    @property
    def effects(self) -> tuple[str, ...]:
        return self.triangles.effects

    @property
    def explained(self) -> bool:
        """The triangles' tests and the sines' pass."""
        return bool(self.triangles.explained and self.sines_pass)

    @property
    def score(self) -> float:
        """The triangles' score (held-out χ² + k ln n) plus the sines' held-out χ²."""
        return self.triangles.score + self.sine_chi2_hold

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "params": self.triangles.params, "explained": self.explained,
                "score": self.score, "triangles_explained": self.triangles.explained,
                "triangles_chi2_fit": self.triangles.chi2_fit, "triangles_chi2_holdout": self.triangles.chi2_holdout,
                "sines_pass": self.sines_pass,
                "sine_chi2_fit": self.sine_chi2_fit, "sine_dof_fit": self.sine_dof_fit,
                "sine_rms_z_fit": math.sqrt(self.sine_chi2_fit / max(self.sine_dof_fit, 1)),
                "sine_chi2_holdout": self.sine_chi2_hold, "sine_dof_holdout": self.sine_dof_hold,
                "sine_rms_z_holdout": math.sqrt(self.sine_chi2_hold / max(self.sine_dof_hold, 1)),
                "force_lag_s": None if self.triangles.channel is None else self.triangles.channel[1],
                "force_lag_form": None if self.triangles.channel is None else LAG_FORM_NAMES[self.triangles.channel[0]]}


def cycle_blocks(sines: Observations) -> Observations:
    """``sines`` with each bin's ``case`` the block its common error belongs to: its record and steady cycle
    (a sine bin's ``segment`` is 2·cycle + 1 or 2, :mod:`isokinetic.diagnosis.sine_observations`)."""
    cycle = (np.asarray(sines.segment) - 1) // 2
    return replace(sines, case=np.array([f"{c}/{k}" for c, k in zip(sines.case, cycle, strict=True)], dtype=object))


def block_parameters(sines: Observations) -> int:
    """The even modes' parameters among ``sines``: two a block (``case`` value), one where a block holds one bin
    (a record's last cycle may end after its first bin)."""
    _names, counts = np.unique(sines.case.astype(str), return_counts=True)
    return int(np.minimum(counts, 2).sum())


class JointDiagnoser:
    """Fits and scores effect sets on a diagnoser's triangle observations ``dg`` and the sine observations
    ``sines`` together (the module's doc says how); ``evaluator``: the sines' model, shared between the joint
    diagnosers of one campaign."""

    def __init__(self, dg: Diagnoser, sines: Observations, damper: Damper, evaluator: Evaluator | None = None):
        self.dg, self.sines = dg, sines
        self.evaluator = Evaluator(sines, damper) if evaluator is None else evaluator   # shared: runs remembered
        self.fit_rows, self.hold_rows = sines.period == 1, sines.period == 2
        blocks = cycle_blocks(sines)
        self.fit_sines, self.hold_sines = blocks.subset(self.fit_rows), blocks.subset(self.hold_rows)
        self.scale_rel_sd = float(sines.noise.get("scale_rel_sd", 0.0))
        self.failed: list[dict] = []

    @property
    def calls(self) -> int:
        """Model runs of the sine records (the triangles' are counted by ``dg``)."""
        return self.evaluator.calls

    def sine_force(self, effects: Effects, lag_s: float | None, gain: float, coulomb_N: float) -> np.ndarray:
        """The model's sine bin means as the load cell reads them: gain·(hydraulic + Coulomb friction), both
        through the diagnoser's force channel at group delay ``lag_s`` (ideal where it has none) [N]."""
        ev, channel = self.evaluator, self.dg.channel
        if channel is None:
            hydraulic = ev.predict(effects)
            friction = ev.friction_ideal() if coulomb_N else 0.0
        else:
            hydraulic = ev.read(effects, channel[0], [lag_s])[0]
            friction = ev.friction_read(channel[0], lag_s) if coulomb_N else 0.0
        return gain * (hydraulic + coulomb_N * friction)

    def sine_z(self, model_N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(period 1, period 2) z of the sine bins against ``model_N``, each steady cycle's even mode taken out
        (:func:`isokinetic.diagnosis.sine_check.record_residuals` over :func:`cycle_blocks`)."""
        return (record_residuals(self.fit_sines, model_N[self.fit_rows]),
                record_residuals(self.hold_sines, model_N[self.hold_rows]))

    def _residuals(self, names: tuple[str, ...]):
        """The joint residual vector of an optimiser vector: the triangles' period-1 z (load-cell terms and
        friction profiled on them) and the sines' period-1 z."""
        dg = self.dg
        obs, w = dg.fit_obs, 1.0 / dg.fit_obs.sigma_N**2
        nonlinear = tuple(n for n in names if n != "friction")
        friction = "friction" in names
        terms = dg.terms()

        def fun(x):
            x = np.asarray(x, dtype=float)
            eff, lag = (x[:-1], float(x[-1])) if dg.channel is not None else (x, None)
            effects = dg.param.effects(nonlinear, eff)
            m = dg.model(effects, fit=True, lag=lag)
            s = dg.friction_signature(lag, fit=True) if friction else obs.sign
            g, fc, o, r = terms.solve(obs.force_N, m, s, w, friction, dg.fit_time_s)
            triangles = (obs.force_N - g * (m + fc * s) - o - dg.drift(r, True)) / obs.sigma_N
            sines = self.sine_z(self.sine_force(effects, lag, g, fc if friction else 0.0))[0]
            return np.concatenate([triangles, sines])
        return fun

    def fit(self, names: Sequence[str], starts: Sequence[Sequence[float]]) -> JointCandidate | None:
        """Best of bounded least-squares fits of ``names`` (the nonlinear effects' values, and the channel's lag
        where ``dg`` has one, from each start) on both kinds of record; None, and a record in ``failed``,
        where none succeeds."""
        dg, names = self.dg, tuple(names)
        nonlinear = [n for n in names if n != "friction"]
        bounds = [dg.param.bounds(n) for n in nonlinear]
        if dg.channel is not None:
            bounds.append(LAG_BOUNDS_S[dg.channel[0]])
            starts = [[*x0, lag] for x0 in starts for lag in dg.lag_starts]
        if not bounds:
            return self.score(names, np.empty(0))
        lower, upper = (np.array(b) for b in zip(*bounds, strict=True))
        fun, best, errors = self._residuals(names), None, []
        for x0 in starts:
            x0 = np.clip(np.asarray(x0, dtype=float), lower + 1e-12, upper - 1e-12)
            secant = SecantJacobian(fun, lower, upper)
            try:
                with np.errstate(over="raise", invalid="raise", divide="raise"):
                    res = optimize.least_squares(secant, x0, jac=secant.jac, bounds=(lower, upper), method="trf",
                                                 x_scale="jac", diff_step=DIFF_STEP, ftol=FIT_TOL, xtol=FIT_TOL,
                                                 max_nfev=40 * len(bounds))
            except FIT_ERRORS as exc:
                errors.append(f"from {np.round(x0, 6).tolist()}: {type(exc).__name__}: {exc}")
                continue
            if np.all(np.isfinite(res.fun)) and (best is None or res.cost < best.cost):
                best = res
        if best is None:
            self.failed.append({"effects": list(names), "reason": "; ".join(errors) or "non-finite residuals"})
            return None
        return self.score(names, best.x)

    def score(self, names: tuple[str, ...], x: np.ndarray) -> JointCandidate | None:
        """The joint candidate of fitted values ``x``: the triangles' candidate scored by ``dg`` (its tests and
        score), the sines' χ² on each period against its degrees of freedom (bins less two a cycle, less the
        fitted parameters on period 1)."""
        dg = self.dg
        nonlinear = tuple(n for n in names if n != "friction")
        try:
            with np.errstate(over="raise", invalid="raise", divide="raise"):
                tri = dg._score(names, nonlinear, x, dg.terms())
                coulomb = tri.x[names.index("friction")] * dg.param.force_ref_N if "friction" in names else 0.0
                lag = None if tri.channel is None else tri.channel[1]
                z1, z2 = self.sine_z(self.sine_force(dg.param.effects(nonlinear, tri.x[[names.index(n) for n in
                                                                                       nonlinear]]),
                                                     lag, tri.gain, coulomb))
        except FIT_ERRORS as exc:
            self.failed.append({"effects": list(names), "reason": f"scoring failed: {type(exc).__name__}: {exc}"})
            return None
        dof1 = z1.size - block_parameters(self.fit_sines) - len(nonlinear) - (tri.channel is not None)
        dof2 = z2.size - block_parameters(self.hold_sines)
        chi1, chi2 = float(z1 @ z1), float(z2 @ z2)
        passes = consistent_with_noise(chi1, dof1, dg.alpha, self.scale_rel_sd) and \
            (dof2 <= 0 or consistent_with_noise(chi2, dof2, dg.alpha, self.scale_rel_sd))
        return JointCandidate(tri, chi1, dof1, chi2, dof2, bool(passes))

    def refit(self, names: Sequence[str], warm: dict[str, float]) -> JointCandidate | None:
        """``names`` fitted from the values ``warm`` (optimiser units) where it has them, else each effect's first
        start."""
        return self.fit(names, [[warm.get(n, self.dg.param.starts(n)[0]) for n in names if n != "friction"]])

    def search(self, prior: Sequence[str] = (), warm: dict[str, float] | None = None,
               max_size: int = MAX_JOINT_SIZE) -> list[JointCandidate]:
        """The catalogue searched on both kinds of record: ``prior`` (the triangles' verdict) refitted, each effect
        alone (from its starts), then, while nothing explains, every pair and the BEAM best of each size extended
        by one more effect, up to ``max_size`` effects; sorted as the triangles' search sorts (explaining first,
        smaller, better score)."""
        warm = dict(warm or {})
        found = [c for c in [self.refit(tuple(prior), warm)] if c is not None] if 0 < len(prior) <= max_size else []
        for e in CATALOGUE:
            if (e,) != tuple(prior):
                c = self.fit((e,), [[s] for s in self.dg.param.starts(e)] if e != "friction" else [[]])
                if c is not None:
                    found.append(c)
                    warm.setdefault(e, float(c.triangles.x[0]))
        tried = {c.effects for c in found}
        if not any(c.explained for c in found) and max_size >= 2:
            for pair in itertools.combinations(CATALOGUE, 2):
                if pair not in tried and (c := self.refit(pair, warm)) is not None:
                    found.append(c)
                tried.add(pair)
        size = 2
        while not any(c.explained for c in found) and size < max_size:
            bases = sorted((c for c in found if len(c.effects) == size), key=lambda c: c.score)[:BEAM]
            for base in bases:
                start = {**warm, **dict(zip(base.effects, base.triangles.x, strict=True))}
                for e in CATALOGUE:
                    names = tuple(n for n in CATALOGUE if n in base.effects or n == e)
                    if names not in tried and (c := self.refit(names, start)) is not None:
                        found.append(c)
                    tried.add(names)
            size += 1
        return sorted(found, key=lambda c: (not c.explained, len(c.effects) if c.explained else 0, c.score))


#: Why a verdict the sine records fail is not ``explained`` (``mixed_note``), and what the joint search made of it.
SINES_FAIL_NOTE = ("the sine records fail the triangles' verdict (sine_check): it does not explain all the campaign's "
                   "records, so it is not explained")
JOINT_REPLACES_NOTE = ("; the search repeated on the triangles and the sine records together (joint) found a verdict "
                       "that explains both, which replaces it (the triangles' verdict: triangles_verdict)")
JOINT_FAILS_NOTE = ("; no candidate of the search repeated on the triangles and the sine records together (joint) "
                    "explains both, so the triangles' verdict stands, not explained")
JOINT_NOT_MADE_NOTE = "; the search was not repeated on both kinds of record (joint says why)"
#: Keys of the triangles' verdict moved into ``triangles_verdict`` where the joint verdict replaces it.
TRIANGLE_VERDICT_KEYS = ("verdict", "explained", "params", "gap_after", "holdout_gap_after", "shrink",
                         "rms_rel_after", "search_note", "unexplained_note", "sensor_note", "instrument")


def joint_search(dg: Diagnoser, sines: Observations, damper: Damper, prior: Sequence[str],
                 channel: tuple[int, float] | None = None) -> tuple[dict, JointCandidate | None]:
    """(the ``joint`` report, its verdict or None): the catalogue searched on ``dg``'s triangle observations (an
    ideal force channel) and the sine records ``sines`` (:meth:`JointDiagnoser.search`), from the triangles'
    verdict ``prior`` (its values fitted on the triangles, the warm start); where that verdict reads the force
    through a lagging ``channel``, again through each form of :data:`isokinetic.diagnosis.instrument.LAG_FORMS` (a
    delay, a 1st- or 2nd-order low-pass: the sines at 10 Hz tell them apart, the triangles' slow reversals need
    not), its lag started from the triangles' and fitted on both (a lag fitted on slow triangles may be air the
    sines resolve), each up to the size of the smallest set that explains so far. No lag is tried that the
    triangles do not need: free on the sines alone, a lag of a millisecond took up a Stribeck hump beside friction
    on the reference rig (with a trace of air: "explained"). The verdict is the first of all candidates sorted as
    the search sorts them: the smallest explaining set with the best score (the lag one more parameter), else the
    best-scoring unexplained one."""
    started, calls = time.perf_counter(), dg.calls
    evaluator, found, failed = Evaluator(sines, damper), [], []
    fitted = dg.refit(tuple(prior)) if prior else None
    warm = {} if fitted is None else dict(zip(fitted.effects, (float(v) for v in fitted.x), strict=True))
    forms = LAG_FORMS if channel is not None else ()
    for cdg in [dg, *(dg.with_channel((form, max(channel[1], LAG_BOUNDS_S[form][0]))) for form in forms)]:
        jd = JointDiagnoser(cdg, sines, damper, evaluator)
        explaining = [len(c.effects) for c in found if c.explained]   # a larger set cannot be the verdict
        found += jd.search(prior, warm, min(explaining, default=max(MAX_JOINT_SIZE, len(prior))))
        failed += jd.failed
    found.sort(key=lambda c: (not c.explained, len(c.effects) if c.explained else 0, c.score))
    best = found[0] if found else None
    report = {"cases": ",".join(dict.fromkeys(sines.case.tolist())), "n_sine_bins": len(sines),
              "block_noise": "each steady cycle's even mode a + b·|M| profiled out of its phase bins",
              "verdict": None if best is None else list(best.effects),
              "explained": bool(best is not None and best.explained),
              "params": None if best is None else best.triangles.params,
              **{k: None if best is None else best.to_dict()[k] for k in ("force_lag_s", "force_lag_form")},
              "candidates": [c.to_dict() for c in found],
              "model_evaluations": dg.calls - calls + evaluator.calls,
              "seconds": round(time.perf_counter() - started, 3)}
    if failed:
        report["failed_fits"] = failed
    return report, best


def judged_on_all_records(result: dict, joint: dict, best: JointCandidate | None, dg: Diagnoser | None) -> dict:
    """``result`` (a diagnosis whose sine check failed) judged on all its records: the triangles' verdict is not
    ``explained`` (``mixed_note`` says why) and the ``joint`` report is added; where the joint verdict ``best``
    explains both kinds of record it replaces the verdict (its effects, parameters and the triangles' gap), and the
    triangles' verdict is kept in ``triangles_verdict``."""
    out = {**result, "joint": joint}
    out["triangles_verdict"] = {k: result[k] for k in TRIANGLE_VERDICT_KEYS if k in result}
    if best is None or not best.explained or dg is None:
        why = JOINT_FAILS_NOTE if "candidates" in joint else JOINT_NOT_MADE_NOTE
        return {**out, "explained": False, "mixed_note": SINES_FAIL_NOTE + why}
    for key in TRIANGLE_VERDICT_KEYS:
        out.pop(key, None)
    tri, obs = best.triangles, dg.obs
    win = obs.is_window
    gap_before = result.get("gap_before")
    lag = None if tri.channel is None else tri.channel[1]
    out.update(verdict=list(best.effects), explained=True, params=tri.params, gap_after=tri.gap_after,
               holdout_gap_after=tri.holdout_gap_after,
               shrink=gap_before / tri.gap_after if gap_before and tri.gap_after > 0 else None,
               rms_rel_after=float(np.sqrt(np.mean(((obs.force_N - tri.measured_prediction)
                                                    / np.abs(obs.force_N))[win] ** 2))) if win.any() else None,
               mixed_note=SINES_FAIL_NOTE + JOINT_REPLACES_NOTE)
    if "instrument" in result:   # the load-cell terms as tested on the triangles, the force channel's lag the joint's
        out["instrument"] = {**result["instrument"], "force_lag_s": lag}
    return out
