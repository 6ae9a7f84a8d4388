"""Blind test of the sim-to-real diagnosis: withheld effects, simulated, diagnosed, scored.

A seeded suite of scenarios (:func:`generate_scenarios`) is exported as ordinary raw campaigns
(``results/blind/raw/<scenario>/``, ``source: simulation``, nothing in the folder names the truth)
and diagnosed through exactly the chain a real raw campaign gets (:func:`diagnose_raw_campaign`).
Only :func:`score` reads the truth (``results/blind/truth/<scenario>.json``).

Scenario
    A :class:`~isokinetic.virtual_rig.VirtualCampaign` with a damper drawn around Table 1 (piston
    area, orifice area, orifice length and both chamber volumes each x U[0.7, 1.3]), a triangle plan
    of 8-12 speeds log-spaced between a low end in [0.005, 0.05] mm/s and a high end in [0.4, 1.5]
    mm/s (3 significant digits), each with the shortest period of {20, 80, 240} s whose amplitude
    Y = W T/4 reaches 0.3 mm (and Y <= 8 mm), 50 Hz, acquisition 2T, phase -pi/2; sensor noise
    force_noise_N ~ U[2, 10] N, force_noise_rel ~ U[0.005, 0.02], LVDT 1 um; and zero, one or two
    of the effects :data:`EFFECTS` with magnitudes between 1x and 5x their detection level.

Magnitude of an effect (what "1x detection" is measured in)
    friction: Coulomb force F_C [N]; leakage: conductance g [m3/(s Pa)]; asymmetry: |a| (random
    sign); discharge, viscosity: the relative deviation |theta/theta_0 - 1| from the nominal
    (manifest) value (random sign); air: the volume fraction V_G/V_C.

Detection level
    The smallest magnitude m whose noise-free characteristic differs from the nominal one by
    rms_z = 3, where rms_z = sqrt(mean_i ((F_i(m) - F_i,nom) / SE_i)^2) over all windows i of the
    plan, F from :class:`~isokinetic.nominal.ModelPlan` (the model run through the plan's own windows),
    and SE_i = sigma_F(F_i(m)) / sqrt(n_i) with sigma_F^2 = force_noise_N^2 + (force_noise_rel F)^2
    the scenario's per-sample force noise at the force the rig would read, n_i the window's samples.
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
import yaml
from scipy.optimize import brentq

from .characteristic import assemble
from .damper import NOMINAL, Damper, Effects
from .figures import save_figure
from .ingest import ingest_campaign
from .io import write_json, write_parquet
from .nominal import ModelPlan
from .plan import paper_plan
from .repeatability import repeatability
from .validate import write_validated
from .virtual_rig import Measurement, VirtualCampaign, export_raw_campaign
from .windows import WindowSpec, windows_stage

log = logging.getLogger("isokinetic.blind")

#: Effect names of the diagnosis contract, in their canonical order (verdict/truth text order).
EFFECTS = ("friction", "leakage", "asymmetry", "discharge", "viscosity", "air")

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

SCENARIO_PREFIX = "blind-"
DESCRIPTION = "Blind-test scenario: simulated damper test campaign; its unmodelled effects are withheld."
DIAGNOSIS_FIGURE = "diagnosis/fig16_gap.png"   # as rule diagnosis writes it


def scenario_names(n: int) -> list[str]:
    """blind-000, blind-001, ... (n names)."""
    return [f"{SCENARIO_PREFIX}{k:03d}" for k in range(n)]


def suite_size(n_per_effect: int, n_pairs: int, n_none: int) -> int:
    return len(EFFECTS) * n_per_effect + n_pairs + n_none


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


def truth_effects(damper: Damper, magnitudes: Mapping[str, float], signs: Mapping[str, float]) -> Effects:
    """The Effects of several effects together."""
    kwargs: dict[str, float] = {}
    for e, m in magnitudes.items():
        kwargs.update(effect_fields(e, m, signs.get(e, 1.0), damper))
    return Effects(**kwargs)


def effects_config(effects: Effects) -> dict:
    """Grouped config form of the active groups ({'friction': {'coulomb_force_N': 90.0}, ...})."""
    out = {}
    for group, keys in Effects.CONFIG_KEYS.items():
        vals = {k: getattr(effects, f) for k, f in keys.items()
                if getattr(effects, f) not in (None, 0.0) and k != "stribeck_velocity_m_s"}
        if vals:
            out[group] = vals
    return out


def force_se(force_N, measurement: Measurement, n_samples) -> np.ndarray:
    """Standard error of a window mean: sqrt(sigma_N^2 + (sigma_rel F)^2) / sqrt(n)."""
    f = np.asarray(force_N, dtype=float)
    sigma = np.sqrt(measurement.force_noise_N**2 + (measurement.force_noise_rel * f) ** 2)
    return sigma / np.sqrt(np.asarray(n_samples, dtype=float))


def rms_z(force_N, nominal_N, measurement: Measurement, n_samples) -> float:
    """rms over windows of (F - F_nominal) / SE(F)."""
    z = (np.asarray(force_N) - np.asarray(nominal_N)) / force_se(force_N, measurement, n_samples)
    return float(np.sqrt(np.mean(z * z)))


def plan_table(vc: VirtualCampaign) -> pd.DataFrame:
    """A status-ok cases table (the columns ModelPlan reads) of a campaign's own plan."""
    rows = [{"campaign": vc.name, "case": c.case, "waveform": c.waveform, "sample_rate_Hz": c.sample_rate_Hz,
             "amplitude_m": c.amplitude_m, "period_s": c.period_s, "frequency_Hz": c.frequency_Hz,
             "phase_rad": c.phase_rad, "duration_s": c.duration_s, "status": "ok"} for c in vc.cases]
    return pd.DataFrame(rows)


@dataclass
class DetectionProblem:
    """rms_z(m) of one effect in one scenario, evaluated through a prepared ModelPlan."""

    plan: ModelPlan
    damper: Damper
    measurement: Measurement
    nominal_N: np.ndarray
    calls: int = 0

    @classmethod
    def of(cls, vc: VirtualCampaign, spec: WindowSpec = WindowSpec()) -> "DetectionProblem":
        mp = ModelPlan.from_cases(vc.name, plan_table(vc), spec)
        return cls(mp, vc.damper, vc.measurement, mp.forces(vc.damper, NOMINAL)[0])

    def rms_z(self, effect: str, magnitude: float, sign: float = 1.0) -> float:
        self.calls += 1
        effects = Effects(**effect_fields(effect, magnitude, sign, self.damper))
        f = self.plan.forces(self.damper, effects)[0]
        return rms_z(f, self.nominal_N, self.measurement, self.plan.stop - self.plan.start)


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
            return math.exp(brentq(f, prev, x, xtol=1e-10, rtol=4 * np.finfo(float).eps, maxiter=200))
        prev = x
    return None


# --------------------------------------------------------------------------------------------
# Scenario generation
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Scenario:
    """One blind scenario: the campaign to export and its withheld truth."""

    name: str
    campaign: VirtualCampaign                 # effects = the truth
    truth: tuple[str, ...]                    # EFFECTS order
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

    def truth_record(self) -> dict:
        """JSON-ready truth (results/blind/truth/<scenario>.json)."""
        vc = self.campaign
        return {
            "format_version": 1,
            "scenario": self.name,
            "truth": list(self.truth),
            "truth_text": self.truth_text,
            "effects": effects_config(vc.effects),
            "magnitude": dict(self.magnitude),
            "magnitude_unit": {e: UNITS[e] for e in self.truth},
            "sign": dict(self.sign),
            "detection_level": dict(self.detection_level),
            "multiple": dict(self.multiple),
            "magnitude_x_detection": None if not self.multiple else self.magnitude_x_detection,
            "magnitude_bin": magnitude_bin(self.magnitude_x_detection),
            "detection_rms_z": TARGET_RMS_Z,
            "damper": vc.damper.to_dict(),
            "measurement": {k: (v if math.isfinite(v) else str(v))
                            for k, v in dataclasses.asdict(vc.measurement).items()},
            "velocities_mm_s": [round(c.velocity_m_s * 1e3, 12) for c in vc.cases],
            "periods_s": [c.period_s for c in vc.cases],
            "noise_seed": vc.seed,
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
              high_end_mm_s: tuple[float, float] = HIGH_END_MM_S) -> tuple[list[float], list[float]]:
    """(velocities [m/s], periods [s]) of a triangle plan."""
    n = int(rng.integers(n_velocities[0], n_velocities[1] + 1))
    lo = math.exp(rng.uniform(math.log(low_end_mm_s[0]), math.log(low_end_mm_s[1])))
    hi = math.exp(rng.uniform(math.log(high_end_mm_s[0]), math.log(high_end_mm_s[1])))
    speeds_mm_s = sorted({min(max(_sig(v, 3), 0.005), 1.5) for v in np.geomspace(lo, hi, n)})
    velocities = [v * 1e-3 for v in speeds_mm_s]
    periods = [period_for(v) for v in velocities]
    for v, t in zip(velocities, periods):
        amp = v * t / 4.0
        if not MIN_AMPLITUDE_M * (1 - 1e-12) <= amp <= MAX_AMPLITUDE_M:
            raise AssertionError(f"amplitude {amp} out of range")  # cannot happen within 0.005-1.5 mm/s
    return velocities, periods


def draw_measurement(rng: np.random.Generator) -> Measurement:
    return Measurement(force_noise_N=_sig(rng.uniform(2.0, 10.0), 3),
                       force_noise_rel=_sig(rng.uniform(0.005, 0.02), 3),
                       displacement_noise_m=1.0e-6)


def make_scenario(name: str, truth: Sequence[str], seed_seq: np.random.SeedSequence,
                  multiples: Mapping[str, float] | None = None, spec: WindowSpec = WindowSpec(),
                  n_velocities: tuple[int, int] = N_VELOCITIES,
                  low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                  high_end_mm_s: tuple[float, float] = HIGH_END_MM_S) -> Scenario:
    """Draw a scenario with the effects ``truth`` at ``multiples`` x their detection level.

    ``multiples`` missing an effect: drawn U[1, 5]. Damper, plan and noise are re-drawn (up to
    MAX_REDRAWS times) while an effect's 5x detection level exceeds its bound.
    """
    rng = np.random.default_rng(seed_seq)
    truth = tuple(e for e in EFFECTS if e in set(truth))
    multiples = dict(multiples or {})
    for redraw in range(MAX_REDRAWS + 1):
        damper = draw_damper(rng)
        velocities, periods = draw_plan(rng, n_velocities, low_end_mm_s, high_end_mm_s)
        measurement = draw_measurement(rng)
        noise_seed = int(rng.integers(0, 2**31 - 1))
        signs = {e: (float(rng.choice([-1.0, 1.0])) if e in SIGNED else 1.0) for e in truth}
        drawn = {e: float(rng.uniform(*MULTIPLE_RANGE)) for e in truth}
        cases = tuple(paper_plan(velocities, periods, [], 1.0, SAMPLE_RATE_HZ, 1.0, 1.0))
        vc = VirtualCampaign(name=name, description=DESCRIPTION, seed=noise_seed, temperature_C=40.0,
                             damper=damper, effects=NOMINAL, measurement=measurement, cases=cases)
        detection = {}
        if truth:
            problem = DetectionProblem.of(vc, spec)
            for e in truth:
                level = detection_level(problem, e, signs[e])
                if level is None or MULTIPLE_RANGE[1] * level > BOUNDS[e]:
                    log.info("%s: %s not detectable within bounds (detection %s, bound %g); re-drawing",
                             name, e, level, BOUNDS[e])
                    break
                detection[e] = level
            if len(detection) < len(truth):
                continue
        mult = {e: float(multiples.get(e, drawn[e])) for e in truth}
        magnitude = {e: mult[e] * detection[e] for e in truth}
        vc = dataclasses.replace(vc, effects=truth_effects(damper, magnitude, signs))
        return Scenario(name=name, campaign=vc, truth=truth, magnitude=magnitude,
                        sign={e: signs[e] for e in truth}, detection_level=detection, multiple=mult,
                        redraws=redraw)
    raise RuntimeError(f"{name}: no plan within {MAX_REDRAWS} re-draws makes {truth} detectable within bounds")


def suite_composition(seed: int, n_per_effect: int, n_pairs: int, n_none: int
                      ) -> list[tuple[tuple[str, ...], dict[str, float]]]:
    """(truth, multiples) per scenario, in name order.

    Singles of one effect get stratified multiples (k-th of n in [1 + 4k/n, 1 + 4(k+1)/n], strata
    in random order); pairs are distinct effect pairs (cycled when more than 15 are asked) with
    U[1, 5] multiples; the whole list is shuffled so a name does not tell its kind.
    """
    for key, v in (("n_per_effect", n_per_effect), ("n_pairs", n_pairs), ("n_none", n_none)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"{key}: must be a non-negative integer, got {v!r}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
    lo, hi = MULTIPLE_RANGE
    kinds: list[tuple[tuple[str, ...], dict[str, float]]] = []
    for e in EFFECTS:
        strata = rng.permutation(n_per_effect)
        for k in strata:
            u = rng.uniform(k / n_per_effect, (k + 1) / n_per_effect)
            kinds.append(((e,), {e: lo + (hi - lo) * float(u)}))
    all_pairs = list(itertools.combinations(EFFECTS, 2))
    order = rng.permutation(len(all_pairs))
    for i in range(n_pairs):
        pair = all_pairs[int(order[i % len(all_pairs)])]
        kinds.append((pair, {e: float(rng.uniform(lo, hi)) for e in pair}))
    kinds += [((), {}) for _ in range(n_none)]
    return [kinds[int(i)] for i in rng.permutation(len(kinds))]


def generate_scenarios(seed: int, n_per_effect: int, n_pairs: int, n_none: int, *,
                       multiple: float | None = None, spec: WindowSpec = WindowSpec(),
                       n_velocities: tuple[int, int] = N_VELOCITIES,
                       low_end_mm_s: tuple[float, float] = LOW_END_MM_S,
                       high_end_mm_s: tuple[float, float] = HIGH_END_MM_S) -> list[Scenario]:
    """The blind suite: ``n_per_effect`` single-effect scenarios per effect, ``n_pairs`` with two
    effects, ``n_none`` without; names blind-000... in a seeded random order.

    ``multiple`` fixes every effect's magnitude at that many detection levels (tests); the plan
    ranges can be narrowed for small suites.
    """
    composition = suite_composition(seed, n_per_effect, n_pairs, n_none)
    out = []
    for k, (name, (truth, mult)) in enumerate(zip(scenario_names(len(composition)), composition)):
        if multiple is not None:
            mult = {e: float(multiple) for e in truth}
        out.append(make_scenario(name, truth, np.random.SeedSequence([int(seed), k]), mult, spec,
                                 n_velocities, low_end_mm_s, high_end_mm_s))
    return out


# --------------------------------------------------------------------------------------------
# Export
# --------------------------------------------------------------------------------------------

#: generated_by keys of an export that are kept (the config campaign and the seed are dropped).
_KEEP_GENERATED = ("generator", "cases", "sample_rate_Hz")


def export_scenario(scenario: Scenario, raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> Path:
    """Raw campaign folder ``raw_root/<name>/`` (truth-free manifest) and ``truth_root/<name>.json``.

    ``virtual_rig.export_raw_campaign`` writes the nominal damper (never the effects) and a
    ``generated_by`` block naming the config campaign and the noise seed; the blind export keeps
    only the generator, cases and sample rate of that block, and a neutral description.
    """
    out = export_raw_campaign(scenario.campaign, Path(raw_root) / scenario.name)
    manifest_path = out / "campaign.yaml"
    manifest = yaml.safe_load(manifest_path.read_text(encoding="utf-8"))
    gen = manifest.get("generated_by") or {}
    manifest["generated_by"] = {k: gen[k] for k in _KEEP_GENERATED if k in gen}
    manifest["description"] = DESCRIPTION
    with open(manifest_path, "w", encoding="utf-8", newline="\n") as fh:
        yaml.safe_dump(manifest, fh, sort_keys=False, default_flow_style=False, allow_unicode=True, width=100)
    write_json(scenario.truth_record(), Path(truth_root) / f"{scenario.name}.json")
    return out


def write_suite(scenarios: Sequence[Scenario], raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> None:
    """Export every scenario (raw folder + truth file)."""
    for s in scenarios:
        export_scenario(s, raw_root, truth_root)
        log.info("%s exported: %d cases, %d re-draw(s)", s.name, len(s.campaign.cases), s.redraws)


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
    from .diagnosis import write_diagnosis  # the lead's module; imported late so generation works without it

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
    return write_diagnosis(root, root / "diagnosis.json", root / DIAGNOSIS_FIGURE, spec)


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

SCORE_COLUMNS = ("scenario", "truth", "verdict", "exact", "exact_up_to_confounding", "n_truth",
                 "magnitude_x_detection", "magnitude_bin", "gap_before", "gap_after", "shrink",
                 "confounded", "error")


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


def score(truths: Iterable[Mapping], diagnoses: Mapping[str, Mapping | None]) -> pd.DataFrame:
    """One row per truth record (sorted by scenario): truth/verdict text, exactness, magnitude and gaps.

    ``truths``: truth records (:meth:`Scenario.truth_record`, at least ``scenario``, ``truth``,
    ``magnitude_x_detection``); ``diagnoses``: scenario -> diagnosis dict (None or missing: the
    diagnosis failed; verdict 'error', not exact).
    """
    rows = []
    for t in truths:
        name = str(t["scenario"])
        truth = set(t.get("truth") or [])
        d = diagnoses.get(name)
        mult = _float(t.get("magnitude_x_detection"))
        if not truth:
            mult = math.nan
        row = {"scenario": name, "truth": effect_text(truth), "n_truth": len(truth),
               "magnitude_x_detection": mult, "magnitude_bin": magnitude_bin(mult)}
        if d is None:
            row.update(verdict="error", exact=False, exact_up_to_confounding=False, gap_before=math.nan,
                       gap_after=math.nan, shrink=math.nan, confounded="", error=True)
        else:
            verdict = set(d.get("verdict") or [])
            groups = _confounded_groups(d)
            row.update(verdict=effect_text(verdict), exact=verdict == truth,
                       exact_up_to_confounding=_up_to_confounding(truth, verdict, groups),
                       gap_before=_float(d.get("gap_before")), gap_after=_float(d.get("gap_after")),
                       shrink=_float(d.get("shrink")),
                       confounded=";".join(effect_text(g) for g in groups), error=False)
        rows.append(row)
    df = pd.DataFrame(rows, columns=list(SCORE_COLUMNS))
    if df.empty:
        return df.astype({"exact": bool, "exact_up_to_confounding": bool, "error": bool, "n_truth": "int64"})
    df = df.astype({"exact": bool, "exact_up_to_confounding": bool, "error": bool, "n_truth": "int64",
                    "magnitude_x_detection": float, "gap_before": float, "gap_after": float, "shrink": float})
    return df.sort_values("scenario", ignore_index=True)


TARGET_SINGLE_RATE = 0.95
TARGET_SINGLE_MIN_MULTIPLE = 2.0
TARGET_MEDIAN_SHRINK = 5.0


def _verdict_of(ok: bool | None) -> str:
    return "N/A" if ok is None else ("PASS" if ok else "FAIL")


def summarize(scores: pd.DataFrame) -> dict:
    """Per-bin exact-attribution rates and the three targets (JSON-ready).

    (a) >= 95 % of single-effect scenarios at >= 2x detection attributed exactly;
    (b) no effect claimed on any scenario without effects;
    (c) median shrink >= 5 over the scenarios with an effect.
    A target without any scenario to judge is 'N/A' (pass: null).
    """
    eff = scores[scores["n_truth"] > 0]
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
    none = scores[scores["n_truth"] == 0]
    claimed = none[none["verdict"] != ""]
    b_pass = None if none.empty else bool(claimed.empty)
    shrink = eff["shrink"].to_numpy(dtype=float)
    shrink = shrink[~np.isnan(shrink)]
    median = float(np.median(shrink)) if shrink.size else None
    if median is not None and not math.isfinite(median):
        median_json = None if math.isnan(median) else "inf"
    else:
        median_json = median
    c_pass = None if median is None else bool(median >= TARGET_MEDIAN_SHRINK)
    return {
        "format_version": 1,
        "n_scenarios": int(len(scores)),
        "n_single": int(len(singles)),
        "n_pairs": int((scores["n_truth"] == 2).sum()),
        "n_none": int(len(none)),
        "n_errors": int(scores["error"].sum()),
        "exact_rate": float(eff["exact"].mean()) if len(eff) else None,
        "bins": bins,
        "targets": {
            "a_single_at_2x": {"description": "single-effect scenarios at >= 2x detection attributed exactly",
                               "n": int(len(a_rows)), "exact": int(a_rows["exact"].sum()), "rate": a_rate,
                               "threshold": TARGET_SINGLE_RATE, "pass": a_pass,
                               "misses": sorted(a_rows.loc[~a_rows["exact"], "scenario"])},
            "b_none_clean": {"description": "no effect claimed on any scenario without effects",
                             "n": int(len(none)), "claimed": int(len(claimed)), "pass": b_pass,
                             "misses": sorted(claimed["scenario"])},
            "c_median_shrink": {"description": "median shrink where an effect was present",
                                "n": int(shrink.size), "median": median_json, "threshold": TARGET_MEDIAN_SHRINK,
                                "pass": c_pass},
        },
        "all_pass": all(t is True for t in (a_pass, b_pass, c_pass)),
    }


def summary_text(summary: Mapping) -> str:
    """The human summary printed by the scoring job."""
    t = summary["targets"]
    lines = [f"blind test: {summary['n_scenarios']} scenarios ({summary['n_single']} single, "
             f"{summary['n_pairs']} pairs, {summary['n_none']} none; {summary['n_errors']} diagnosis errors)",
             "exact attribution by magnitude (weakest effect, x detection level):"]
    for name, b in summary["bins"].items():
        rate = "  -  " if b["rate"] is None else f"{100 * b['rate']:5.1f} %"
        rs = "  -  " if b["rate_single"] is None else f"{100 * b['rate_single']:5.1f} %"
        lines.append(f"  {name:>5}: {b['exact']:3d}/{b['n']:<3d} {rate}   (single effect {b['exact_single']}/"
                     f"{b['n_single']} {rs})")
    a, bn, c = t["a_single_at_2x"], t["b_none_clean"], t["c_median_shrink"]
    a_rate = "-" if a["rate"] is None else f"{100 * a['rate']:.1f} %"
    lines.append(f"(a) {_verdict_of(a['pass'])}: single effect at >= 2x detection exact {a['exact']}/{a['n']} "
                 f"= {a_rate} (target >= {100 * a['threshold']:.0f} %)"
                 + (f"; missed {', '.join(a['misses'])}" if a["misses"] else ""))
    lines.append(f"(b) {_verdict_of(bn['pass'])}: effects claimed on {bn['claimed']}/{bn['n']} scenarios without "
                 f"effects (target 0)" + (f"; {', '.join(bn['misses'])}" if bn["misses"] else ""))
    med = "-" if c["median"] is None else (c["median"] if isinstance(c["median"], str) else f"{c['median']:.3g}")
    lines.append(f"(c) {_verdict_of(c['pass'])}: median shrink {med} over {c['n']} scenarios with effects "
                 f"(target >= {c['threshold']:g})")
    return "\n".join(lines)


def confusion_counts(scores: pd.DataFrame) -> pd.DataFrame:
    """Counts of truth set (rows) x verdict set (columns); '' shown as 'none'."""
    order = {e: i for i, e in enumerate(EFFECTS)}

    def key(text: str):
        if text == "":
            return (0, ())
        if text == "error":
            return (9, ())
        parts = text.split("+")
        return (len(parts), tuple(order.get(p, 99) for p in parts))

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
                                   for k in ("a_single_at_2x", "b_none_clean", "c_median_shrink"))
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
