"""The observations a diagnosis compares with the model: window and transient-bin means, in plan time.

Sine cases give phase bins of their steady cycles instead, in the plan time of their fitted motion, with
their own noise model (:mod:`isokinetic.diagnosis.sine_observations`); the rest of this docstring is about
triangle cases.

Data. The *observations* of a campaign are, for every status-ok triangle case and each of its four
half-periods, the steady window of the characteristic (mean force over [start, end]·T/2, the
window of "A method for the identification of hydraulic damper characteristics from steady
velocity inputs", Titurus et al.) and ``n_bins`` *transient bins* that split the part before the
window, [0, start]·T/2, into equal times (the relaxation after each velocity reversal that the
windows leave out). All times are *plan times*: record time minus the case's measured motion start
(``motion_start_s`` of cases.parquet), so windows and bins sit where the piston really moved,
whatever the actuator delay or the time axis' origin. A sample the record lacks (a logger's dropped sample)
is left out of the model's mean too (``Observations.holes``), so both are means over the same times: inside a
reversal's transient one missing sample moves a bin's mean by a large share of the force's swing. A window's
force spikes (:mod:`isokinetic.measurement.spikes`, the characteristic's rule on the same samples) are left out
the same way, of the window's mean, of the model's, and of the samples the noise model sees; the transient
bins are not searched for spikes (a reversal's force is no steady trend to tell a spike from).

Noise. Each observation's standard error combines (a) the variance of a mean of n consecutive
samples under the campaign's pooled force-noise model (:mod:`isokinetic.measurement.noise`: white
plus first-order coloured noise with an additive and a force-proportional part, fitted to the
windows' variograms, so autocorrelated noise is not mistaken for signal) at the observation's mean
square force, and (b) a between-period scatter ``rep_rel·|F|``, the period-to-period difference of
the window means beyond (a), estimated robustly and consistently
(:func:`isokinetic.measurement.noise.between_period_scatter`).

Within-window parts. Each triangle window is also split into WINDOW_PARTS equal times (equal strokes: the
piston moves at constant speed there) whose means (``Observations.subwindows``, kind 'window', the same cases
and segments, standard errors from the pooled noise model alone) are never fitted: the residual-structure tests
look at how the force changes along the stroke inside a window (:mod:`isokinetic.diagnosis.structure`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import case_plan
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.diagnosis.sine_observations import (
    N_SINE_BINS,
    SKIPPED_CYCLES,
    SineFit,
    between_case_scatter,
    bin_variance_model,
    fit_sine,
    mean_speed,
    phase_bins,
)
from isokinetic.measurement.drive import measured_drive
from isokinetic.measurement.noise import between_period_scatter, fit_noise_model
from isokinetic.measurement.spikes import spike_mask
from isokinetic.measurement.windows import WindowSpec, motion_start, windowed_half_periods
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import Drive, drive_times
from isokinetic.physics.sine_drive import SineDrive

#: Per-observation columns gathered while the observations are built (:class:`_Collector`).
COLUMNS = ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop", "force_N",
           "msq_N2", "n", "fs", "white_se2", "speed_rel_se", "slot", "cycle", "cycle_s")
#: Columns of :class:`Observations` taken as they were gathered.
KEPT_COLUMNS = ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop", "force_N")
_INT_COLUMNS = ("case_index", "segment", "period", "start", "stop", "n", "slot", "cycle")
_TEXT_COLUMNS = ("case", "kind")
#: Equal parts of each triangle window kept as ``Observations.subwindows`` (positions along the stroke).
WINDOW_PARTS = 4


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
    drives: tuple[Drive | SineDrive | None, ...] = ()
    noise: dict = field(default_factory=dict)   # the pooled noise model(s), for the report
    speed_rel_se: np.ndarray | None = None      # relative standard error of the drive's measured speed
    viscosity_scale: tuple[float, ...] = ()     # per plan, μ(T_case)/μ_nominal (viscosity law); empty: all 1
    # (observation, model sample within its case) of the model samples in an observation's range that have no
    # measured sample (dropped samples): the model's mean leaves them out (:func:`missing_samples`)
    holes: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    # the triangle windows' WINDOW_PARTS parts (never fitted; None: not built, or a subset)
    subwindows: Observations | None = None
    # the load cell's declared calibration (gain, relative standard uncertainty) (campaign.json force_calibration,
    # manifest columns.force.calibration); None: none declared
    force_calibration: tuple[float, float] | None = None

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
            if isinstance(drive, SineDrive):   # its grid: n_samples from grid_start_s
                drive = replace(drive, n_samples=int(self.stop[rows].max()))
                plans.append(plan)
            else:
                offset = 0.0 if drive is None else drive.grid_offset_s
                plans.append(replace(plan, duration_s=offset + (int(self.stop[rows].max()) - 1) / plan.sample_rate_Hz))
            drives.append(drive)
        fields_ = {name: getattr(self, name)[keep] for name in ("case", "kind", "segment", "period", "sign",
                                                                "speed_m_s", "start", "stop", "force_N", "sigma_N")}
        new_row = np.cumsum(np.asarray(mask, dtype=bool)) - 1
        held = np.asarray(mask, dtype=bool)[self.holes[:, 0]]
        holes = np.column_stack([new_row[self.holes[held, 0]], self.holes[held, 1]])
        return Observations(campaign=self.campaign, plans=tuple(plans), rep_rel=self.rep_rel, holes=holes,
                            case_index=np.array([remap[i] for i in self.case_index[keep]], dtype=np.int64),
                            drives=tuple(drives) if self.drives else (), noise=self.noise, viscosity_scale=scales,
                            force_calibration=self.force_calibration,
                            speed_rel_se=None if self.speed_rel_se is None else self.speed_rel_se[keep], **fields_)


@dataclass(frozen=True)
class CaseRecord:
    """One case's measured record in plan time, and the plan-time grid of its driven model."""

    plan: CasePlan
    tau_s: np.ndarray            # record time minus the measured motion start
    force_N: np.ndarray
    displacement_m: np.ndarray
    model_times_s: np.ndarray    # the driven model's sample times (plan time)
    drive: Drive | SineDrive
    fit: SineFit | None = None   # a sine case's fitted motion


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
    sine_model_means: Mapping = field(default_factory=dict)   # (case, model start sample) -> a model's bin mean
    holes: list = field(default_factory=list)            # (observation, model sample) without a measured sample
    parts: _Collector | None = None                      # the windows' WINDOW_PARTS parts (same plans)
    spikes: dict = field(default_factory=dict)           # (case, first, end sample) -> its spike mask
    enclosing: tuple | None = None                       # a parts collector: (case, first, end) of their window

    def add(self, rec: CaseRecord, kind: str, k: int, sign: float, a: float, b: float, period: int | None = None,
            speed_m_s: float | None = None, slot: int | None = None, cycle: int = -1) -> int:
        """Add the mean over plan times [a, b) of segment ``k``; the model's stop sample (0: too few samples).
        ``period`` (default: the triangle's (k + 1) // 2), ``speed_m_s`` (default: the planned speed),
        ``slot`` (the place in a period matched across periods, default ``sign``) and ``cycle`` (-1: none)
        for a sine's bins."""
        m0, m1 = np.searchsorted(rec.tau_s, [a, b], side="left")
        j0, j1 = np.searchsorted(rec.model_times_s, [a, b], side="left")
        if m1 - m0 < 2 or j1 - j0 < 2:
            return 0
        plan, cols = rec.plan, self.cols
        fs = plan.sample_rate_Hz
        if m1 - m0 < j1 - j0:
            row = len(cols["case"])
            self.holes += [(row, int(j0 + h)) for h in missing_samples(rec.tau_s[m0:m1], rec.model_times_s[j0:j1], fs)]
        fw = rec.force_N[m0:m1]
        if kind == "window" and plan.waveform == "triangle":   # the characteristic's spikes, left out of both means
            fw = self._without_spikes(rec, m0, m1, j0, j1, len(cols["case"]))
        fn = fw - self.force_offset_N
        cols["case"].append(plan.case)
        cols["case_index"].append(len(self.plans))
        cols["kind"].append(kind)
        cols["segment"].append(k)
        cols["period"].append((k + 1) // 2 if period is None else period)
        cols["sign"].append(sign)
        cols["speed_m_s"].append(plan.velocity_m_s if speed_m_s is None else speed_m_s)
        cols["slot"].append(int(sign) if slot is None else slot)
        cols["cycle"].append(cycle)
        cols["cycle_s"].append(1.0 / plan.frequency_Hz if cycle >= 0 else math.nan)
        cols["start"].append(int(j0))
        cols["stop"].append(int(j1))
        cols["force_N"].append(float(fw.mean()))
        cols["msq_N2"].append(float(np.mean(fn * fn)))
        cols["n"].append(int(m1 - m0))
        cols["fs"].append(fs)
        if kind == "window" and plan.waveform == "triangle":   # a sine's noise: its difference windows
            self.all_windows.setdefault(fs, []).append(fn)
            if (plan.case, k) not in self.unsteady:
                self.window_samples.setdefault(fs, []).append(fn)
        cols["white_se2"].append(float(np.var(fw, ddof=1)) / fw.size)
        return int(j1)

    def _without_spikes(self, rec: CaseRecord, m0: int, m1: int, j0: int, j1: int, row: int) -> np.ndarray:
        """The force of the measured samples [m0, m1) less the spikes the characteristic leaves out of the window
        (:func:`isokinetic.measurement.spikes.spike_mask`, the same samples; a window's part: those its window
        leaves out there), each spike's model sample made a hole of observation ``row`` so that the model's mean
        leaves it out too."""
        fw = rec.force_N[m0:m1]
        key = (rec.plan.case, int(m0), int(m1))
        spikes = self.spikes.get(key)
        window = self.enclosing
        if spikes is None and window is not None and window[0] == key[0] and window[1] <= m0 and m1 <= window[2] \
                and window in self.spikes:   # a window's part: the samples its window leaves out
            spikes = self.spikes[window][m0 - window[1]:m1 - window[1]]
        if spikes is None:
            spikes = self.spikes[key] = spike_mask(rec.force_N, int(m0), int(m1))
        if not spikes.any():
            return fw
        model = rec.model_times_s[j0:j1]
        at = np.clip(np.searchsorted(model, rec.tau_s[m0:m1][spikes] - 0.5 / rec.plan.sample_rate_Hz), 0,
                     model.size - 1)
        self.holes += [(row, int(j0 + j)) for j in np.unique(at)]
        return fw[~spikes]

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
            if self.parts is not None:
                m0, m1 = np.searchsorted(rec.tau_s, [a, b], side="left")
                self.parts.enclosing = (plan.case, int(m0), int(m1))
                self.parts.add_parts(rec, k, sign, a, b)
            rel_se = speed_relative_se(rec.tau_s, rec.displacement_m, a, b)
            edges = t0 + np.linspace(0.0, spec.start_fraction * half, n_bins + 1)
            for a, b in zip(edges[:-1], edges[1:], strict=True):
                self.add(rec, "transient", k, sign, a, b)
            self.cols["speed_rel_se"] += [rel_se] * (len(self.cols["case"]) - before)
        self.plans.append(replace(plan, duration_s=float(rec.model_times_s[max(last - 1, 0)])))
        self.drives.append(rec.drive)
        self.scales.append(float(viscosity_scale))

    def add_parts(self, rec: CaseRecord, k: int, sign: float, a: float, b: float) -> None:
        """The WINDOW_PARTS equal parts of the window [a, b) of segment ``k`` (a collector of parts, whose plans
        are the windows' collector's)."""
        edges = np.linspace(a, b, WINDOW_PARTS + 1)
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            before = len(self.cols["case"])
            self.add(rec, "window", k, sign, lo, hi)
            self.cols["speed_rel_se"] += [0.0] * (len(self.cols["case"]) - before)

    def add_sine_case(self, rec: CaseRecord, n_bins: int, viscosity_scale: float = 1.0) -> None:
        """The ``n_bins`` phase bins of every steady cycle of a sine case (:mod:`sine_observations`; of the
        last cycle, those the record holds), and its drive cut to the last model sample they need."""
        fit = rec.fit
        period = 1.0 / fit.frequency_Hz
        end = float(rec.tau_s[-1]) + 1.0 / rec.plan.sample_rate_Hz    # a bin may lack its last sample
        last = 0
        for m in range(SKIPPED_CYCLES, int(math.ceil(end / period))):
            steady = m - SKIPPED_CYCLES
            for j, (fa, fb, sign, kind) in enumerate(phase_bins(n_bins)):
                a, b = (m + fa) * period, (m + fb) * period
                if b > end:    # the record ends inside the cycle: its complete bins only
                    break
                before = len(self.cols["case"])
                last = max(last, self.add(rec, kind, 2 * steady + (1 if sign > 0 else 2), sign, a, b,
                                          1 + steady % 2, mean_speed(rec.drive, a, b), j, m))
                self.cols["speed_rel_se"] += [fit.amplitude_rel_se] * (len(self.cols["case"]) - before)
        if last == 0:
            return
        self.plans.append(rec.plan)
        self.drives.append(replace(rec.drive, n_samples=last))
        self.scales.append(float(viscosity_scale))

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(v, dtype=np.int64 if k in _INT_COLUMNS else (object if k in _TEXT_COLUMNS else float))
                for k, v in self.cols.items()}


def has_four_windows(segments) -> bool:
    """Whether a triangle case's window segments are all four (two periods, both directions): what
    :func:`case_record` needs to drive the model."""
    return sorted(segments) == [1, 2, 3, 4]


def case_record(row: pd.Series, series: pd.DataFrame, win: pd.DataFrame) -> CaseRecord | None:
    """The record of a cases.parquet row in plan time, driven by its windows' measured speeds; None
    unless the case has its four windows (``win``: its characteristic rows indexed by segment)."""
    plan = case_plan(row)
    start_s = motion_start(row)
    t = series["time_s"].to_numpy()
    tau = t - start_s
    if not has_four_windows(win.index):
        return None
    drive = measured_drive(win.index, win["velocity_m_s"], float(t[0]), start_s, plan.sample_rate_Hz)
    tm = drive_times(replace(plan, duration_s=float(tau[-1])), drive)
    return CaseRecord(plan=plan, tau_s=tau, force_N=series["force_N"].to_numpy(),
                      displacement_m=series["displacement_m"].to_numpy(), model_times_s=tm, drive=drive)


def sine_case_record(row: pd.Series, series: pd.DataFrame, displacement_scale: float = 1.0) -> CaseRecord | None:
    """The record of a sine case of cases.parquet, in the plan time of its fitted motion (τ = 0 at the fitted
    sine's cycle start nearest to the record's start), driven by that sine with its amplitude divided by
    ``displacement_scale`` (an LVDT scale measured elsewhere); None for a record of under two cycles."""
    plan = case_plan(row)
    t = series["time_s"].to_numpy(dtype=float)
    y = series["displacement_m"].to_numpy(dtype=float)
    if t.size < 8 or not (plan.frequency_Hz > 0.0) or t[-1] - t[0] < (SKIPPED_CYCLES + 1) / plan.frequency_Hz:
        return None
    after = t >= t[0] + SKIPPED_CYCLES / plan.frequency_Hz
    fit = fit_sine(t[after], y[after], plan.frequency_Hz)
    if fit is None:
        return None
    fit = fit.divided(displacement_scale)
    start = fit.start_s(float(t[0]))
    fs = plan.sample_rate_Hz
    n = int(round((t[-1] - t[0]) * fs)) + 1
    drive = SineDrive(fit.amplitude_m, fit.frequency_Hz, float(t[0]) - start, n, fit.harmonics, fit.harmonic_se_m)
    return CaseRecord(plan=replace(plan, amplitude_m=fit.amplitude_m, frequency_Hz=fit.frequency_Hz), tau_s=t - start,
                      force_N=series["force_N"].to_numpy(dtype=float), displacement_m=y,
                      model_times_s=drive.times(fs), drive=drive, fit=fit)


def build_observations(campaign: str, cases: pd.DataFrame, char: pd.DataFrame,
                       load_series: Callable[[pd.Series], pd.DataFrame], spec: WindowSpec = DEFAULTS.window,
                       n_bins: int = 4, force_offset_N: float = 0.0,
                       unsteady: frozenset = frozenset(), input_var_N2: np.ndarray | None = None,
                       viscosity_scales: Mapping[str, float] | None = None, sine_bins: int = N_SINE_BINS,
                       displacement_scale: float = 1.0,
                       sine_model_means: Mapping[tuple[str, int], float] | None = None,
                       spike_masks: dict | None = None, parts: bool = True) -> Observations:
    """Windows and transient bins of every triangle case, in plan time, with honest standard errors, and
    the phase bins of every status-ok sine case (:func:`sine_case_record`, :mod:`sine_observations`; its
    drive's amplitude divided by ``displacement_scale``; ``sine_model_means``: (case, model start sample) -> a
    model's bin mean, whose cycle-to-cycle change is taken off before the bins' noise model,
    :func:`sine_observations.bin_variance_model`).

    Measured means are taken from the case's series over [a, b) in plan time (record time minus
    ``motion_start_s``), the model's over the same plan-time interval of its driven grid, so both
    use the same samples. The proportional part of the noise scales with the true force, so the
    noise model sees the samples less a known load-cell offset ``force_offset_N``, and only the
    windows not named (case, segment) in ``unsteady`` (the stage's ``prepare`` finds both first).
    ``input_var_N2`` adds, per observation, the variance that the measured drive speed's own error
    propagates into the model (:func:`isokinetic.diagnosis.model.drive_input_variance`).
    ``viscosity_scales`` (case -> μ(T_case)/μ_nominal) models each case at its own temperature's viscosity.
    ``spike_masks``: a dict that remembers each window's spike mask across builds of the same records (a mask
    depends on the samples alone). ``parts`` off: no ``subwindows`` (a build whose parts nothing reads).
    """
    by_case = {c: g.set_index("segment") for c, g in char.groupby("case")}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle") & cases["case"].isin(by_case)]
    masks = {} if spike_masks is None else spike_masks
    collector = _Collector(force_offset_N, unsteady, sine_model_means=sine_model_means or {}, spikes=masks)
    collector.parts = _Collector(force_offset_N, unsteady, plans=collector.plans, drives=collector.drives,
                                 scales=collector.scales, spikes=masks) if parts else None
    for _, row in ok.iterrows():
        series = load_series(row)
        rec = case_record(row, series, by_case[case_plan(row).case])
        if rec is not None:
            collector.add_case(rec, spec, n_bins, (viscosity_scales or {}).get(rec.plan.case, 1.0))
    for _, row in cases[(cases["status"] == "ok") & (cases["waveform"] == "sine")].iterrows():
        rec = sine_case_record(row, load_series(row), displacement_scale)
        if rec is not None:
            collector.add_sine_case(rec, sine_bins, (viscosity_scales or {}).get(rec.plan.case, 1.0))
    return _observations(campaign, collector, input_var_N2)


def _observations(campaign: str, collector: _Collector, input_var_N2: np.ndarray | None) -> Observations:
    """The gathered means with their standard errors: noise model, floor, drive input, between-period scatter."""
    arrays = collector.arrays()
    se2, noise = _noise_variances({**collector.all_windows, **collector.window_samples}, arrays)
    se2, noise = _sine_variances(arrays, se2, noise, collector.sine_model_means)
    # a floor where the noise model has nothing (constant, quantised windows): the samples' own scatter
    floor = np.maximum(arrays["white_se2"], (1e-9 * np.abs(arrays["force_N"]) + 1e-9) ** 2)
    se2 = np.where(se2 > 0.0, se2, floor)
    if input_var_N2 is not None and len(input_var_N2) == se2.size:
        se2 = se2 + input_var_N2
    force = arrays["force_N"]
    rep_rel = _between_period(arrays, se2, _sine_model(arrays, collector.sine_model_means))
    sigma = np.sqrt(se2 + (rep_rel * force) ** 2)
    keep = {k: arrays[k] for k in KEPT_COLUMNS}
    scales = tuple(collector.scales) if any(x != 1.0 for x in collector.scales) else ()
    holes = np.array(collector.holes, dtype=np.int64).reshape(-1, 2)
    return Observations(campaign=campaign, plans=tuple(collector.plans), drives=tuple(collector.drives),
                        viscosity_scale=scales, holes=holes,
                        rep_rel=rep_rel, sigma_N=sigma, noise={**noise, "between_period_rel": rep_rel},
                        speed_rel_se=arrays["speed_rel_se"], subwindows=_parts(campaign, collector, noise), **keep)


def _parts(campaign: str, collector: _Collector, noise: Mapping) -> Observations | None:
    """The windows' parts (``collector.parts``) with the standard errors of the pooled noise model alone (what the
    parts of one window share, the between-period scatter, the drive's speed error, cancels within it); None
    where there are none."""
    if collector.parts is None or not collector.parts.cols["case"]:
        return None
    arrays = collector.parts.arrays()
    se2 = np.zeros(arrays["force_N"].size)
    for fs, model in (noise.get("objects") or {}).items():
        at = arrays["fs"] == fs
        se2[at] = model.mean_variance(arrays["n"][at], arrays["msq_N2"][at])
    floor = np.maximum(arrays["white_se2"], (1e-9 * np.abs(arrays["force_N"]) + 1e-9) ** 2)
    sigma = np.sqrt(np.where(se2 > 0.0, se2, floor))
    holes = np.array(collector.parts.holes, dtype=np.int64).reshape(-1, 2)
    return Observations(campaign=campaign, plans=tuple(collector.plans), drives=tuple(collector.drives),
                        rep_rel=0.0, sigma_N=sigma, holes=holes,
                        viscosity_scale=tuple(collector.scales) if any(x != 1.0 for x in collector.scales) else (),
                        **{k: arrays[k] for k in KEPT_COLUMNS})


def missing_samples(measured_s: np.ndarray, model_s: np.ndarray, fs: float) -> np.ndarray:
    """Indices into ``model_s`` of the model times with no measured time within half a sample interval
    (``measured_s`` ascending): the samples a record dropped."""
    i = np.searchsorted(measured_s, model_s)
    after = np.abs(measured_s[np.minimum(i, measured_s.size - 1)] - model_s)
    before = np.abs(model_s - measured_s[np.maximum(i - 1, 0)])
    return np.flatnonzero(np.minimum(before, after) > 0.5 / fs)


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


def _sine_variances(arrays: Mapping[str, np.ndarray], se2: np.ndarray, noise: dict,
                    model_means: Mapping[tuple[str, int], float]) -> tuple[np.ndarray, dict]:
    """The sine bins' variances from their cycle-to-cycle differences (:func:`bin_variance_model`, the cases of
    at least the median period), in place of the triangles' noise model; ``noise['sine']`` reports it."""
    sine = arrays["cycle"] >= 0
    if not sine.any():
        return se2, noise
    keys = np.array([f"{c}/{j}" for c, j in zip(arrays["case"][sine], arrays["slot"][sine], strict=True)])
    period = arrays["cycle_s"][sine]
    model = _sine_model(arrays, model_means)
    model = None if model is None else model[sine]
    force, n = arrays["force_N"][sine], arrays["n"][sine].astype(float)
    a, b = bin_variance_model(keys, arrays["cycle"][sine], force, n, period >= float(np.median(period)), model)
    out = se2.copy()
    out[sine] = a / n + b * force**2
    case_rel = 0.0
    if model is not None:
        case_rel = between_case_scatter(arrays["case"][sine], force - model, model, out[sine])
        out[sine] += (case_rel * force) ** 2
    return out, {**noise, "sine": {"white_var_N2": a, "rel_var": b, "between_case_rel": case_rel}}


def _sine_model(arrays: Mapping[str, np.ndarray], model_means: Mapping[tuple[str, int], float]) -> np.ndarray | None:
    """A model's mean of every sine bin (0 for the triangles' observations), None unless it has every one."""
    if not model_means:
        return None
    sine = arrays["cycle"] >= 0
    model = np.zeros(arrays["force_N"].size)
    model[sine] = [model_means.get((c, int(k)), math.nan) for c, k in
                   zip(arrays["case"][sine], arrays["start"][sine], strict=True)]
    return model if np.all(np.isfinite(model)) else None


def _between_period(arrays: Mapping[str, np.ndarray], se2: np.ndarray, model_N: np.ndarray | None = None) -> float:
    """Between-period relative scatter of the window means beyond their noise variance (of the means less
    ``model_N`` where given: a sine's modelled cycle-to-cycle convergence is no scatter). A triangle has one
    window per direction and period; a sine's "periods" alternate its steady cycles, and its last two cycles
    are compared (the most converged: a damper whose effects the model lacks converges in its own way over
    the first cycles)."""
    win = arrays["kind"] == "window"
    force = arrays["force_N"] - (0.0 if model_N is None else model_N)
    df = pd.DataFrame({"case": arrays["case"][win], "slot": arrays["slot"][win], "period": arrays["period"][win],
                       "force": force[win], "level": arrays["force_N"][win], "se2": se2[win]})
    wide = df.pivot_table(index=["case", "slot"], columns="period", values=["force", "level", "se2"],
                          aggfunc="last").dropna()
    if wide.empty:
        return 0.0
    d = (wide[("force", 2)] - wide[("force", 1)]).to_numpy()
    mean = 0.5 * (wide[("level", 1)].abs() + wide[("level", 2)].abs()).to_numpy()
    return float(between_period_scatter(d, (wide[("se2", 1)] + wide[("se2", 2)]).to_numpy(), mean))
