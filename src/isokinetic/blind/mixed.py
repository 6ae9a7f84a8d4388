"""A mixed campaign on the independent reference rig: slow triangles plus a sine matrix, with Coulomb friction and
entrained air (issue 35, part 3's test case: a diagnosis that judges the triangles alone reports the friction and
loses the air the sines show far beyond their noise).

:func:`write_mixed_campaign` writes the raw campaign folder and returns its truth; the magnitudes are set in
detection levels on the triangles' windows, the blind suite's rms_z = 3 rule
(:class:`~isokinetic.blind.generate.DetectionProblem`), and the air's rms_z on the sines' phase bins
(:class:`~isokinetic.blind.generate.SineDetectionProblem`) is reported beside it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from isokinetic.blind.generate import (
    SAMPLE_RATE_HZ,
    SINE_SAMPLE_RATE_HZ,
    DetectionProblem,
    SineDetectionProblem,
    detection_level,
    period_for,
    physical_effects,
)
from isokinetic.blind.hidden import rig_cases
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

#: The mixed campaign's slow triangles [mm/s] (periods: blind.generate.period_for), 50 Hz.
MIXED_TRIANGLE_SPEEDS_MM_S = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5)
#: Its sine matrix: every frequency [Hz] at every amplitude [mm], MIXED_SINE_CYCLES cycles at 1 kHz.
MIXED_SINE_FREQUENCIES_HZ = (0.5, 2.0, 8.0)
MIXED_SINE_AMPLITUDES_MM = (0.02, 0.06)
MIXED_SINE_CYCLES = 6
#: Its rig: some delay and servo lag, white plus proportional coloured force noise, an ideal sensor chain.
MIXED_RIG = rr.RigImperfections(delay_s=0.005, servo_lag_s=0.004, force_noise_N=3.0, force_noise_rel=0.008,
                                noise_corner_Hz=1.0, displacement_noise_m=1.0e-6, force_resolution_N=0.01,
                                displacement_resolution_m=1e-8, command_resolution_m=1e-8)


def mixed_plan() -> list[CasePlan]:
    """The mixed campaign's cases in test order: the triangles T01.. (slowest first), then the sines S01..
    (each frequency at each amplitude)."""
    tri = []
    for i, v in enumerate(MIXED_TRIANGLE_SPEEDS_MM_S, start=1):
        period = period_for(v * 1e-3)
        tri.append(CasePlan(f"T{i:02d}", "triangle", SAMPLE_RATE_HZ, amplitude_m=v * 1e-3 * period / 4.0,
                            period_s=period, duration_s=2.0 * period))
    grid = [(f, a) for f in MIXED_SINE_FREQUENCIES_HZ for a in MIXED_SINE_AMPLITUDES_MM]
    sines = [CasePlan(f"S{i:02d}", "sine", SINE_SAMPLE_RATE_HZ, amplitude_m=a * 1e-3, frequency_Hz=f, phase_rad=0.0,
                      duration_s=MIXED_SINE_CYCLES / f) for i, (f, a) in enumerate(grid, start=1)]
    return tri + sines


def write_mixed_campaign(folder: str | Path, seed: int = 0, friction_multiple: float = 3.0,
                         air_multiple: float = 1.0, rig: rr.RigImperfections = MIXED_RIG) -> dict:
    """Write a raw mixed campaign (slow triangles plus a sine matrix, :func:`mixed_plan`) of the Table-1 damper
    with Coulomb friction and entrained air, simulated by the independent reference rig, and return its truth.

    The friction is ``friction_multiple`` times its detection level on the triangles' windows, the air
    ``air_multiple`` times its detection level there (1: just at the edge of what the triangles show): the same
    rms_z = 3 rule as the blind suite's (:class:`~isokinetic.blind.generate.DetectionProblem`). The air's
    rms_z on the sines' phase bins (:class:`~isokinetic.blind.generate.SineDetectionProblem`) is
    reported beside it: far beyond 3, what a diagnosis that weighs the sines must not lose. ``folder`` must be
    absent or empty, its name a campaign id; the export as :func:`isokinetic.blind.generate.export_scenario`
    writes it (nominal damper and charge pressure only). Returns the truth: ``truth`` ['friction', 'air'],
    ``params`` (coulomb_force_N, air_volume_fraction), ``detection_level``, ``multiple``, the air's and
    friction's rms_z on the triangles and on the sines, the cases, the rig and the seed.
    """
    cases = mixed_plan()
    tri = [c for c in cases if c.waveform == "triangle"]
    sines = [c for c in cases if c.waveform == "sine"]
    problem = DetectionProblem.of(Path(folder).name, tri, TABLE_1, rig)
    level = {e: detection_level(problem, e) for e in ("friction", "air")}
    magnitude = {"friction": friction_multiple * level["friction"], "air": air_multiple * level["air"]}
    sine_problem = SineDetectionProblem.of(sines, TABLE_1, rig)
    effects = physical_effects(TABLE_1, magnitude, {}, 5.0e6)
    rrc.write_campaign(folder, [*rig_cases(tri), *(rr.SineCase(c.case, c.frequency_Hz, c.amplitude_m,
                                                               MIXED_SINE_CYCLES, c.sample_rate_Hz) for c in sines)],
                       rr.DamperDesign.from_mapping(TABLE_1.to_dict()), effects, rig, seed,
                       description="Mixed campaign: slow triangles and a sine matrix", declare_charge_pressure=True)
    rms = {f"{e}_rms_z_{part}": p.rms_z(e, magnitude[e]) for e in magnitude
           for part, p in (("triangles", problem), ("sines", sine_problem))}
    return {"truth": ["friction", "air"], "params": {"coulomb_force_N": magnitude["friction"],
                                                     "air_volume_fraction": magnitude["air"]},
            "detection_level": level, "multiple": {"friction": friction_multiple, "air": air_multiple}, **rms,
            "cases": [c.case for c in cases], "rig": dataclasses.asdict(rig), "seed": int(seed)}
