"""Out-of-catalogue scenarios of the blind suite that hide from the steady characteristic (issue 35).

Kinds (:data:`isokinetic.contracts.scenarios.HIDDEN_AXES`: each one's ``where`` axis), in the reference rig's
physical forms (:class:`isokinetic.reference.rig.TrueEffects`):

bypass (position)
    A groove in the bore open within 1 mm of mid-stroke (its ends tapered over 0.1 mm), a second flow path of
    the orifice's form (Eq. 7) of area A_g: the force drops while the piston passes it, within each window
    whose stroke crosses the groove's ends and over the whole of the windows of the strokes inside it.
    Strength: A_g / A_O.
worn_bore (position)
    The bore worn around mid-stroke: an annular leakage gap h_w (1 - (y/L)^2) within L = 1.5 mm of it (none
    elsewhere). Strength: h_w [m].
gas_spring (position)
    A rod's gas volume: the load cell also reads k y. Strength: k [N/m].
wear (time)
    The orifice erodes: its area A_O (1 + w (f - 1/2)) in the case whose middle lies at the fraction f of the
    campaign's time. Strength: w.
warmup (time)
    The oil warms by dT over the campaign, unlogged: the viscosity of Vogel's law at T + dT (f - 1/2).
    Strength: dT [K].

Signature and strength
    What the catalogue cannot absorb, from the rig's noise-free force (this scenario's damper, plan and rig):
    for the position kinds the structure *within* each window, each window (the diagnosis' windows of the
    plan, :class:`~isokinetic.measurement.model_windows.ModelPlan`) cut into :data:`N_SUB` parts by position,
    each part's mean change minus its window's mean change (a steady characteristic, whatever its effects,
    gives a constant force in a steady window); for the time kinds each window's mean change (centred on the
    campaign's middle, so that the campaign-mean damper is the nominal one). Each in standard errors of that
    mean under the rig's exact noise (:meth:`isokinetic.reference.rig.RigImperfections.mean_noise_variance_N2`),
    and summarised as rms_z over all of them: the suite's detection rule (rms_z = 3 is one detection level).
    A scenario draws a multiple m in :data:`HIDDEN_MULTIPLE_RANGE`, measures rms_z at a base strength s0 and
    scales it to s0 (3 m / rms_z0)^e (e: :data:`STRENGTH_EXPONENT`, within :data:`STRENGTH_BOUND`), then
    measures rms_z again at that strength: what the truth reports (``hidden.rms_z``; ``visible`` where it
    reaches 3, and then the expected answer is ``explained: false`` with the kind's axis; else the catalogue
    truth, which the out-of-catalogue effect does not disturb beyond the noise).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from isokinetic.contracts.scenarios import DETECTION_RMS_Z, HIDDEN_AXES
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.measurement.model_windows import ModelPlan
from isokinetic.measurement.windows import WindowSpec
from isokinetic.physics.damper import Damper
from isokinetic.physics.plan import CasePlan
from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

#: Parts of a window, by position, whose mean changes the position kinds' signature compares.
N_SUB = 4
#: Drawn multiple of a hidden kind's signature detection level (rms_z = 3).
HIDDEN_MULTIPLE_RANGE = (2.0, 5.0)
#: Base strength of each kind (units: the module doc; the bypass' in A_g / A_O).
BASE_STRENGTH = {"bypass": 0.1, "worn_bore": 5.0e-6, "gas_spring": 1.0e4, "wear": 0.05, "warmup": 2.0}
#: How the signature grows with the strength, about (rms_z ~ s^(1/e)): the worn bore's leakage as h_w^3.
STRENGTH_EXPONENT = {"bypass": 1.0, "worn_bore": 1.0 / 3.0, "gas_spring": 1.0, "wear": 1.0, "warmup": 1.0}
#: Largest plausible strength of each kind.
STRENGTH_BOUND = {"bypass": 1.0, "worn_bore": 50.0e-6, "gas_spring": 1.0e6, "wear": 0.5, "warmup": 30.0}
STRENGTH_UNIT = {"bypass": "A_g/A_O", "worn_bore": "m", "gas_spring": "N/m", "wear": "relative area change",
                 "warmup": "K"}
#: The groove's half width and taper, the worn band's half length [m].
GROOVE_HALF_WIDTH_M = 1.0e-3
GROOVE_TAPER_M = 1.0e-4
WORN_HALF_LENGTH_M = 1.5e-3
#: Integration tolerance of the noise-free signature runs (the export's is 1e-10).
SIGNATURE_RTOL = 1.0e-8
TARGET_RMS_Z = DETECTION_RMS_Z


def plan_table(name: str, cases: Sequence[CasePlan]) -> pd.DataFrame:
    """A status-ok cases table (the columns ModelPlan reads) of a plan."""
    rows = [{"campaign": name, "case": c.case, "waveform": c.waveform, "sample_rate_Hz": c.sample_rate_Hz,
             "amplitude_m": c.amplitude_m, "period_s": c.period_s, "frequency_Hz": c.frequency_Hz,
             "phase_rad": c.phase_rad, "duration_s": c.duration_s, "status": "ok"} for c in cases]
    return pd.DataFrame(rows)


def hidden_fields(kind: str, strength: float, damper: Damper) -> dict[str, float]:
    """TrueEffects fields of a hidden kind at ``strength`` (its unit: :data:`STRENGTH_UNIT`)."""
    if kind == "bypass":
        return {"bypass_area_m2": strength * damper.orifice_area_m2, "bypass_half_width_m": GROOVE_HALF_WIDTH_M,
                "bypass_taper_m": GROOVE_TAPER_M}
    if kind == "worn_bore":
        return {"bore_wear_gap_m": strength, "bore_wear_half_length_m": WORN_HALF_LENGTH_M}
    if kind == "gas_spring":
        return {"gas_spring_N_m": strength}
    if kind == "wear":
        return {"orifice_wear_rel": strength}
    if kind == "warmup":
        return {"warmup_K": strength}
    raise KeyError(f"unknown hidden kind {kind!r}; known: {tuple(HIDDEN_AXES)}")


def rig_cases(cases: Sequence[CasePlan]) -> list[rr.TriangleCase]:
    """The reference rig's triangle cases of a plan."""
    return [rr.TriangleCase(c.case, c.velocity_m_s, c.period_s, c.sample_rate_Hz) for c in cases]


def rig_forces(damper: Damper, cases: Sequence[CasePlan], effects: rr.TrueEffects, rig: rr.RigImperfections,
               temperature_C: float = 40.0) -> list[np.ndarray]:
    """The rig's noise-free load-cell force of every case at its sample times, the cases run in plan order as
    :func:`isokinetic.reference.campaign.write_campaign` runs them (wear and warm-up by campaign time)."""
    design = rr.DamperDesign.from_mapping(damper.to_dict())
    rcases = rig_cases(cases)
    out = []
    for i, (case, f) in enumerate(zip(rcases, rrc.case_time_fractions(rcases), strict=True)):
        warm, area = rr.campaign_drift(effects, f, temperature_C)
        s = rr.true_series(case, design, effects, rig, i, len(rcases), SIGNATURE_RTOL, warm, area)
        out.append(s["force_N"].to_numpy())
    return out


def window_plan(name: str, cases: Sequence[CasePlan], spec: WindowSpec = DEFAULTS.window) -> ModelPlan:
    """The diagnosis' windows of the plan (sample indices of each case's record)."""
    return ModelPlan.from_cases(name, plan_table(name, cases), spec)


def signature_z(axis: str, with_effect: Sequence[np.ndarray], without: Sequence[np.ndarray], cases: Sequence[CasePlan],
                windows: ModelPlan, rig: rr.RigImperfections) -> np.ndarray:
    """z of the hidden effect's signature (module doc): per window part (axis 'position') or per window
    (axis 'time'), the mean change in standard errors of that mean."""
    index = {c.case: i for i, c in enumerate(cases)}
    out = []
    for ci, a, b in zip(windows.case_index, windows.start, windows.stop, strict=True):
        plan = windows.plans[int(ci)]
        k = index[plan.case]
        f, d = with_effect[k][a:b], with_effect[k][a:b] - without[k][a:b]

        def se(part: np.ndarray, _fs=plan.sample_rate_Hz, _f=f) -> float:
            return math.sqrt(rig.mean_noise_variance_N2(part.size, float(np.mean(_f[part])), _fs))

        if axis == "time":
            out.append(float(d.mean()) / se(np.arange(d.size)))
            continue
        for part in np.array_split(np.arange(d.size), N_SUB):
            out.append(float(d[part].mean() - d.mean()) / se(part))
    return np.asarray(out)


def signature_rms_z(kind: str, strength: float, damper: Damper, cases: Sequence[CasePlan], base: rr.TrueEffects,
                    rig: rr.RigImperfections, windows: ModelPlan, without: Sequence[np.ndarray]) -> float:
    """rms_z of a hidden kind's signature at ``strength`` on top of ``base`` (whose forces are ``without``)."""
    effects = dataclasses.replace(base, **hidden_fields(kind, strength, damper))
    z = signature_z(HIDDEN_AXES[kind], rig_forces(damper, cases, effects, rig), without, cases, windows, rig)
    return float(np.sqrt(np.mean(z * z))) if z.size else 0.0


def hidden_effects(kind: str, name: str, damper: Damper, cases: Sequence[CasePlan], base: rr.TrueEffects,
                   rig: rr.RigImperfections, rng: np.random.Generator,
                   spec: WindowSpec = DEFAULTS.window) -> tuple[dict[str, float], dict]:
    """(TrueEffects fields, the truth's ``hidden`` record) of a hidden kind in one drawn scenario: its strength
    scaled to a drawn multiple of its signature's detection level and its rms_z measured there (module doc)."""
    windows = window_plan(name, cases, spec)
    without = rig_forces(damper, cases, base, rig)
    multiple = float(rng.uniform(*HIDDEN_MULTIPLE_RANGE))
    s0 = BASE_STRENGTH[kind]
    z0 = signature_rms_z(kind, s0, damper, cases, base, rig, windows, without)
    scale = (TARGET_RMS_Z * multiple / z0) ** STRENGTH_EXPONENT[kind] if z0 > 0.0 else math.inf
    strength = float(f"{min(s0 * scale, STRENGTH_BOUND[kind]):.3g}")
    z = signature_rms_z(kind, strength, damper, cases, base, rig, windows, without)
    record = {"kind": kind, "axis": HIDDEN_AXES[kind], "strength": strength, "strength_unit": STRENGTH_UNIT[kind],
              "drawn_multiple": multiple, "rms_z": z, "multiple": z / TARGET_RMS_Z, "visible": bool(z >= TARGET_RMS_Z),
              "signature": ("within-window parts" if HIDDEN_AXES[kind] == "position" else "window means")}
    return hidden_fields(kind, strength, damper), record


def expected_answer(out_of_catalogue: str, truth: Sequence[str], hidden: Mapping) -> dict:
    """The truth's expected answer: an old out-of-catalogue kind (in the steady characteristic) ``explained:
    false``; a hidden kind that moves the observations beyond their noise ``explained: false`` with its axis
    named in ``where``; one that does not, the catalogue truth (``explained`` either way); in-catalogue
    scenarios their truth."""
    if not out_of_catalogue:
        return {"explained": None, "where_axis": None, "verdict": list(truth)}
    if out_of_catalogue not in HIDDEN_AXES:
        return {"explained": False, "where_axis": None, "verdict": None}
    if hidden.get("visible"):
        return {"explained": False, "where_axis": HIDDEN_AXES[out_of_catalogue], "verdict": None}
    return {"explained": None, "where_axis": None, "verdict": list(truth)}
