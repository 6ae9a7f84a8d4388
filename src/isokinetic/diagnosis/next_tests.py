"""The next test (issue 37): which extra cases would separate the readings a campaign cannot tell apart, and
how much rig time they cost.

Rivals. Each confounded group of the verdict (``confounded`` in diagnosis.json), and the partial explanations of
an unexplained verdict that names effects whose overdispersed scores lie within CONFOUNDED_SCORE of each other, is
turned into full hypotheses (:func:`group_readings`, :func:`partial_readings`): damper effects with their fitted
parameters and the instrument terms fitted with them (load-cell gain, offset and zero drift, force-channel lag), each
predicting any new case. They are built from the diagnosis' own fits, refitted where a reading was not fitted
(:meth:`Diagnoser.refit`): the verdict against the same-size candidates within the margin; the verdict with its
load-cell gain against discharge + viscosity with none; the verdict's effects through an ideal force channel against
the lag without the effects it is confounded with (or the rival candidate with the other channel); the verdict
without the drifting effect, drift free, against the verdict without the drift; the verdict against an LVDT scale k
(:func:`fit_scale`: the model's gain 1/k tied to C_D·√k). Where the verdict's own terms are that family (discharge
and a free gain, no viscosity), no case of any waveform separates them, and the plan says so.

Candidates: :mod:`isokinetic.diagnosis.next_cases` (triangle cases within the rig's limits whose windows start after
convergence, Eq. 28, and a repeat of the first case at the end; a sine-only campaign's, sine cases).

Criterion (:class:`PairState`, :meth:`GroupModel.separation`). The expected χ² difference between rivals A and B
when A is true, linearised with B refitted: Δχ²_A→B = ||(I − P_B)(μ_A − μ_B)/σ||² over the old observations and the
candidates', P_B the weighted projection on B's Jacobian (its effects' parameters, its force-channel lag, its gain,
friction, offset and drift columns). Of two non-nested rivals the smaller direction counts (the plan must separate
whichever is true); of nested ones (one's terms a subset of the other's), the larger true and the smaller refitted
(the likelihood-ratio test of the extra terms). A group's separation is its least separated pair. σ of a new mean is
the campaign's own fitted noise model (white plus coloured, :class:`isokinetic.measurement.noise.NoiseModel`, for
the mean of its samples) with the between-period scatter. A D-optimal design on the parameters would buy precision
of every parameter, including those the rivals share; this criterion buys only the difference the rivals predict, in
the units the verdict's tests use (χ²).

Selection (:func:`greedy_plan`): greedy, the case that adds most to Σ_group min(Δχ²_group, TARGET_SE²) per minute
of rig time, until every group reaches TARGET_SE standard errors, MAX_CASES cases or BUDGET_S of rig time. New
cases run after the campaign's, in the plan's order (their campaign times enter the drift terms).

A group holding the load cell's gain gets a calibration against a reference force instead
(:mod:`isokinetic.diagnosis.next_calibration`, ``calibrations``): its Δχ² is credited to the group before the cases
are chosen (an independent measurement: χ² adds), so cases go only to groups it leaves short of TARGET_SE. A group
holding the LVDT's scale gets a calibration of the LVDT (also the family no case separates, which builds no readings:
:func:`scale_family`), which resolves its listing.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from isokinetic.contracts.settings import DEFAULTS, DesignLimits, WindowSpec
from isokinetic.diagnosis.candidate import CONFOUNDED_SCORE, Candidate, overdispersed_score
from isokinetic.diagnosis.instrument import DRIFT, LAG_FORM_NAMES
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.next_calibration import calibration_text, declared_calibration, declared_lvdt, proposals
from isokinetic.diagnosis.next_cases import (
    MAX_CASE_S,
    SETUP_S,
    Probe,
    RigLimits,
    candidate_cases,
    mean_variance_N2,
    probe_observations,
    rig_limits,
    sine_probe_observations,
)
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.diagnosis.sine_observations import N_SINE_BINS
from isokinetic.diagnosis.verdict import DRIFT_CONFOUNDED_CORRELATION as CORRELATION_LIMIT
from isokinetic.physics.damper import Damper

CRITERION = ("expected chi-square difference between rivals A and B when A is true, B refitted (linearised: "
             "||(I - P_B)(mu_A - mu_B)/sigma||^2 over the old and the new observations, P_B the weighted projection "
             "on B's effects and instrument terms; the smaller direction of non-nested rivals, the larger true of "
             "nested ones), sigma from the campaign's fitted noise model; greedy per minute of rig time")
NO_PLAN_NOTE = "no confounding: no further test proposed"
#: Separation a group should reach [standard errors, √Δχ²].
TARGET_SE = 5.0
#: Most cases a plan proposes, and its rig-time budget [s].
MAX_CASES = 8
BUDGET_S = 7200.0
#: A case "resolves" a group where it adds at least this to the group's Δχ².
RESOLVES_MIN_CHI2 = 1.0
#: Step of the finite-difference Jacobian: optimiser units (order one) and the force channel's lag [s].
JAC_STEP = 1e-4
LAG_STEP_S = 1e-4
#: Partial explanations of an unexplained verdict taken as rivals (best overdispersed score first).
MAX_PARTIAL_RIVALS = 3
PHYSICS = ("discharge", "viscosity")
#: Highest sample rate of the model runs at the candidates [Hz]: a window's or transient bin's mean is an integral
#: over its times, which 250 samples a second resolve for the relaxations and force channels fitted (group delays of
#: a few ms and more); a 2 kHz campaign's 20-min candidates would otherwise hold tens of millions of samples.
MODEL_RATE_HZ = 250.0
#: What decides a group no case of the rig's range separates to the target, by the instrument term in it (first
#: match): a check of the sensor itself.
ADVICE = (("displacement_scale", "record the command channel or calibrate the LVDT"),
          ("force_gain", "calibrate the load cell against a reference force"),
          ("force_lag", "check the force channel's dynamics (its filter settings, or a step of known force)"),
          ("force_drift", "check the load cell's zero before and after the campaign"))
SCALE_REASON = ("inside the model an LVDT scale k is a load-cell gain 1/k plus C_D·√k: no case of any waveform "
                "separates them")


@dataclass(frozen=True)
class Reading:
    """One rival: a fitted candidate (effects, parameters, instrument terms, force channel) and its label.
    ``scale``: an LVDT scale k read as its model equivalent, gain 1/k tied to C_D·√k (one parameter, ln k)."""

    label: str
    candidate: Candidate
    scale: bool = False


# ----------------------------------------------------------------------------------------------------------------
# the rivals
# ----------------------------------------------------------------------------------------------------------------

def _label(c: Candidate, shown: Sequence[str] = ()) -> str:
    """A reading's name: its effects, its force-channel lag, and the instrument terms ``shown`` it has free."""
    parts = list(c.effects) + (["force_lag"] if c.channel is not None else [])
    parts += [t for t in shown if t in c.instrument]
    return "+".join(parts) or "nominal"


def _without(names: Sequence[str], drop: Sequence[str]) -> tuple[str, ...]:
    return tuple(n for n in names if n not in drop)


def _lag_rival(best: Candidate, candidates: Sequence[Candidate], margin: float) -> Candidate | None:
    """The candidate the verdict's lag confounding names (:func:`isokinetic.diagnosis.verdict.instrument_confounding`):
    explaining, with the other force channel, other effects, within ``margin``, the best scoring."""
    rivals = [c for c in candidates if c.explained and (c.channel is None) != (best.channel is None)
              and c.effects != best.effects and abs(c.score - best.score) < margin]
    return min(rivals, key=lambda c: c.score) if rivals else None


def group_readings(group: Sequence[str], ctx: Mapping) -> list[Reading] | str:
    """The rival readings of one confounded ``group`` (a list of at least two), or why none can be built.

    ``ctx``: the diagnosis' fits (``dg`` the diagnoser without a force channel, ``bdg`` the verdict's, ``best``,
    ``candidates``, ``hyp`` the sensor hypothesis, ``verdict``, ``margin`` the sensor margin)."""
    dg, bdg, best = ctx["dg"], ctx["bdg"], ctx["best"]
    verdict = tuple(ctx["verdict"])
    if "displacement_scale" in group:
        return scale_readings(group, ctx)
    if "force_gain" in group:
        physics = tuple(e for e in PHYSICS if e in group)
        if ctx.get("gain_needed"):   # the verdict with its gain against discharge and viscosity with none
            alt = bdg.refit(tuple(sorted({*verdict, *physics}, key=_order)), _without(bdg.instrument, ["force_gain"]),
                            best)
        else:                        # the verdict's discharge and viscosity against a gain without them
            alt = bdg.refit(_without(verdict, physics), bdg.instrument, best)
        pair = [(best, ("force_gain",)), (alt, ("force_gain",))]
    elif DRIFT in group:
        drifting = tuple(e for e in group if e != DRIFT)
        drift = bdg.refit(_without(verdict, drifting), bdg.instrument, best)
        alt = bdg.refit(verdict, _without(bdg.instrument, [DRIFT]), best)
        pair = [(drift, (DRIFT,)), (alt, (DRIFT,))]
    elif "force_lag" in group:
        rival = _lag_rival(best, ctx["candidates"], ctx["margin"])
        if rival is not None and list(group) == sorted({*verdict, *rival.effects}) + ["force_lag"]:
            pair = [(best, ()), (rival, ())]
        else:
            lagged = tuple(e for e in group if e != "force_lag")
            hyp = ctx.get("hyp")
            channel = best.channel if best.channel is not None else (None if hyp is None else (hyp["form"],
                                                                                                hyp["lag_s"]))
            lag_dg = dg.with_channel(channel) if channel is not None else None
            damper_reading = dg.refit(verdict, dg.instrument, best)
            sensor_reading = None if lag_dg is None else lag_dg.refit(_without(verdict, lagged), dg.instrument, best)
            pair = [(damper_reading, ()), (sensor_reading, ())]
    else:
        found = [c for c in ctx["candidates"] if c.explained and len(c.effects) == len(best.effects)
                 and set(c.effects) <= set(group) and c.score - best.score < CONFOUNDED_SCORE]
        pair = [(best, ())] + [(c, ()) for c in found if c.effects != best.effects]
    out = [Reading(_label(c, shown), c) for c, shown in pair if c is not None]
    return out if len(out) >= 2 else "a rival reading could not be fitted"


def scale_readings(group: Sequence[str], ctx: Mapping) -> list[Reading] | str:
    """The readings of an unmeasured LVDT scale's group: the verdict as fitted (its discharge, viscosity or
    load-cell gain) against an LVDT scale k (the true speeds the measured ones over k: the model's gain 1/k with
    C_D·√k, :func:`fit_scale`) with the verdict's other effects. Where the verdict's own terms are that family
    (discharge and a free gain, no viscosity), the two are one model: no case separates them (SCALE_REASON)."""
    best, bdg = ctx["best"], ctx["bdg"]
    if "viscosity" not in group and "discharge" in best.effects:
        return SCALE_REASON
    scale = fit_scale(bdg, best)
    if scale is None:
        return "the LVDT-scale reading could not be fitted"
    return [Reading(_label(best, ("force_gain",)), best), Reading("displacement_scale", scale, scale=True)]


def fit_scale(dg: Diagnoser, best: Candidate) -> Candidate | None:
    """The LVDT-scale reading fitted to the campaign: the verdict's effects other than discharge and viscosity
    held, ln k within ±SCALE_BOUND, the model's gain 1/k and discharge coefficient C_D·√k, the load-cell offset
    (and drift) profiled; a Candidate whose ``x`` holds the discharge's optimiser value (ln √k)."""
    from scipy.optimize import minimize_scalar

    from isokinetic.diagnosis.instrument import SCALE_BOUND

    keep = tuple(e for e in best.effects if e not in PHYSICS and e != "friction")
    names = (*keep, "discharge")
    held = [best.x[best.effects.index(e)] for e in keep]
    terms = dg.terms(_without(dg.instrument, ["force_gain"]))
    obs = dg.obs
    lag = None if best.channel is None else best.channel[1]
    ch = dg if best.channel is None else dg.with_channel(best.channel)

    def fitted(log_k: float):
        model = ch.model(dg.param.effects(names, [*held, 0.5 * log_k]), lag=lag) / math.exp(log_k)
        _g, _fc, o, r = terms.solve(obs.force_N, model, obs.sign, dg.weight, False, dg.time_s)
        z = (obs.force_N - model - o - (0.0 if dg.time_s is None else r * dg.time_s)) / obs.sigma_N
        return float(z @ z), o, r

    bound = math.log1p(SCALE_BOUND)
    res = minimize_scalar(lambda u: fitted(u)[0], bounds=(-bound, bound), method="bounded",
                          options={"xatol": 1e-6})
    if not np.isfinite(res.fun):
        return None
    _chi2, o, r = fitted(float(res.x))
    x = np.array([*held, 0.5 * float(res.x)])
    return replace(best, effects=names, x=x, params=dict(dg.param.si(n, v) for n, v in zip(names, x, strict=True)),
                   gain=math.exp(-float(res.x)), offset_N=o, drift_N_s=r, instrument=dg.instrument)


def _order(effect: str) -> int:
    from isokinetic.contracts.scenarios import CATALOGUE

    return CATALOGUE.index(effect) if effect in CATALOGUE else len(CATALOGUE)


def partial_readings(best: Candidate, candidates: Sequence[Candidate]) -> list[Reading]:
    """Of an unexplained verdict: the partial explanations whose overdispersed score lies within CONFOUNDED_SCORE of
    the best (:func:`isokinetic.diagnosis.candidate.parsimonious`' choice among them), up to MAX_PARTIAL_RIVALS."""
    if best.explained or len(candidates) < 2:
        return []
    scores = {id(c): overdispersed_score(c, candidates) for c in candidates}
    close = sorted((c for c in candidates if scores[id(c)] <= min(scores.values()) + CONFOUNDED_SCORE),
                   key=lambda c: scores[id(c)])
    if not any(c is best for c in close):   # by identity: a Candidate holds arrays
        close = [best, *close]
    distinct = {}
    for c in close:   # one reading per effect set and channel kind (the search and the lag search fit some twice)
        distinct.setdefault((c.effects, c.channel is None), c)
    close = list(distinct.values())
    return [Reading(_label(c), c) for c in close[:MAX_PARTIAL_RIVALS]] if len(close) >= 2 else []


# ----------------------------------------------------------------------------------------------------------------
# predictions of a reading, and its Jacobian
# ----------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Channel:
    """Where a reading's prediction is made: an evaluator, each observation's campaign time relative to the
    reference (None: no drift term) and the diagnoser's parametrisation."""

    evaluator: Evaluator
    time_s: np.ndarray | None
    dg: Diagnoser

    def hydraulic(self, c: Candidate, x: np.ndarray | None = None, lag: float | None = None) -> np.ndarray:
        """The damper model of ``c`` (its optimiser values ``x``, default its own) as its force channel reads it
        (``lag`` default its own), friction excluded."""
        names = tuple(n for n in c.effects if n != "friction")
        x = np.array([c.x[c.effects.index(n)] for n in names]) if x is None else x
        eff = self.dg.param.effects(names, x)
        if c.channel is None:
            return self.evaluator.predict(eff)
        return self.evaluator.read(eff, c.channel[0], [c.channel[1] if lag is None else lag])[0]

    def friction_column(self, c: Candidate, lag: float | None = None) -> np.ndarray:
        if c.channel is None:
            return self.evaluator.friction_ideal()
        return self.evaluator.friction_read(c.channel[0], c.channel[1] if lag is None else lag)

    def coulomb_N(self, c: Candidate) -> float:
        return float(c.x[c.effects.index("friction")]) * self.dg.param.force_ref_N if "friction" in c.effects else 0.0

    def prediction(self, c: Candidate) -> np.ndarray:
        """What the load cell reads under ``c``: g (F_model + F_C col) + F_0 + r t."""
        t = 0.0 if self.time_s is None else self.time_s
        return c.gain * (self.hydraulic(c) + self.coulomb_N(c) * self.friction_column(c)) + c.offset_N \
            + c.drift_N_s * t

    def jacobian(self, c: Candidate) -> np.ndarray:
        """Columns of the measured prediction's change per parameter of ``c``: each nonlinear effect (optimiser
        units, forward differences), the lag, the gain, the Coulomb force, the offset and the drift (those free)."""
        base = self.hydraulic(c)
        names = [n for n in c.effects if n != "friction"]
        x = np.array([c.x[c.effects.index(n)] for n in names])
        cols = []
        for i in range(len(names)):
            step = JAC_STEP * max(1.0, abs(x[i]))
            cols.append(c.gain * (self.hydraulic(c, x + step * np.eye(len(x))[i]) - base) / step)
        fc = self.coulomb_N(c)
        col = self.friction_column(c)
        if c.channel is not None:
            lag = c.channel[1] + LAG_STEP_S
            cols.append(c.gain * (self.hydraulic(c, lag=lag) + fc * self.friction_column(c, lag) - base - fc * col)
                        / LAG_STEP_S)
        if "force_gain" in c.instrument:
            cols.append(base + fc * col)
        if "friction" in c.effects:
            cols.append(c.gain * col)
        if "force_offset" in c.instrument:
            cols.append(np.ones_like(base))
        if DRIFT in c.instrument and self.time_s is not None:
            cols.append(np.asarray(self.time_s, dtype=float))
        return np.column_stack(cols) if cols else np.zeros((base.size, 0))


def nested(a: Reading, b: Reading) -> bool:
    """Whether reading ``a`` is a special case of ``b`` (its effects, instrument terms and channel among b's; an
    LVDT scale's tied terms are one parameter, nested in neither direction)."""
    ca, cb = a.candidate, b.candidate
    return (not a.scale and not b.scale and set(ca.effects) <= set(cb.effects)
            and set(ca.instrument) <= set(cb.instrument) and (ca.channel is None or cb.channel is not None))


# ----------------------------------------------------------------------------------------------------------------
# the criterion
# ----------------------------------------------------------------------------------------------------------------

@dataclass
class PairState:
    """The normal equations of one directed pair (A true, B refitted) over the observations so far (column-scaled):
    M = JᵀJ, b = Jᵀr, rr = rᵀr; Δχ² = rr − bᵀM⁺b."""

    true: int
    refit: int
    scale: np.ndarray
    m: np.ndarray
    b: np.ndarray
    rr: float

    def added(self, r: np.ndarray, jac: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        js = jac / self.scale
        return self.m + js.T @ js, self.b + js.T @ r, self.rr + float(r @ r)

    @staticmethod
    def chi2(m: np.ndarray, b: np.ndarray, rr: float) -> float:
        if not b.size:
            return max(rr, 0.0)
        return max(rr - float(b @ np.linalg.pinv(m, rcond=1e-10, hermitian=True) @ b), 0.0)


def pair_state(true: int, refit: int, old: Sequence[tuple[np.ndarray, np.ndarray]], sigma: np.ndarray) -> PairState:
    """The directed pair's normal equations over the old observations (``old``: each reading's (μ, J))."""
    r = (old[true][0] - old[refit][0]) / sigma
    jac = old[refit][1] / sigma[:, None]
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    scale = np.where(scale > 0.0, scale, 1.0)
    js = jac / scale
    return PairState(true, refit, scale, js.T @ js, js.T @ r, float(r @ r))


def directed_pairs(readings: Sequence[Reading]) -> list[list[tuple[int, int]]]:
    """Per unordered pair of readings, the directions that count: both for non-nested readings (the smaller
    separates), the larger true and the smaller refitted for nested ones."""
    out = []
    for i in range(len(readings)):
        for j in range(i + 1, len(readings)):
            a, b = readings[i], readings[j]
            if nested(a, b):
                out.append([(j, i)])
            elif nested(b, a):
                out.append([(i, j)])
            else:
                out.append([(i, j), (j, i)])
    return out


def jacobian_columns(c: Candidate, has_time: bool) -> list[str]:
    """The names of :meth:`Channel.jacobian`'s columns of ``c``, in order."""
    return ([n for n in c.effects if n != "friction"] + (["force_lag"] if c.channel is not None else [])
            + [t for t in ("force_gain",) if t in c.instrument] + [e for e in ("friction",) if e in c.effects]
            + [t for t in ("force_offset",) if t in c.instrument]
            + ([DRIFT] if DRIFT in c.instrument and has_time else []))


@dataclass
class Correlation:
    """A group the diagnosis lists by a fit correlation (an effect against the force-channel lag or the zero drift,
    beyond CORRELATION_LIMIT, :func:`isokinetic.diagnosis.verdict.instrument_confounding`): the verdict's Fisher
    information over the observations so far (columns scaled), its Jacobian on every probe row (the drift's column
    set when a case runs), the effects' columns and the instrument term's."""

    reading: Reading
    probe_jac: np.ndarray
    fisher: np.ndarray
    scale: np.ndarray
    effects: tuple[int, ...]
    term: int
    drift: bool

    def rho(self, fisher: np.ndarray | None = None) -> float:
        """The largest |correlation| of the effects with the instrument term in the fit."""
        cov = np.linalg.pinv(self.fisher if fisher is None else fisher, rcond=1e-12, hermitian=True)
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        return max(abs(float(cov[e, self.term])) / (d[e] * d[self.term]) for e in self.effects)

    def chi2(self, fisher: np.ndarray | None = None) -> float:
        """The correlation as the plan's separation: TARGET_SE² where it falls to CORRELATION_LIMIT, 0 at 1."""
        rho = min(self.rho(fisher), 1.0)
        return TARGET_SE ** 2 * (1.0 - rho * rho) / (1.0 - CORRELATION_LIMIT ** 2)


@dataclass
class GroupModel:
    """One group's readings, their predictions and Jacobians on the old observations and on every probe row
    (drift parts apart: they depend on when a case runs), and the pairs' states; ``corr`` for a group the diagnosis
    lists by a fit correlation (its separation is then the correlation's, :meth:`Correlation.chi2`)."""

    name: str
    readings: list[Reading]
    probe_mu: list[np.ndarray]
    probe_jac: list[np.ndarray]
    pairs: list[list[PairState]]
    variance_scale: float = 1.0   # the overdispersion ŝ² of partial explanations (none explains): Δχ² in its units
    corr: Correlation | None = None
    credit: float = 0.0   # Δχ² of an independent measurement planned beside the cases (a load-cell calibration)

    def separation(self, states: Sequence | None = None, credited: bool = True) -> float:
        """The group's Δχ²: its least separated pair (each pair its smaller counted direction); of a correlation
        group, the correlation's equivalent (``states``' last member its Fisher information); with ``credit`` unless
        not ``credited`` (added to the least separated pair: it can only understate the sum of a pair's own)."""
        extra = self.credit if credited else 0.0
        if self.corr is not None:
            return self.corr.chi2(None if states is None else states[-1]) + extra
        if states is None:
            states = [[(s.m, s.b, s.rr) for s in pair] for pair in self.pairs]
        return min(min(PairState.chi2(*s) for s in pair) for pair in states) / self.variance_scale + extra


def drift_column(reading: Reading) -> bool:
    return DRIFT in reading.candidate.instrument


def probe_rows(group: GroupModel, k: int, rows: np.ndarray, t_rel: np.ndarray, sigma: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """(μ, J) of reading ``k`` on probe ``rows`` run at campaign times ``t_rel`` (relative to the reference):
    the drift's force and column added."""
    c = group.readings[k].candidate
    mu = group.probe_mu[k][rows] + c.drift_N_s * t_rel
    jac = group.probe_jac[k][rows].copy()
    if drift_column(group.readings[k]) and jac.shape[1]:
        jac[:, -1] = t_rel
    return mu / sigma, jac / sigma[:, None]


def with_case(group: GroupModel, rows: np.ndarray, t_rel: np.ndarray, sigma: np.ndarray) -> list:
    """The pairs' normal equations with one more case's rows (a correlation group: and, last, the verdict's Fisher
    information)."""
    cached = {}
    out: list = []
    for pair in group.pairs:
        states = []
        for s in pair:
            for k in (s.true, s.refit):
                if k not in cached:
                    cached[k] = probe_rows(group, k, rows, t_rel, sigma)
            r = cached[s.true][0] - cached[s.refit][0]
            states.append(s.added(r, cached[s.refit][1]))
        out.append(states)
    if group.corr is not None:
        c = group.corr
        jac = c.probe_jac[rows].copy()
        if c.drift:
            jac[:, -1] = t_rel
        js = jac / sigma[:, None] / c.scale
        out.append(c.fisher + js.T @ js)
    return out


def commit(group: GroupModel, states: Sequence) -> None:
    if group.corr is not None:
        group.corr.fisher = states[-1]
        states = states[:-1]
    for pair, new in zip(group.pairs, states, strict=True):
        for s, (m, b, rr) in zip(pair, new, strict=True):
            s.m, s.b, s.rr = m, b, rr


# ----------------------------------------------------------------------------------------------------------------
# the plan
# ----------------------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ProbeRows:
    """Every candidate's rows: the case each row belongs to, its time after the case's start [s], its σ [N]."""

    case: np.ndarray
    time_s: np.ndarray
    sigma_N: np.ndarray

    def of(self, i: int) -> np.ndarray:
        return np.flatnonzero(self.case == i)


def tied(reading: Reading, jac: np.ndarray) -> np.ndarray:
    """The Jacobian of an LVDT-scale reading (``reading.scale``): its discharge and gain columns merged into one
    of ln k (C_D·√k: ∂x/∂ln k = 1/2; gain 1/k: ∂g/∂ln k = -g); other readings' unchanged."""
    if not reading.scale:
        return jac
    c = reading.candidate
    nonlinear = [n for n in c.effects if n != "friction"]
    i, g = nonlinear.index("discharge"), len(nonlinear) + (c.channel is not None)
    merged = 0.5 * jac[:, i] - c.gain * jac[:, g]
    rest = [k for k in range(jac.shape[1]) if k not in (i, g)]
    return np.column_stack([merged, jac[:, rest]])


def group_model(name: str, readings: list[Reading], old: Channel, probe: Channel,
                variance_scale: float = 1.0, target: tuple | None = None, credit: float = 0.0) -> GroupModel:
    """A group's readings evaluated on the old observations and the probes; ``variance_scale`` the noise's
    overdispersion the group's Δχ² is divided by; ``target`` (:func:`correlation_target`) where the diagnosis lists
    the group by a fit correlation; ``credit`` the Δχ² of a calibration planned beside the cases."""
    olds = [(old.prediction(r.candidate), tied(r, old.jacobian(r.candidate))) for r in readings]
    mus = [probe.prediction(r.candidate) for r in readings]
    jacs = [tied(r, probe.jacobian(r.candidate)) for r in readings]
    sigma = old.dg.obs.sigma_N
    pairs = [[pair_state(i, j, olds, sigma) for i, j in dirs] for dirs in directed_pairs(readings)]
    return GroupModel(name, readings, mus, jacs, pairs, variance_scale,
                      None if target is None else correlation(target, old, probe), credit)


def correlation(target: tuple, old: Channel, probe: Channel) -> Correlation:
    """The verdict's Fisher information over the old observations and its Jacobian on the probes
    (:class:`Correlation`) of a ``target`` (reading, correlated effects, instrument term)."""
    reading, effects, term = target
    c = reading.candidate
    has_time = old.time_s is not None
    names = jacobian_columns(c, has_time)
    jac = old.jacobian(c) / old.dg.obs.sigma_N[:, None]
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    scale = np.where(scale > 0.0, scale, 1.0)
    js = jac / scale
    return Correlation(reading, probe.jacobian(c), js.T @ js, scale, tuple(names.index(e) for e in effects),
                       names.index(term), DRIFT in c.instrument and has_time)


def correlation_target(group: Sequence[str], result: Mapping, ctx: Mapping) -> tuple | None:
    """(the verdict's reading, the effects, the instrument term) where the diagnosis lists ``group`` by a fit
    correlation beyond CORRELATION_LIMIT (``identifiability.lag_correlation`` with the verdict's lag, or
    ``drift_correlation`` with its zero drift), else None: there the plan must bring the correlation down."""
    best = ctx["best"]
    ident = result.get("identifiability") or {}
    if DRIFT in group and DRIFT in best.instrument:
        term, corr = DRIFT, ident.get("drift_correlation") or {}
    elif "force_lag" in group and best.channel is not None:
        term, corr = "force_lag", ident.get("lag_correlation") or {}
    else:
        return None
    effects = tuple(e for e in group if e != term)
    if not effects or not all(e in best.effects and abs(corr.get(e) or 0.0) > CORRELATION_LIMIT for e in effects):
        return None
    return Reading(_label(best, (DRIFT,)), best), effects, term


def greedy_plan(groups: Sequence[GroupModel], probes: Sequence[Probe], rows: ProbeRows, t_end_rel_s: float,
                target_se: float = TARGET_SE, max_cases: int = MAX_CASES, budget_s: float = BUDGET_S) -> list[dict]:
    """The ranked plan: each step the probe adding most to Σ_group min(Δχ², target²) per minute of rig time (at
    least RESOLVES_MIN_CHI2: a case that adds less is not worth its time), until every group reaches the target,
    ``max_cases`` or ``budget_s``. Per step: the probe's index, its start
    [s after the reference time], the groups' Δχ² before and after it."""
    cap = target_se ** 2
    now = [g.separation() for g in groups]
    chosen, plan, used = set(), [], 0.0
    while len(plan) < max_cases and any(d < cap for d in now):
        best = None
        for i, probe in enumerate(probes):
            if i in chosen or used + probe.rig_time_s > budget_s:
                continue
            idx = rows.of(i)
            t_rel = t_end_rel_s + used + rows.time_s[idx]
            states = [with_case(g, idx, t_rel, rows.sigma_N[idx]) for g in groups]
            after = [g.separation(s) for g, s in zip(groups, states, strict=True)]
            gain = sum(min(a, cap) - min(b, cap) for a, b in zip(after, now, strict=True))
            rate = gain / (probe.rig_time_s / 60.0)
            if gain >= RESOLVES_MIN_CHI2 and (best is None or rate > best[0]):   # a case must earn its time
                best = (rate, i, states, after)
        if best is None:
            break
        _rate, i, states, after = best
        for g, s in zip(groups, states, strict=True):
            commit(g, s)
        plan.append({"probe": i, "start_s": t_end_rel_s + used, "before": now, "after": after})
        chosen.add(i)
        used += probes[i].rig_time_s
        now = after
    return plan


def rival_dict(group: str, reading: Reading, force_ref_N: float) -> dict:
    """A rival in diagnosis.json: its label, group, effects, parameters and instrument terms."""
    c = reading.candidate
    return {"label": reading.label, "group": group, "effects": list(c.effects), "params": dict(c.params),
            "instrument": {"force_gain": c.gain if "force_gain" in c.instrument else None,
                           "force_offset_N": c.offset_N if "force_offset" in c.instrument else None,
                           "force_drift_N_s": c.drift_N_s if DRIFT in c.instrument else None,
                           "force_lag_s": None if c.channel is None else c.channel[1],
                           "force_lag_form": None if c.channel is None else LAG_FORM_NAMES[c.channel[0]]}}


def plan_entry(n: int, probe: Probe, step: dict, names: Sequence[str]) -> dict:
    """One case of the plan (the agreed shape, with its label and each group's marginal separation)."""
    plan = probe.plan
    gains = {g: b - a for g, a, b in zip(names, step["before"], step["after"], strict=True)}
    resolves = [g for g, d in gains.items() if d >= RESOLVES_MIN_CHI2]
    triangle = plan.waveform == "triangle"
    return {"case": f"N{n:02d}", "waveform": plan.waveform,
            "velocity_m_s": plan.velocity_m_s if triangle else None, "amplitude_m": plan.amplitude_m,
            "period_s": plan.period_s if triangle else None, "frequency_Hz": None if triangle else plan.frequency_Hz,
            "periods": 2 if triangle else int(round(plan.duration_s * plan.frequency_Hz)),
            "sample_rate_Hz": plan.sample_rate_Hz, "duration_s": plan.duration_s,
            "rig_time_s": probe.rig_time_s, "resolves": resolves,
            "separation_se": math.sqrt(max(max(gains.values()), 0.0)) if gains else 0.0,
            "separation_se_by_group": {g: math.sqrt(max(d, 0.0)) for g, d in gains.items()}, "label": probe.label}


def overdispersion_of(candidates) -> float:
    """ŝ² of readings none of which need explain: the smallest χ²_fit/dof among them, at least 1 (as
    :func:`isokinetic.diagnosis.candidate.overdispersed_score` takes it): where the readings leave misfit the noise
    model does not describe, a χ² difference counts in that unit."""
    return max(1.0, min(c.chi2_fit / max(c.n_fit - c.k, 1) for c in candidates))


def contexts_groups(result: Mapping, ctx: Mapping) -> tuple[list[tuple[str, list[Reading]]], dict, dict, dict]:
    """(group name, readings) of each confounded group, and of the partial explanations within the margin of an
    unexplained verdict; {group: why no case separates it}; {group: its overdispersion ŝ²}
    (:func:`overdispersion_of` its readings; partial explanations: of every candidate); {group: its correlation
    target} (:func:`correlation_target`)."""
    out, unresolvable, overdispersion, targets = [], {}, {}, {}
    ctx = {**ctx, "gain_needed": (result.get("instrument") or {}).get("force_gain") is not None}
    for group in result.get("confounded") or []:
        name = "+".join(group)
        readings = group_readings(group, ctx)
        if isinstance(readings, str):
            unresolvable[name] = readings
        elif all(name != n for n, _ in out):
            out.append((name, readings))
            overdispersion[name] = overdispersion_of(r.candidate for r in readings)
            target = correlation_target(group, result, ctx)
            if target is not None:
                targets[name] = target
    if not result.get("confounded") and not result.get("explained", True) and result.get("verdict") \
            and ctx.get("candidates"):   # partial explanations of a named verdict (none named: outside the catalogue)
        partial = partial_readings(ctx["best"], ctx["candidates"])
        if partial:
            name = "+".join(sorted({e for r in partial for e in r.candidate.effects}, key=_order))
            out.append((name, partial))
            overdispersion[name] = overdispersion_of(ctx["candidates"])
    return out, unresolvable, overdispersion, targets


def next_tests(result: Mapping, ctx: Mapping | None, damper: Damper, spec: WindowSpec = DEFAULTS.window,
               n_bins: int = 4, design: DesignLimits = DEFAULTS.design, declared: Mapping | None = None) -> dict:
    """The ``next_tests`` block of diagnosis.json (contract 1.6) for a diagnosis ``result`` and its fits ``ctx``
    (:func:`isokinetic.diagnosis.verdict.diagnose_observations`' ``predictions['fits']``): the load-cell calibration
    that separates its gain groups and the LVDT's of its scale groups
    (:func:`isokinetic.diagnosis.next_calibration.proposals`, credited to them first), then the cases; the rig time
    of both."""
    started = time.perf_counter()
    groups, unresolvable, overdispersion, targets = ([], {}, {}, {}) if ctx is None else contexts_groups(result, ctx)
    if not groups and not unresolvable:
        return {"needed": False, "note": NO_PLAN_NOTE, "plan": []}
    family = scale_family(unresolvable, ctx)
    calibrations, credits, why_not = proposals(groups, family, declared_calibration(ctx["dg"].obs),
                                               declared_lvdt(result))
    block = {"needed": True, "criterion": CRITERION, "target_se": TARGET_SE, "rivals": [], "plan": [],
             "calibrations": calibrations, "separation_se": {}, "unresolvable": unresolvable}
    if groups:
        block.update(planned(groups, ctx, damper, spec, n_bins, design, declared, overdispersion, targets, credits))
    block["separation_se"].update({g: math.sqrt(credits[g]) for g, _ in family if g in credits})   # no case adds
    block["total_rig_time_s"] = float(sum(e["rig_time_s"] for e in (*block["plan"], *calibrations)))
    block["note"] = plan_note(block, why_not)
    block["seconds"] = round(time.perf_counter() - started, 3)
    return block


def scale_family(unresolvable: Mapping[str, str], ctx: Mapping) -> list[tuple[str, list[Reading]]]:
    """The LVDT-scale groups no case separates (SCALE_REASON) as the readings an LVDT calibration tells apart: the
    verdict (the LVDT's scale 1) against the scale, whose k is 1/g of the verdict's fitted gain g (nothing to fit)."""
    best = ctx["best"]
    return [(g, [Reading(_label(best, ("force_gain",)), best), Reading("displacement_scale", best, scale=True)])
            for g, why in unresolvable.items() if why == SCALE_REASON]


def planned(groups: Sequence[tuple[str, list[Reading]]], ctx: Mapping, damper: Damper, spec: WindowSpec,
            n_bins: int, design: DesignLimits, declared: Mapping | None, overdispersion: Mapping | None = None,
            targets: Mapping | None = None, credits: Mapping | None = None) -> dict:
    """The plan's keys (rivals, plan, separations, limits) of the groups that cases can separate; ``credits``: the
    Δχ² a calibration adds to a group, counted before the cases are chosen (in ``separation_se``, not in
    ``separation_se_now``, the campaign's own)."""
    dg: Diagnoser = ctx["dg"]
    obs = dg.obs
    limits = rig_limits(obs, damper, design, declared)
    effects = [dg.param.effects([n for n in r.candidate.effects if n != "friction"],
                                [r.candidate.x[r.candidate.effects.index(n)] for n in r.candidate.effects
                                 if n != "friction"]) for _, rs in groups for r in rs]
    probes = candidate_cases(obs, damper, limits, effects, spec, n_bins, design.convergence_fraction)
    if not probes:
        return {"rivals": [rival_dict(name, r, dg.param.force_ref_N) for name, rs in groups for r in rs],
                "candidates_considered": 0, "limits": limits_dict(limits, design)}
    scale = float(np.median(obs.viscosity_scale)) if obs.viscosity_scale else 1.0
    # the model runs the candidates on a grid of at most MODEL_RATE_HZ (their means are integrals over the same
    # times); each mean's noise is that of the rig's samples
    model = [replace(p, plan=replace(p.plan, sample_rate_Hz=min(p.plan.sample_rate_Hz, MODEL_RATE_HZ))) for p in probes]
    pobs = probe_observations(obs.campaign, model, spec, n_bins, scale) if probes[0].plan.waveform == "triangle" \
        else sine_probe_observations(obs.campaign, model, N_SINE_BINS, scale)
    fs = limits.sample_rate_Hz
    model_fs = np.array([p.sample_rate_Hz for p in pobs.plans])[pobs.case_index]
    rig_fs = np.array([p.plan.sample_rate_Hz for p in probes])[pobs.case_index]
    probe_ch = Channel(Evaluator(pobs, damper), None if dg.time_s is None else np.zeros(len(pobs)), dg)
    old_ch = Channel(dg.evaluator, dg.time_s, dg)
    models = [group_model(name, rs, old_ch, probe_ch, (overdispersion or {}).get(name, 1.0), (targets or {}).get(name),
                          (credits or {}).get(name, 0.0)) for name, rs in groups]
    own = [m.separation(credited=False) for m in models]
    rho_now = {m.name: m.corr.rho() for m in models if m.corr is not None}
    verdict_mu = models[0].probe_mu[0]
    n = np.round((pobs.stop - pobs.start) * rig_fs / model_fs)
    sigma = np.sqrt(mean_variance_N2(obs.noise, fs, n, verdict_mu) + (obs.rep_rel * verdict_mu) ** 2)
    row_case = pobs.case_index
    row_time = 0.5 * (pobs.start + pobs.stop) / model_fs
    peak = np.zeros(len(probes))
    for m in models:
        for mu in m.probe_mu:
            np.maximum.at(peak, row_case, np.abs(mu))
    usable = peak <= limits.max_force_N
    rows = ProbeRows(np.where(usable[row_case], row_case, -1), row_time, sigma)
    t_end = 0.0 if dg.time_s is None else float(np.max(dg.time_s))
    steps = greedy_plan(models, probes, rows, t_end)
    names = [m.name for m in models]
    plan = [plan_entry(k, probes[s["probe"]], s, names) for k, s in enumerate(steps, start=1)]
    final = steps[-1]["after"] if steps else [m.separation() for m in models]
    return {"rivals": [rival_dict(m.name, r, dg.param.force_ref_N) for m in models for r in m.readings],
            "plan": plan, "separation_se": {g: math.sqrt(max(d, 0.0)) for g, d in zip(names, final, strict=True)},
            "separation_se_now": {g: math.sqrt(max(d, 0.0)) for g, d in zip(names, own, strict=True)},
            "candidates_considered": int(usable.sum()),
            "correlation": {m.name: {"now": rho_now[m.name], "plan": m.corr.rho(), "limit": CORRELATION_LIMIT}
                            for m in models if m.corr is not None},
            "limits": limits_dict(limits, design)}


def limits_dict(limits: RigLimits, design: DesignLimits) -> dict:
    """The rig's limits the candidates kept to (``next_tests.limits``), with where each came from."""
    return {"max_speed_m_s": limits.max_speed_m_s, "min_amplitude_m": limits.min_amplitude_m,
            "max_amplitude_m": limits.max_amplitude_m, "max_force_N": limits.max_force_N,
            "max_frequency_Hz": limits.max_frequency_Hz, "sample_rate_Hz": limits.sample_rate_Hz,
            "convergence_fraction": design.convergence_fraction, "max_case_s": MAX_CASE_S, "budget_s": BUDGET_S,
            "setup_s": SETUP_S, "source": limits.source}


def advice(group: str) -> str:
    """The sensor check that decides a group cases cannot separate ('' for a group of damper effects alone)."""
    members = group.split("+")
    return next((what for term, what in ADVICE if term in members), "")


def plan_note(block: Mapping, calibration_why: Mapping | None = None) -> str:
    """One line: what the plan does (or why there is none): the calibration proposed first (``calibrations``), then
    the cases; a gain or LVDT-scale group gets no advice in words where a calibration entry or ``calibration_why``
    (why none is proposed) speaks for it."""
    target = block["target_se"]
    done = [g for g, se in (block.get("separation_se_now") or {}).items() if se >= target]
    parts = [f"{g}: the campaign's own data already separate the rivals ({block['separation_se_now'][g]:.1f} SE)"
             for g in done]
    calibrations = block.get("calibrations") or []
    parts += [calibration_text(c) for c in calibrations]
    told = {g for c in calibrations for g in c["resolves"]} | set(calibration_why or {})
    final = block["separation_se"]
    if block["plan"]:
        short = [g for g, se in final.items() if se < target]
        minutes = (block["total_rig_time_s"] - sum(c["rig_time_s"] for c in calibrations)) / 60.0   # the cases'
        parts.append(f"{len(block['plan'])} case(s), {minutes:.1f} min of rig time, "
                     + ("with the calibration" + "s" * (len(calibrations) > 1) + " " if calibrations else "")
                     + "separate "
                     + ", ".join(f"{g} by {se:.1f} SE" for g, se in final.items())
                     + (f" (short of {target:g} SE: {', '.join(short)})" if short else ""))
        parts += [f"{g}: {advice(g)} to decide" for g in short if advice(g) and g not in told]
    elif left := [g for g, se in final.items() if g not in done and se < target and g not in block["unresolvable"]]:
        parts.append("no candidate case within the rig's limits adds to the separation of " + ", ".join(left))
        parts += [f"{g}: {advice(g)} to decide" for g in left if advice(g) and g not in told]
    elif block.get("candidates_considered") == 0:
        parts.append("no candidate case lies within the rig's limits and the design constraints")
    parts += [f"{g}: {why}" for g, why in {**block["unresolvable"], **(calibration_why or {})}.items()]
    return "; ".join(parts)
