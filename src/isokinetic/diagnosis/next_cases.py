"""The candidate cases of the next tests (issue 37, :mod:`isokinetic.diagnosis.next_tests`): the rig's limits,
the triangle (or sine) cases within them and the paper's design constraints, a repeat, their observations, and the
noise of a new mean.

Triangle cases (a campaign with triangle windows) on a grid of speeds log-spaced from SPEED_BELOW times below the
campaign's slowest to the rig's top speed, and of amplitudes log-spaced within the design limits
(:class:`isokinetic.contracts.settings.DesignLimits`) and the piston's stroke; period 4Y/W (Eq. 26); only those whose
windows start after the pressure has converged for every rival (Eq. 28 from rest, and from the opposite direction's
steady pressure after each reversal: :func:`isokinetic.physics.convergence.stroke_to_converge`; a case above the A-T
diagram's quasi-steady boundary), with enough samples per window and no longer than MAX_CASE_S (the rivals' peak
force is checked by the plan); beside them a repeat of the campaign's first triangle case at the end (a drift of the
zero or of a parameter moves it, a constant effect does not). A sine-only campaign gets sine cases instead
(:func:`sine_cases`): the waveform its diagnosis reads. Each case's windows and transient bins (phase bins) are those
of the campaign's own (:mod:`isokinetic.diagnosis.observations`), driven by the planned motion. No standstill: the
diagnosis' search does not read one.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from isokinetic.contracts.settings import DEFAULTS, DesignLimits, WindowSpec
from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.sine_observations import SKIPPED_CYCLES, mean_speed, phase_bins
from isokinetic.measurement.windows import windowed_half_periods
from isokinetic.physics.convergence import strokes_to_converge_in_a_cycle
from isokinetic.physics.damper import Damper, Effects
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import Drive, drive_times
from isokinetic.physics.sine_drive import SineDrive

#: Rig time a case costs beside its record [s]: the stated default for setting a case up and starting it.
SETUP_S = 30.0
#: Longest record a candidate may need [s].
MAX_CASE_S = 1200.0
#: The speed grid: N_SPEEDS speeds from the campaign's slowest divided by SPEED_BELOW to the rig's top speed;
#: where the rig's top speed is not known, SPEED_ABOVE times the campaign's fastest (a stated default).
N_SPEEDS = 10
SPEED_BELOW = 4.0
SPEED_ABOVE = 2.0
#: Amplitudes of the grid, log-spaced within the design limits and the stroke.
N_AMPLITUDES = 4
#: The rig's largest force where the load cell's full scale is not known: this times the largest window force.
FORCE_ABOVE = 2.0
#: Fewest samples in a window, and in a transient bin, of a candidate triangle.
MIN_WINDOW_SAMPLES = 20
MIN_BIN_SAMPLES = 2
#: Sine candidates (a sine-only campaign's): N_FREQUENCIES frequencies log-spaced from the campaign's lowest divided
#: by FREQUENCY_BELOW to the rig's top frequency (where not known, FREQUENCY_ABOVE times the campaign's highest, a
#: stated default) times the N_AMPLITUDES amplitudes of the triangles' grid, of peak speed 2πfY from the campaign's
#: slowest over SPEED_BELOW to the rig's top speed, each recorded for SINE_CYCLES cycles and at least MIN_SINE_S (the
#: first cycle is left out, SKIPPED_CYCLES, and a bin's noise wants four steady cycles).
N_FREQUENCIES = 8
FREQUENCY_BELOW = 4.0
FREQUENCY_ABOVE = 2.0
SINE_CYCLES = 10
MIN_SINE_S = 10.0


@dataclass(frozen=True)
class RigLimits:
    """What the rig can run (SI): speeds, amplitudes (design limits and the stroke), force, sample rate; ``source``
    says where each came from."""

    max_speed_m_s: float
    min_amplitude_m: float
    max_amplitude_m: float
    max_force_N: float
    sample_rate_Hz: float
    max_frequency_Hz: float = math.nan
    source: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Probe:
    """A candidate case: its plan, its label and its rig time [s]."""

    case: str
    plan: CasePlan
    label: str
    rig_time_s: float


def rig_limits(obs: Observations, damper: Damper, design: DesignLimits = DEFAULTS.design,
               declared: Mapping | None = None) -> RigLimits:
    """The rig's limits: ``declared`` (max_speed_m_s, max_force_N, max_amplitude_m) where given, else the stated
    defaults (SPEED_ABOVE times the campaign's fastest speed, a sine's peak speed 2πfY among them, FORCE_ABOVE
    times its largest window force, FREQUENCY_ABOVE times its highest sine frequency); the amplitude within
    ``design`` and 0.95 of the smaller chamber's stroke (Eq. 2); the campaign's triangle sample rate (the most
    common; a sine-only campaign's, its sines')."""
    declared = dict(declared or {})
    tri = np.array([p.waveform == "triangle" for p in obs.plans])
    rates = [p.sample_rate_Hz for p, t in zip(obs.plans, tri, strict=True) if t] \
        or [p.sample_rate_Hz for p in obs.plans]
    fs = max(set(rates), key=rates.count)
    sines = [p for p in obs.plans if p.waveform == "sine"]
    speed = max([float(np.max(obs.speed_m_s)), *(2.0 * math.pi * p.frequency_Hz * p.amplitude_m for p in sines)]) \
        * SPEED_ABOVE
    frequency = max((p.frequency_Hz for p in sines), default=math.nan) * FREQUENCY_ABOVE
    force = float(np.max(np.abs(obs.force_N[obs.is_window]))) * FORCE_ABOVE
    stroke = 0.95 * min(damper.chamber_volume_1_m3, damper.chamber_volume_2_m3) / damper.piston_area_m2
    source = {"max_speed_m_s": "declared" if "max_speed_m_s" in declared else f"{SPEED_ABOVE:g} x the campaign's",
              "max_force_N": "declared" if "max_force_N" in declared else f"{FORCE_ABOVE:g} x the largest window force",
              "amplitude": "design limits and 0.95 of the stroke", "sample_rate_Hz": "the campaign's",
              "max_frequency_Hz": "declared" if "max_frequency_Hz" in declared
              else f"{FREQUENCY_ABOVE:g} x the campaign's highest sine frequency"}
    return RigLimits(max_speed_m_s=float(declared.get("max_speed_m_s", speed)),
                     min_amplitude_m=design.min_amplitude_m,
                     max_amplitude_m=min(design.max_amplitude_m, float(declared.get("max_amplitude_m", stroke)),
                                         stroke),
                     max_force_N=float(declared.get("max_force_N", force)), sample_rate_Hz=float(fs),
                     max_frequency_Hz=float(declared.get("max_frequency_Hz", frequency)), source=source)



def converges(plan: CasePlan, damper: Damper, effects: Sequence[Effects], phi: float, spec: WindowSpec) -> bool:
    """Whether every window of the triangle ``plan`` starts after Δp has reached ϕ of its steady value for each of
    ``effects``: the window's start stroke 2·start_fraction·Y against the stroke to converge from rest at -Y (Eq. 28,
    the first half-period) and from the opposite steady Δp after a reversal at either end."""
    y, w = plan.amplitude_m, plan.velocity_m_s
    have = 2.0 * spec.start_fraction * y
    for eff in effects:
        need = strokes_to_converge_in_a_cycle(w, damper, phi=phi, start_position_m=-y, effects=eff)
        if not all(np.isfinite(s) and s <= have for s in need):
            return False
    return True


def _window_samples_ok(plan: CasePlan, spec: WindowSpec, n_bins: int) -> bool:
    half_samples = 0.5 * plan.period_s * plan.sample_rate_Hz
    return ((spec.end_fraction - spec.start_fraction) * half_samples >= MIN_WINDOW_SAMPLES
            and spec.start_fraction * half_samples / n_bins >= MIN_BIN_SAMPLES)


def triangle_plan(case: str, speed_m_s: float, amplitude_m: float, fs: float) -> CasePlan:
    """A triangle case of speed W and amplitude Y: period 4Y/W (Eq. 26), two periods recorded, phase -π/2."""
    period = 4.0 * amplitude_m / speed_m_s
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=fs, amplitude_m=amplitude_m, period_s=period,
                    duration_s=2.0 * period)


def candidate_cases(obs: Observations, damper: Damper, limits: RigLimits, effects: Sequence[Effects],
                    spec: WindowSpec, n_bins: int, phi: float) -> list[Probe]:
    """The candidates (module docstring) of the waveform the campaign's diagnosis reads: a campaign with triangle
    windows, the triangle grid and a repeat of its first triangle case (a sine beside triangles is set aside by the
    search, and a triangle would set a sine-only campaign's sines aside); a sine-only campaign, the sine grid and a
    repeat of its first sine case. Each within the rig's limits and the design constraints (force checked later, on
    the rivals' predictions)."""
    if not any(p.waveform == "triangle" for p in obs.plans):
        return sine_cases(obs, limits)
    speeds = obs.speed_m_s[obs.speed_m_s > 0]
    lo = float(speeds.min()) / SPEED_BELOW if speeds.size else 1e-4
    grid_v = np.geomspace(lo, max(limits.max_speed_m_s, lo * 1.01), N_SPEEDS)
    grid_y = np.geomspace(limits.min_amplitude_m, max(limits.max_amplitude_m, limits.min_amplitude_m), N_AMPLITUDES)
    probes = []
    for v in grid_v:
        for y in grid_y:
            plan = triangle_plan(f"C{len(probes) + 1:03d}", float(v), float(y), limits.sample_rate_Hz)
            probes.append(Probe(plan.case, plan, f"triangle {v * 1e3:.3g} mm/s, {y * 1e3:.3g} mm", 0.0))
    first = next(p for p in obs.plans if p.waveform == "triangle")
    plan = replace(first, case=f"C{len(probes) + 1:03d}", duration_s=2.0 * first.period_s)
    probes.append(Probe(plan.case, plan, f"repeat of {first.case} at the end", 0.0))
    return [replace(p, rig_time_s=p.plan.duration_s + SETUP_S) for p in probes
            if p.plan.duration_s <= MAX_CASE_S and p.plan.velocity_m_s <= limits.max_speed_m_s * (1 + 1e-9)
            and limits.min_amplitude_m * (1 - 1e-9) <= p.plan.amplitude_m <= limits.max_amplitude_m * (1 + 1e-9)
            and _window_samples_ok(p.plan, spec, n_bins) and converges(p.plan, damper, effects, phi, spec)]


def sine_plan(case: str, frequency_Hz: float, amplitude_m: float, fs: float) -> CasePlan:
    """A sine case of SINE_CYCLES cycles and at least MIN_SINE_S, in whole cycles."""
    cycles = max(SINE_CYCLES, math.ceil(MIN_SINE_S * frequency_Hz))
    return CasePlan(case=case, waveform="sine", sample_rate_Hz=fs, amplitude_m=amplitude_m,
                    frequency_Hz=frequency_Hz, phase_rad=0.0, duration_s=cycles / frequency_Hz)


def sine_cases(obs: Observations, limits: RigLimits) -> list[Probe]:
    """A sine-only campaign's candidates: the frequency and amplitude grid (module docstring), each within the
    amplitude limits, the rig's top speed and frequency, and MAX_CASE_S, at least 8 samples a cycle; and a repeat of
    its first sine case at the end."""
    sines = [p for p in obs.plans if p.waveform == "sine"]
    f_lo = min(p.frequency_Hz for p in sines) / FREQUENCY_BELOW
    f_hi = limits.max_frequency_Hz if math.isfinite(limits.max_frequency_Hz) else max(p.frequency_Hz for p in sines)
    v_lo = min(2.0 * math.pi * p.frequency_Hz * p.amplitude_m for p in sines) / SPEED_BELOW
    probes = []
    for f in np.geomspace(f_lo, max(f_hi, f_lo * 1.01), N_FREQUENCIES):
        for y in np.geomspace(limits.min_amplitude_m, max(limits.max_amplitude_m, limits.min_amplitude_m),
                              N_AMPLITUDES):
            if 2.0 * math.pi * f * y >= v_lo:
                plan = sine_plan(f"C{len(probes) + 1:03d}", float(f), float(y), limits.sample_rate_Hz)
                probes.append(Probe(plan.case, plan, f"sine {f:.3g} Hz, {y * 1e3:.3g} mm", 0.0))
    first = sines[0]
    plan = sine_plan(f"C{len(probes) + 1:03d}", first.frequency_Hz, first.amplitude_m, first.sample_rate_Hz)
    probes.append(Probe(plan.case, plan, f"repeat of {first.case} at the end", 0.0))
    return [replace(p, rig_time_s=p.plan.duration_s + SETUP_S) for p in probes
            if p.plan.duration_s <= MAX_CASE_S and p.plan.sample_rate_Hz >= 8.0 * p.plan.frequency_Hz
            and 2.0 * math.pi * p.plan.frequency_Hz * p.plan.amplitude_m <= limits.max_speed_m_s * (1 + 1e-9)
            and p.plan.frequency_Hz <= max(f_hi, first.frequency_Hz) * (1 + 1e-9)
            and limits.min_amplitude_m * (1 - 1e-9) <= p.plan.amplitude_m <= limits.max_amplitude_m * (1 + 1e-9)]


def sine_probe_observations(campaign: str, probes: Sequence[Probe], n_bins: int,
                            viscosity_scale: float) -> Observations:
    """The phase bins (as a sine record's, :mod:`isokinetic.diagnosis.sine_observations`: every cycle after the
    first, ``n_bins`` each) of the sine ``probes``, driven by their planned sines; forces 0 and σ 1."""
    keys = ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop")
    cols = {k: [] for k in keys}
    plans, drives = [], []
    for probe in probes:
        plan = probe.plan
        fs, f = plan.sample_rate_Hz, plan.frequency_Hz
        drive = SineDrive(plan.amplitude_m, f, 0.0, int(round(plan.duration_s * fs)) + 1)
        times = drive.times(fs)
        last = 0
        for m in range(SKIPPED_CYCLES, int(round(plan.duration_s * f))):
            steady = m - SKIPPED_CYCLES
            for fa, fb, sign, kind in phase_bins(n_bins):
                a, b = (m + fa) / f, (m + fb) / f
                j0, j1 = (int(j) for j in np.searchsorted(times, [a, b], side="left"))
                values = (plan.case, len(plans), kind, 2 * steady + (1 if sign > 0 else 2), 1 + steady % 2, sign,
                          mean_speed(drive, a, b), j0, j1)
                for key, value in zip(keys, values, strict=True):
                    cols[key].append(value)
                last = max(last, j1)
        plans.append(plan)
        drives.append(replace(drive, n_samples=last))
    return _probe_observations(campaign, cols, plans, drives, viscosity_scale)


def probe_observations(campaign: str, probes: Sequence[Probe], spec: WindowSpec, n_bins: int,
                       viscosity_scale: float) -> Observations:
    """The windows and transient bins (as the campaign's, :mod:`isokinetic.diagnosis.observations`) of the
    triangle ``probes``, driven at their planned speeds; forces 0 and σ 1 (the plan sets σ)."""
    cols = {k: [] for k in ("case", "case_index", "kind", "segment", "period", "sign", "speed_m_s", "start", "stop")}
    plans, drives = [], []
    for probe in probes:
        plan = probe.plan
        drive = Drive((plan.velocity_m_s,) * 4)
        times = drive_times(plan, drive)
        half = plan.period_s / 2.0
        for k, (t0, _t1, sign) in enumerate(windowed_half_periods(plan, plan.duration_s, spec), start=1):
            edges = [(t0 + a, t0 + b, "transient") for a, b in
                     zip(*(np.linspace(0.0, spec.start_fraction * half, n_bins + 1)[s] for s in (slice(None, -1),
                                                                                                 slice(1, None))),
                         strict=True)]
            edges.append((t0 + spec.start_fraction * half, t0 + spec.end_fraction * half + 0.5 / plan.sample_rate_Hz,
                          "window"))
            for a, b, kind in edges:
                j0, j1 = np.searchsorted(times, [a, b], side="left")
                for key, value in (("case", plan.case), ("case_index", len(plans)), ("kind", kind), ("segment", k),
                                   ("period", (k + 1) // 2), ("sign", sign), ("speed_m_s", plan.velocity_m_s),
                                   ("start", int(j0)), ("stop", int(j1))):
                    cols[key].append(value)
        plans.append(replace(plan, duration_s=float(times[max(int(max(cols["stop"][-1], 1)) - 1, 0)])))
        drives.append(drive)
    return _probe_observations(campaign, cols, plans, drives, viscosity_scale)


def _probe_observations(campaign: str, cols: Mapping[str, list], plans: Sequence[CasePlan], drives: Sequence,
                        viscosity_scale: float) -> Observations:
    """The Observations of the candidates' gathered columns (forces 0, σ 1)."""
    arrays = {k: np.asarray(v, dtype=object if k in ("case", "kind") else
                            (np.int64 if k in ("case_index", "segment", "period", "start", "stop") else float))
              for k, v in cols.items()}
    n = len(arrays["case"])
    return Observations(campaign=campaign, plans=tuple(plans), drives=tuple(drives), force_N=np.zeros(n),
                        sigma_N=np.ones(n), rep_rel=0.0,
                        viscosity_scale=(viscosity_scale,) * len(plans) if viscosity_scale != 1.0 else (), **arrays)


def mean_variance_N2(noise: Mapping, fs: float, n: np.ndarray, force_N: np.ndarray) -> np.ndarray:
    """Variance of a mean of ``n`` samples at the true force ``force_N`` under the campaign's noise model: its
    triangle windows' (white plus coloured, :meth:`isokinetic.measurement.noise.NoiseModel.mean_variance`, of the
    sample rate nearest ``fs``), else its sine bins' (a/n + b F²); ValueError where it has neither."""
    objects = noise.get("objects") or {}
    n = np.maximum(np.asarray(n, dtype=float), 1.0)
    f2 = np.asarray(force_N, dtype=float) ** 2
    if objects:
        model = objects[min(objects, key=lambda r: abs(float(r) - fs))]
        return np.asarray(model.mean_variance(n, f2), dtype=float)
    sine = noise.get("sine")
    if sine:
        return sine["white_var_N2"] / n + sine["rel_var"] * f2 + (sine.get("between_case_rel", 0.0) ** 2) * f2
    raise ValueError("the campaign has no fitted noise model")
