"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect causes it, how far it shrinks.

Output contract: shared/spec/diagnosis-output.md, version 1.1 (schema: diagnosis.schema.json,
package data beside this module).

Data. The *observations* of a campaign are, for every status-ok triangle case and each of its four
half-periods, the steady window of the characteristic (mean force over [start, end]·T/2) and
``n_bins`` *transient bins* that split the part before the window, [0, start]·T/2, into equal
times (the relaxation after each velocity reversal that the windows leave out). All times are
*plan times*: record time minus the case's measured motion start (``motion_start_s`` of
cases.parquet), so windows and bins sit where the piston really moved, whatever the actuator
delay or the time axis' origin.

Noise. Each observation's standard error combines (a) the variance of a mean of n consecutive
samples under the campaign's pooled force-noise model (:mod:`isokinetic.noise`: white plus
first-order coloured noise with an additive and a force-proportional part, fitted to the windows'
variograms, so autocorrelated noise is not mistaken for signal) at the observation's mean square
force, and (b) a between-period scatter ``rep_rel·|F|``, the period-to-period difference of the
window means beyond (a), estimated robustly and consistently (:func:`noise.between_period_scatter`).

Model. The nominal damper of ``campaign.json`` simulated noise-free through each case *driven by
its measured kinematics* (:class:`virtual_rig.Drive`: the measured speed of each half-period, on
the measured samples' plan times), reduced over the same samples; a candidate adds damper effects
with fitted parameters. Simulation: :func:`virtual_rig.triangle_responses` (Eq. 13-14).

Instrument terms. The load cell reads F_meas = g·F + F_0: a gain g (|g - 1| <= GAIN_BOUND) and a
zero offset F_0 (|F_0| <= OFFSET_BOUND_REL of the largest window force) are profiled out of every
fit in closed form (bounded weighted least squares). The actuator delay is measured, not fitted:
the median over cases of ``delay_s`` (motion start minus the record's first time stamp). They are
reported under ``instrument`` and never count as damper effects; a term is reported (non-null)
only where a likelihood-ratio test at ``alpha`` needs it.

Gap metric ``rms_z``. Root mean square over the characteristic points (windows) of
z = (F_measured - F_model)/σ. A model that explains the data to within noise gives rms_z ≈ 1.

Candidates. Each effect of :data:`EFFECTS` alone (one parameter each), every pair, then, while
nothing explains, the :data:`BEAM` best candidates of the largest size extended by one more effect;
a size is tried only while no smaller set explains (none when the nominal model does). Coulomb
friction, like the load-cell terms, is linear in the means and profiled in closed form
(:class:`LinearTerms`); the other effects are fitted.
Each is fitted with bounded least squares (scipy ``least_squares``, 'trf') on the period-1
observations (segments 1-2, windows and transient bins) and scored on period 2 (segments 3-4),
which the fit did not see: ``score`` = χ²(period 2) + k·ln(n_fit) (lower is better; k parameters,
instrument terms included). A candidate *explains* the gap when its fit χ² (n_fit - k degrees
of freedom), its holdout χ² (n_holdout) and the χ² of the windows alone (the characteristic, both
periods; the transient bins, four times as many, must not hide a misfit of the characteristic) are
consistent with noise at level ``alpha``. The
verdict is the smallest explaining set with the best score; ``[]`` when the nominal model (with the
instrument terms) already explains all observations. Explaining candidates of the verdict's size
whose score is within ``CONFOUNDED_SCORE`` of the best are listed as ``confounded``, and so is a
load-cell gain that discharge and viscosity together explain as well (or the reverse). When no
candidate explains the gap, the verdict is the candidate with the best overdispersed score
(:func:`overdispersed_score`), ``explained`` is false and a note says the gap lies outside the
catalogue. A fit that fails is listed under ``failed_fits`` with its reason; a campaign that cannot
be diagnosed at all still gets a diagnosis.json with ``status: failed`` and the reason.
"""

from __future__ import annotations

import itertools
import json
import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import optimize, stats

from .campaign import case_plan
from .damper import AIR_COMPRESSIBILITY_1_PA, NOMINAL, Damper, Effects, friction_force, laminar_coefficient
from .nominal import measured_drive, motion_start
from .noise import between_period_scatter, fit_noise_model, scaled_chi2_sf
from .plan import CasePlan
from .virtual_rig import Drive, Hydraulics, drive_times, triangle_responses
from .windows import WindowSpec, windowed_half_periods

log = logging.getLogger("isokinetic.diagnosis")

FORMAT_VERSION = 1
CONTRACT_VERSION = "1.1"
METRIC = "rms_z"
#: The candidate effects, in the contract's names.
EFFECTS = ("friction", "leakage", "asymmetry", "discharge", "viscosity", "air")
#: Instrument terms profiled out of every fit (load cell): F_meas = gain·F + offset.
INSTRUMENT = ("force_offset", "force_gain")
#: Largest load-cell gain error |g - 1| a calibrated load cell is allowed.
GAIN_BOUND = 0.02
#: Largest load-cell zero offset, as a fraction of the largest window force |F|.
OFFSET_BOUND_REL = 0.05
#: Significance level: a χ² with a smaller p-value is not noise.
ALPHA = 1e-3
#: Score difference (χ² units) within which two explaining candidates count as confounded.
CONFOUNDED_SCORE = 10.0
#: Relative tolerance on cost and parameters at which a search fit stops: 1e-3 of a χ² or of a
#: parameter is far below what ranks candidates or matters against the parameter's uncertainty.
FIT_TOL = 1e-3
#: Tolerance of the verdict's final (polishing) fit, whose parameters are reported.
POLISH_TOL = 1e-6
#: Candidates of each size extended by one more effect while nothing explains the gap.
BEAM = 3
#: Panel width of the model's segment tables (virtual_rig.DEFAULT_STEP is 0.03): error ~1e-8 of the
#: pressure scale, far below any window's noise, with about half the nodes.
MODEL_STEP = 0.06
#: Relative step of the drive speeds for the model's speed sensitivity (:func:`drive_input_variance`).
SPEED_STEP = 1e-4
#: A window whose nominal-model force varies by more than this fraction of the per-sample noise
#: (standard deviations) is still relaxing and is kept out of the noise fit (:func:`unsteady_windows`).
UNSTEADY_FRACTION = 0.25
#: |z| of a characteristic point beyond which it is not explained by noise (for ``where``).
Z_SIGNIFICANT = 3.0
#: The diagnosis.json schema, shipped as package data beside this module.
SCHEMA_RESOURCE = "diagnosis.schema.json"
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
    plans: tuple[CasePlan, ...]   # simulated plans (plan time), cut to the last sample needed
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
    rep_rel: float                # between-period relative scatter beyond the noise model
    drives: tuple[Drive | None, ...] = ()
    noise: dict = field(default_factory=dict)   # the pooled noise model(s), for the report
    speed_rel_se: np.ndarray | None = None      # relative standard error of the drive's measured speed

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
        plans, drives = [], []
        for old in used:
            rows = keep[self.case_index[keep] == old]
            plan = self.plans[old]
            drive = self.drives[old] if self.drives else None
            offset = 0.0 if drive is None else drive.grid_offset_s
            plans.append(replace(plan, duration_s=offset + (int(self.stop[rows].max()) - 1) / plan.sample_rate_Hz))
            drives.append(drive)
        fields_ = {name: getattr(self, name)[keep] for name in ("case", "kind", "segment", "period", "sign",
                                                                "speed_m_s", "start", "stop", "force_N", "sigma_N")}
        return Observations(campaign=self.campaign, plans=tuple(plans), rep_rel=self.rep_rel,
                            case_index=np.array([remap[i] for i in self.case_index[keep]], dtype=np.int64),
                            drives=tuple(drives) if self.drives else (), noise=self.noise,
                            speed_rel_se=None if self.speed_rel_se is None else self.speed_rel_se[keep], **fields_)


def build_observations(campaign: str, cases: pd.DataFrame, char: pd.DataFrame,
                       load_series: Callable[[pd.Series], pd.DataFrame], spec: WindowSpec = WindowSpec(),
                       n_bins: int = 4, force_offset_N: float = 0.0,
                       unsteady: frozenset = frozenset(), input_var_N2: np.ndarray | None = None) -> Observations:
    """Windows and transient bins of every triangle case, in plan time, with honest standard errors.

    Measured means are taken from the case's series over [a, b) in plan time (record time minus
    ``motion_start_s``), the model's over the same plan-time interval of its driven grid, so both
    use the same samples. The proportional part of the noise scales with the true force, so the
    noise model sees the samples less a known load-cell offset ``force_offset_N``, and only the
    windows not named (case, segment) in ``unsteady`` (:func:`prepare` finds both first).
    ``input_var_N2`` adds, per observation, the variance that the measured drive speed's own error
    propagates into the model (:func:`prepare`).
    """
    by_case = {c: g.set_index("segment") for c, g in char.groupby("case")}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle") & cases["case"].isin(by_case)]
    cols: dict[str, list] = {k: [] for k in ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s",
                                             "start", "stop", "force_N", "msq_N2", "n", "fs", "white_se2",
                                             "speed_rel_se")}
    plans, drives, window_samples, all_windows = [], [], {}, {}
    for _, row in ok.iterrows():
        plan = case_plan(row)
        series = load_series(row)
        start_s = motion_start(row)
        t = series["time_s"].to_numpy()
        tau = t - start_s
        f = series["force_N"].to_numpy()
        y = series["displacement_m"].to_numpy()
        fs = plan.sample_rate_Hz
        half = plan.period_s / 2.0
        win = by_case[plan.case]
        if sorted(win.index) != [1, 2, 3, 4]:
            continue
        drive = measured_drive(win.index, win["velocity_m_s"], float(t[0]), start_s, fs)
        full = replace(plan, duration_s=float(tau[-1]))
        tm = drive_times(full, drive)
        segs = windowed_half_periods(plan, float(tau[-1]), spec)
        last = 0

        def add(kind, k, sign, a, b):
            m0, m1 = np.searchsorted(tau, [a, b], side="left")
            j0, j1 = np.searchsorted(tm, [a, b], side="left")
            if m1 - m0 < 2 or j1 - j0 < 2:
                return 0
            fw = f[m0:m1]
            fn = fw - force_offset_N
            cols["case"].append(plan.case)
            cols["case_index"].append(len(plans))
            cols["kind"].append(kind)
            cols["segment"].append(k)
            cols["period"].append((k + 1) // 2)
            cols["sign"].append(sign)
            cols["speed_m_s"].append(plan.velocity_m_s)
            cols["start"].append(int(j0))
            cols["stop"].append(int(j1))
            cols["force_N"].append(float(fw.mean()))
            cols["msq_N2"].append(float(np.mean(fn * fn)))
            cols["n"].append(int(m1 - m0))
            cols["fs"].append(fs)
            if kind == "window":
                all_windows.setdefault(fs, []).append(fn)
                if (plan.case, k) not in unsteady:
                    window_samples.setdefault(fs, []).append(fn)
            cols["white_se2"].append(float(np.var(fw, ddof=1)) / fw.size)
            return int(j1)

        for k, (t0, _t1, sign) in enumerate(segs, start=1):
            # the window's end is closed (as windows.window_ranges): one step past it, half a sample
            a, b = t0 + spec.start_fraction * half, t0 + spec.end_fraction * half + 0.5 / fs
            before = len(cols["case"])
            last = max(last, add("window", k, sign, a, b))
            rel_se = speed_relative_se(tau, y, a, b)
            edges = t0 + np.linspace(0.0, spec.start_fraction * half, n_bins + 1)
            for a, b in zip(edges[:-1], edges[1:]):
                add("transient", k, sign, a, b)
            cols["speed_rel_se"] += [rel_se] * (len(cols["case"]) - before)
        plans.append(replace(plan, duration_s=float(tm[max(last - 1, 0)])))
        drives.append(drive)
    ints = ("case_index", "segment", "period", "start", "stop", "n")
    arrays = {k: np.asarray(v, dtype=np.int64 if k in ints else (object if k in ("case", "kind") else float))
              for k, v in cols.items()}
    se2, noise = _noise_variances({**all_windows, **window_samples}, arrays)
    # a floor where the noise model has nothing (constant, quantised windows): the samples' own scatter
    floor = np.maximum(arrays["white_se2"], (1e-9 * np.abs(arrays["force_N"]) + 1e-9) ** 2)
    se2 = np.where(se2 > 0.0, se2, floor)
    if input_var_N2 is not None and len(input_var_N2) == se2.size:
        se2 = se2 + input_var_N2
    force = arrays["force_N"]
    rep_rel = _between_period(arrays, se2)
    sigma = np.sqrt(se2 + (rep_rel * force) ** 2)
    keep = {k: arrays[k] for k in ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start",
                                   "stop", "force_N")}
    return Observations(campaign=campaign, plans=tuple(plans), drives=tuple(drives), rep_rel=rep_rel,
                        sigma_N=sigma, noise={**noise, "between_period_rel": rep_rel},
                        speed_rel_se=arrays["speed_rel_se"], **keep)


def speed_relative_se(tau: np.ndarray, y: np.ndarray, a: float, b: float) -> float:
    """Relative standard error of the least-squares speed of the displacement over [a, b) (plan time):
    the error with which the measured drive speed enters the model (LVDT noise)."""
    m0, m1 = np.searchsorted(tau, [a, b], side="left")
    if m1 - m0 < 3:
        return 0.0
    tw, yw = tau[m0:m1], y[m0:m1]
    tc = tw - tw.mean()
    sxx = float(np.dot(tc, tc))
    slope = float(np.dot(tc, yw - yw.mean())) / sxx
    resid = yw - yw.mean() - slope * tc
    se = math.sqrt(float(np.dot(resid, resid)) / (tw.size - 2) / sxx)
    return se / abs(slope) if slope else 0.0


def _noise_variances(window_samples: Mapping[float, list], arrays: Mapping[str, np.ndarray]) -> tuple[np.ndarray, dict]:
    """Variance of every observation's mean under the pooled noise model of its sample rate."""
    se2 = np.zeros(arrays["force_N"].size)
    rel_sd = np.zeros(arrays["force_N"].size)
    models, objects = {}, {}
    for fs, samples in window_samples.items():
        model = fit_noise_model(samples, fs)
        at = arrays["fs"] == fs
        se2[at] = model.mean_variance(arrays["n"][at], arrays["msq_N2"][at])
        if model.param_cov is not None:
            rel_sd[at] = model.mean_variance_rel_sd(arrays["n"][at], arrays["msq_N2"][at])
        models[f"{fs:g}"] = {k: v for k, v in model.to_dict().items() if k != "param_cov"}
        objects[fs] = model
    scale = float(np.mean(np.clip(rel_sd, 0.0, 2.0))) if rel_sd.size else 0.0
    return se2, {"model": models, "objects": objects, "scale_rel_sd": scale}


def _between_period(arrays: Mapping[str, np.ndarray], se2: np.ndarray) -> float:
    """Between-period relative scatter of the window means beyond their noise variance."""
    win = arrays["kind"] == "window"
    df = pd.DataFrame({"case": arrays["case"][win], "sign": arrays["sign"][win], "period": arrays["period"][win],
                       "force": arrays["force_N"][win], "se2": se2[win]})
    wide = df.pivot_table(index=["case", "sign"], columns="period", values=["force", "se2"], aggfunc="first").dropna()
    if wide.empty:
        return 0.0
    d = (wide[("force", 2)] - wide[("force", 1)]).to_numpy()
    mean = 0.5 * (wide[("force", 1)].abs() + wide[("force", 2)].abs()).to_numpy()
    return float(between_period_scatter(d, (wide[("se2", 1)] + wide[("se2", 2)]).to_numpy(), mean))


class Evaluator:
    """Noise-free model means over the observations' sample ranges, for any effects."""

    def __init__(self, obs: Observations, damper: Damper):
        self.obs = obs
        self.damper = damper
        drives = obs.drives or (None,) * len(obs.plans)
        sizes = np.array([drive_times(p, d).size for p, d in zip(obs.plans, drives)], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes + 1)])  # +1: a leading zero per case in the cumsum
        self._lo = offsets[obs.case_index] + obs.start
        self._hi = offsets[obs.case_index] + obs.stop
        self._n = (obs.stop - obs.start).astype(float)
        self.calls = 0

    def predict(self, effects: Effects = NOMINAL) -> np.ndarray:
        """Model mean force of every observation [N] (Eq. 8 with Δp from Eq. 13-14)."""
        return self._moments(effects, 1)[0]

    def spread(self, effects: Effects = NOMINAL) -> np.ndarray:
        """Standard deviation of the model force over each observation's samples [N]: how far the
        window is from steady (a window that starts before convergence, Eq. 28-29, is not)."""
        mean, square = self._moments(effects, 2)
        return np.sqrt(np.maximum(square - mean * mean, 0.0))

    def _moments(self, effects: Effects, order: int) -> list[np.ndarray]:
        self.calls += 1
        hyd = Hydraulics.from_damper(self.damper, effects)
        parts = [[] for _ in range(order)]
        drives = self.obs.drives if self.obs.drives else None
        friction = bool(effects.coulomb_force_N or effects.stribeck_force_N)
        for _t, dp, vel in triangle_responses(self.obs.plans, hyd, 0.0, MODEL_STEP, drives):
            force = hyd.piston_area_m2 * dp
            if friction:  # the search profiles friction linearly (LinearTerms): its runs carry none
                force = force + friction_force(vel, effects)
            for k in range(order):
                parts[k].append(np.concatenate([[0.0], np.cumsum(force ** (k + 1))]))
        out = []
        for k in range(order):
            cs = np.concatenate(parts[k])
            out.append((cs[self._hi] - cs[self._lo]) / self._n)
        return out


# ----------------------------------------------------------------------------------------------
# instrument terms
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LinearTerms:
    """Terms linear in the measured means, profiled out of every fit in closed form.

    F_meas = g·(m + F_C·s) + F_0 with m the hydraulic model (Eq. 8 without friction), s = ±1 the
    observation's direction (Coulomb friction, Eq. 8's F_f, is sign(v)·F_C over a constant-velocity
    segment), g the load-cell gain, F_0 its zero offset. Solved as bounded weighted linear least
    squares in (g, g·F_C, F_0) (scipy ``lsq_linear``). ``free`` names the instrument terms fitted
    (others fixed at g = 1, F_0 = 0).
    """

    free: tuple[str, ...] = INSTRUMENT
    offset_bound_N: float = 0.0
    gain_bound: float = GAIN_BOUND
    friction_bound_N: float = math.inf

    def solve(self, force_N: np.ndarray, model_N: np.ndarray, sign: np.ndarray, weight: np.ndarray,
              friction: bool) -> tuple[float, float, float]:
        """(gain, coulomb_force_N, offset_N) minimising Σ w (F - g (m + F_C s) - F_0)² within the bounds."""
        root_w = np.sqrt(weight)
        y = force_N.copy()
        cols, lo, hi, names = [], [], [], []
        if "force_gain" in self.free:
            cols.append(model_N), lo.append(1.0 - self.gain_bound), hi.append(1.0 + self.gain_bound), names.append("g")
        else:
            y = y - model_N
        if friction:
            cols.append(sign), lo.append(0.0), hi.append((1.0 + self.gain_bound) * self.friction_bound_N)
            names.append("c")
        if "force_offset" in self.free and self.offset_bound_N > 0:
            cols.append(np.ones_like(y)), lo.append(-self.offset_bound_N), hi.append(self.offset_bound_N)
            names.append("o")
        if not cols:
            return 1.0, 0.0, 0.0
        a = np.column_stack(cols) * root_w[:, None]
        sol = optimize.lsq_linear(a, y * root_w, bounds=(lo, hi), method="bvls").x
        v = dict(zip(names, sol))
        g = float(v.get("g", 1.0))
        return g, float(v.get("c", 0.0)) / g, float(v.get("o", 0.0))


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
        """(SI parameter name, value) of an optimiser value (clipped to the effect's bounds)."""
        d = self.damper
        lo, hi = self.bounds(effect)
        x = min(max(float(x), lo), hi)
        # only the requested effect is evaluated: exp() of another effect's value may overflow
        if effect == "friction":
            return "coulomb_force_N", x * self.force_ref_N
        if effect == "leakage":
            return "leakage_conductance_m3_s_Pa", x / self._c1
        if effect == "asymmetry":
            return "asymmetry", x
        if effect == "discharge":
            return "discharge_coefficient", d.discharge_coefficient * math.exp(x)
        if effect == "viscosity":
            return "viscosity_Pa_s", d.viscosity_Pa_s * math.exp(x)
        if effect == "air":
            return "air_volume_fraction", x / self._air_ratio
        raise KeyError(f"unknown effect {effect!r}; known: {EFFECTS}")

    def effects(self, names: Sequence[str], x: Sequence[float]) -> Effects:
        return Effects(**dict(self.si(n, v) for n, v in zip(names, x)))


# ----------------------------------------------------------------------------------------------
# fitting and scoring
# ----------------------------------------------------------------------------------------------

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
    offset_N: float = 0.0

    @property
    def k(self) -> int:
        """Fitted parameters: damper effects plus free instrument terms."""
        return len(self.effects) + len(self.instrument)

    @property
    def measured_prediction(self) -> np.ndarray:
        """What the load cell would read: gain·F_model + offset."""
        return self.gain * self.prediction + self.offset_N

    def to_dict(self) -> dict:
        return {"effects": list(self.effects), "params": self.params, "gap_after": self.gap_after,
                "holdout_gap_after": self.holdout_gap_after, "score": self.score, "explained": self.explained,
                "chi2_fit": self.chi2_fit, "chi2_holdout": self.chi2_holdout, "n_fit": self.n_fit,
                "n_holdout": self.n_holdout,
                "instrument": {"force_gain": self.gain if "force_gain" in self.instrument else None,
                               "force_offset_N": self.offset_N if "force_offset" in self.instrument else None}}


def rms(z: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(z)))) if z.size else float("nan")


def consistent_with_noise(chi2: float, dof: int, alpha: float = ALPHA, scale_rel_sd: float = 0.0) -> bool:
    """χ² test: True when a χ² this large has probability >= alpha under noise alone.

    ``scale_rel_sd``: relative uncertainty of the noise model's variance scale, common to all the
    z in the sum (:func:`noise.scaled_chi2_sf`); 0 for a plain χ² test.
    """
    return dof > 0 and math.isfinite(chi2) and scaled_chi2_sf(chi2, dof, scale_rel_sd) >= alpha


class Diagnoser:
    """Fits and scores candidate effect sets on one campaign's observations."""

    def __init__(self, obs: Observations, damper: Damper, alpha: float = ALPHA):
        self.obs = obs
        self.evaluator = Evaluator(obs, damper)
        self.alpha = alpha
        windows = np.abs(obs.force_N[obs.is_window])
        self.param = Parametrisation(damper, float(np.median(windows)) if windows.size else 1.0)
        self.linear = LinearTerms(offset_bound_N=OFFSET_BOUND_REL * float(windows.max()) if windows.size else 0.0,
                                  friction_bound_N=self.param.bounds("friction")[1] * self.param.force_ref_N)
        self.weight = 1.0 / obs.sigma_N**2
        self.fit_mask = obs.period == 1
        self.hold_mask = obs.period == 2
        self.fit_obs = obs.subset(self.fit_mask)   # period 1: simulated only up to its last sample
        self.fit_evaluator = Evaluator(self.fit_obs, damper)
        self.nominal = self.evaluator.predict(NOMINAL)
        self.scale_rel_sd = float(obs.noise.get("scale_rel_sd", 0.0))
        self.failed: list[dict] = []

    def z(self, prediction: np.ndarray) -> np.ndarray:
        return (self.obs.force_N - prediction) / self.obs.sigma_N

    def terms(self, instrument: Sequence[str]) -> LinearTerms:
        return replace(self.linear, free=tuple(instrument))

    def _residuals(self, nonlinear: Sequence[str], friction: bool, terms: LinearTerms):
        obs, w = self.fit_obs, 1.0 / self.fit_obs.sigma_N**2

        def fun(x):
            m = self.fit_evaluator.predict(self.param.effects(nonlinear, x))
            g, fc, o = terms.solve(obs.force_N, m, obs.sign, w, friction)
            return (obs.force_N - g * (m + fc * obs.sign) - o) / obs.sigma_N
        return fun

    def fit(self, names: Sequence[str], starts: Sequence[Sequence[float]],
            instrument: Sequence[str] = INSTRUMENT, tol: float = FIT_TOL) -> Candidate | None:
        """Best of bounded least-squares fits of the nonlinear effects from the given starting points
        (one value per effect of ``names`` other than friction, which is profiled with the instrument
        terms); None (and a record in ``failed``) when no fit succeeds."""
        names = tuple(names)
        terms = self.terms(instrument)
        nonlinear = tuple(n for n in names if n != "friction")
        friction = "friction" in names
        if not nonlinear:
            return self._guarded(names, nonlinear, np.empty(0), terms)
        lower, upper = zip(*(self.param.bounds(n) for n in nonlinear))
        fun = self._residuals(nonlinear, friction, terms)
        best, errors = None, []
        for x0 in starts:
            x0 = np.clip(np.asarray(x0, dtype=float), np.asarray(lower) + 1e-12, np.asarray(upper) - 1e-12)
            try:
                with np.errstate(over="raise", invalid="raise", divide="raise"):
                    res = optimize.least_squares(fun, x0, bounds=(lower, upper), method="trf", x_scale="jac",
                                                 diff_step=1e-6, ftol=tol, xtol=tol,
                                                 max_nfev=40 * len(nonlinear))
            except (ValueError, FloatingPointError, ArithmeticError, np.linalg.LinAlgError) as exc:
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
        except (ValueError, FloatingPointError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self.failed.append({"effects": list(names), "instrument": list(terms.free),
                                "reason": f"scoring failed: {type(exc).__name__}: {exc}"})
            return None

    def _score(self, names: tuple[str, ...], nonlinear: tuple[str, ...], x: np.ndarray,
               terms: LinearTerms) -> Candidate:
        hydraulic = self.evaluator.predict(self.param.effects(nonlinear, x)) if nonlinear else self.nominal
        fm, sign = self.fit_mask, self.obs.sign
        g, fc, o = terms.solve(self.obs.force_N[fm], hydraulic[fm], sign[fm], self.weight[fm], "friction" in names)
        pred = hydraulic + fc * sign
        z = self.z(g * pred + o)
        win = self.obs.is_window
        chi2_fit = float(np.sum(z[fm] ** 2))
        chi2_hold = float(np.sum(z[self.hold_mask] ** 2))
        n_fit, n_hold = int(fm.sum()), int(self.hold_mask.sum())
        k = len(names) + len(terms.free)
        eps = self.scale_rel_sd
        chi2_win = float(np.sum(z[win] ** 2))
        explained = (consistent_with_noise(chi2_fit, n_fit - k, self.alpha, eps)
                     and consistent_with_noise(chi2_hold, n_hold, self.alpha, eps)
                     and consistent_with_noise(chi2_win, int(win.sum()) - k, self.alpha, eps))
        values = dict(zip(nonlinear, np.asarray(x, dtype=float)))
        values["friction"] = fc / self.param.force_ref_N
        full_x = np.array([values[n] for n in names], dtype=float)
        return Candidate(effects=names, x=full_x, params=dict(self.param.si(n, v) for n, v in zip(names, full_x)),
                         prediction=pred, chi2_fit=chi2_fit, chi2_holdout=chi2_hold, n_fit=n_fit, n_holdout=n_hold,
                         gap_after=rms(z[win & fm]), holdout_gap_after=rms(z[win & self.hold_mask]),
                         score=chi2_hold + k * math.log(n_fit), explained=explained,
                         instrument=tuple(terms.free), gain=g, offset_N=o)

    def refit(self, names: Sequence[str], instrument: Sequence[str], warm: Candidate | None = None,
              tol: float = FIT_TOL) -> Candidate | None:
        """Fit ``names`` with the instrument terms ``instrument``, warm-started from ``warm``."""
        nonlinear = [n for n in names if n != "friction"]
        x0 = [warm.x[warm.effects.index(n)] if warm is not None and n in warm.effects else self.param.starts(n)[0]
              for n in nonlinear]
        return self.fit(tuple(names), [x0], instrument, tol)

    def nominal_p_value(self, instrument: Sequence[str] = INSTRUMENT) -> float:
        """p-value of the χ² tests of the nominal model with the instrument terms (fitted on all
        observations), over all observations and over the windows (the characteristic) alone:
        twice the smaller p-value (Bonferroni), the probability of such a χ² from noise alone."""
        terms = self.terms(instrument)
        g, _fc, o = terms.solve(self.obs.force_N, self.nominal, self.obs.sign, self.weight, False)
        z = self.z(g * self.nominal + o)
        win = self.obs.is_window
        k = len(terms.free)
        tests = [(float(np.sum(z**2)), len(z) - k), (float(np.sum(z[win] ** 2)), int(win.sum()) - k)]
        if any(dof <= 0 for _, dof in tests):
            return 0.0
        # the smaller of the two p-values, Bonferroni-corrected: the test of both at once
        return min(1.0, 2.0 * min(scaled_chi2_sf(c, dof, self.scale_rel_sd) for c, dof in tests))

    def nominal_explains(self, instrument: Sequence[str] = INSTRUMENT) -> bool:
        """The nominal model with the instrument terms is within noise at level ``alpha``."""
        return self.nominal_p_value(instrument) >= self.alpha

    def search(self) -> list[Candidate]:
        """Singles, then pairs (warm-started from the singles), then greedy extension of the BEAM best
        of the largest size, each size only while no smaller set explains the gap (the verdict is the
        smallest explaining set, so larger ones cannot change it)."""
        singles = {e: self.fit((e,), [[s] for s in self.param.starts(e)] if e != "friction" else [[]])
                   for e in EFFECTS}
        found = [c for c in singles.values() if c is not None]
        start = {e: (c.x[0] if c is not None else self.param.starts(e)[0]) for e, c in singles.items()}

        def nonlinear_start(names, source=None):
            return [[(source.x[source.effects.index(n)] if source is not None and n in source.effects else start[n])
                     for n in names if n != "friction"]]

        if not any(c.explained for c in found):
            for pair in itertools.combinations(EFFECTS, 2):
                c = self.fit(pair, nonlinear_start(pair))
                if c is not None:
                    found.append(c)
        size = 2
        while found and not any(c.explained for c in found) and size < len(EFFECTS):
            bases = sorted((c for c in found if len(c.effects) == size), key=lambda c: c.score)[:BEAM]
            tried = set()
            for base in bases:
                for e in EFFECTS:
                    names = tuple(n for n in EFFECTS if n in base.effects or n == e)
                    if e in base.effects or names in tried:
                        continue
                    tried.add(names)
                    c = self.fit(names, nonlinear_start(names, base))
                    if c is not None:
                        found.append(c)
            size += 1
        return sorted(found, key=lambda c: (not c.explained, len(c.effects) if c.explained else 0, c.score))


def overdispersed_score(candidate: Candidate, candidates: Sequence[Candidate]) -> float:
    """Quasi-likelihood score when nothing fits within noise: χ²_holdout / ŝ² + k ln n_fit.

    ŝ² = min over candidates of χ²_fit/(n_fit - k), the noise inflation that the best model needs.
    """
    s2 = min(c.chi2_fit / max(c.n_fit - c.k, 1) for c in candidates)
    return candidate.chi2_holdout / max(s2, 1.0) + candidate.k * math.log(candidate.n_fit)


def identifiability(dg: Diagnoser, candidate: Candidate) -> dict:
    """Standard errors (SI) and correlations of the effect parameters from the Fisher information JᵀJ.

    J: derivatives of the fit residuals (period 1) with respect to every effect parameter (optimiser
    units; friction analytic, the others by forward differences) and the free instrument terms, so
    the standard errors account for the instrument terms fitted alongside.
    """
    fm = dg.fit_mask
    sigma, sign = dg.obs.sigma_N[fm], dg.obs.sign[fm]
    g = candidate.gain
    cols = []
    nonlinear = [n for n in candidate.effects if n != "friction"]
    base = dict(zip(candidate.effects, candidate.x))
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
    if not candidate.effects:
        return {"identifiable": True, "parameters": {}}
    jac = np.column_stack(cols)
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


def instrument_report(dg: Diagnoser, best: Candidate, delay_s: float | None) -> tuple[dict, dict]:
    """The ``instrument`` key and its test details: each load-cell term refitted as fixed (gain 1,
    offset 0) and kept where the fit χ² rises beyond the χ²₁ quantile at 1 - alpha."""
    needed = {}
    tests = {}
    threshold = float(stats.chi2.isf(dg.alpha, 1))
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


def case_delays(cases: pd.DataFrame) -> dict:
    """Measured actuator delay over the status-ok triangle cases (``delay_s`` of cases.parquet)."""
    if "delay_s" not in cases:
        return {"delay_s": None}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    d = ok["delay_s"].to_numpy(dtype=float)
    d = d[np.isfinite(d)]
    if not d.size:
        return {"delay_s": None}
    return {"delay_s": float(np.median(d)), "delay_min_s": float(d.min()), "delay_max_s": float(d.max()),
            "n_cases": int(d.size)}


def diagnose_observations(obs: Observations, damper: Damper, alpha: float = ALPHA,
                          delays: Mapping | None = None) -> tuple[dict, dict]:
    """The diagnosis dict of the contract, and the predictions (nominal, verdict) for figures."""
    started = time.perf_counter()
    delays = dict(delays or {"delay_s": None})
    dg = Diagnoser(obs, damper, alpha)
    win = obs.is_window
    z_nom = dg.z(dg.nominal)
    gap_before = rms(z_nom[win])
    out = {"format_version": FORMAT_VERSION, "contract_version": CONTRACT_VERSION, "campaign": obs.campaign,
           "status": "ok", "metric": METRIC,
           "gap_before": gap_before, "where": [b for b in gap_bands(obs, dg.nominal) if b["significant"]],
           "noise": {**{k: v for k, v in obs.noise.items() if k != "objects"}, "repeatability_rel": obs.rep_rel, "n_windows": int(win.sum()),
                     "n_transient_bins": int((~win).sum()), "alpha": alpha},
           "rms_rel_before": rms(((obs.force_N - dg.nominal) / np.abs(obs.force_N))[win])}
    nominal_fit = dg.refit((), INSTRUMENT)
    out["nominal_p_value"] = dg.nominal_p_value()
    nominal_ok = out["nominal_p_value"] >= alpha
    candidates = [] if nominal_ok else dg.search()
    out["candidates"] = [c.to_dict() for c in candidates]
    explaining = [c for c in candidates if c.explained]
    if nominal_ok or not candidates:
        best = nominal_fit
        verdict = []
        if nominal_ok:
            out["search_note"] = "the nominal model with the instrument terms explains the data: no effect searched"
        if not nominal_ok:
            out["unexplained_note"] = "no candidate fit succeeded (see failed_fits)"
        out.update(verdict=[], explained=bool(nominal_ok), gap_after=best.gap_after,
                   holdout_gap_after=best.holdout_gap_after,
                   shrink=gap_before / best.gap_after if best.gap_after > 0 else None)
    else:
        best = explaining[0] if explaining else min(candidates, key=lambda c: overdispersed_score(c, candidates))
        polished = dg.refit(best.effects, best.instrument, best, POLISH_TOL)
        if polished is not None and polished.chi2_fit <= best.chi2_fit:
            best = polished
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
                   rms_rel_after=rms(((obs.force_N - best.measured_prediction) / np.abs(obs.force_N))[win]),
                   identifiability=identifiability(dg, best))
        rivals = [c for c in explaining if len(c.effects) == len(best.effects) and c.effects != best.effects
                  and c.score - best.score < CONFOUNDED_SCORE]
        if rivals:
            out["confounded"] = [sorted({e for c in [best, *rivals] for e in c.effects})] if len(best.effects) > 1 \
                else [[best.effects[0], *(c.effects[0] for c in rivals)]]
            out["confounded_note"] = (f"{len(rivals)} other candidate(s) of the same size also explain the gap "
                                      f"within noise with a score less than {CONFOUNDED_SCORE:g} worse; the verdict "
                                      "holds the best-scoring one")
    instrument, tests = instrument_report(dg, best, delays.get("delay_s"))
    out["instrument"] = instrument
    out["instrument_tests"] = {**tests, "delay": {k: v for k, v in delays.items() if k != "delay_s"},
                               "bounds": {"force_gain": [1.0 - GAIN_BOUND, 1.0 + GAIN_BOUND],
                                          "force_offset_N": [-dg.linear.offset_bound_N,
                                                             dg.linear.offset_bound_N]}}
    group = gain_confounding(dg, best, candidates, instrument["force_gain"] is not None)
    if group:
        out.setdefault("confounded", []).append(group)
        out["confounded_instrument_note"] = (
            "a load-cell gain error and a change of discharge coefficient plus viscosity explain the data "
            "alike: the data cannot tell an instrument gain from these damper effects; calibrate the load cell "
            "to decide")
    if dg.failed:
        out["failed_fits"] = dg.failed
    out["nominal_explains"] = nominal_ok
    out["model_evaluations"] = dg.evaluator.calls + dg.fit_evaluator.calls
    out["seconds"] = round(time.perf_counter() - started, 3)
    predictions = {"nominal": dg.nominal,
                   "verdict": None if best is None or not verdict else best.measured_prediction}
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


def no_model(campaign: str, reason: str, status: str = "not_diagnosed") -> dict:
    """The diagnosis of a campaign that cannot be diagnosed (no damper data, no triangle case), or
    whose diagnosis failed (``status`` 'failed', with the reason)."""
    return {"format_version": FORMAT_VERSION, "contract_version": CONTRACT_VERSION, "campaign": campaign,
            "status": status, "reason": reason, "metric": METRIC, "gap_before": None, "where": [],
            "candidates": [], "verdict": [], "explained": False,
            "instrument": {"delay_s": None, "force_offset_N": None, "force_gain": None},
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


def prepare(campaign_root: Path, spec: WindowSpec = WindowSpec(), n_bins: int = 4,
            alpha: float = ALPHA) -> tuple[str, Damper | None, pd.DataFrame, Observations | None, str]:
    """(campaign, damper, cases, observations, reason) of a processed campaign folder.

    Observations are built twice: first to profile the load-cell offset against the nominal model,
    then with the noise model fitted to offset-free samples (the proportional noise scales with the
    true force). Observations is None, with the reason, when the campaign cannot be diagnosed.
    """
    root = Path(campaign_root)
    campaign, damper, cases, char = load_campaign(root)
    if damper is None:
        return campaign, None, cases, None, "campaign.yaml has no damper block: there is no nominal model"
    if char.empty:
        return campaign, damper, cases, None, "no status-ok triangle case: no characteristic to compare"
    cache: dict[str, pd.DataFrame] = {}

    def load(row):
        key = str(row["timeseries_file"])
        if key not in cache:
            cache[key] = pd.read_parquet(root / key)
        return cache[key]

    obs = build_observations(campaign, cases, char, load, spec, n_bins)
    if len(obs):
        dg0 = Diagnoser(obs, damper, alpha)
        first = dg0.refit((), INSTRUMENT)
        offset = 0.0 if first is None else first.offset_N
        obs = build_observations(campaign, cases, char, load, spec, n_bins, offset,
                                 unsteady_windows(obs, dg0.evaluator.spread(NOMINAL)),
                                 drive_input_variance(obs, damper, dg0.nominal))
    if len(obs) == 0:
        return campaign, damper, cases, None, "no triangle case with four windows: nothing to compare"
    return campaign, damper, cases, obs, ""


def drive_input_variance(obs: Observations, damper: Damper, nominal_N: np.ndarray) -> np.ndarray:
    """Variance [N²] that the error of each measured drive speed propagates into the model means:
    (∂F/∂ln v · se(v)/v)², ∂F/∂ln v from the nominal model with every speed scaled by 1 + SPEED_STEP."""
    if obs.speed_rel_se is None or not obs.drives or not any(obs.drives):
        return np.zeros(len(obs))
    scaled = tuple(None if d is None else replace(d, speeds_m_s=tuple(v * (1.0 + SPEED_STEP) for v in d.speeds_m_s))
                   for d in obs.drives)
    shifted = Evaluator(replace(obs, drives=scaled), damper).predict(NOMINAL)
    return ((shifted - nominal_N) / SPEED_STEP * obs.speed_rel_se) ** 2


def unsteady_windows(obs: Observations, model_spread_N: np.ndarray) -> frozenset:
    """(case, segment) of the windows whose nominal-model force is not steady: its spread over the
    window exceeds UNSTEADY_FRACTION of the per-sample noise the first noise fit estimated (at most
    half of the windows, the least steady first, so that the noise fit keeps data)."""
    win = np.flatnonzero(obs.is_window)
    models = obs.noise.get("objects") or {}
    rates = [obs.plans[obs.case_index[i]].sample_rate_Hz for i in win]
    per_sample = np.array([math.sqrt(max(models[fs].sample_variance_N2(obs.force_N[i] ** 2), 1e-300))
                           if fs in models else math.inf for i, fs in zip(win, rates)])
    spread = model_spread_N[win]
    least_steady = np.argsort(-spread / per_sample)[: len(win) // 2]
    bad = [win[j] for j in least_steady if spread[j] > UNSTEADY_FRACTION * per_sample[j]]
    return frozenset((str(obs.case[i]), int(obs.segment[i])) for i in bad)


def diagnose(campaign_root: Path, spec: WindowSpec = WindowSpec(), n_bins: int = 4,
             alpha: float = ALPHA) -> tuple[dict, Observations | None, dict]:
    """Diagnose a processed campaign folder ``results/<campaign>/``.

    Returns (diagnosis dict, observations, predictions); observations is None when the campaign
    cannot be diagnosed (no damper block, no triangle case). The dict's ``sources`` key lists the
    observations used (:func:`observation_sources`).
    """
    campaign, damper, cases, obs, reason = prepare(campaign_root, spec, n_bins, alpha)
    if obs is None:
        return {**no_model(campaign, reason), "sources": observation_sources(None, cases)}, None, {}
    result, predictions = diagnose_observations(obs, damper, alpha, case_delays(cases))
    result["sources"] = observation_sources(obs, cases)
    return result, obs, predictions


def diagnosis_schema() -> dict:
    """The diagnosis.json schema (package data, so a regular install validates too)."""
    return json.loads(resources.files(__package__).joinpath(SCHEMA_RESOURCE).read_text(encoding="utf-8"))


def validate_diagnosis(result: Mapping) -> None:
    """Validate a diagnosis dict against the diagnosis.json schema (raises ValidationError)."""
    import jsonschema

    jsonschema.validate(result, diagnosis_schema())


def write_diagnosis(campaign_root: Path, json_path: Path, figure_path: Path, spec: WindowSpec = WindowSpec(),
                    n_bins: int = 4) -> dict:
    """Diagnose, validate against the schema, write diagnosis.json and the gap figure."""
    from .diagnosis_figure import gap_figure
    from .figures import save_figure
    from .io import write_json

    try:
        result, obs, predictions = diagnose(Path(campaign_root), spec, n_bins)
    except Exception as exc:  # noqa: BLE001 - an accepted campaign always gets its diagnosis.json
        log.exception("diagnosis of %s failed", campaign_root)
        name = Path(campaign_root).name
        try:
            name = load_campaign(Path(campaign_root))[0]
        except Exception:  # noqa: BLE001
            pass
        result, obs, predictions = no_model(name, f"diagnosis failed: {type(exc).__name__}: {exc}", "failed"), None, {}
    validate_diagnosis(result)
    write_json(result, json_path)
    save_figure(gap_figure(result, obs, predictions), figure_path)
    return result
