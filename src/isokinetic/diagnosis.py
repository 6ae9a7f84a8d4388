"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect causes it, how far it shrinks.

Output contract: shared/spec/diagnosis-output.md (schema: workflow/schemas/diagnosis.schema.json).

Data. The *observations* of a campaign are, for every status-ok triangle case and each of its four
half-periods, the steady window of the characteristic (mean force over [start, end]·T/2) and
``n_bins`` *transient bins* that split the part before the window, [0, start]·T/2, into equal
times (the relaxation after each velocity reversal that the windows leave out). Each observation
has a standard error σ: for a window, the window's force standard deviation over √n; for a bin,
the standard deviation of its segment's window over √n_bin (the force noise there is at most the
window's, which sits at the segment's largest |F|); both combined with a repeatability term
``rep_rel·|F|``, the period-to-period scatter beyond window noise pooled over the campaign (the
median over case/direction pairs, so that a few pairs whose periods differ for physical reasons,
e.g. a first half-period that starts from rest, do not inflate it).

Model. The nominal damper of ``campaign.json`` (no effects) simulated noise-free through the
same cases on the plan's sample grid (k/fs), reduced over the same sample ranges; a candidate adds
effects with fitted parameters. Simulation: :func:`virtual_rig.triangle_responses` (Eq. 13-14).

Gap metric ``rms_z``. Root mean square over the characteristic points (windows) of
z = (F_measured - F_model)/σ. A model that explains the data to within noise gives rms_z ≈ 1.

Candidates. Each effect of :data:`EFFECTS` alone (one parameter each), every pair, then, while
nothing explains, the :data:`BEAM` best candidates of the largest size extended by one more effect. Each is fitted with bounded
least squares (scipy ``least_squares``, 'trf') on the period-1 observations (segments 1-2, windows
and transient bins) and scored on period 2 (segments 3-4), which the fit did not see:
``score`` = χ²(period 2) + k·ln(n_fit) (lower is better; k parameters). A candidate *explains* the
gap when both its fit χ² (n_fit - k degrees of freedom) and its holdout χ² (n_holdout) are
consistent with noise at level ``alpha``. The verdict is the smallest explaining set with the
best score; ``[]`` when the nominal model already explains all observations. Explaining
candidates of the verdict's size whose score is within ``CONFOUNDED_SCORE`` of the best are listed
as ``confounded``: the data cannot tell them apart. Identifiability of the verdict's parameters is
reported from the Fisher information JᵀJ of the fit (standard errors, correlation). When no
candidate explains the gap, the verdict is the candidate with the best overdispersed score
(:func:`overdispersed_score`), ``explained`` is false and a note says the gap lies outside the
catalogue.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import optimize, stats

from .campaign import case_plan
from .damper import AIR_COMPRESSIBILITY_1_PA, NOMINAL, Damper, Effects, friction_force, laminar_coefficient
from .plan import CasePlan
from .virtual_rig import Hydraulics, triangle_responses
from .windows import WindowSpec, windowed_half_periods

log = logging.getLogger("isokinetic.diagnosis")

FORMAT_VERSION = 1
METRIC = "rms_z"
#: The candidate effects, in the contract's names.
EFFECTS = ("friction", "leakage", "asymmetry", "discharge", "viscosity", "air")
#: Significance level: a χ² with a smaller p-value is not noise.
ALPHA = 1e-3
#: Score difference (χ² units) within which two explaining candidates count as confounded.
CONFOUNDED_SCORE = 10.0
#: Relative tolerance on cost and parameters at which a fit stops: 1e-6 of a parameter is far
#: below its statistical uncertainty, and the χ² changes by less than 1e-6 of itself.
FIT_TOL = 1e-6
#: Candidates of each size extended by one more effect while nothing explains the gap.
BEAM = 3
#: |z| of a characteristic point beyond which it is not explained by noise (for ``where``).
Z_SIGNIFICANT = 3.0
SCHEMA_PATH = Path(__file__).resolve().parents[2] / "workflow" / "schemas" / "diagnosis.schema.json"
#: Inputs of a diagnosis, relative to results/<campaign>/ (named in its ``sources`` key).
CHARACTERISTIC_FILE = "characteristic.parquet"
CASES_FILE = "cases.parquet"


# ----------------------------------------------------------------------------------------------
# observations
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Observations:
    """Measured window and transient-bin means of a campaign, with the model's sample ranges."""

    campaign: str
    plans: tuple[CasePlan, ...]   # simulated plans, cut to the last sample needed
    case: np.ndarray              # case id per observation
    case_index: np.ndarray        # index into plans
    kind: np.ndarray              # 'window' | 'transient'
    segment: np.ndarray
    period: np.ndarray
    sign: np.ndarray              # +1 / -1 (direction)
    speed_m_s: np.ndarray         # planned |W|
    start: np.ndarray             # model sample range [start, stop) within the case
    stop: np.ndarray
    force_N: np.ndarray
    sigma_N: np.ndarray
    rep_rel: float                # pooled relative repeatability scatter

    def __len__(self) -> int:
        return int(self.force_N.size)

    @property
    def is_window(self) -> np.ndarray:
        return self.kind == "window"

    def subset(self, mask: np.ndarray) -> "Observations":
        """The observations where ``mask``; each plan cut to the last sample they need."""
        keep = np.flatnonzero(mask)
        used = sorted(set(self.case_index[keep].tolist()))
        remap = {old: new for new, old in enumerate(used)}
        plans = []
        for old in used:
            rows = keep[self.case_index[keep] == old]
            plan = self.plans[old]
            plans.append(replace(plan, duration_s=int(self.stop[rows].max()) / plan.sample_rate_Hz))
        fields = {name: getattr(self, name)[keep] for name in ("case", "kind", "segment", "period", "sign",
                                                               "speed_m_s", "start", "stop", "force_N", "sigma_N")}
        return Observations(campaign=self.campaign, plans=tuple(plans), rep_rel=self.rep_rel,
                            case_index=np.array([remap[i] for i in self.case_index[keep]], dtype=np.int64),
                            **fields)


def repeatability_scatter(char: pd.DataFrame) -> float:
    """Pooled relative period-to-period scatter beyond window noise (one measurement, 1 σ).

    For each case and direction q = (d² - se1² - se2²) / (2 F̄²), d = F2 - F1, se = std/√n;
    returns sqrt(max(0, median q)).
    """
    if char.empty:
        return 0.0
    se = char["force_std_N"] / np.sqrt(char["n_samples"])
    wide = char.assign(se=se).pivot_table(index=["case", "direction"], columns="period",
                                          values=["force_N", "se"], aggfunc="first").dropna()
    if wide.empty:
        return 0.0
    d = wide[("force_N", 2)] - wide[("force_N", 1)]
    mean = 0.5 * (wide[("force_N", 1)].abs() + wide[("force_N", 2)].abs())
    q = (d**2 - wide[("se", 1)] ** 2 - wide[("se", 2)] ** 2) / (2.0 * mean**2)
    return float(math.sqrt(max(0.0, float(np.median(q)))))


def build_observations(campaign: str, cases: pd.DataFrame, char: pd.DataFrame,
                       load_series: Callable[[pd.Series], pd.DataFrame], spec: WindowSpec = WindowSpec(),
                       n_bins: int = 4) -> Observations:
    """Windows (from the characteristic) and transient bins (from the series) of every triangle case."""
    rep_rel = repeatability_scatter(char)
    by_case = {c: g.set_index("segment") for c, g in char.groupby("case")}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle") & cases["case"].isin(by_case)]
    cols: dict[str, list] = {k: [] for k in ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s",
                                             "start", "stop", "force_N", "sigma_N")}
    plans = []
    for _, row in ok.iterrows():
        plan = case_plan(row)
        series = load_series(row)
        t = series["time_s"].to_numpy()
        f = series["force_N"].to_numpy()
        fs = plan.sample_rate_Hz
        half = plan.period_s / 2.0
        segs = windowed_half_periods(plan, float(t[-1]), spec)
        win = by_case[plan.case]
        last = 0

        def add(kind, k, sign, i0, i1, force, sigma):
            cols["case"].append(plan.case)
            cols["case_index"].append(len(plans))
            cols["kind"].append(kind)
            cols["segment"].append(k)
            cols["period"].append((k + 1) // 2)
            cols["sign"].append(sign)
            cols["speed_m_s"].append(plan.velocity_m_s)
            cols["start"].append(i0)
            cols["stop"].append(i1)
            cols["force_N"].append(force)
            cols["sigma_N"].append(sigma)

        for k, (t0, _t1, sign) in enumerate(segs, start=1):
            w = win.loc[k]
            noise = float(w["force_std_N"])
            i0 = int(round(float(w["window_start_s"]) * fs))
            i1 = int(round(float(w["window_end_s"]) * fs)) + 1
            add("window", k, sign, i0, i1, float(w["force_N"]),
                math.hypot(noise / math.sqrt(float(w["n_samples"])), rep_rel * float(w["force_N"])))
            last = max(last, i1)
            edges = t0 + np.linspace(0.0, spec.start_fraction * half, n_bins + 1)
            for a, b in zip(edges[:-1], edges[1:]):
                m0, m1 = np.searchsorted(t, a, side="left"), np.searchsorted(t, b, side="left")
                j0, j1 = int(math.ceil(a * fs - 1e-9)), int(math.ceil(b * fs - 1e-9))
                if m1 - m0 < 2 or j1 - j0 < 2:
                    continue
                mean = float(f[m0:m1].mean())
                add("transient", k, sign, j0, j1, mean, math.hypot(noise / math.sqrt(m1 - m0), rep_rel * mean))
        plans.append(replace(plan, duration_s=last / fs))
    ints = ("case_index", "segment", "period", "start", "stop")
    arrays = {k: np.asarray(v, dtype=np.int64 if k in ints else (object if k in ("case", "kind") else float))
              for k, v in cols.items()}
    return Observations(campaign=campaign, plans=tuple(plans), rep_rel=rep_rel, **arrays)


class Evaluator:
    """Noise-free model means over the observations' sample ranges, for any effects."""

    def __init__(self, obs: Observations, damper: Damper):
        self.obs = obs
        self.damper = damper
        sizes = np.array([int(round(p.duration_s * p.sample_rate_Hz)) + 1 for p in obs.plans], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes + 1)])  # +1: a leading zero per case in the cumsum
        self._lo = offsets[obs.case_index] + obs.start
        self._hi = offsets[obs.case_index] + obs.stop
        self._n = (obs.stop - obs.start).astype(float)
        self.calls = 0

    def predict(self, effects: Effects = NOMINAL) -> np.ndarray:
        """Model mean force of every observation [N] (Eq. 8 with Δp from Eq. 13-14)."""
        self.calls += 1
        hyd = Hydraulics.from_damper(self.damper, effects)
        parts = []
        for _t, dp, vel in triangle_responses(self.obs.plans, hyd, 0.0):
            force = hyd.piston_area_m2 * dp + friction_force(vel, effects)
            parts.append(np.concatenate([[0.0], np.cumsum(force)]))
        cs = np.concatenate(parts)
        return (cs[self._hi] - cs[self._lo]) / self._n


# ----------------------------------------------------------------------------------------------
# candidate parameters
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Parametrisation:
    """Optimiser units of each effect's parameter, scaled to order one for this campaign.

    friction: F_C / F_ref (F_ref median |F| of the windows); leakage: g·c1 (leakage relative to the
    orifice's laminar conductance); asymmetry: a; discharge, viscosity: ln(θ/θ_nominal);
    air: V_G/V_C · β_air/β_oil (air compressibility relative to the oil's).
    """

    damper: Damper
    force_ref_N: float

    @property
    def _c1(self) -> float:
        return float(laminar_coefficient(self.damper))

    @property
    def _air_ratio(self) -> float:
        return AIR_COMPRESSIBILITY_1_PA / self.damper.oil_compressibility_1_Pa

    def bounds(self, effect: str) -> tuple[float, float]:
        return {"friction": (0.0, 20.0), "leakage": (0.0, 1.0e3), "asymmetry": (-0.9, 0.9),
                "discharge": (math.log(0.1), math.log(10.0)), "viscosity": (math.log(0.02), math.log(50.0)),
                "air": (0.0, 0.5 * AIR_COMPRESSIBILITY_1_PA / self.damper.oil_compressibility_1_Pa)}[effect]

    def starts(self, effect: str) -> list[float]:
        """Starting points of a single-effect fit (two, to avoid a local minimum)."""
        return {"friction": [0.01, 0.3], "leakage": [0.05, 3.0], "asymmetry": [0.02, -0.02],
                "discharge": [0.2, -0.2], "viscosity": [0.2, -0.2], "air": [0.05, 5.0]}[effect]

    def si(self, effect: str, x: float) -> tuple[str, float]:
        """(SI parameter name, value) of an optimiser value."""
        d = self.damper
        return {"friction": ("coulomb_force_N", x * self.force_ref_N),
                "leakage": ("leakage_conductance_m3_s_Pa", x / self._c1),
                "asymmetry": ("asymmetry", x),
                "discharge": ("discharge_coefficient", d.discharge_coefficient * math.exp(x)),
                "viscosity": ("viscosity_Pa_s", d.viscosity_Pa_s * math.exp(x)),
                "air": ("air_volume_fraction", x / self._air_ratio)}[effect]

    def effects(self, names: Sequence[str], x: Sequence[float]) -> Effects:
        return Effects(**dict(self.si(n, v) for n, v in zip(names, x)))


# ----------------------------------------------------------------------------------------------
# fitting and scoring
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Candidate:
    effects: tuple[str, ...]
    x: np.ndarray
    params: dict
    prediction: np.ndarray
    chi2_fit: float
    chi2_holdout: float
    n_fit: int
    n_holdout: int
    gap_after: float
    holdout_gap_after: float
    score: float
    explained: bool
    jacobian: np.ndarray

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "params": self.params, "gap_after": self.gap_after,
                "holdout_gap_after": self.holdout_gap_after, "score": self.score, "explained": self.explained,
                "chi2_fit": self.chi2_fit, "chi2_holdout": self.chi2_holdout, "n_fit": self.n_fit,
                "n_holdout": self.n_holdout}


def rms(z: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(z)))) if z.size else float("nan")


def consistent_with_noise(chi2: float, dof: int, alpha: float = ALPHA) -> bool:
    """χ² test: True when a χ² this large has probability >= alpha under noise alone."""
    return dof > 0 and float(stats.chi2.sf(chi2, dof)) >= alpha


class Diagnoser:
    """Fits and scores candidate effect sets on one campaign's observations."""

    def __init__(self, obs: Observations, damper: Damper, alpha: float = ALPHA):
        self.obs = obs
        self.evaluator = Evaluator(obs, damper)
        self.alpha = alpha
        windows = np.abs(obs.force_N[obs.is_window])
        self.param = Parametrisation(damper, float(np.median(windows)) if windows.size else 1.0)
        self.fit_mask = obs.period == 1
        self.hold_mask = obs.period == 2
        self.fit_obs = obs.subset(self.fit_mask)   # period 1: simulated only up to its last sample
        self.fit_evaluator = Evaluator(self.fit_obs, damper)
        self.nominal = self.evaluator.predict(NOMINAL)

    def z(self, prediction: np.ndarray) -> np.ndarray:
        return (self.obs.force_N - prediction) / self.obs.sigma_N

    def _residuals(self, names: Sequence[str]):
        obs = self.fit_obs

        def fun(x):
            return (obs.force_N - self.fit_evaluator.predict(self.param.effects(names, x))) / obs.sigma_N
        return fun

    def fit(self, names: Sequence[str], starts: Sequence[Sequence[float]]) -> Candidate:
        """Best of bounded least-squares fits from the given starting points."""
        lower, upper = zip(*(self.param.bounds(n) for n in names))
        fun = self._residuals(names)
        best = None
        for x0 in starts:
            x0 = np.clip(np.asarray(x0, dtype=float), np.asarray(lower) + 1e-12, np.asarray(upper) - 1e-12)
            try:
                res = optimize.least_squares(fun, x0, bounds=(lower, upper), method="trf", x_scale="jac",
                                             diff_step=1e-6, ftol=FIT_TOL, xtol=FIT_TOL, max_nfev=60 * len(names))
            except (ValueError, FloatingPointError) as exc:  # e.g. a stroke that empties a chamber
                log.warning("campaign %s: fit of %s from %s failed: %s", self.obs.campaign, names, x0, exc)
                continue
            if best is None or res.cost < best.cost:
                best = res
        if best is None:
            raise RuntimeError(f"campaign {self.obs.campaign}: no fit of {list(names)} converged")
        return self._score(tuple(names), best.x, best.jac)

    def _score(self, names: tuple[str, ...], x: np.ndarray, jac: np.ndarray) -> Candidate:
        pred = self.evaluator.predict(self.param.effects(names, x))
        z = self.z(pred)
        win = self.obs.is_window
        chi2_fit = float(np.sum(z[self.fit_mask] ** 2))
        chi2_hold = float(np.sum(z[self.hold_mask] ** 2))
        n_fit, n_hold, k = int(self.fit_mask.sum()), int(self.hold_mask.sum()), len(names)
        explained = (consistent_with_noise(chi2_fit, n_fit - k, self.alpha)
                     and consistent_with_noise(chi2_hold, n_hold, self.alpha))
        return Candidate(effects=names, x=np.asarray(x, dtype=float),
                         params=dict(self.param.si(n, float(v)) for n, v in zip(names, x)),
                         prediction=pred, chi2_fit=chi2_fit, chi2_holdout=chi2_hold, n_fit=n_fit, n_holdout=n_hold,
                         gap_after=rms(z[win & self.fit_mask]), holdout_gap_after=rms(z[win & self.hold_mask]),
                         score=chi2_hold + k * math.log(n_fit), explained=explained, jacobian=np.asarray(jac))

    def nominal_explains(self) -> bool:
        z = self.z(self.nominal)
        return consistent_with_noise(float(np.sum(z**2)), len(z), self.alpha)

    def search(self) -> list[Candidate]:
        """Singles, pairs (warm-started from the singles), then greedy extension while nothing explains."""
        singles = {e: self.fit((e,), [[s] for s in self.param.starts(e)]) for e in EFFECTS}
        found = list(singles.values())
        for a, b in itertools.combinations(EFFECTS, 2):
            found.append(self.fit((a, b), [[singles[a].x[0], singles[b].x[0]]]))
        size = 2
        while not any(c.explained for c in found) and size < len(EFFECTS):
            bases = sorted((c for c in found if len(c.effects) == size), key=lambda c: c.score)[:BEAM]
            tried = set()
            for base in bases:
                for e in EFFECTS:
                    names = tuple(n for n in EFFECTS if n in base.effects or n == e)
                    if e in base.effects or names in tried:
                        continue
                    tried.add(names)
                    x0 = [base.x[base.effects.index(n)] if n in base.effects else singles[n].x[0] for n in names]
                    found.append(self.fit(names, [x0]))
            size += 1
        return sorted(found, key=lambda c: (not c.explained, len(c.effects) if c.explained else 0, c.score))


def overdispersed_score(candidate: Candidate, candidates: Sequence[Candidate]) -> float:
    """Quasi-likelihood score when nothing fits within noise: χ²_holdout / ŝ² + k ln n_fit.

    ŝ² = min over candidates of χ²_fit/(n_fit - k), the noise inflation that the best model needs.
    """
    s2 = min(c.chi2_fit / max(c.n_fit - len(c.effects), 1) for c in candidates)
    return candidate.chi2_holdout / max(s2, 1.0) + len(candidate.effects) * math.log(candidate.n_fit)


def identifiability(candidate: Candidate, param: Parametrisation) -> dict:
    """Standard errors (SI) and correlation of the parameters from the Fisher information JᵀJ."""
    jac = candidate.jacobian
    info = jac.T @ jac
    try:
        cov = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return {"identifiable": False, "reason": "singular Fisher information"}
    out: dict = {"identifiable": True, "parameters": {}}
    for i, name in enumerate(candidate.effects):
        x, sx = float(candidate.x[i]), float(math.sqrt(max(cov[i, i], 0.0)))
        key, value = param.si(name, x)
        _, shifted = param.si(name, x + sx)
        out["parameters"][key] = {"estimate": value, "std_error": abs(shifted - value),
                                  "relative_std_error": abs(shifted - value) / abs(value) if value else None}
    if len(candidate.effects) > 1:
        d = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        corr = cov / np.outer(d, d)
        out["correlation"] = {f"{a}~{b}": float(corr[i, j])
                              for (i, a), (j, b) in itertools.combinations(enumerate(candidate.effects), 2)}
    return out


# ----------------------------------------------------------------------------------------------
# where the gap lies
# ----------------------------------------------------------------------------------------------

def gap_bands(obs: Observations, prediction: np.ndarray, z_significant: float = Z_SIGNIFICANT) -> list[dict]:
    """Contiguous runs of characteristic points (per direction, ordered by speed) alike in significance
    and, for significant points, in sign.

    A point is significant when |z| > z_significant; each band gives its speed range (positive,
    the direction names the quadrant), the mean signed relative error of the force magnitude,
    sign(v)(F_meas - F_model)/|F_meas| (negative: the damper is weaker than the model), and the
    mean z. Both periods' points are pooled per case.
    """
    win = obs.is_window
    df = pd.DataFrame({"case": obs.case[win], "sign": obs.sign[win], "speed": obs.speed_m_s[win],
                       "force": obs.force_N[win], "model": prediction[win], "sigma": obs.sigma_N[win]})
    df["z"] = (df["force"] - df["model"]) / df["sigma"]
    df["rel"] = df["sign"] * (df["force"] - df["model"]) / df["force"].abs()  # < 0: measured weaker
    per_case = df.groupby(["sign", "case"], as_index=False).agg(speed=("speed", "first"), z=("z", "mean"),
                                                               rel=("rel", "mean"))
    bands = []
    for sign, group in per_case.groupby("sign"):
        group = group.sort_values("speed")
        state = [(True, int(np.sign(zv))) if abs(zv) > z_significant else (False, 0) for zv in group["z"]]
        run_start = 0
        for i in range(1, len(group) + 1):
            if i == len(group) or state[i] != state[run_start]:
                part = group.iloc[run_start:i]
                bands.append({"direction": "+" if sign > 0 else "-", "v_min_m_s": float(part["speed"].min()),
                              "v_max_m_s": float(part["speed"].max()), "mean_rel_error": float(part["rel"].mean()),
                              "mean_z": float(part["z"].mean()), "n_cases": int(len(part)),
                              "significant": state[run_start][0]})
                run_start = i
    return bands


# ----------------------------------------------------------------------------------------------
# the stage
# ----------------------------------------------------------------------------------------------

def _json_number(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(float(x)) else None


def diagnose_observations(obs: Observations, damper: Damper, alpha: float = ALPHA) -> tuple[dict, dict]:
    """The diagnosis dict of the contract, and the predictions (nominal, verdict) for figures."""
    started = time.perf_counter()
    dg = Diagnoser(obs, damper, alpha)
    win = obs.is_window
    z_nom = dg.z(dg.nominal)
    gap_before = rms(z_nom[win])
    out = {"format_version": FORMAT_VERSION, "campaign": obs.campaign, "status": "ok", "metric": METRIC,
           "gap_before": gap_before, "where": [b for b in gap_bands(obs, dg.nominal) if b["significant"]],
           "noise": {"repeatability_rel": obs.rep_rel, "n_windows": int(win.sum()),
                     "n_transient_bins": int((~win).sum()), "alpha": alpha},
           "rms_rel_before": rms(((obs.force_N - dg.nominal) / np.abs(obs.force_N))[win])}
    nominal_ok = dg.nominal_explains()
    candidates = dg.search()
    out["candidates"] = [c.to_dict() for c in candidates]
    explaining = [c for c in candidates if c.explained]
    if nominal_ok:
        verdict, best = [], None
        out.update(verdict=[], explained=True, gap_after=gap_before,
                   holdout_gap_after=rms(z_nom[win & dg.hold_mask]), shrink=1.0)
    else:
        best = explaining[0] if explaining else min(candidates, key=lambda c: overdispersed_score(c, candidates))
        verdict = list(best.effects)
        if not explaining:
            out["unexplained_note"] = (
                "no candidate of the catalogue explains the gap within noise: the verdict is the candidate "
                "with the best overdispersed score (χ² divided by the smallest achievable χ²/dof, plus "
                "k ln n); the remaining gap points to an effect outside the catalogue (for example backlash, "
                "fixture or servo compliance, or a flow path of another form)")
        out.update(verdict=verdict, explained=best.explained, gap_after=best.gap_after,
                   holdout_gap_after=best.holdout_gap_after, params=best.params,
                   shrink=gap_before / best.gap_after if best.gap_after > 0 else None,
                   rms_rel_after=rms(((obs.force_N - best.prediction) / np.abs(obs.force_N))[win]),
                   identifiability=identifiability(best, dg.param))
        rivals = [c for c in explaining if len(c.effects) == len(best.effects) and c is not best
                  and c.score - best.score < CONFOUNDED_SCORE]
        if rivals:
            out["confounded"] = [sorted({e for c in [best, *rivals] for e in c.effects})] if len(best.effects) > 1 \
                else [[best.effects[0], *(c.effects[0] for c in rivals)]]
            out["confounded_note"] = (f"{len(rivals)} other candidate(s) of the same size also explain the gap "
                                      f"within noise with a score less than {CONFOUNDED_SCORE:g} worse; the verdict "
                                      "holds the best-scoring one")
    out["nominal_explains"] = nominal_ok
    out["model_evaluations"] = dg.evaluator.calls + dg.fit_evaluator.calls
    out["seconds"] = round(time.perf_counter() - started, 3)
    predictions = {"nominal": dg.nominal, "verdict": None if best is None else best.prediction}
    return _finite(out), predictions


def _finite(obj):
    """JSON-safe: NaN/inf to None, numpy scalars to Python."""
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _json_number(obj)
    return obj


def no_model(campaign: str, reason: str) -> dict:
    """The diagnosis of a campaign that cannot be diagnosed (no damper data, no triangle case)."""
    return {"format_version": FORMAT_VERSION, "campaign": campaign, "status": "not_diagnosed", "reason": reason,
            "metric": METRIC, "gap_before": None, "where": [], "candidates": [], "verdict": [],
            "gap_after": None, "holdout_gap_after": None, "shrink": None}


def load_campaign(campaign_root: Path) -> tuple[str, Damper | None, pd.DataFrame, pd.DataFrame]:
    root = Path(campaign_root)
    meta = json.loads((root / "ingest" / "campaign.json").read_text(encoding="utf-8"))
    damper = None if meta.get("damper") is None else Damper.from_mapping(meta["damper"])
    return meta["campaign"], damper, pd.read_parquet(root / CASES_FILE), pd.read_parquet(
        root / CHARACTERISTIC_FILE)


def observation_sources(obs: Observations | None, cases: pd.DataFrame | None) -> dict:
    """Row-level lineage of a diagnosis (its ``sources`` key; paths relative to results/<campaign>/).

    ``windows``: the characteristic rows used as window observations, as (case, segment) keys
    'T01/1,T01/2,...' (:func:`lineage.row_keys`); ``transient_bins``: 'case/segment:n' per
    half-period with n transient bins taken from that case's time series; ``timeseries``: for each
    case used, its time series file and raw file with sha256 (from ``cases.parquet``).
    """
    from .lineage import row_keys

    out = {"characteristic_file": CHARACTERISTIC_FILE, "cases_file": CASES_FILE, "windows": "",
           "transient_bins": "", "timeseries": {}}
    if obs is None or len(obs) == 0:
        return out
    frame = pd.DataFrame({"case": obs.case, "segment": obs.segment, "kind": obs.kind})
    out["windows"] = row_keys(frame[frame["kind"] == "window"])
    bins = frame[frame["kind"] == "transient"].groupby(["case", "segment"], sort=False).size()
    out["transient_bins"] = ",".join(f"{c}/{k}:{n}" for (c, k), n in bins.items())
    used = list(dict.fromkeys(obs.case.tolist()))
    if cases is not None and len(cases):
        by_case = cases.set_index("case")
        for c in used:
            if c in by_case.index:
                row = by_case.loc[c]
                out["timeseries"][c] = {k: str(row[k]) for k in ("timeseries_file", "raw_file", "raw_sha256")
                                        if k in row}
    return out


def diagnose(campaign_root: Path, spec: WindowSpec = WindowSpec(), n_bins: int = 4,
             alpha: float = ALPHA) -> tuple[dict, Observations | None, dict]:
    """Diagnose a processed campaign folder ``results/<campaign>/``.

    Returns (diagnosis dict, observations, predictions); observations is None when the campaign
    cannot be diagnosed (no damper block, no triangle case). The dict's ``sources`` key lists the
    observations used (:func:`observation_sources`).
    """
    root = Path(campaign_root)
    campaign, damper, cases, char = load_campaign(root)
    if damper is None:
        result = no_model(campaign, "campaign.yaml has no damper block: there is no nominal model")
        return {**result, "sources": observation_sources(None, cases)}, None, {}
    if char.empty:
        result = no_model(campaign, "no status-ok triangle case: no characteristic to compare")
        return {**result, "sources": observation_sources(None, cases)}, None, {}
    obs = build_observations(campaign, cases, char, lambda row: pd.read_parquet(root / row["timeseries_file"]),
                             spec, n_bins)
    result, predictions = diagnose_observations(obs, damper, alpha)
    result["sources"] = observation_sources(obs, cases)
    return result, obs, predictions


def validate_diagnosis(result: Mapping) -> None:
    """Validate a diagnosis dict against workflow/schemas/diagnosis.schema.json (raises ValidationError)."""
    import jsonschema

    schema = json.loads(SCHEMA_PATH.read_text(encoding="utf-8"))
    jsonschema.validate(result, schema)


def write_diagnosis(campaign_root: Path, json_path: Path, figure_path: Path, spec: WindowSpec = WindowSpec(),
                    n_bins: int = 4) -> dict:
    """Diagnose, validate against the schema, write diagnosis.json and the gap figure."""
    from .diagnosis_figure import gap_figure
    from .figures import save_figure
    from .io import write_json

    result, obs, predictions = diagnose(Path(campaign_root), spec, n_bins)
    validate_diagnosis(result)
    write_json(result, json_path)
    save_figure(gap_figure(result, obs, predictions), figure_path)
    return result
