"""Blind test of the sim-to-real diagnosis: withheld effects, simulated, diagnosed, scored.

A seeded suite of scenarios (:func:`generate_scenarios`) is exported as ordinary raw campaigns
(``results/blind/raw/<scenario>/``, ``source: simulation``, nothing in the folder names the truth)
and diagnosed through exactly the chain a real raw campaign gets (:func:`diagnose_raw_campaign`).
Only :func:`score` reads the truth (``results/blind/truth/<scenario>.json``).

Scenario
    A campaign simulated by the independent reference rig (:mod:`isokinetic.reference_rig`: two
    chamber pressures, physical effect forms, an imperfect rig; it shares no code with the
    diagnosis' model) for a damper drawn around Table 1 (piston area, orifice area, orifice length
    and both chamber volumes each x U[0.7, 1.3]), a triangle plan of 8-12 speeds log-spaced between a
    low end in [0.005, 0.05] mm/s and a high end in [0.4, 1.5] mm/s (3 significant digits), each with
    the shortest period of {20, 80, 240} s whose amplitude Y = W T/4 reaches 0.3 mm (and Y <= 8 mm),
    50 Hz, acquisition 2T, in a random test order. Every scenario draws rig nuisances
    (:data:`RIG_RANGES`): actuator delay and servo lag, white plus proportional coloured force noise,
    load-cell offset and gain error, LVDT noise and a slow viscosity drift over the campaign. It has
    zero, one or two of the catalogue effects :data:`EFFECTS` at 1x-5x their detection level, or one
    effect outside the catalogue (:data:`OUT_OF_CATALOGUE`: Stribeck friction, backlash, a relief
    valve). The rig writes its own column names and units and rounds the manifest as a person would.

Magnitude of an effect (what "1x detection" is measured in)
    friction: Coulomb force F_C [N]; leakage: conductance g [m3/(s Pa)]; asymmetry: |a| (random
    sign); discharge, viscosity: the relative deviation |theta/theta_0 - 1| from the nominal
    (manifest) value (random sign); air: the volume fraction V_G/V_C.

Detection level
    The smallest magnitude m whose noise-free characteristic differs from the nominal one by
    rms_z = 3, where rms_z = sqrt(mean_i ((F_i(m) - F_i,nom) / SE_i)^2) over all windows i of the
    plan, F from :class:`~isokinetic.nominal.ModelPlan` (the model run through the plan's own windows),
    and SE_i the rig's exact noise of a mean of the window's n_i samples at F_i(m) (white plus
    proportional coloured noise, :func:`reference_rig.mean_noise_variance`).
    Found by a coarse scan of log m upwards from 1e-7 of the effect's bound (first crossing of 3,
    so the *smallest* root) refined by ``brentq`` on log m. An effect whose 5x detection level
    exceeds its physical bound (:data:`BOUNDS`; or that never reaches rms_z = 3) makes the
    scenario re-draw its damper, plan and noise (same random stream, so still deterministic; the
    number of re-draws is recorded).

Determinism: the suite composition and order come from ``SeedSequence(seed)``, scenario k from
``SeedSequence([seed, k])``; the same arguments give identical scenarios and identical files.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import logging
import math
import os
import shutil
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from .characteristic import assemble
from . import reference_rig as rr
from .damper import NOMINAL, Damper, Effects, nominal_force
from .figures import save_figure
from .ingest import ingest_campaign
from .io import write_json, write_parquet
from .nominal import ModelPlan
from .plan import CasePlan, paper_plan
from .repeatability import repeatability
from .scenarios import EFFECTS, OUT_OF_CATALOGUE, scenario_names
from .validate import write_validated
from .windows import WindowSpec, windows_stage

log = logging.getLogger("isokinetic.blind")


#: Table 1 of the reference paper: the centre of the drawn geometries.
TABLE1 = Damper(piston_area_m2=4.0e-3, chamber_volume_1_m3=3.0e-4, chamber_volume_2_m3=3.0e-4,
                orifice_area_m2=6.0e-8, orifice_length_m=5.0e-4, discharge_coefficient=0.6,
                density_kg_m3=815.0, viscosity_Pa_s=0.03, oil_compressibility_1_Pa=3.8e-9)

#: Damper fields perturbed per scenario, each x U[1 - GEOMETRY_SPREAD, 1 + GEOMETRY_SPREAD].
GEOMETRY_FIELDS = ("piston_area_m2", "orifice_area_m2", "orifice_length_m", "chamber_volume_1_m3",
                   "chamber_volume_2_m3")
GEOMETRY_SPREAD = 0.30

#: Largest plausible magnitude of each effect (its unit: see the module doc). 5x the detection
#: level must stay below it, else the scenario is re-drawn.
BOUNDS = {"friction": 2000.0, "leakage": 1.0e-10, "asymmetry": 0.5, "discharge": 0.5, "viscosity": 0.8,
          "air": 0.2}
#: Unit of each effect's magnitude (truth files).
UNITS = {"friction": "coulomb_force_N", "leakage": "leakage_conductance_m3_s_Pa", "asymmetry": "abs(asymmetry)",
         "discharge": "abs(C_D/C_D0 - 1)", "viscosity": "abs(mu/mu0 - 1)", "air": "air_volume_fraction"}
#: Effects whose magnitude carries a random sign.
SIGNED = ("asymmetry", "discharge", "viscosity")

TARGET_RMS_Z = 3.0
MULTIPLE_RANGE = (1.0, 5.0)
MAGNITUDE_BINS = (("1-2x", 1.0, 2.0), ("2-3x", 2.0, 3.0), ("3-5x", 3.0, math.inf))

PERIODS_S = (20.0, 80.0, 240.0)
MIN_AMPLITUDE_M = 0.3e-3
MAX_AMPLITUDE_M = 8.0e-3
SAMPLE_RATE_HZ = 50.0
LOW_END_MM_S = (0.005, 0.05)      # log-uniform range of the slowest speed
HIGH_END_MM_S = (0.4, 1.5)        # log-uniform range of the fastest speed
N_VELOCITIES = (8, 12)
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

#: The diagnosis' significance level, against which false alarms are judged (target b).
ALPHA_DEFAULT = 1e-3

DESCRIPTION = "Blind-test scenario: simulated damper test campaign; its unmodelled effects are withheld."
DIAGNOSIS_FIGURE = "diagnosis/fig16_gap.png"   # as rule diagnosis writes it


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
    """Effects keyword arguments of one effect at ``magnitude`` (its unit) and ``sign``."""
    if effect == "friction":
        return {"coulomb_force_N": magnitude}
    if effect == "leakage":
        return {"leakage_conductance_m3_s_Pa": magnitude}
    if effect == "asymmetry":
        return {"asymmetry": sign * magnitude}
    if effect == "discharge":
        return {"discharge_coefficient": damper.discharge_coefficient * (1.0 + sign * magnitude)}
    if effect == "viscosity":
        return {"viscosity_Pa_s": damper.viscosity_Pa_s * (1.0 + sign * magnitude)}
    if effect == "air":
        return {"air_volume_fraction": magnitude}
    raise KeyError(f"unknown effect {effect!r}; known: {EFFECTS}")


def plan_table(name: str, cases: Sequence[CasePlan]) -> pd.DataFrame:
    """A status-ok cases table (the columns ModelPlan reads) of a plan."""
    rows = [{"campaign": name, "case": c.case, "waveform": c.waveform, "sample_rate_Hz": c.sample_rate_Hz,
             "amplitude_m": c.amplitude_m, "period_s": c.period_s, "frequency_Hz": c.frequency_Hz,
             "phase_rad": c.phase_rad, "duration_s": c.duration_s, "status": "ok"} for c in cases]
    return pd.DataFrame(rows)


@dataclass
class DetectionProblem:
    """rms_z(m) of one effect in one scenario, evaluated through a prepared ModelPlan.

    SE of a window mean: the rig's exact noise of a mean of n samples (white plus proportional
    coloured, :func:`reference_rig.mean_noise_variance`) at the window's force.
    """

    plan: ModelPlan
    damper: Damper
    rig: rr.RigImperfections
    nominal_N: np.ndarray
    calls: int = 0

    @classmethod
    def of(cls, name: str, cases: Sequence[CasePlan], damper: Damper, rig: rr.RigImperfections,
           spec: WindowSpec = WindowSpec()) -> "DetectionProblem":
        mp = ModelPlan.from_cases(name, plan_table(name, cases), spec)
        return cls(mp, damper, rig, mp.forces(damper, NOMINAL)[0])

    def se(self, force_N: np.ndarray) -> np.ndarray:
        fs = np.array([p.sample_rate_Hz for p in self.plan.plans])[self.plan.case_index]
        n = self.plan.stop - self.plan.start
        return np.sqrt([rr.mean_noise_variance(int(k), float(f), self.rig, float(r))
                        for k, f, r in zip(n, force_N, fs)])

    def rms_z(self, effect: str, magnitude: float, sign: float = 1.0) -> float:
        self.calls += 1
        effects = Effects(**effect_fields(effect, magnitude, sign, self.damper))
        f = self.plan.forces(self.damper, effects)[0]
        z = (f - self.nominal_N) / self.se(f)
        return float(np.sqrt(np.mean(z * z)))


def detection_level(problem: DetectionProblem, effect: str, sign: float = 1.0, bound: float | None = None,
                    target: float = TARGET_RMS_Z, scan_decades: float = 7.0, scan_points: int = 15) -> float | None:
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

    @property
    def truth_text(self) -> str:
        return effect_text(self.truth)

    @property
    def magnitude_x_detection(self) -> float:
        """The weakest truth effect's magnitude in detection levels (NaN without effects)."""
        return min(self.multiple.values()) if self.multiple else math.nan

    def rig_cases(self) -> list[rr.TriangleCase]:
        return [rr.TriangleCase(c.case, c.velocity_m_s, c.period_s, c.sample_rate_Hz) for c in self.cases]

    def truth_params(self) -> dict[str, float]:
        """Catalogue-form SI parameters of the truth effects (what an exact verdict should fit)."""
        eq = rr.catalogue_equivalent(self.damper, self.effects)
        keys = {"friction": "coulomb_force_N", "leakage": "leakage_conductance_m3_s_Pa", "asymmetry": "asymmetry",
                "discharge": "discharge_coefficient", "viscosity": "viscosity_Pa_s", "air": "air_volume_fraction"}
        return {keys[e]: float(eq[keys[e]]) for e in self.truth}

    def instrument_truth(self) -> dict[str, float]:
        """The rig's instrument terms as the diagnosis reports them: the delay of the piston behind the
        command in a steady ramp (delay + servo lag), the load-cell offset and gain."""
        return {"delay_s": self.rig.delay_s + self.rig.servo_lag_s, "force_offset_N": self.rig.force_offset_N,
                "force_gain": self.rig.force_gain}

    def truth_record(self) -> dict:
        """JSON-ready truth (results/blind/truth/<scenario>.json)."""
        return {
            "format_version": 2,
            "scenario": self.name,
            "generator": "isokinetic.reference_rig",
            "truth": list(self.truth),
            "truth_text": self.truth_text,
            "out_of_catalogue": self.out_of_catalogue,
            "params": self.truth_params(),
            "instrument": self.instrument_truth(),
            "effects": dataclasses.asdict(self.effects),
            "rig": dataclasses.asdict(self.rig),
            "magnitude": dict(self.magnitude),
            "magnitude_unit": {e: UNITS[e] for e in self.truth},
            "sign": dict(self.sign),
            "detection_level": dict(self.detection_level),
            "multiple": dict(self.multiple),
            "magnitude_x_detection": None if not self.multiple else self.magnitude_x_detection,
            "magnitude_bin": magnitude_bin(self.magnitude_x_detection),
            "detection_rms_z": TARGET_RMS_Z,
            "damper": self.damper.to_dict(),
            "velocities_mm_s": [round(c.velocity_m_s * 1e3, 12) for c in self.cases],
            "periods_s": [c.period_s for c in self.cases],
            "noise_seed": self.noise_seed,
            "redraws": self.redraws,
        }


def _sig(x: float, digits: int = 4) -> float:
    return float(f"{x:.{digits}g}")


def draw_damper(rng: np.random.Generator) -> Damper:
    """Table 1 with the geometry fields x U[0.7, 1.3] (4 significant digits)."""
    values = TABLE1.to_dict()
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


def full_scale_N(damper: Damper, cases: Sequence[CasePlan]) -> float:
    """The load cell's full scale: the next of 1, 2, 5 x 10^k above 1.25 x the plan's largest force."""
    peak = 1.25 * float(np.max(np.abs(nominal_force(np.array([c.velocity_m_s for c in cases]), damper))))
    k = math.floor(math.log10(max(peak, 1e-9)))
    return next(m * 10.0**k for m in (1.0, 2.0, 5.0, 10.0) if m * 10.0**k >= peak)


def draw_rig(rng: np.random.Generator, full_scale: float) -> rr.RigImperfections:
    """Rig nuisances, drawn in every scenario (RIG_RANGES)."""
    r = RIG_RANGES
    return rr.RigImperfections(
        delay_s=_sig(rng.uniform(*r["delay_s"]), 3), servo_lag_s=_sig(rng.uniform(*r["servo_lag_s"]), 3),
        force_noise_N=_sig(rng.uniform(*r["force_noise_N"]), 3),
        force_noise_rel=_sig(rng.uniform(*r["force_noise_rel"]), 3),
        noise_corner_Hz=_sig(math.exp(rng.uniform(*np.log(r["noise_corner_Hz"]))), 3),
        force_offset_N=_sig(rng.uniform(-1.0, 1.0) * r["force_offset_fs"] * full_scale, 3),
        force_gain=1.0 + _sig(rng.uniform(-1.0, 1.0) * r["force_gain_error"], 3),
        displacement_noise_m=r["displacement_noise_m"],
        viscosity_drift_rel=_sig(rng.uniform(-1.0, 1.0) * r["viscosity_drift_rel"], 3),
        force_resolution_N=0.01, displacement_resolution_m=1e-8, command_resolution_m=1e-8)


def charge_pressure_Pa(damper: Damper, cases: Sequence[CasePlan]) -> float:
    """Charge (accumulator) pressure of the drawn damper: twice the plan's largest steady Δp, at least
    5 MPa (2 significant digits), so that neither chamber comes near zero absolute pressure."""
    dp_max = float(np.max(np.abs(nominal_force(np.array([c.velocity_m_s for c in cases]), damper))))
    return _sig(max(5.0e6, 2.0 * dp_max / damper.piston_area_m2), 2)


def physical_effects(damper: Damper, magnitudes: Mapping[str, float], signs: Mapping[str, float],
                     charge_Pa: float = 5.0e6) -> rr.TrueEffects:
    """The reference rig's physical effects whose catalogue equivalents are ``magnitudes``."""
    kw: dict[str, float] = {"charge_pressure_Pa": charge_Pa}
    for e, m in magnitudes.items():
        s = signs.get(e, 1.0)
        if e == "friction":
            kw["coulomb_force_N"] = m
        elif e == "leakage":
            kw["leakage_gap_m"] = rr.leakage_gap_from_conductance(m, damper)
        elif e == "asymmetry":
            kw["asymmetry"] = s * m
        elif e == "discharge":
            kw["discharge_coefficient"] = damper.discharge_coefficient * (1.0 + s * m)
        elif e == "viscosity":
            kw["viscosity_Pa_s"] = damper.viscosity_Pa_s * (1.0 + s * m)
        elif e == "air":
            kw["air_fraction_at_charge"] = rr.air_fraction_from_catalogue(m, charge_Pa)
        else:
            raise KeyError(f"unknown effect {e!r}; known: {EFFECTS}")
    return rr.TrueEffects(**kw)


def out_of_catalogue_effects(kind: str, damper: Damper, cases: Sequence[CasePlan],
                             friction_detection_N: float) -> rr.TrueEffects:
    """An effect outside the catalogue, strong enough to be seen (OUT_OF_CATALOGUE).

    stribeck: a Coulomb force of 3x its detection level plus a breakaway peak decaying over v_S at the
    geometric middle of the plan's speeds (seals: 0.1-1 mm/s), F_S = STRIBECK_PEAK of the nominal
    hydraulic force at v_S (a weaker hump is absorbed by friction + viscosity: README); backlash: 20-40 um of free play; relief: a relief valve that
    cracks at half the plan's largest steady pressure and passes 30 % of the piston flow at it.
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
    raise KeyError(f"unknown out-of-catalogue effect {kind!r}; known: {OUT_OF_CATALOGUE}")


def make_scenario(name: str, truth: Sequence[str], seed_seq: np.random.SeedSequence,
                  multiples: Mapping[str, float] | None = None, spec: WindowSpec = WindowSpec(),
                  n_velocities: tuple[int, int] = N_VELOCITIES,
                  low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                  high_end_mm_s: tuple[float, float] = HIGH_END_MM_S, out_of_catalogue: str = "",
                  rig: rr.RigImperfections | None = None) -> Scenario:
    """Draw a scenario with the effects ``truth`` at ``multiples`` x their detection level.

    ``multiples`` missing an effect: drawn U[1, 5]. Damper, plan and rig are re-drawn (up to
    MAX_REDRAWS times) while an effect's 5x detection level exceeds its bound. ``rig`` overrides
    the drawn nuisances (tests).
    """
    rng = np.random.default_rng(seed_seq)
    truth = tuple(e for e in EFFECTS if e in set(truth))
    multiples = dict(multiples or {})
    for redraw in range(MAX_REDRAWS + 1):
        damper = draw_damper(rng)
        cases = tuple(draw_plan(rng, n_velocities, low_end_mm_s, high_end_mm_s))
        drawn_rig = draw_rig(rng, full_scale_N(damper, cases))
        the_rig = drawn_rig if rig is None else rig
        noise_seed = int(rng.integers(0, 2**31 - 1))
        signs = {e: (float(rng.choice([-1.0, 1.0])) if e in SIGNED else 1.0) for e in truth}
        drawn = {e: float(rng.uniform(*MULTIPLE_RANGE)) for e in truth}
        need = set(truth) | ({"friction"} if out_of_catalogue == "stribeck" else set())
        detection = {}
        if need:
            problem = DetectionProblem.of(name, cases, damper, the_rig, spec)
            for e in sorted(need, key=EFFECTS.index):
                level = detection_level(problem, e, signs.get(e, 1.0))
                if level is None or MULTIPLE_RANGE[1] * level > BOUNDS[e]:
                    log.info("%s: %s not detectable within bounds (detection %s, bound %g); re-drawing",
                             name, e, level, BOUNDS[e])
                    break
                detection[e] = level
            if len(detection) < len(need):
                continue
        mult = {e: float(multiples.get(e, drawn[e])) for e in truth}
        magnitude = {e: mult[e] * detection[e] for e in truth}
        effects = physical_effects(damper, magnitude, signs, charge_pressure_Pa(damper, cases))
        if out_of_catalogue:
            extra = out_of_catalogue_effects(out_of_catalogue, damper, cases, detection.get("friction", 0.0))
            effects = dataclasses.replace(effects, **{f.name: getattr(extra, f.name) for f in dataclasses.fields(extra)
                                                      if getattr(extra, f.name) != getattr(rr.NOMINAL_EFFECTS, f.name)})
        return Scenario(name=name, damper=damper, cases=cases, effects=effects, rig=the_rig, noise_seed=noise_seed,
                        truth=truth, out_of_catalogue=out_of_catalogue, magnitude=magnitude,
                        sign={e: signs[e] for e in truth}, detection_level={e: detection[e] for e in truth},
                        multiple=mult, redraws=redraw)
    raise RuntimeError(f"{name}: no plan within {MAX_REDRAWS} re-draws makes {truth} detectable within bounds")


def suite_composition(seed: int, n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0
                      ) -> list[tuple[tuple[str, ...], dict[str, float], str]]:
    """(truth, multiples, out-of-catalogue kind) per scenario, in name order.

    Singles of one effect get stratified multiples (k-th of n in [1 + 4k/n, 1 + 4(k+1)/n], strata
    in random order); pairs are distinct effect pairs (cycled when more than 15 are asked) with
    U[1, 5] multiples; ``n_out`` out-of-catalogue scenarios cycle through OUT_OF_CATALOGUE; the
    whole list is shuffled so a name does not tell its kind.
    """
    for key, v in (("n_per_effect", n_per_effect), ("n_pairs", n_pairs), ("n_none", n_none), ("n_out", n_out)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"{key}: must be a non-negative integer, got {v!r}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
    lo, hi = MULTIPLE_RANGE
    kinds: list[tuple[tuple[str, ...], dict[str, float], str]] = []
    for e in EFFECTS:
        strata = rng.permutation(n_per_effect)
        for k in strata:
            u = rng.uniform(k / n_per_effect, (k + 1) / n_per_effect)
            kinds.append(((e,), {e: lo + (hi - lo) * float(u)}, ""))
    all_pairs = list(itertools.combinations(EFFECTS, 2))
    order = rng.permutation(len(all_pairs))
    for i in range(n_pairs):
        pair = all_pairs[int(order[i % len(all_pairs)])]
        kinds.append((pair, {e: float(rng.uniform(lo, hi)) for e in pair}, ""))
    kinds += [((), {}, "") for _ in range(n_none)]
    kinds += [((), {}, OUT_OF_CATALOGUE[i % len(OUT_OF_CATALOGUE)]) for i in range(n_out)]
    return [kinds[int(i)] for i in rng.permutation(len(kinds))]


def generate_scenarios(seed: int, n_per_effect: int, n_pairs: int, n_none: int, n_out: int = 0, *,
                       multiple: float | None = None, spec: WindowSpec = WindowSpec(),
                       n_velocities: tuple[int, int] = N_VELOCITIES,
                       low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                       high_end_mm_s: tuple[float, float] = HIGH_END_MM_S) -> list[Scenario]:
    """The blind suite: ``n_per_effect`` single-effect scenarios per effect, ``n_pairs`` with two
    effects, ``n_none`` without, ``n_out`` with an effect outside the catalogue; names blind-000...
    in a seeded random order.

    ``multiple`` fixes every effect's magnitude at that many detection levels (tests); the plan
    ranges can be narrowed for small suites.
    """
    composition = suite_composition(seed, n_per_effect, n_pairs, n_none, n_out)
    out = []
    for k, (name, (truth, mult, kind)) in enumerate(zip(scenario_names(len(composition)), composition)):
        if multiple is not None:
            mult = {e: float(multiple) for e in truth}
        out.append(make_scenario(name, truth, np.random.SeedSequence([int(seed), k]), mult, spec,
                                 n_velocities, low_end_mm_s, high_end_mm_s, kind))
    return out


# --------------------------------------------------------------------------------------------
# Export
# --------------------------------------------------------------------------------------------

def export_scenario(scenario: Scenario, raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> Path:
    """Raw campaign folder ``raw_root/<name>/`` written by the reference rig (nominal damper only,
    its own units and column names, the phase rounded as a person writes it) and the truth
    ``truth_root/<name>.json``."""
    out = Path(raw_root) / scenario.name
    rr.write_campaign(out, scenario.rig_cases(), rr.DamperDesign.from_mapping(scenario.damper.to_dict()),
                      scenario.effects, scenario.rig, scenario.noise_seed, description=DESCRIPTION,
                      write_phase=scenario.noise_seed % 2 == 0)
    write_json(scenario.truth_record(), Path(truth_root) / f"{scenario.name}.json")
    return out


def write_suite(scenarios: Sequence[Scenario], raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> None:
    """Export every scenario (raw folder + truth file)."""
    for s in scenarios:
        export_scenario(s, raw_root, truth_root)
        log.info("%s exported: %d cases, %d re-draw(s)", s.name, len(s.cases), s.redraws)


# --------------------------------------------------------------------------------------------
# Blind diagnosis
# --------------------------------------------------------------------------------------------

def diagnose_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                          spec: WindowSpec = WindowSpec(), *, repeatability_tolerance: float = 0.05,
                          sample_rate_tolerance: float = 0.05) -> dict:
    """The per-campaign chain of a real raw campaign, into ``work_root/<campaign>/``; the diagnosis.

    ingest -> validate (cases/quarantine.parquet) -> windows -> repeatability -> characteristic ->
    ``diagnosis.write_diagnosis`` (diagnosis.json and diagnosis/fig16_gap.png, as rule diagnosis).
    Reads only ``raw_dir``.
    An existing ``work_root/<campaign>/`` is replaced.
    """
    from .diagnosis import write_diagnosis

    root = process_raw_campaign(raw_dir, work_root, spec, repeatability_tolerance=repeatability_tolerance,
                                sample_rate_tolerance=sample_rate_tolerance)
    return write_diagnosis(root, root / "diagnosis.json", root / DIAGNOSIS_FIGURE, spec)


def process_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                         spec: WindowSpec = WindowSpec(), *, repeatability_tolerance: float = 0.05,
                         sample_rate_tolerance: float = 0.05) -> Path:
    """ingest -> validate -> windows -> repeatability -> characteristic of a raw campaign into
    ``work_root/<campaign>/`` (replaced if it exists); returns that folder. Reads only ``raw_dir``."""
    raw_dir = Path(raw_dir)
    root = Path(work_root) / raw_dir.name
    if root.exists():
        shutil.rmtree(root)
    ingest_campaign(raw_dir, root)
    write_validated(root, sample_rate_tolerance=sample_rate_tolerance)
    windows = windows_stage(root, spec)
    write_parquet(windows, root / "windows.parquet")
    rep = repeatability(windows, repeatability_tolerance)
    write_parquet(rep, root / "repeatability.parquet")
    write_parquet(assemble(windows, rep), root / "characteristic.parquet")
    return root


def diagnose_suite(raw_root: str | os.PathLike, names: Sequence[str], work_root: str | os.PathLike,
                   spec: WindowSpec = WindowSpec(), **kwargs) -> dict[str, dict | None]:
    """:func:`diagnose_raw_campaign` of each named scenario; a failure is logged, written to
    ``work_root/<name>/error.txt`` and returned as None (scored as a wrong verdict)."""
    out: dict[str, dict | None] = {}
    for name in names:
        try:
            out[name] = diagnose_raw_campaign(Path(raw_root) / name, work_root, spec, **kwargs)
            log.info("%s: verdict %s", name, effect_text(out[name].get("verdict") or []) or "none")
        except Exception as exc:  # noqa: BLE001 - one scenario fails alone, scoring counts it
            log.exception("%s: diagnosis failed", name)
            folder = Path(work_root) / name
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "error.txt").write_text(f"{type(exc).__name__}: {exc}\n", encoding="utf-8")
            out[name] = None
    return out


# --------------------------------------------------------------------------------------------
# Scoring
# --------------------------------------------------------------------------------------------

SCORE_COLUMNS = ("scenario", "truth", "out_of_catalogue", "verdict", "exact", "exact_up_to_confounding",
                 "explained", "n_truth", "magnitude_x_detection", "magnitude_bin", "gap_before", "gap_after",
                 "shrink", "confounded", "param_error_max", "delay_error_s", "offset_error_N", "gain_error",
                 "error")

#: Parameter keys of the catalogue effects and their nominal (no-effect) value: discharge and
#: viscosity are judged on their deviation from the manifest's value, the rest from zero.
PARAM_KEYS = {"friction": "coulomb_force_N", "leakage": "leakage_conductance_m3_s_Pa", "asymmetry": "asymmetry",
              "discharge": "discharge_coefficient", "viscosity": "viscosity_Pa_s", "air": "air_volume_fraction"}


def _float(value) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return math.nan
    return out


def _confounded_groups(diagnosis: Mapping) -> list[list[str]]:
    groups = diagnosis.get("confounded") or []
    return [list(g) for g in groups if isinstance(g, (list, tuple))]


def _up_to_confounding(truth: set[str], verdict: set[str], groups: list[list[str]]) -> bool:
    """Verdict equals the truth after mapping each confounded group to one representative."""
    rep = {}
    for g in groups:
        for e in g:
            rep[e] = min(g)
    return {rep.get(e, e) for e in truth} == {rep.get(e, e) for e in verdict}


def param_error(truth: Mapping, diagnosis: Mapping) -> float:
    """Largest relative error of the verdict's fitted effect sizes against the truth's.

    An effect's size is its parameter minus the nominal value (the manifest's C_D or viscosity for
    discharge and viscosity, zero otherwise): |fitted size - true size| / |true size|.
    """
    if "params" not in truth:
        return math.nan
    fitted = diagnosis.get("params") or {}
    nominal = truth.get("damper") or {}
    worst = 0.0
    for e in truth.get("truth") or []:
        key = PARAM_KEYS[e]
        base = float(nominal.get(key, 0.0)) if e in ("discharge", "viscosity") else 0.0
        true_size = float(truth["params"][key]) - base
        got = _float(fitted.get(key))
        if not math.isfinite(got) or true_size == 0.0:
            return math.inf
        worst = max(worst, abs((got - base) - true_size) / abs(true_size))
    return worst


def instrument_errors(truth: Mapping, diagnosis: Mapping) -> tuple[float, float, float]:
    """(delay, offset, gain) errors of the diagnosis' instrument estimates against the rig's truth.

    The estimate is the reported value, or where the diagnosis reports null (not needed by its
    test), the verdict fit's own estimate (``instrument_tests``): a null offset still has to be
    near the true one.
    """
    if "instrument" not in truth:
        return math.nan, math.nan, math.nan
    inst = diagnosis.get("instrument") or {}
    tests = diagnosis.get("instrument_tests") or {}
    true = truth["instrument"]

    def estimate(key: str, test: str, default: float) -> float:
        v = inst.get(key)
        if v is None:
            v = (tests.get(test) or {}).get("estimate", default)
        return _float(v)

    measured = _float(inst.get("delay_s"))
    delay = abs(measured - _float(true.get("delay_s"))) if math.isfinite(measured) else math.inf
    offset = abs(estimate("force_offset_N", "force_offset", 0.0) - _float(true.get("force_offset_N", 0.0)))
    gain = abs(estimate("force_gain", "force_gain", 1.0) - _float(true.get("force_gain", 1.0)))
    return delay, offset, gain


def score(truths: Iterable[Mapping], diagnoses: Mapping[str, Mapping | None]) -> pd.DataFrame:
    """One row per truth record (sorted by scenario): truth/verdict text, exactness, magnitude, gaps,
    parameter and instrument errors.

    ``truths``: truth records (:meth:`Scenario.truth_record`); ``diagnoses``: scenario -> diagnosis
    dict (None or missing: the diagnosis failed; verdict 'error', not exact).
    """
    rows = []
    for t in truths:
        name = str(t["scenario"])
        truth = set(t.get("truth") or [])
        d = diagnoses.get(name)
        mult = _float(t.get("magnitude_x_detection"))
        if not truth:
            mult = math.nan
        row = {"scenario": name, "truth": effect_text(truth), "out_of_catalogue": str(t.get("out_of_catalogue") or ""),
               "n_truth": len(truth), "magnitude_x_detection": mult, "magnitude_bin": magnitude_bin(mult)}
        if d is None or d.get("status") not in ("ok", None):
            row.update(verdict="error", exact=False, exact_up_to_confounding=False, explained=False,
                       gap_before=math.nan, gap_after=math.nan, shrink=math.nan, confounded="",
                       param_error_max=math.nan, delay_error_s=math.nan, offset_error_N=math.nan,
                       gain_error=math.nan, error=True)
        else:
            verdict = set(d.get("verdict") or [])
            groups = _confounded_groups(d)
            exact = verdict == truth and not row["out_of_catalogue"]
            delay, offset, gain = instrument_errors(t, d)
            row.update(verdict=effect_text(verdict), exact=exact,
                       exact_up_to_confounding=_up_to_confounding(truth, verdict, groups),
                       explained=bool(d.get("explained", True)),
                       gap_before=_float(d.get("gap_before")), gap_after=_float(d.get("gap_after")),
                       shrink=_float(d.get("shrink")), confounded=";".join("+".join(g) for g in groups),
                       param_error_max=param_error(t, d) if exact and truth else math.nan,
                       delay_error_s=delay, offset_error_N=offset, gain_error=gain, error=False)
        rows.append(row)
    df = pd.DataFrame(rows, columns=list(SCORE_COLUMNS))
    types = {"exact": bool, "exact_up_to_confounding": bool, "explained": bool, "error": bool, "n_truth": "int64"}
    if df.empty:
        return df.astype(types)
    df = df.astype({**types, **{c: float for c in ("magnitude_x_detection", "gap_before", "gap_after", "shrink",
                                                   "param_error_max", "delay_error_s", "offset_error_N",
                                                   "gain_error")}})
    return df.sort_values("scenario", ignore_index=True)


TARGET_SINGLE_RATE = 0.95
TARGET_SINGLE_MIN_MULTIPLE = 2.0
TARGET_MEDIAN_SHRINK = 5.0
TARGET_OUT_OF_CATALOGUE_RATE = 0.90
TARGET_PARAM_ERROR = 0.15
TARGET_DELAY_ERROR_S = 0.002
TARGET_OFFSET_ERROR_N = 2.0


def _json_float(x) -> float | str | None:
    """A JSON-safe number: None for NaN, 'inf' for infinity."""
    x = float(x)
    return x if math.isfinite(x) else (None if math.isnan(x) else "inf")


def _verdict_of(ok: bool | None) -> str:
    return "N/A" if ok is None else ("PASS" if ok else "FAIL")


def summarize(scores: pd.DataFrame, alpha: float | None = None) -> dict:
    """Per-bin exact-attribution rates and the five targets (JSON-ready).

    (a) >= 95 % of single-effect scenarios at >= 2x detection attributed exactly;
    (b) effects claimed on scenarios without effects at most at the test's level ``alpha`` (and
        none in a suite too small to measure that: fewer than 1/alpha such scenarios);
    (c) >= 90 % of out-of-catalogue scenarios reported ``explained: false``;
    (d) median shrink >= 5 over the scenarios with catalogue effects;
    (e) the fitted effect sizes of every exact verdict within 15 % of the truth, and on every
        in-catalogue scenario the actuator delay within 2 ms and the load-cell offset within 2 N.
    A target without any scenario to judge is 'N/A' (pass: null).
    """
    alpha = ALPHA_DEFAULT if alpha is None else alpha
    inside = scores[scores["out_of_catalogue"] == ""]
    eff = inside[inside["n_truth"] > 0]
    singles = eff[eff["n_truth"] == 1]
    bins = {}
    for name, _lo, _hi in MAGNITUDE_BINS:
        b = eff[eff["magnitude_bin"] == name]
        bs = singles[singles["magnitude_bin"] == name]
        bins[name] = {"n": int(len(b)), "exact": int(b["exact"].sum()),
                      "rate": float(b["exact"].mean()) if len(b) else None,
                      "n_single": int(len(bs)), "exact_single": int(bs["exact"].sum()),
                      "rate_single": float(bs["exact"].mean()) if len(bs) else None}
    a_rows = singles[singles["magnitude_x_detection"] >= TARGET_SINGLE_MIN_MULTIPLE]
    a_rate = float(a_rows["exact"].mean()) if len(a_rows) else None
    a_pass = None if a_rate is None else bool(a_rate >= TARGET_SINGLE_RATE)
    none = inside[inside["n_truth"] == 0]
    claimed = none[none["verdict"] != ""]
    b_rate = float(len(claimed) / len(none)) if len(none) else None
    b_pass = None if none.empty else bool(len(claimed) <= math.floor(alpha * len(none)))
    out = scores[scores["out_of_catalogue"] != ""]
    c_flagged = out[~out["explained"] & ~out["error"]]
    c_rate = float(len(c_flagged) / len(out)) if len(out) else None
    c_pass = None if c_rate is None else bool(c_rate >= TARGET_OUT_OF_CATALOGUE_RATE)
    shrink = eff["shrink"].to_numpy(dtype=float)
    shrink = shrink[~np.isnan(shrink)]
    median = float(np.median(shrink)) if shrink.size else None
    median_json = median if median is None or math.isfinite(median) else (None if math.isnan(median) else "inf")
    d_pass = None if median is None else bool(median >= TARGET_MEDIAN_SHRINK)
    exact = eff[eff["exact"] & ~eff["param_error_max"].isna()]   # NaN: a truth without parameters
    p_err = exact["param_error_max"].to_numpy(dtype=float)
    p_bad = exact.loc[~(exact["param_error_max"] <= TARGET_PARAM_ERROR), "scenario"]
    judged = inside[~inside["error"] & ~inside["delay_error_s"].isna()]
    d_bad = judged.loc[~(judged["delay_error_s"] <= TARGET_DELAY_ERROR_S), "scenario"]
    o_bad = judged.loc[~(judged["offset_error_N"] <= TARGET_OFFSET_ERROR_N), "scenario"]
    e_pass = None if judged.empty else bool(p_bad.empty and d_bad.empty and o_bad.empty)
    return {
        "format_version": 2,
        "n_scenarios": int(len(scores)),
        "n_single": int(len(singles)),
        "n_pairs": int((eff["n_truth"] == 2).sum()),
        "n_none": int(len(none)),
        "n_out_of_catalogue": int(len(out)),
        "n_errors": int(scores["error"].sum()),
        "exact_rate": float(eff["exact"].mean()) if len(eff) else None,
        "bins": bins,
        "targets": {
            "a_single_at_2x": {"description": "single-effect scenarios at >= 2x detection attributed exactly",
                               "n": int(len(a_rows)), "exact": int(a_rows["exact"].sum()), "rate": a_rate,
                               "threshold": TARGET_SINGLE_RATE, "pass": a_pass,
                               "misses": sorted(a_rows.loc[~a_rows["exact"], "scenario"])},
            "b_none_clean": {"description": "effects claimed on scenarios without effects (false alarms)",
                             "n": int(len(none)), "claimed": int(len(claimed)), "rate": b_rate, "alpha": alpha,
                             "pass": b_pass, "misses": sorted(claimed["scenario"])},
            "c_out_of_catalogue": {"description": "out-of-catalogue scenarios reported explained: false",
                                   "n": int(len(out)), "flagged": int(len(c_flagged)), "rate": c_rate,
                                   "threshold": TARGET_OUT_OF_CATALOGUE_RATE, "pass": c_pass,
                                   "misses": sorted(set(out["scenario"]) - set(c_flagged["scenario"]))},
            "d_median_shrink": {"description": "median shrink where a catalogue effect was present",
                                "n": int(shrink.size), "median": median_json, "threshold": TARGET_MEDIAN_SHRINK,
                                "pass": d_pass},
            "e_parameters": {"description": "exact verdicts' effect sizes within 15 %; delay within 2 ms and "
                                            "offset within 2 N on every in-catalogue scenario",
                             "n_exact": int(len(exact)),
                             "param_error_max": _json_float(np.max(p_err)) if p_err.size else None,
                             "param_error_median": _json_float(np.median(p_err)) if p_err.size else None,
                             "n_judged": int(len(judged)),
                             "delay_error_max_s": _json_float(judged["delay_error_s"].max()) if len(judged) else None,
                             "offset_error_max_N": _json_float(judged["offset_error_N"].max()) if len(judged) else None,
                             "gain_error_max": _json_float(judged["gain_error"].max()) if len(judged) else None,
                             "pass": e_pass, "param_misses": sorted(p_bad), "delay_misses": sorted(d_bad),
                             "offset_misses": sorted(o_bad)},
        },
        "all_pass": (all(t is not False for t in (a_pass, b_pass, c_pass, d_pass, e_pass))
                     and any(t is True for t in (a_pass, b_pass, c_pass, d_pass, e_pass))),
    }


def summary_text(summary: Mapping) -> str:
    """The human summary printed by the scoring job."""
    t = summary["targets"]
    lines = [f"blind test: {summary['n_scenarios']} scenarios ({summary['n_single']} single, {summary['n_pairs']} "
             f"pairs, {summary['n_none']} none, {summary['n_out_of_catalogue']} out of catalogue; "
             f"{summary['n_errors']} diagnosis errors)",
             "exact attribution by magnitude (weakest effect, x detection level):"]
    for name, b in summary["bins"].items():
        rate = "  -  " if b["rate"] is None else f"{100 * b['rate']:5.1f} %"
        rs = "  -  " if b["rate_single"] is None else f"{100 * b['rate_single']:5.1f} %"
        lines.append(f"  {name:>5}: {b['exact']:3d}/{b['n']:<3d} {rate}   (single effect {b['exact_single']}/"
                     f"{b['n_single']} {rs})")
    a, bn, c, d, e = (t[k] for k in ("a_single_at_2x", "b_none_clean", "c_out_of_catalogue", "d_median_shrink",
                                     "e_parameters"))
    pct = lambda x: "-" if x is None else f"{100 * x:.1f} %"  # noqa: E731
    lines.append(f"(a) {_verdict_of(a['pass'])}: single effect at >= 2x detection exact {a['exact']}/{a['n']} "
                 f"= {pct(a['rate'])} (target >= {100 * a['threshold']:.0f} %)"
                 + (f"; missed {', '.join(a['misses'])}" if a["misses"] else ""))
    lines.append(f"(b) {_verdict_of(bn['pass'])}: effects claimed on {bn['claimed']}/{bn['n']} scenarios without "
                 f"effects = {pct(bn['rate'])} (target <= alpha = {bn['alpha']:g})"
                 + (f"; {', '.join(bn['misses'])}" if bn["misses"] else ""))
    lines.append(f"(c) {_verdict_of(c['pass'])}: out-of-catalogue scenarios reported not explained {c['flagged']}/"
                 f"{c['n']} = {pct(c['rate'])} (target >= {100 * c['threshold']:.0f} %)"
                 + (f"; missed {', '.join(c['misses'])}" if c["misses"] else ""))
    med = "-" if d["median"] is None else (d["median"] if isinstance(d["median"], str) else f"{d['median']:.3g}")
    lines.append(f"(d) {_verdict_of(d['pass'])}: median shrink {med} over {d['n']} scenarios with effects "
                 f"(target >= {d['threshold']:g})")
    fmt = lambda x, scale=1.0, unit="": "-" if x is None else (x if isinstance(x, str) else f"{x * scale:.3g}{unit}")  # noqa: E731
    lines.append(f"(e) {_verdict_of(e['pass'])}: effect sizes of {e['n_exact']} exact verdicts within "
                 f"{fmt(e['param_error_max'], 100, ' %')} (median {fmt(e['param_error_median'], 100, ' %')}; "
                 f"target 15 %); over {e['n_judged']} scenarios delay error <= {fmt(e['delay_error_max_s'], 1e3, ' ms')}"
                 f" (target 2 ms), offset error <= {fmt(e['offset_error_max_N'], 1, ' N')} (target 2 N), "
                 f"gain error <= {fmt(e['gain_error_max'], 100, ' %')}"
                 + "".join(f"; {k.split('_')[0]} misses {', '.join(e[k])}" for k in
                           ("param_misses", "delay_misses", "offset_misses") if e[k]))
    return "\n".join(lines)


def confusion_counts(scores: pd.DataFrame) -> pd.DataFrame:
    """Counts of truth set (rows) x verdict set (columns); '' shown as 'none'."""
    order = {e: i for i, e in enumerate(EFFECTS)}

    def key(text: str):
        if text == "":
            return (0, ())
        if text == "error":
            return (9, ())
        if text.startswith("("):  # an out-of-catalogue truth
            return (0.5, (text,))
        parts = text.split("+")
        return (len(parts), tuple(order.get(p, 99) for p in parts))

    scores = scores.assign(truth=[t if t or not o else f"({o})" for t, o in
                                  zip(scores["truth"], scores.get("out_of_catalogue", [""] * len(scores)))])
    truths = sorted(set(scores["truth"]), key=key)
    verdicts = sorted(set(scores["verdict"]) | set(truths), key=key)
    table = pd.crosstab(scores["truth"], scores["verdict"]).reindex(index=truths, columns=verdicts, fill_value=0)
    label = lambda s: "none" if s == "" else s  # noqa: E731
    table.index = [label(s) for s in table.index]
    table.columns = [label(s) for s in table.columns]
    return table


def confusion_figure(scores: pd.DataFrame, summary: Mapping | None = None):
    """Fig. 17: truth effect set against verdict set, counts; exact attributions on the diagonal."""
    from matplotlib.figure import Figure

    table = confusion_counts(scores)
    n_r, n_c = table.shape
    fig = Figure(figsize=(max(5.0, 1.0 + 0.55 * n_c), max(3.5, 1.4 + 0.4 * n_r)), layout="constrained")
    ax = fig.add_subplot()
    if n_r == 0:
        ax.text(0.5, 0.5, "no scenarios scored", ha="center", va="center", color="tab:red")
        ax.set_axis_off()
        return fig
    counts = table.to_numpy()
    ax.imshow(counts, cmap="Blues", vmin=0, vmax=max(1, counts.max()), aspect="auto")
    for i in range(n_r):
        for j in range(n_c):
            if counts[i, j]:
                exact = table.index[i] == table.columns[j]
                ax.text(j, i, str(counts[i, j]), ha="center", va="center", fontsize=9,
                        color="white" if counts[i, j] > 0.6 * counts.max() else "black",
                        fontweight="bold" if exact else "normal")
    ax.set_xticks(range(n_c), table.columns, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(n_r), table.index, fontsize=8)
    ax.set_xlabel("verdict (effect set)")
    ax.set_ylabel("truth (effect set)")
    title = f"Blind test: {len(scores)} scenarios, {int(scores['exact'].sum())} attributed exactly"
    if summary is not None:
        t = summary["targets"]
        title += "\n" + "  ".join(f"({k[0]}) {_verdict_of(t[k]['pass'])}"
                                   for k in ("a_single_at_2x", "b_none_clean", "c_out_of_catalogue",
                                             "d_median_shrink", "e_parameters"))
    ax.set_title(title, fontsize=10)
    return fig


def read_truths(truth_root: str | os.PathLike) -> list[dict]:
    return [json.loads(p.read_text(encoding="utf-8")) for p in sorted(Path(truth_root).glob("*.json"))]


def read_diagnoses(work_roots: Iterable[str | os.PathLike], names: Iterable[str]) -> dict[str, dict | None]:
    """scenario -> diagnosis.json content found under any of ``work_roots`` (None if absent)."""
    found: dict[str, dict | None] = {}
    roots = [Path(r) for r in work_roots]
    for name in names:
        found[name] = None
        for r in roots:
            p = r / name / "diagnosis.json"
            if p.is_file():
                found[name] = json.loads(p.read_text(encoding="utf-8"))
                break
    return found


#: Row-level lineage columns of scores.parquet (:func:`score_sources`), after SCORE_COLUMNS.
SOURCE_COLUMNS = ("raw_dir", "truth_file", "diagnosis_file")


def score_sources(truth_root: str | os.PathLike, work_roots: Iterable[str | os.PathLike],
                  names: Iterable[str]) -> pd.DataFrame:
    """Where each scenario's score came from: scenario, raw_dir, truth_file, diagnosis_file.

    truth_file: the truth record read (its 'scenario' key, under ``truth_root``); diagnosis_file: the
    diagnosis.json found under ``work_roots`` (as :func:`read_diagnoses`); raw_dir: the raw campaign
    folder that diagnosis ingested (the parent of ``manifest_file`` in its ingest/campaign.json),
    else ``<truth_root>/../raw/<scenario>`` when that folder exists. '' where there is none.
    """
    truth_files = {}
    for p in sorted(Path(truth_root).glob("*.json")):
        name = json.loads(p.read_text(encoding="utf-8")).get("scenario")
        truth_files.setdefault(str(name), p.as_posix())
    roots = [Path(r) for r in work_roots]
    rows = []
    for name in names:
        diagnosis, raw = "", ""
        for r in roots:
            if not diagnosis and (r / name / "diagnosis.json").is_file():
                diagnosis = (r / name / "diagnosis.json").as_posix()
            meta_path = r / name / "ingest" / "campaign.json"
            if not raw and meta_path.is_file():
                manifest = json.loads(meta_path.read_text(encoding="utf-8")).get("manifest_file") or ""
                raw = Path(manifest).parent.as_posix() if manifest else ""
        if not raw and (Path(truth_root).parent / "raw" / name).is_dir():
            raw = (Path(truth_root).parent / "raw" / name).as_posix()
        rows.append({"scenario": name, "raw_dir": raw, "truth_file": truth_files.get(name, ""),
                     "diagnosis_file": diagnosis})
    return pd.DataFrame(rows, columns=["scenario", *SOURCE_COLUMNS]).astype(str)


def write_scores(truth_root, work_roots, scores_path, summary_path, figure_path) -> tuple[pd.DataFrame, dict]:
    """Score the suite: scores.parquet (SCORE_COLUMNS and the sources, SOURCE_COLUMNS), summary.json and
    the confusion figure; returns both."""
    truths = read_truths(truth_root)
    work_roots = list(work_roots)
    diagnoses = read_diagnoses(work_roots, [t["scenario"] for t in truths])
    scores = score(truths, diagnoses)
    scores = scores.merge(score_sources(truth_root, work_roots, scores["scenario"].tolist()), on="scenario",
                          how="left", validate="one_to_one")
    summary = summarize(scores)
    write_parquet(scores, scores_path)
    write_json(summary, summary_path)
    save_figure(confusion_figure(scores, summary), figure_path)
    return scores, summary
