"""The blind suite of the diagnosis, drawn on the reference rig, exported as raw campaigns (rule blind_generate).

A seeded suite of scenarios (:func:`generate_scenarios`) is exported as ordinary raw campaigns
(``results/blind/raw/<scenario>/``, ``source: simulation``, nothing in the folder names the truth)
with the withheld truth beside them (``results/blind/truth/<scenario>.json``, :func:`write_suite`).
They are diagnosed through exactly the chain a real raw campaign gets
(:mod:`isokinetic.stages.blind_diagnose`); only the scoring (:mod:`isokinetic.blind.score`)
reads the truth.

Scenario
    A campaign simulated by the independent reference rig (:mod:`isokinetic.reference.rig`:
    two chamber pressures, physical effect forms, an imperfect rig; it shares no code with the
    diagnosis' model) for a damper drawn around Table 1 of "A method for the identification of
    hydraulic damper characteristics from steady velocity inputs" (Titurus et al.;
    :data:`isokinetic.physics.damper.TABLE_1`: piston area, orifice area, orifice length and both
    chamber volumes each x U[0.7, 1.3]), a triangle plan of 8-12 speeds log-spaced between a low
    end in [0.005, 0.05] mm/s and a high end in [0.4, 1.5] mm/s (3 significant digits), each with
    the shortest period of {20, 80, 240} s whose amplitude Y = W T/4 reaches 0.3 mm (and Y <= 8 mm),
    50 Hz, acquisition 2T, in a random test order. Every scenario draws rig nuisances
    (:data:`RIG_RANGES`): actuator delay and servo lag, white plus proportional coloured force noise,
    load-cell offset and gain error, LVDT noise and a slow viscosity drift over the campaign, and the
    sensor chain's (:data:`SENSOR_RANGES`, issue 21): a force-channel low-pass (or none), an LVDT gain
    error, a load-cell zero drift and sample dropouts; the export has a command channel, so the LVDT's
    gain is measurable (its speed against the command's). It has
    zero, one or two of the catalogue effects :data:`EFFECTS` at 1x-5x their detection level, or one
    effect outside the catalogue (:data:`OUT_OF_CATALOGUE`: Stribeck friction, backlash, a relief
    valve, :func:`out_of_catalogue_true_effects`; or one that hides from the steady characteristic and shows on
    one ``where`` axis, issue 35: a groove open near mid-stroke, a worn bore, a gas spring, an orifice's wear or
    the oil's unlogged warm-up over the campaign, :mod:`isokinetic.blind.hidden`, its truth saying whether
    it moves the observations beyond their noise and so what answer is expected). The rig writes its own column
    names and units and rounds the manifest as a person would.

Sine-only scenario (issue 21)
    The same damper draw, nuisances and sensor chain, but the plan is a sine sweep
    (:func:`draw_sine_plan`: 5-7 frequencies log-spaced over 0.2-10 Hz, peak speeds log-spaced from
    0.03-0.1 to 0.6-1.5 mm/s, four cycles each at 1 kHz, in a random test order), with no effect or
    one catalogue effect at 1x-5x its sine detection level. The load cell's full scale follows the
    largest force the sweep reaches (:func:`plan_peak_force_N`: a stiff damper's force at a few Hz is
    held far below the steady force at the same peak speed by compressibility). The servo distorts the
    sine (:data:`DISTORTION_RANGES`, :func:`draw_sine_harmonics`): second and third harmonics of the
    actuator's motion, which the manifest and the command channel do not show.

Magnitude of an effect (what "1x detection" is measured in)
    friction: Coulomb force F_C [N]; leakage: conductance g [m3/(s Pa)]; asymmetry: |a| (random
    sign); discharge, viscosity: the relative deviation |theta/theta_0 - 1| from the nominal
    (manifest) value (random sign); air: the volume fraction V_G/V_C.

Detection level
    The smallest magnitude m whose noise-free characteristic differs from the nominal one by
    rms_z = 3, where rms_z = sqrt(mean_i ((F_i(m) - F_i,nom) / SE_i)^2) over all windows i of the
    plan, F from :class:`~isokinetic.stages.nominal.ModelPlan` (the model run through the plan's own
    windows), and SE_i the rig's exact noise of a mean of the window's n_i samples at F_i(m) (white
    plus proportional coloured noise, :func:`isokinetic.reference.campaign.mean_noise_variance`).
    On a sine-only plan the same computation runs on the phase bins the diagnosis compares
    (:class:`SineDetectionProblem`: the model driven by each case's planned sine, 16 bins a cycle
    over the cycles after the first, window and transient bins alike). Found by a coarse scan of
    log m upwards from 1e-7 of the effect's bound (first crossing of 3, so the *smallest* root)
    refined by ``brentq`` on log m. An effect whose 5x detection level exceeds its physical bound
    (:data:`BOUNDS`; or that never reaches rms_z = 3) makes the scenario re-draw its damper, plan and
    noise (same random stream, so still deterministic; the number of re-draws is recorded).

Determinism: the suite composition and order come from ``SeedSequence(seed)``
(:func:`isokinetic.contracts.scenarios.suite_composition`), scenario k from ``SeedSequence([seed, k])``;
the same arguments give identical scenarios and identical files, whichever chunk of the suite draws them.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from isokinetic.blind.hidden import HIDDEN_AXES, expected_answer, hidden_effects, plan_table
from isokinetic.contracts.scenarios import (
    DETECTION_RMS_Z,
    EFFECTS,
    MULTIPLE_RANGE,
    OUT_OF_CATALOGUE,
    scenario_names,
    suite_composition,
)
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.io import write_json
from isokinetic.measurement.model_windows import ModelPlan
from isokinetic.measurement.windows import WindowSpec
from isokinetic.physics.damper import NOMINAL, TABLE_1, Damper, Effects, friction_force, nominal_force
from isokinetic.physics.effects import REGISTRY
from isokinetic.physics.plan import CasePlan, paper_plan
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

log = logging.getLogger(__name__)

#: Damper fields perturbed per scenario, each x U[1 - GEOMETRY_SPREAD, 1 + GEOMETRY_SPREAD].
GEOMETRY_FIELDS = ("piston_area_m2", "orifice_area_m2", "orifice_length_m", "chamber_volume_1_m3",
                   "chamber_volume_2_m3")
GEOMETRY_SPREAD = 0.30

#: The suite's effects' records (isokinetic.physics.effects: each with a BlindDraw), by name.
DRAWN = {e.name: e for e in REGISTRY if e.blind is not None}
#: Largest plausible magnitude of each effect (its unit: see the module doc). 5x the detection
#: level must stay below it, else the scenario is re-drawn.
BOUNDS = {name: e.blind.bound for name, e in DRAWN.items()}
#: Unit of each effect's magnitude (truth files).
UNITS = {name: e.blind.unit for name, e in DRAWN.items()}
#: Effects whose magnitude carries a random sign.
SIGNED = tuple(name for name, e in DRAWN.items() if e.blind.signed)

TARGET_RMS_Z = DETECTION_RMS_Z
MAGNITUDE_BINS = (("1-2x", 1.0, 2.0), ("2-3x", 2.0, 3.0), ("3-5x", 3.0, math.inf))

PERIODS_S = (20.0, 80.0, 240.0)
MIN_AMPLITUDE_M = 0.3e-3
MAX_AMPLITUDE_M = 8.0e-3
SAMPLE_RATE_HZ = 50.0
LOW_END_MM_S = (0.005, 0.05)      # log-uniform range of the slowest speed
HIGH_END_MM_S = (0.4, 1.5)        # log-uniform range of the fastest speed
N_VELOCITIES = (8, 12)
#: Sine-only scenarios: a sweep of 5-7 frequencies log-spaced over SINE_FREQUENCY_HZ, peak speeds log-spaced
#: from a low end in SINE_LOW_SPEED_MM_S to a high end in SINE_HIGH_SPEED_MM_S (an amplitude of some 20-80 um),
#: SINE_CYCLES cycles each at SINE_SAMPLE_RATE_HZ, in a random test order.
SINE_FREQUENCY_HZ = (0.2, 10.0)
SINE_N_FREQUENCIES = (5, 7)
SINE_LOW_SPEED_MM_S = (0.03, 0.1)
SINE_HIGH_SPEED_MM_S = (0.6, 1.5)
SINE_CYCLES = 4
SINE_SAMPLE_RATE_HZ = 1000.0
MAX_REDRAWS = 50


#: Stribeck breakaway peak of the out-of-catalogue scenario, as a fraction of the nominal hydraulic
#: force at the Stribeck velocity.
STRIBECK_PEAK = 0.2

#: Ranges of the rig nuisances drawn in every scenario: actuator delay and first-order servo lag
#: [s]; white force noise [N]; proportional coloured noise (1 sigma, relative) and its corner [Hz];
#: load-cell offset (fraction of full scale, either sign) and gain error (either sign); LVDT noise
#: [m]; viscosity drift over the campaign (relative, either sign; temperature within about 0.1 C).
RIG_RANGES = {"delay_s": (0.0, 0.025), "servo_lag_s": (0.002, 0.010), "force_noise_N": (2.0, 10.0),
              "force_noise_rel": (0.005, 0.015), "noise_corner_Hz": (0.1, 5.0), "force_offset_fs": 0.02,
              "force_gain_error": 0.01, "displacement_noise_m": 1.0e-6, "viscosity_drift_rel": 0.003}

#: Ranges of the sensor-chain nuisances (issue 21), also drawn in every scenario: the force channel
#: behind an anti-alias Butterworth low-pass with probability ``force_filter_p``, its corner
#: log-uniform in ``force_filter_Hz`` and its order 1 or 2 (group delay 16-113 ms); the LVDT's gain
#: error (either sign); the load-cell zero drift over the whole campaign (fraction of full scale,
#: either sign); the fraction of samples dropped from the record.
SENSOR_RANGES = {"force_filter_p": 0.5, "force_filter_Hz": (2.0, 10.0), "displacement_gain_error": 0.015,
                 "force_drift_fs": 0.002, "dropout_fraction": (0.0, 0.01)}


#: A servo's distortion of a sine command (every scenario draws it, its sine cases carry it): the actuator's
#: second and third harmonics, relative to the fundamental, each with a uniform phase (a total harmonic
#: distortion of up to 3.6 %).
DISTORTION_RANGES = {"harmonic_2": (0.0, 0.03), "harmonic_3": (0.0, 0.02)}


DESCRIPTION = "Blind-test scenario: simulated damper test campaign; its unmodelled effects are withheld."
#: Parameter keys of the catalogue effects in truth records and diagnoses (SI, the catalogue's form).
PARAM_KEYS = {name: e.field for name, e in DRAWN.items()}
#: The reference rig's conversions a record's RigMapping names: (model value, damper, charge pressure [Pa]) ->
#: the rig's field (isokinetic.reference.campaign); a record without one maps the model's value as it is.
RIG_CONVERSIONS = {
    "leakage_gap_from_conductance": lambda value, damper, charge_Pa: rrc.leakage_gap_from_conductance(value, damper),
    "air_fraction_from_catalogue": lambda value, damper, charge_Pa: rrc.air_fraction_from_catalogue(value, charge_Pa),
}


def effect_text(effects: Iterable[str]) -> str:
    """Sorted (EFFECTS order) names joined by '+': 'friction', 'leakage+air', '' for none."""
    order = {e: i for i, e in enumerate(EFFECTS)}
    return "+".join(sorted(set(effects), key=lambda e: (order.get(e, len(EFFECTS)), e)))


def magnitude_bin(multiple: float) -> str:
    """'1-2x', '2-3x', '3-5x' of a magnitude in detection levels; '' for NaN (no effect)."""
    if multiple is None or not math.isfinite(multiple):
        return ""
    for name, _lo, hi in MAGNITUDE_BINS:
        if multiple < hi:
            return name
    return MAGNITUDE_BINS[-1][0]


# --------------------------------------------------------------------------------------------
# Effects and the detection level
# --------------------------------------------------------------------------------------------

def effect_fields(effect: str, magnitude: float, sign: float, damper: Damper) -> dict[str, float]:
    """Effects keyword arguments of one effect at ``magnitude`` (its unit) and ``sign``, in its record's
    BlindDraw form: 'absolute' the magnitude, 'signed' sign x magnitude, 'relative' the damper's own value
    x (1 + sign x magnitude)."""
    record = DRAWN.get(effect)
    if record is None:
        raise KeyError(f"unknown effect {effect!r}; known: {EFFECTS}")
    form = record.blind.form
    if form == "relative":
        return {record.field: getattr(damper, record.field) * (1.0 + sign * magnitude)}
    return {record.field: sign * magnitude if form == "signed" else magnitude}


class MeanDetection:
    """rms_z(m) of one effect against the nominal model over a problem's means (``forces``), each mean's SE the
    rig's exact noise of a mean of its ``n_samples`` at its force and ``rates_Hz`` (white plus proportional
    coloured, :func:`isokinetic.reference.campaign.mean_noise_variance`): what :class:`DetectionProblem` and
    :class:`SineDetectionProblem` share."""

    def se(self, force_N: np.ndarray) -> np.ndarray:
        return np.sqrt([rrc.mean_noise_variance(int(k), float(f), self.rig, float(r))
                        for k, f, r in zip(self.n_samples, force_N, self.rates_Hz, strict=True)])

    def rms_z(self, effect: str, magnitude: float, sign: float = 1.0) -> float:
        self.calls += 1
        f = self.forces(Effects(**effect_fields(effect, magnitude, sign, self.damper)))
        z = (f - self.nominal_N) / self.se(f)
        return float(np.sqrt(np.mean(z * z)))


@dataclass
class DetectionProblem(MeanDetection):
    """rms_z(m) of one effect in one scenario, evaluated through a prepared ModelPlan: its window means."""

    plan: ModelPlan
    damper: Damper
    rig: rr.RigImperfections
    nominal_N: np.ndarray
    calls: int = 0

    @classmethod
    def of(cls, name: str, cases: Sequence[CasePlan], damper: Damper, rig: rr.RigImperfections,
           spec: WindowSpec = DEFAULTS.window) -> DetectionProblem:
        mp = ModelPlan.from_cases(name, plan_table(name, cases), spec)
        return cls(mp, damper, rig, mp.forces(damper, NOMINAL)[0])

    def forces(self, effects: Effects) -> np.ndarray:
        """The model's window means [N]."""
        return self.plan.forces(self.damper, effects)[0]

    @property
    def n_samples(self) -> np.ndarray:
        return self.plan.stop - self.plan.start

    @property
    def rates_Hz(self) -> np.ndarray:
        return np.array([p.sample_rate_Hz for p in self.plan.plans])[self.plan.case_index]


@dataclass
class SineDetectionProblem(MeanDetection):
    """rms_z(m) of one effect in one sine-only scenario: the same computation as :class:`DetectionProblem` on
    the sine records' phase bins, which is what the diagnosis compares there.

    The noise-free model (Eq. 1, 2, 7 with the effects, friction added to the force;
    :func:`isokinetic.physics.sine_drive.sine_drive_response`) is driven by each case's planned sine from rest
    and sampled at the rig's sample times; its force is reduced to the diagnosis' phase bins
    (:data:`~isokinetic.diagnosis.sine_observations.N_SINE_BINS` per cycle, every cycle after the first
    ``SKIPPED_CYCLES``, window and transient bins alike); SE of a bin mean: the rig's exact noise of a mean of
    its n samples at its force (:func:`isokinetic.reference.campaign.mean_noise_variance`).
    """

    cases: tuple[CasePlan, ...]
    damper: Damper
    rig: rr.RigImperfections
    bins: tuple[np.ndarray, ...]    # per case, the bin of each sample (-1: in no bin)
    nominal_N: np.ndarray = field(default_factory=lambda: np.zeros(0))
    calls: int = 0

    @classmethod
    def of(cls, cases: Sequence[CasePlan], damper: Damper, rig: rr.RigImperfections) -> SineDetectionProblem:
        problem = cls(tuple(cases), damper, rig, tuple(sine_sample_bins(c) for c in cases))
        problem.nominal_N = problem.forces(NOMINAL)
        return problem

    def forces(self, effects: Effects) -> np.ndarray:
        """Bin means of the model's force [N], case after case."""
        out = []
        for force, b in zip(sine_model_forces(self.cases, self.damper, effects), self.bins, strict=True):
            used = b >= 0
            out.append(np.bincount(b[used], weights=force[used]) / np.bincount(b[used]))
        return np.concatenate(out)

    @property
    def n_samples(self) -> np.ndarray:
        return np.concatenate([np.bincount(b[b >= 0]) for b in self.bins])

    @property
    def rates_Hz(self) -> np.ndarray:
        return np.concatenate([np.full(int(b.max()) + 1, c.sample_rate_Hz)
                               for c, b in zip(self.cases, self.bins, strict=True)])


def sine_model_forces(cases: Sequence[CasePlan], damper: Damper, effects: Effects = NOMINAL) -> list[np.ndarray]:
    """The noise-free model's force [N] of each sine case at t = k/fs (k = 0 .. duration fs), driven by the
    planned sine from rest: A_p Δp (Eq. 1, 2, 7 with the effects) plus the friction of Eq. 8."""
    from isokinetic.physics.hydraulics import Hydraulics
    from isokinetic.physics.sine_drive import SineDrive, sine_drive_response

    hyd = Hydraulics.from_damper(damper, effects)
    out = []
    for c in cases:
        n = int(round(c.duration_s * c.sample_rate_Hz)) + 1
        _t, dp, vel = sine_drive_response(SineDrive(c.amplitude_m, c.frequency_Hz, 0.0, n), c.sample_rate_Hz, hyd)
        out.append(hyd.piston_area_m2 * dp + friction_force(vel, effects))
    return out


def sine_sample_bins(case: CasePlan) -> np.ndarray:
    """The phase bin of each of a sine case's samples t = k/fs (k = 0 .. duration fs, as the rig records):
    N_SINE_BINS per cycle, numbered on from the first cycle after SKIPPED_CYCLES; -1 before it and after the
    last whole cycle."""
    from isokinetic.diagnosis.sine_observations import N_SINE_BINS, SKIPPED_CYCLES

    n = int(round(case.duration_s * case.sample_rate_Hz)) + 1
    cycles = np.arange(n) * (case.frequency_Hz / case.sample_rate_Hz)
    whole = math.floor(case.duration_s * case.frequency_Hz + 1e-9)
    b = np.floor((cycles - SKIPPED_CYCLES) * N_SINE_BINS + 1e-9).astype(int)
    return np.where((cycles >= SKIPPED_CYCLES - 1e-12) & (b < (whole - SKIPPED_CYCLES) * N_SINE_BINS), b, -1)


def detection_level(problem: DetectionProblem | SineDetectionProblem, effect: str, sign: float = 1.0,
                    bound: float | None = None, target: float = TARGET_RMS_Z, scan_decades: float = 7.0,
                    scan_points: int = 15) -> float | None:
    """Smallest magnitude in (0, bound] with rms_z = ``target``; None when rms_z(bound) < target.

    Scan log m on ``scan_points`` points from bound*10^-scan_decades up to the bound (extended
    downwards while the lowest point is already above target), then ``brentq`` on log m between
    the last point below and the first point at/above the target.
    """
    bound = BOUNDS[effect] if bound is None else bound

    def f(x: float) -> float:  # log(rms_z / target) at magnitude e^x
        return math.log(problem.rms_z(effect, math.exp(x), sign) / target)

    grid = np.linspace(math.log(bound) - scan_decades * math.log(10.0), math.log(bound), scan_points)
    lo_val = f(grid[0])
    while lo_val >= 0.0:
        grid = grid - (grid[-1] - grid[0])
        lo_val = f(grid[0])
        if grid[0] < math.log(bound) - 40 * math.log(10.0):
            raise RuntimeError(f"{effect}: rms_z stays above {target} at vanishing magnitude")
    prev = grid[0]
    for x in grid[1:]:
        if f(x) >= 0.0:
            from scipy.optimize import brentq  # scipy.optimize (~0.5 s): only while the suite is generated

            return math.exp(brentq(f, prev, x, xtol=1e-6, rtol=1e-6, maxiter=200))
        prev = x
    return None


# --------------------------------------------------------------------------------------------
# Scenario generation (on the independent reference rig)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Scenario:
    """One blind scenario: a reference-rig campaign to export and its withheld truth."""

    name: str
    damper: Damper                            # nominal design (the manifest's damper block)
    cases: tuple[CasePlan, ...]               # the plan, in test order
    effects: rr.TrueEffects                   # the damper's true physics (reference-rig form)
    rig: rr.RigImperfections                  # the rig's nuisances
    noise_seed: int
    truth: tuple[str, ...]                    # catalogue effects, EFFECTS order
    out_of_catalogue: str = ""                # '' or one of OUT_OF_CATALOGUE
    magnitude: dict[str, float] = field(default_factory=dict)       # per effect, its unit
    sign: dict[str, float] = field(default_factory=dict)
    detection_level: dict[str, float] = field(default_factory=dict)
    multiple: dict[str, float] = field(default_factory=dict)        # magnitude / detection level
    redraws: int = 0
    sine_harmonics: tuple[tuple[int, float, float], ...] = ()       # the servo's distortion of its sine cases
    hidden: dict = field(default_factory=dict)      # a hidden kind's strength and signature (blind.hidden)

    @property
    def truth_text(self) -> str:
        return effect_text(self.truth)

    @property
    def magnitude_x_detection(self) -> float:
        """The weakest truth effect's magnitude in detection levels (NaN without effects)."""
        return min(self.multiple.values()) if self.multiple else math.nan

    @property
    def waveform(self) -> str:
        """'sine' for a sine-only campaign, else 'triangle'."""
        return "sine" if all(c.waveform == "sine" for c in self.cases) else "triangle"

    def rig_cases(self) -> list[rr.TriangleCase | rr.SineCase]:
        return [rr.SineCase(c.case, c.frequency_Hz, c.amplitude_m, round(c.duration_s * c.frequency_Hz, 9),
                            c.sample_rate_Hz, self.sine_harmonics) if c.waveform == "sine"
                else rr.TriangleCase(c.case, c.velocity_m_s, c.period_s, c.sample_rate_Hz) for c in self.cases]

    def truth_params(self) -> dict[str, float]:
        """Catalogue-form SI parameters of the truth effects (what an exact verdict should fit)."""
        eq = rrc.catalogue_equivalent(self.damper, self.effects)
        return {PARAM_KEYS[e]: float(eq[PARAM_KEYS[e]]) for e in self.truth}

    def instrument_truth(self) -> dict[str, float]:
        """The rig's instrument terms as the diagnosis reports them: the delay of the piston behind the
        command in a steady ramp (delay + servo lag), the load-cell offset (at the campaign's middle: a
        zero drift moves it), the load-cell gain, the force channel's lag (its low-pass' group delay, 0
        without one), the LVDT's scale and the load-cell zero drift [N/s]."""
        rig = self.rig
        middle = 0.5 * campaign_duration_s(self.cases)
        return {"delay_s": rig.delay_s + rig.servo_lag_s, "force_offset_N": rig.force_offset_N
                + rig.force_drift_N_s * middle, "force_gain": rig.force_gain,
                "force_lag_s": rig.force_group_delay_s(), "displacement_scale": rig.displacement_gain,
                "force_drift_N_s": rig.force_drift_N_s, "force_offset_at_start_N": rig.force_offset_N}

    def truth_record(self) -> dict:
        """JSON-ready truth (results/blind/truth/<scenario>.json)."""
        return {
            "format_version": 3,
            "scenario": self.name,
            "generator": "isokinetic.reference",
            "truth": list(self.truth),
            "truth_text": self.truth_text,
            "out_of_catalogue": self.out_of_catalogue,
            "expected": expected_answer(self.out_of_catalogue, self.truth, self.hidden),
            "hidden": dict(self.hidden),
            "params": self.truth_params(),
            "instrument": self.instrument_truth(),
            "effects": dataclasses.asdict(self.effects),
            "rig": {**dataclasses.asdict(self.rig), "sine_harmonics": [list(h) for h in self.sine_harmonics]},
            "magnitude": dict(self.magnitude),
            "magnitude_unit": {e: UNITS[e] for e in self.truth},
            "sign": dict(self.sign),
            "detection_level": dict(self.detection_level),
            "multiple": dict(self.multiple),
            "magnitude_x_detection": None if not self.multiple else self.magnitude_x_detection,
            "magnitude_bin": magnitude_bin(self.magnitude_x_detection),
            "detection_rms_z": TARGET_RMS_Z,
            "damper": self.damper.to_dict(),
            "waveform": self.waveform,
            "velocities_mm_s": [round(case_speed_m_s(c) * 1e3, 12) for c in self.cases],
            "periods_s": [c.period_s if c.waveform == "triangle" else 1.0 / c.frequency_Hz for c in self.cases],
            "noise_seed": self.noise_seed,
            "redraws": self.redraws,
        }


def _sig(x: float, digits: int = 4) -> float:
    return float(f"{x:.{digits}g}")


def draw_damper(rng: np.random.Generator) -> Damper:
    """Table 1 with the geometry fields x U[0.7, 1.3] (4 significant digits)."""
    values = TABLE_1.to_dict()
    for name in GEOMETRY_FIELDS:
        values[name] = _sig(values[name] * rng.uniform(1.0 - GEOMETRY_SPREAD, 1.0 + GEOMETRY_SPREAD))
    return Damper(**values)


def period_for(velocity_m_s: float) -> float:
    """Shortest period of PERIODS_S whose amplitude W T/4 reaches MIN_AMPLITUDE_M."""
    for period in PERIODS_S:
        if velocity_m_s * period / 4.0 >= MIN_AMPLITUDE_M * (1 - 1e-12):
            return period
    raise ValueError(f"speed {velocity_m_s * 1e3:.4g} mm/s: amplitude below {MIN_AMPLITUDE_M * 1e3} mm "
                     f"even at T = {PERIODS_S[-1]} s")


def draw_plan(rng: np.random.Generator, n_velocities: tuple[int, int] = N_VELOCITIES,
              low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
              high_end_mm_s: tuple[float, float] = HIGH_END_MM_S) -> list[CasePlan]:
    """Triangle cases T01.. of 3-significant-digit speeds, in a random test order (so that a slow
    drift over the campaign is not aligned with speed, as good practice has it)."""
    n = int(rng.integers(n_velocities[0], n_velocities[1] + 1))
    lo = math.exp(rng.uniform(math.log(low_end_mm_s[0]), math.log(low_end_mm_s[1])))
    hi = math.exp(rng.uniform(math.log(high_end_mm_s[0]), math.log(high_end_mm_s[1])))
    speeds = [v * 1e-3 for v in sorted({min(max(_sig(v, 3), 0.005), 1.5) for v in np.geomspace(lo, hi, n)})]
    cases = paper_plan(speeds, [period_for(v) for v in speeds], [], 1.0, SAMPLE_RATE_HZ, 1.0, 1.0)
    return [cases[int(i)] for i in rng.permutation(len(cases))]


def draw_sine_plan(rng: np.random.Generator) -> list[CasePlan]:
    """A sine sweep S01..: 5-7 frequencies log-spaced over SINE_FREQUENCY_HZ (3 significant digits), peak
    speeds log-spaced from a low end in SINE_LOW_SPEED_MM_S to a high end in SINE_HIGH_SPEED_MM_S (amplitudes
    to 4 digits, as the manifest writes them), SINE_CYCLES cycles each, in a random test order."""
    n = int(rng.integers(SINE_N_FREQUENCIES[0], SINE_N_FREQUENCIES[1] + 1))
    lo = math.exp(rng.uniform(*np.log(SINE_LOW_SPEED_MM_S)))
    hi = math.exp(rng.uniform(*np.log(SINE_HIGH_SPEED_MM_S)))
    cases = [CasePlan(f"S{i:02d}", "sine", SINE_SAMPLE_RATE_HZ, amplitude_m=_sig(v * 1e-3 / (2 * math.pi * f), 4),
                      frequency_Hz=f, phase_rad=0.0, duration_s=SINE_CYCLES / f)
             for i, (f, v) in enumerate(zip((_sig(f, 3) for f in np.geomspace(*SINE_FREQUENCY_HZ, n)),
                                            np.geomspace(lo, hi, n), strict=True), start=1)]
    return [cases[int(i)] for i in rng.permutation(len(cases))]


def case_speed_m_s(case: CasePlan) -> float:
    """A case's largest planned speed: the triangle's W, a sine's 2 pi f Y."""
    return case.velocity_m_s if case.waveform == "triangle" else 2.0 * math.pi * case.frequency_Hz * case.amplitude_m


def plan_peak_force_N(damper: Damper, cases: Sequence[CasePlan]) -> float:
    """The plan's largest nominal force [N]: the steady force at the fastest triangle speed; for sine cases the
    model's largest force over the record (compressibility keeps a stiff damper's force at a few Hz far below
    the steady force at the same peak speed, :func:`sine_model_forces`)."""
    tri = [c.velocity_m_s for c in cases if c.waveform == "triangle"]
    sines = [c for c in cases if c.waveform == "sine"]
    peak = float(np.max(np.abs(nominal_force(np.array(tri), damper)))) if tri else 0.0
    return max([peak] + [float(np.max(np.abs(f))) for f in sine_model_forces(sines, damper)])


def full_scale_N(damper: Damper, cases: Sequence[CasePlan]) -> float:
    """The load cell's full scale: the next of 1, 2, 5 x 10^k above 1.25 x the plan's largest force
    (:func:`plan_peak_force_N`)."""
    peak = 1.25 * plan_peak_force_N(damper, cases)
    k = math.floor(math.log10(max(peak, 1e-9)))
    return next(m * 10.0**k for m in (1.0, 2.0, 5.0, 10.0) if m * 10.0**k >= peak)


def campaign_duration_s(cases: Sequence[CasePlan]) -> float:
    """The campaign's length, its cases back to back (as the reference rig counts campaign time)."""
    return float(sum(c.duration_s + 1.0 / c.sample_rate_Hz for c in cases))


def draw_sensor_chain(rng: np.random.Generator, full_scale: float, duration_s: float) -> dict[str, float]:
    """The sensor-chain nuisances of one scenario (SENSOR_RANGES), as RigImperfections fields."""
    r = SENSOR_RANGES
    filtered = bool(rng.random() < r["force_filter_p"])
    corner = _sig(math.exp(rng.uniform(*np.log(r["force_filter_Hz"]))), 3)
    order = int(rng.integers(1, 3))
    gain = 1.0 + _sig(rng.uniform(-1.0, 1.0) * r["displacement_gain_error"], 3)
    drift = _sig(rng.uniform(-1.0, 1.0) * r["force_drift_fs"] * full_scale / duration_s, 3)
    dropout = _sig(rng.uniform(*r["dropout_fraction"]), 3)
    return {"force_filter_Hz": corner if filtered else 0.0, "force_filter_order": order if filtered else 2,
            "displacement_gain": gain, "force_drift_N_s": drift, "dropout_fraction": dropout}


def draw_rig(rng: np.random.Generator, full_scale: float, duration_s: float = 1.0,
             chain_rng: np.random.Generator | None = None) -> rr.RigImperfections:
    """Rig nuisances, drawn in every scenario (RIG_RANGES), and the sensor chain's (SENSOR_RANGES, the zero
    drift spread over ``duration_s``, the campaign's length) from their own stream ``chain_rng`` (None: an
    ideal sensor chain), so that a scenario is the same with or without its sensor chain."""
    r = RIG_RANGES
    rig = rr.RigImperfections(
        delay_s=_sig(rng.uniform(*r["delay_s"]), 3), servo_lag_s=_sig(rng.uniform(*r["servo_lag_s"]), 3),
        force_noise_N=_sig(rng.uniform(*r["force_noise_N"]), 3),
        force_noise_rel=_sig(rng.uniform(*r["force_noise_rel"]), 3),
        noise_corner_Hz=_sig(math.exp(rng.uniform(*np.log(r["noise_corner_Hz"]))), 3),
        force_offset_N=_sig(rng.uniform(-1.0, 1.0) * r["force_offset_fs"] * full_scale, 3),
        force_gain=1.0 + _sig(rng.uniform(-1.0, 1.0) * r["force_gain_error"], 3),
        displacement_noise_m=r["displacement_noise_m"],
        viscosity_drift_rel=_sig(rng.uniform(-1.0, 1.0) * r["viscosity_drift_rel"], 3),
        force_resolution_N=0.01, displacement_resolution_m=1e-8, command_resolution_m=1e-8)
    return rig if chain_rng is None else dataclasses.replace(rig, **draw_sensor_chain(chain_rng, full_scale,
                                                                                      duration_s))


def draw_sine_harmonics(rng: np.random.Generator) -> tuple[tuple[int, float, float], ...]:
    """The servo's distortion of a sine (:data:`DISTORTION_RANGES`): (k, relative amplitude, phase) of the
    second and third harmonics (:class:`isokinetic.reference.rig.SineCase`), 3 significant digits."""
    return tuple((k, _sig(rng.uniform(*DISTORTION_RANGES[f"harmonic_{k}"]), 3),
                  _sig(rng.uniform(-math.pi, math.pi), 3)) for k in (2, 3))


def charge_pressure_Pa(damper: Damper, cases: Sequence[CasePlan]) -> float:
    """Charge (accumulator) pressure of the drawn damper: twice the plan's largest steady Δp, at least
    5 MPa (2 significant digits), so that neither chamber comes near zero absolute pressure."""
    dp_max = float(np.max(np.abs(nominal_force(np.array([case_speed_m_s(c) for c in cases]), damper))))
    return _sig(max(5.0e6, 2.0 * dp_max / damper.piston_area_m2), 2)


def physical_effects(damper: Damper, magnitudes: Mapping[str, float], signs: Mapping[str, float],
                     charge_Pa: float = 5.0e6) -> rr.TrueEffects:
    """The reference rig's physical effects whose catalogue equivalents are ``magnitudes``: each effect's model
    value (:func:`effect_fields`) in its record's rig field (RigMapping), through the rig's conversion where it
    names one (:data:`RIG_CONVERSIONS`)."""
    kw: dict[str, float] = {"charge_pressure_Pa": charge_Pa}
    for e, m in magnitudes.items():
        (value,) = effect_fields(e, m, signs.get(e, 1.0), damper).values()
        rig = DRAWN[e].rig
        kw[rig.field] = RIG_CONVERSIONS[rig.conversion](value, damper, charge_Pa) if rig.conversion else value
    return rr.TrueEffects(**kw)


def out_of_catalogue_true_effects(kind: str, damper: Damper, cases: Sequence[CasePlan],
                                  friction_detection_N: float) -> rr.TrueEffects:
    """The reference rig's physical effects of an out-of-catalogue scenario of ``kind``
    (OUT_OF_CATALOGUE), strong enough to be seen.

    stribeck: a Coulomb force of 3x its detection level plus a breakaway peak decaying over v_S at the
    geometric middle of the plan's speeds (seals: 0.1-1 mm/s), F_S = STRIBECK_PEAK of the nominal
    hydraulic force at v_S (a weaker hump is absorbed by friction + viscosity: docs/diagnosis.md); backlash:
    30 um of free play; relief: a relief valve that cracks at half the plan's largest steady
    pressure and passes 30 % of the piston flow at it.
    """
    speeds = np.array([c.velocity_m_s for c in cases])
    if kind == "stribeck":
        v_s = float(np.sqrt(speeds.min() * speeds.max()))
        return rr.TrueEffects(coulomb_force_N=3.0 * friction_detection_N, stribeck_velocity_m_s=v_s,
                              stribeck_force_N=STRIBECK_PEAK * float(nominal_force(v_s, damper)))
    if kind == "backlash":
        return rr.TrueEffects(backlash_m=30e-6)
    if kind == "relief":
        dp_max = float(nominal_force(speeds.max(), damper)) / damper.piston_area_m2
        crack = 0.5 * dp_max
        unit = float(rr.relief_flow(dp_max, crack, 1.0, 0.7, damper.density_kg_m3))
        return rr.TrueEffects(relief_cracking_pressure_Pa=crack,
                              relief_area_gradient_m2_Pa=0.3 * damper.piston_area_m2 * speeds.max() / unit)
    raise KeyError(f"unknown out-of-catalogue effect {kind!r} (the hidden kinds: blind.hidden); known: "
                   f"{OUT_OF_CATALOGUE}")


def detection_levels(name: str, effects: Iterable[str], cases: Sequence[CasePlan], damper: Damper,
                     rig: rr.RigImperfections, signs: Mapping[str, float],
                     spec: WindowSpec = DEFAULTS.window) -> dict[str, float] | None:
    """Detection level of each of ``effects`` (EFFECTS order) on one drawn damper, plan and rig; None
    as soon as one is not detectable with MULTIPLE_RANGE[1] x its level within its bound (BOUNDS)."""
    detection: dict[str, float] = {}
    if not effects:
        return detection
    problem = SineDetectionProblem.of(cases, damper, rig) if cases[0].waveform == "sine" else \
        DetectionProblem.of(name, cases, damper, rig, spec)
    for e in sorted(effects, key=EFFECTS.index):
        level = detection_level(problem, e, signs.get(e, 1.0))
        if level is None or MULTIPLE_RANGE[1] * level > BOUNDS[e]:
            log.info("%s: %s not detectable within bounds (detection %s, bound %g); re-drawing",
                     name, e, level, BOUNDS[e])
            return None
        detection[e] = level
    return detection


def overlay(effects: rr.TrueEffects, extra: rr.TrueEffects) -> rr.TrueEffects:
    """``effects`` with every field that ``extra`` sets away from the nominal (no-effect) value."""
    return dataclasses.replace(effects, **{f.name: getattr(extra, f.name) for f in dataclasses.fields(extra)
                                           if getattr(extra, f.name) != getattr(rr.NOMINAL_EFFECTS, f.name)})


def make_scenario(name: str, truth: Sequence[str], seed_seq: np.random.SeedSequence,
                  multiples: Mapping[str, float] | None = None, spec: WindowSpec = DEFAULTS.window,
                  n_velocities: tuple[int, int] = N_VELOCITIES,
                  low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                  high_end_mm_s: tuple[float, float] = HIGH_END_MM_S, out_of_catalogue: str = "",
                  rig: rr.RigImperfections | None = None, sensor_chain: bool = True,
                  waveform: str = "triangle") -> Scenario:
    """Draw a scenario with the effects ``truth`` at ``multiples`` x their detection level.

    ``multiples`` missing an effect: drawn U[1, 5]. Damper, plan and rig are re-drawn (up to
    MAX_REDRAWS times) while an effect's 5x detection level exceeds its bound. ``rig`` overrides
    the drawn nuisances (tests); ``sensor_chain`` False leaves the sensor chain ideal (:func:`draw_rig`; its
    own stream, child 21 of ``seed_seq``: everything else is drawn as without it). The servo's distortion of
    the sine cases has its own stream too (child 22, :func:`draw_sine_harmonics`). ``waveform`` 'sine': a
    sine-only campaign (:func:`draw_sine_plan`, the plan ranges unused), its detection levels on its phase bins
    (:class:`SineDetectionProblem`).
    """
    if waveform == "sine" and out_of_catalogue:
        raise ValueError(f"{name}: out-of-catalogue scenarios are triangle campaigns")
    rng = np.random.default_rng(seed_seq)
    chain_rng = np.random.default_rng(np.random.SeedSequence(seed_seq.entropy, spawn_key=(*seed_seq.spawn_key, 21))) \
        if sensor_chain else None
    harmonics = draw_sine_harmonics(np.random.default_rng(
        np.random.SeedSequence(seed_seq.entropy, spawn_key=(*seed_seq.spawn_key, 22))))
    truth = tuple(e for e in EFFECTS if e in set(truth))
    multiples = dict(multiples or {})
    for redraw in range(MAX_REDRAWS + 1):
        damper = draw_damper(rng)
        cases = tuple(draw_sine_plan(rng) if waveform == "sine" else
                      draw_plan(rng, n_velocities, low_end_mm_s, high_end_mm_s))
        drawn_rig = draw_rig(rng, full_scale_N(damper, cases), campaign_duration_s(cases), chain_rng)
        the_rig = drawn_rig if rig is None else rig
        noise_seed = int(rng.integers(0, 2**31 - 1))
        signs = {e: (float(rng.choice([-1.0, 1.0])) if e in SIGNED else 1.0) for e in truth}
        drawn = {e: float(rng.uniform(*MULTIPLE_RANGE)) for e in truth}
        need = set(truth) | ({"friction"} if out_of_catalogue == "stribeck" else set())
        detection = detection_levels(name, need, cases, damper, the_rig, signs, spec)
        if detection is None:
            continue
        mult = {e: float(multiples.get(e, drawn[e])) for e in truth}
        magnitude = {e: mult[e] * detection[e] for e in truth}
        effects = physical_effects(damper, magnitude, signs, charge_pressure_Pa(damper, cases))
        hidden: dict = {}
        if out_of_catalogue in HIDDEN_AXES:
            fields, hidden = hidden_effects(out_of_catalogue, name, damper, cases, effects, the_rig,
                                            np.random.default_rng(np.random.SeedSequence(
                                                seed_seq.entropy, spawn_key=(*seed_seq.spawn_key, 23))), spec)
            effects = dataclasses.replace(effects, **fields)
        elif out_of_catalogue:
            effects = overlay(effects, out_of_catalogue_true_effects(out_of_catalogue, damper, cases,
                                                                     detection.get("friction", 0.0)))
        return Scenario(name=name, damper=damper, cases=cases, effects=effects, rig=the_rig, noise_seed=noise_seed,
                        truth=truth, out_of_catalogue=out_of_catalogue, magnitude=magnitude,
                        sign={e: signs[e] for e in truth}, detection_level={e: detection[e] for e in truth},
                        multiple=mult, redraws=redraw, sine_harmonics=harmonics, hidden=hidden)
    raise RuntimeError(f"{name}: no plan within {MAX_REDRAWS} re-draws makes {truth} detectable within bounds")


def generate_scenarios(seed: int, n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0, n_sine: int = 0, *,
                       multiple: float | None = None, spec: WindowSpec = DEFAULTS.window,
                       n_velocities: tuple[int, int] = N_VELOCITIES,
                       low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                       high_end_mm_s: tuple[float, float] = HIGH_END_MM_S,
                       sensor_chain: bool = True, names: Sequence[str] | None = None) -> list[Scenario]:
    """The blind suite: ``n_per_effect`` single-effect scenarios per effect, ``n_pairs`` with two
    effects, ``n_none`` without, ``n_out`` with an effect outside the catalogue (triangle campaigns; names
    blind-000... in a seeded random order), then ``n_sine`` sine-only campaigns
    (:func:`isokinetic.contracts.scenarios.suite_composition`).

    ``multiple`` fixes every effect's magnitude at that many detection levels (tests); the plan
    ranges can be narrowed for small suites; ``sensor_chain`` False draws the same suite with an ideal
    sensor chain (the same scenarios otherwise); ``names`` draws only those scenarios (a chunk of the
    suite: each is the same as in the whole suite), in the suite's order.
    """
    composition = suite_composition(seed, n_per_effect, n_pairs, n_none, n_out, n_sine)
    all_names = scenario_names(len(composition))
    if names is not None and set(names) - set(all_names):
        raise ValueError(f"not in the suite: {sorted(set(names) - set(all_names))}")
    wanted = set(all_names if names is None else names)
    out = []
    for k, (name, (truth, mult, kind, waveform)) in enumerate(zip(all_names, composition, strict=True)):
        if name not in wanted:
            continue
        if multiple is not None:
            mult = {e: float(multiple) for e in truth}
        out.append(make_scenario(name, truth, np.random.SeedSequence([int(seed), k]), mult, spec,
                                 n_velocities, low_end_mm_s, high_end_mm_s, kind, sensor_chain=sensor_chain,
                                 waveform=waveform))
    return out


# --------------------------------------------------------------------------------------------
# Export
# --------------------------------------------------------------------------------------------

def export_scenario(scenario: Scenario, raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> Path:
    """Raw campaign folder ``raw_root/<name>/`` written by the reference rig (nominal damper only, its
    charge pressure included, its own units and column names, the phase rounded as a person writes it) and the truth
    ``truth_root/<name>.json``."""
    out = Path(raw_root) / scenario.name
    rrc.write_campaign(out, scenario.rig_cases(), rr.DamperDesign.from_mapping(scenario.damper.to_dict()),
                      scenario.effects, scenario.rig, scenario.noise_seed, description=DESCRIPTION,
                      write_phase=scenario.noise_seed % 2 == 0, declare_charge_pressure=True)
    write_json(scenario.truth_record(), Path(truth_root) / f"{scenario.name}.json")
    return out


def write_suite(scenarios: Sequence[Scenario], raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> None:
    """Export every scenario (raw folder + truth file)."""
    for s in scenarios:
        export_scenario(s, raw_root, truth_root)
        log.info("%s exported: %d cases, %d re-draw(s)", s.name, len(s.cases), s.redraws)

