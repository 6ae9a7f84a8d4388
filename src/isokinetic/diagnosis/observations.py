"""The observations a diagnosis compares with the model: window and transient-bin means, in plan time.

Data. The *observations* of a campaign are, for every status-ok triangle case and each of its four
half-periods, the steady window of the characteristic (mean force over [start, end]·T/2, the
window of "A method for the identification of hydraulic damper characteristics from steady
velocity inputs", Titurus et al.) and ``n_bins`` *transient bins* that split the part before the
window, [0, start]·T/2, into equal times (the relaxation after each velocity reversal that the
windows leave out). All times are *plan times*: record time minus the case's measured motion start
(``motion_start_s`` of cases.parquet), so windows and bins sit where the piston really moved,
whatever the actuator delay or the time axis' origin.

Noise. Each observation's standard error combines (a) the variance of a mean of n consecutive
samples under the campaign's pooled force-noise model (:mod:`isokinetic.measurement.noise`: white
plus first-order coloured noise with an additive and a force-proportional part, fitted to the
windows' variograms, so autocorrelated noise is not mistaken for signal) at the observation's mean
square force, and (b) a between-period scatter ``rep_rel·|F|``, the period-to-period difference of
the window means beyond (a), estimated robustly and consistently
(:func:`isokinetic.measurement.noise.between_period_scatter`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import case_plan
from isokinetic.measurement.noise import between_period_scatter, fit_noise_model
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import Drive, drive_times
from isokinetic.stages.nominal import measured_drive, motion_start
from isokinetic.stages.windows import WindowSpec, windowed_half_periods

#: Per-observation columns gathered while the observations are built (:class:`_Collector`).
COLUMNS = ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop", "force_N",
           "msq_N2", "n", "fs", "white_se2", "speed_rel_se")
#: Columns of :class:`Observations` taken as they were gathered.
KEPT_COLUMNS = ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop", "force_N")
_INT_COLUMNS = ("case_index", "segment", "period", "start", "stop", "n")
_TEXT_COLUMNS = ("case", "kind")


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
    viscosity_scale: tuple[float, ...] = ()     # per plan, μ(T_case)/μ_nominal (viscosity law); empty: all 1

    def __len__(self) -> int:
        return int(self.force_N.size)

    @property
    def is_window(self) -> np.ndarray:
        return self.kind == "window"

    def subset(self, mask: np.ndarray) -> Observations:
        """The observations where ``mask``; each plan cut to the last sample they need."""
        keep = np.flatnonzero(mask)
        used = sorted(set(self.case_index[keep].tolist()))
        remap = {old: new for new, old in enumerate(used)}
        plans, drives = [], []
        scales = tuple(self.viscosity_scale[old] for old in used) if self.viscosity_scale else ()
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
                            drives=tuple(drives) if self.drives else (), noise=self.noise, viscosity_scale=scales,
                            speed_rel_se=None if self.speed_rel_se is None else self.speed_rel_se[keep], **fields_)


@dataclass(frozen=True)
class CaseRecord:
    """One case's measured record in plan time, and the plan-time grid of its driven model."""

    plan: CasePlan
    tau_s: np.ndarray            # record time minus the measured motion start
    force_N: np.ndarray
    displacement_m: np.ndarray
    model_times_s: np.ndarray    # the driven model's sample times (plan time)
    drive: Drive


@dataclass
class _Collector:
    """Accumulates the observations of a campaign, case after case (a builder: mutable on purpose).

    ``force_offset_N`` is taken off the samples the noise model sees; windows named (case, segment)
    in ``unsteady`` are kept out of the noise fit.
    """

    force_offset_N: float = 0.0
    unsteady: frozenset = frozenset()
    cols: dict[str, list] = field(default_factory=lambda: {k: [] for k in COLUMNS})
    plans: list = field(default_factory=list)
    drives: list = field(default_factory=list)
    scales: list = field(default_factory=list)           # per plan, μ(T_case)/μ_nominal
    window_samples: dict = field(default_factory=dict)   # sample rate -> steady windows' samples
    all_windows: dict = field(default_factory=dict)      # sample rate -> every window's samples

    def add(self, rec: CaseRecord, kind: str, k: int, sign: float, a: float, b: float) -> int:
        """Add the mean over plan times [a, b) of segment ``k``; the model's stop sample (0: too few samples)."""
        m0, m1 = np.searchsorted(rec.tau_s, [a, b], side="left")
        j0, j1 = np.searchsorted(rec.model_times_s, [a, b], side="left")
        if m1 - m0 < 2 or j1 - j0 < 2:
            return 0
        plan, cols = rec.plan, self.cols
        fs = plan.sample_rate_Hz
        fw = rec.force_N[m0:m1]
        fn = fw - self.force_offset_N
        cols["case"].append(plan.case)
        cols["case_index"].append(len(self.plans))
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
            self.all_windows.setdefault(fs, []).append(fn)
            if (plan.case, k) not in self.unsteady:
                self.window_samples.setdefault(fs, []).append(fn)
        cols["white_se2"].append(float(np.var(fw, ddof=1)) / fw.size)
        return int(j1)

    def add_case(self, rec: CaseRecord, spec: WindowSpec, n_bins: int, viscosity_scale: float = 1.0) -> None:
        """The window and ``n_bins`` transient bins of each half-period of one case (modelled with the
        viscosity times ``viscosity_scale``: the oil at the case's temperature)."""
        plan = rec.plan
        fs, half = plan.sample_rate_Hz, plan.period_s / 2.0
        last = 0
        for k, (t0, _t1, sign) in enumerate(windowed_half_periods(plan, float(rec.tau_s[-1]), spec), start=1):
            # the window's end is closed (as windows.window_ranges): one step past it, half a sample
            a, b = t0 + spec.start_fraction * half, t0 + spec.end_fraction * half + 0.5 / fs
            before = len(self.cols["case"])
            last = max(last, self.add(rec, "window", k, sign, a, b))
            rel_se = speed_relative_se(rec.tau_s, rec.displacement_m, a, b)
            edges = t0 + np.linspace(0.0, spec.start_fraction * half, n_bins + 1)
            for a, b in zip(edges[:-1], edges[1:], strict=True):
                self.add(rec, "transient", k, sign, a, b)
            self.cols["speed_rel_se"] += [rel_se] * (len(self.cols["case"]) - before)
        self.plans.append(replace(plan, duration_s=float(rec.model_times_s[max(last - 1, 0)])))
        self.drives.append(rec.drive)
        self.scales.append(float(viscosity_scale))

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v, dtype=np.int64 if k in _INT_COLUMNS else (object if k in _TEXT_COLUMNS else float))
                for k, v in self.cols.items()}


def case_record(row: pd.Series, series: pd.DataFrame, win: pd.DataFrame) -> CaseRecord | None:
    """The record of a cases.parquet row in plan time, driven by its windows' measured speeds; None
    unless the case has its four windows (``win``: its characteristic rows indexed by segment)."""
    plan = case_plan(row)
    start_s = motion_start(row)
    t = series["time_s"].to_numpy()
    tau = t - start_s
    if sorted(win.index) != [1, 2, 3, 4]:
        return None
    drive = measured_drive(win.index, win["velocity_m_s"], float(t[0]), start_s, plan.sample_rate_Hz)
    tm = drive_times(replace(plan, duration_s=float(tau[-1])), drive)
    return CaseRecord(plan=plan, tau_s=tau, force_N=series["force_N"].to_numpy(),
                      displacement_m=series["displacement_m"].to_numpy(), model_times_s=tm, drive=drive)


def build_observations(campaign: str, cases: pd.DataFrame, char: pd.DataFrame,
                       load_series: Callable[[pd.Series], pd.DataFrame], spec: WindowSpec = WindowSpec(),
                       n_bins: int = 4, force_offset_N: float = 0.0,
                       unsteady: frozenset = frozenset(), input_var_N2: np.ndarray | None = None,
                       viscosity_scales: Mapping[str, float] | None = None) -> Observations:
    """Windows and transient bins of every triangle case, in plan time, with honest standard errors.

    Measured means are taken from the case's series over [a, b) in plan time (record time minus
    ``motion_start_s``), the model's over the same plan-time interval of its driven grid, so both
    use the same samples. The proportional part of the noise scales with the true force, so the
    noise model sees the samples less a known load-cell offset ``force_offset_N``, and only the
    windows not named (case, segment) in ``unsteady`` (the stage's ``prepare`` finds both first).
    ``input_var_N2`` adds, per observation, the variance that the measured drive speed's own error
    propagates into the model (:func:`isokinetic.diagnosis.model.drive_input_variance`).
    ``viscosity_scales`` (case -> μ(T_case)/μ_nominal) models each case at its own temperature's viscosity.
    """
    by_case = {c: g.set_index("segment") for c, g in char.groupby("case")}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle") & cases["case"].isin(by_case)]
    collector = _Collector(force_offset_N, unsteady)
    for _, row in ok.iterrows():
        series = load_series(row)
        rec = case_record(row, series, by_case[case_plan(row).case])
        if rec is not None:
            collector.add_case(rec, spec, n_bins, (viscosity_scales or {}).get(rec.plan.case, 1.0))
    return _observations(campaign, collector, input_var_N2)


def _observations(campaign: str, collector: _Collector, input_var_N2: np.ndarray | None) -> Observations:
    """The gathered means with their standard errors: noise model, floor, drive input, between-period scatter."""
    arrays = collector.arrays()
    se2, noise = _noise_variances({**collector.all_windows, **collector.window_samples}, arrays)
    # a floor where the noise model has nothing (constant, quantised windows): the samples' own scatter
    floor = np.maximum(arrays["white_se2"], (1e-9 * np.abs(arrays["force_N"]) + 1e-9) ** 2)
    se2 = np.where(se2 > 0.0, se2, floor)
    if input_var_N2 is not None and len(input_var_N2) == se2.size:
        se2 = se2 + input_var_N2
    force = arrays["force_N"]
    rep_rel = _between_period(arrays, se2)
    sigma = np.sqrt(se2 + (rep_rel * force) ** 2)
    keep = {k: arrays[k] for k in KEPT_COLUMNS}
    scales = tuple(collector.scales) if any(x != 1.0 for x in collector.scales) else ()
    return Observations(campaign=campaign, plans=tuple(collector.plans), drives=tuple(collector.drives),
                        viscosity_scale=scales,
                        rep_rel=rep_rel, sigma_N=sigma, noise={**noise, "between_period_rel": rep_rel},
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
