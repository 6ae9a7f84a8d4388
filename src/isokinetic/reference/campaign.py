"""What leaves the independent reference rig (:mod:`isokinetic.reference.rig`): measured
channels, the raw-campaign export, and the catalogue equivalents of its hidden truth.

Part of the separately written reference against which the project's diagnosis is tested (the
method of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs", Titurus et al.; equation and table numbers are the paper's). Like its
sibling it shares no code with the rest of ``isokinetic``: it imports only numpy, scipy, pandas,
yaml, the standard library and :mod:`isokinetic.reference.rig`.

Measurement
    Force channel F_meas = g F_true + F0 + sigma_w w_k + |F_true| sigma_rel c_k, with w white and c
    a unit-variance AR(1) sequence (rho = exp(-2 pi f_c / fs), stationary start); the LVDT measures
    the actuator x with white noise; every channel is then quantised. Optional sensor-chain
    nuisances (:class:`RigImperfections`): a Butterworth low-pass on the force channel, a zero drift
    linear in campaign time, an LVDT gain, and dropped samples. Noise of case i is drawn from
    ``SeedSequence([seed, i])``.

Catalogue equivalents
    The parameters the project's diagnosis fits (Coulomb friction, laminar leakage conductance,
    asymmetry, C_D, viscosity, air fraction of Eq. 3) that the rig's physical effects amount to,
    for scoring; and the inverse maps used to draw a rig from catalogue values.

Export
    :func:`write_campaign` writes a raw campaign folder (campaign.yaml plus one CSV per case) in
    column names and units deliberately unlike the project's (:data:`EXPORT_COLUMNS`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from isokinetic.reference.rig import (
    IDEAL_RIG,
    NOMINAL_EFFECTS,
    TABLE1,
    VOGEL_B_K,
    VOGEL_C_K,
    DamperDesign,
    RigCase,
    RigImperfections,
    SineCase,
    TrueEffects,
    annular_leakage_conductance,
    campaign_drift,
    piston_diameter_m,
    true_series,
    true_viscosity,
    vogel_viscosity_ratio,
)

#: Isothermal compressibility of air at atmospheric pressure, Table 1 [1/Pa] (catalogue form).
AIR_COMPRESSIBILITY_CATALOGUE_1_PA = 9.9e-6

#: Campaign (folder) names allowed by the raw-campaign spec.
_CAMPAIGN_NAME = re.compile(r"[a-z0-9][a-z0-9_-]*\Z")


# ---------------------------------------------------------------------------------------------
# Measurement
# ---------------------------------------------------------------------------------------------

def case_rng(seed: int, case_index: int) -> np.random.Generator:
    """Noise stream of case ``case_index``: Generator(SeedSequence([seed, case_index]))."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(case_index)]))


def ar1_sequence(innovations, rho: float) -> np.ndarray:
    """Unit-variance stationary AR(1): c0 = e0, c_k = rho c_(k-1) + sqrt(1 - rho^2) e_k."""
    e = np.asarray(innovations, dtype=float)
    if e.size == 0:
        return e.copy()
    out = np.empty_like(e)
    out[0] = e[0]
    if e.size > 1:
        from scipy.signal import lfilter  # scipy.signal (~0.5 s): only where rig noise is drawn

        out[1:], _ = lfilter([math.sqrt(1.0 - rho * rho)], [1.0, -rho], e[1:], zi=[rho * e[0]])
    return out


def mean_noise_variance(n_samples: int, force_N: float, rig: RigImperfections, sample_rate_Hz: float) -> float:
    """Exact variance of the mean of n consecutive force-noise samples at true force F [N^2].

    See :meth:`RigImperfections.mean_noise_variance_N2` (the formula lives with the noise parameters).
    """
    return rig.mean_noise_variance_N2(n_samples, force_N, sample_rate_Hz)


def quantise(x, step: float) -> np.ndarray:
    """Nearest integer multiple of ``step`` (never -0.0)."""
    return np.rint(np.asarray(x, dtype=float) / step) * step + 0.0


def lowpass(t_s: np.ndarray, x: np.ndarray, corner_Hz: float, order: int) -> np.ndarray:
    """x through an analog Butterworth low-pass (order 1 or 2, corner ``corner_Hz``, unit DC gain),
    the input linearly interpolated between samples, starting at rest at x[0].

    The exact discretisation of ``scipy.signal.lsim`` (the same matrix exponential: state x_k = x_(k-1) Ad
    + u_(k-1) Bd0 + u_k Bd1), its recursion run per mode of Ad by ``lfilter`` instead of lsim's Python loop
    over the samples (same output within 1e-13 relative, twenty times faster)."""
    from scipy import linalg, signal  # scipy.signal: only where a filtered force channel is simulated

    b, a = signal.butter(order, 2.0 * math.pi * corner_Hz, btype="low", analog=True)
    A, B, C, D = signal.tf2ss(b, a)
    u = np.asarray(x, dtype=float)
    n = A.shape[0]
    start = -np.linalg.solve(A, B[:, 0]) * u[0]     # the steady state at the first input
    if u.size < 2:
        return (C @ start + D[0] * u[0]).astype(float)
    m = np.zeros((n + 2, n + 2))   # lsim's first-order hold: [[A dt, B dt, 0], [0, 0, 1], [0, 0, 0]]
    m[:n, :n], m[:n, n:n + 1], m[n, n + 1] = A * float(t_s[1] - t_s[0]), B * float(t_s[1] - t_s[0]), 1.0
    e = linalg.expm(m.T)
    ad, bd1 = e[:n, :n], e[n + 1:, :n]
    bd0 = e[n:n + 1, :n] - bd1
    # w_k = x_k - u_k Bd1 obeys w_k = w_(k-1) Ad + u_(k-1) (Bd1 Ad + Bd0); per mode of Ad (column form)
    lam, vec = np.linalg.eig(ad.T)
    gain = np.linalg.solve(vec, (bd1 @ ad + bd0).T)[:, 0]
    mode0 = np.linalg.solve(vec, start - bd1[0] * u[0])
    uc = u.astype(complex)
    modes = np.stack([signal.lfilter([0.0, gain[j]], [1.0, -lam[j]], uc, zi=[mode0[j]])[0] for j in range(n)])
    return (C @ vec @ modes).real[0] + float((bd1 @ C.T + D)[0, 0]) * u


def measure(truth: pd.DataFrame, case: RigCase, rig: RigImperfections, seed: int,
            case_index: int, campaign_time_s: float = 0.0) -> pd.DataFrame:
    """Measured channels of a true record: adds force_meas_N, displacement_meas_m, command_meas_m.

    The three noise streams (white force, AR(1) innovations, LVDT) are always drawn, in this
    order, so that switching one noise source off leaves the others unchanged. The force channel
    is g F + F0 + r (t_c + t) (zero drift; ``campaign_time_s`` t_c: the case's start in campaign
    time), low-pass filtered when the rig has a force filter, plus noise; the LVDT reads k x.
    """
    n = len(truth)
    rng = case_rng(seed, case_index)
    white = rng.standard_normal(n)
    coloured = ar1_sequence(rng.standard_normal(n), rig.noise_correlation(case.sample_rate_Hz))
    lvdt = rng.standard_normal(n)
    f = truth["force_N"].to_numpy()
    t = truth["time_s"].to_numpy()
    analog = rig.force_gain * f + rig.force_offset_N
    if rig.force_drift_N_s != 0.0:
        analog = analog + rig.force_drift_N_s * (campaign_time_s + t)
    if rig.force_filter_Hz > 0.0:
        analog = lowpass(t, analog, rig.force_filter_Hz, rig.force_filter_order)
    force = analog + rig.force_noise_N * white + np.abs(f) * rig.force_noise_rel * coloured
    out = truth.copy()
    out["force_meas_N"] = quantise(force, rig.force_resolution_N)
    x = truth["actuator_m"].to_numpy()
    if rig.displacement_gain != 1.0:
        x = rig.displacement_gain * x
    out["displacement_meas_m"] = quantise(x + rig.displacement_noise_m * lvdt, rig.displacement_resolution_m)
    out["command_meas_m"] = quantise(truth["command_m"].to_numpy(), rig.command_resolution_m)
    return out


def simulate_case(case: RigCase, damper=TABLE1, effects: TrueEffects = NOMINAL_EFFECTS,
                  rig: RigImperfections = IDEAL_RIG, seed: int = 0, case_index: int = 0,
                  n_cases: int = 1, rtol: float = 1e-10, viscosity_ratio: float = 1.0,
                  campaign_time_s: float = 0.0, orifice_area_ratio: float = 1.0) -> pd.DataFrame:
    """:func:`true_series` followed by :func:`measure` (true and measured columns together)."""
    return measure(true_series(case, damper, effects, rig, case_index, n_cases, rtol, viscosity_ratio,
                               orifice_area_ratio), case, rig, seed, case_index, campaign_time_s)


def dropped(series: pd.DataFrame, rig: RigImperfections, seed: int, case_index: int) -> pd.DataFrame:
    """The record without its dropped samples: each sample but the first and last is missing with
    probability ``rig.dropout_fraction`` (stream SeedSequence([seed, i, 11]), apart from the noise)."""
    if rig.dropout_fraction == 0.0 or len(series) < 3:
        return series
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(case_index), 11]))
    keep = rng.random(len(series)) >= rig.dropout_fraction
    keep[0] = keep[-1] = True
    return series[keep].reset_index(drop=True)


@dataclasses.dataclass(frozen=True)
class OilTemperature:
    """A campaign whose oil warms from case to case: the truth (Vogel's law, mu = A exp(b / (T - c))) and
    what the rig logs of it.

    Case i runs at ``case_temperatures_C[i]`` with the viscosity mu_true(T_i) (mu_true holds at the
    campaign's ``temperature_C``); the logged channel (:data:`TEMPERATURE_COLUMN`, in K) rises by
    ``warmup_K`` over each record with white sensor noise ``sensor_noise_K``, quantised to 0.01 K. The
    manifest's ``damper.viscosity_law`` gives two datasheet points of the truth at ``law_points_C``, the
    viscosities rounded to three significant digits: a Walther line through them is close to, not equal
    to, the Vogel truth between them.
    """

    case_temperatures_C: tuple[float, ...]
    vogel_b_K: float = VOGEL_B_K
    vogel_c_K: float = VOGEL_C_K
    warmup_K: float = 0.3
    sensor_noise_K: float = 0.05
    law_points_C: tuple[float, float] = (40.0, 100.0)

    def viscosity_ratio(self, case_index: int, temperature_C: float) -> float:
        """mu(T_case) / mu(T_campaign)."""
        return float(vogel_viscosity_ratio(self.case_temperatures_C[case_index], temperature_C, self.vogel_b_K,
                                           self.vogel_c_K))

    def law(self, viscosity_Pa_s: float, temperature_C: float) -> dict:
        """The manifest's viscosity_law: two rounded points of the truth."""
        return {"kind": "walther", "points": [
            [float(t), _sig(viscosity_Pa_s * float(vogel_viscosity_ratio(t, temperature_C, self.vogel_b_K,
                                                                          self.vogel_c_K)), 3)]
            for t in self.law_points_C]}

    def logged_K(self, time_s: np.ndarray, case_index: int, seed: int) -> np.ndarray:
        """The temperature channel of case i [K]: linear warm-up plus sensor noise, quantised to 0.01 K."""
        t = np.asarray(time_s, dtype=float)
        span = max(float(t[-1] - t[0]), 1e-12) if t.size else 1.0
        rise = self.warmup_K * ((t - t[0]) / span - 0.5) if t.size else t
        noise = np.random.default_rng(np.random.SeedSequence([int(seed), int(case_index), 7])).standard_normal(t.size)
        return quantise(self.case_temperatures_C[case_index] + 273.15 + rise + self.sensor_noise_K * noise, 0.01)


#: CSV column of the logged oil temperature (K), written only for a campaign with an :class:`OilTemperature`.
TEMPERATURE_COLUMN = ("oil_K", "K")


# ---------------------------------------------------------------------------------------------
# Catalogue equivalents (scoring)
# ---------------------------------------------------------------------------------------------

def catalogue_equivalent(damper, effects: TrueEffects) -> dict:
    """The catalogue-form parameters the project's diagnosis fits, from the physical effects.

    coulomb_force_N = F_C (the Stribeck excess has no catalogue form); leakage conductance
    pi D h^3 / (12 mu L) at the campaign-mean true viscosity; asymmetry a; path_asymmetry the one-sided
    path's r (``path_resistance_neg``, the same form); discharge coefficient
    and viscosity (None when not changed); air_volume_fraction phi_cat with
    phi_cat * 9.9e-6 = phi0 / p0, i.e. the gas term of the mixture compressibility at the
    charge pressure (:func:`chamber_capacitance`, neglecting its -phi0 beta_oil part) written
    in the catalogue form beta_eff = beta_oil + phi_cat beta_air (Eq. 3, Table 1).
    """
    mu = true_viscosity(damper, effects)
    return {
        "coulomb_force_N": float(effects.coulomb_force_N),
        "leakage_conductance_m3_s_Pa": annular_leakage_conductance(damper.piston_area_m2, effects.leakage_gap_m,
                                                                   mu, effects.seal_length_m),
        "asymmetry": float(effects.asymmetry),
        "path_asymmetry": float(effects.path_resistance_neg),
        "discharge_coefficient": (None if effects.discharge_coefficient is None
                                  else float(effects.discharge_coefficient)),
        "viscosity_Pa_s": None if effects.viscosity_Pa_s is None else float(effects.viscosity_Pa_s),
        "air_volume_fraction": effects.air_fraction_at_charge
        / (effects.charge_pressure_Pa * AIR_COMPRESSIBILITY_CATALOGUE_1_PA),
    }


def out_of_catalogue_effects(effects: TrueEffects, strong_stribeck_ratio: float = 0.5) -> tuple[str, ...]:
    """Names of the active effects with no catalogue form: 'stribeck' (F_S >= ratio F_C and
    F_S > 0), 'backlash', 'relief_valve', 'bypass', 'worn_bore', 'gas_spring', 'wear', 'warmup'."""
    names = []
    if effects.stribeck_force_N > 0.0 and effects.stribeck_force_N >= strong_stribeck_ratio * effects.coulomb_force_N:
        names.append("stribeck")
    if effects.backlash_m > 0.0:
        names.append("backlash")
    if effects.relief_cracking_pressure_Pa is not None and effects.relief_area_gradient_m2_Pa > 0.0:
        names.append("relief_valve")
    for name, value in (("bypass", effects.bypass_area_m2), ("worn_bore", effects.bore_wear_gap_m),
                        ("gas_spring", effects.gas_spring_N_m), ("wear", effects.orifice_wear_rel),
                        ("warmup", effects.warmup_K)):
        if value != 0.0:
            names.append(name)
    return tuple(names)


def air_fraction_from_catalogue(catalogue_fraction: float, charge_pressure_Pa: float = 5.0e6) -> float:
    """phi0 = phi_cat p0 9.9e-6: the free-gas fraction at p0 with the catalogue's gas term."""
    return catalogue_fraction * charge_pressure_Pa * AIR_COMPRESSIBILITY_CATALOGUE_1_PA


def leakage_gap_from_conductance(conductance_m3_s_Pa: float, damper, viscosity_Pa_s: float | None = None,
                                 seal_length_m: float = 0.02) -> float:
    """Radial gap h = (12 mu L g / (pi D))^(1/3) giving the laminar conductance g [m].

    ``viscosity_Pa_s`` defaults to the design viscosity; pass the true one when it differs.
    """
    mu = damper.viscosity_Pa_s if viscosity_Pa_s is None else viscosity_Pa_s
    diameter = piston_diameter_m(damper.piston_area_m2)
    return (12.0 * mu * seal_length_m * conductance_m3_s_Pa / (math.pi * diameter)) ** (1.0 / 3.0)


# ---------------------------------------------------------------------------------------------
# Raw campaign export
# ---------------------------------------------------------------------------------------------

#: channel -> (column name, unit, SI value of one unit); deliberately not the project's names.
EXPORT_COLUMNS = {
    "time": ("t_ms", "ms", 1.0e-3),
    "displacement": ("lvdt_um", "um", 1.0e-6),
    "force": ("load_N", "N", 1.0),
    "command": ("command_um", "um", 1.0e-6),
}


def _decimals(step_in_unit: float) -> int:
    """Decimal places that print integer multiples of ``step_in_unit`` exactly (ValueError if > 12)."""
    for n in range(13):
        scaled = step_in_unit * 10**n
        if abs(scaled - round(scaled)) <= 1e-9 * max(scaled, 1.0):
            return n
    raise ValueError(f"resolution {step_in_unit!r} is not a short decimal")


def _quantised(values_si: np.ndarray, step_si: float, unit_si: float, sign: float = 1.0) -> tuple[np.ndarray, int]:
    """Quantised values in the export unit, as the floats k * step (k integer counts) that print
    exactly with the returned number of decimals."""
    step = step_si / unit_si
    dec = _decimals(step)
    counts = np.rint(np.asarray(values_si) / step_si).astype(np.int64) * int(round(sign))
    return counts * round(step, dec) + 0.0, dec


def _times_ms(t_s: np.ndarray, sample_rate_Hz: float, offset_s: float) -> tuple[np.ndarray, int]:
    """Time stamps in ms and the decimals they print with."""
    def exact(x: float, n: int) -> bool:
        return abs(x * 10**n - round(x * 10**n)) <= 1e-9

    dec = next((n for n in range(7) if exact(1e3 / sample_rate_Hz, n) and exact(offset_s * 1e3, n)), 6)
    return (t_s + offset_s) * 1e3 + 0.0, dec


def _fixed(values: np.ndarray, dec: int) -> list[str]:
    """``f"{v:.{dec}f}"`` of every value."""
    return [f"{v:.{dec}f}" for v in values.tolist()]


def _fixed_ascii(values: np.ndarray, dec: int) -> np.ndarray | None:
    """``f"{v:.{dec}f}"`` of every value as ASCII codes, one column per value (right-aligned,
    padded at the top with 0 bytes); None when that is not provably the same text.

    v is printed as the integer m = rint(v 10^dec) with a point before its last ``dec`` digits and a
    sign when v < 0 or v is -0.0 (so -0.001 rounded to 2 decimals is "-0.00", as Python prints it). That is
    Python's correctly rounded text whenever v 10^dec lies within 1/4 of m (the product's rounding
    error is far below the remaining 1/4 for |m| < 2^50); otherwise, or for a non-finite value, None.
    """
    scaled = values * 10.0**dec
    m = np.rint(scaled)
    if not (np.all(np.isfinite(scaled)) and np.all(np.abs(scaled - m) <= 0.25) and np.all(np.abs(m) < 2.0**50)):
        return None
    rest = np.abs(m).astype(np.int64)
    n_int = len(str(int(rest.max(initial=0)) // 10**dec))
    width = 1 + n_int + (dec + 1 if dec else 0)            # sign, integer digits, point and decimals
    out = np.zeros((width, values.size), dtype=np.uint8)
    row = width - 1
    for _ in range(dec):
        rest, digit = np.divmod(rest, 10)
        out[row] = digit + 48
        row -= 1
    if dec:
        out[row] = ord(".")
        row -= 1
    rest, digit = np.divmod(rest, 10)
    out[row] = digit + 48                                  # the units digit, always
    lead = np.full(values.size, row)
    for higher in range(row - 1, 0, -1):
        more = rest > 0
        rest, digit = np.divmod(rest, 10)
        out[higher] = np.where(more, digit + 48, 0)
        lead = np.where(more, higher, lead)
    negative = np.flatnonzero(np.signbit(values))                 # -0.0 too, printed "-0.00" by Python
    out[lead[negative] - 1, negative] = ord("-")
    return out


def _csv_text(header: str, columns: Sequence[tuple[np.ndarray, int]]) -> str:
    """CSV text of fixed-decimal columns (header line, "\\n" line ends): rows of ``f"{v:.{dec}f}"``.

    Built as one byte matrix (:func:`_fixed_ascii`: fields, commas and line ends, padding
    dropped), several times faster than formatting value by value; value by value when that is
    not provably identical.
    """
    n = len(columns[0][0])
    fields = [_fixed_ascii(values, dec) for values, dec in columns]
    if n == 0 or any(f is None for f in fields):
        rows = zip(*(_fixed(values, dec) for values, dec in columns))
        return header + "\n" + "\n".join(map(",".join, rows)) + "\n"
    sep = np.full((1, n), ord(","), dtype=np.uint8)
    parts = [x for f in fields for x in (f, sep)]
    parts[-1] = np.full((1, n), ord("\n"), dtype=np.uint8)
    table = np.concatenate(parts, axis=0).T.ravel()
    return header + "\n" + table[table != 0].tobytes().decode("ascii")


def case_csv(series: pd.DataFrame, case: RigCase, rig: RigImperfections, invert_force: bool = False,
             time_offset_s: float = 0.0, temperature_K: np.ndarray | None = None) -> str:
    """CSV text of one measured case (columns :data:`EXPORT_COLUMNS`, "\\n" line ends; and
    :data:`TEMPERATURE_COLUMN` when ``temperature_K`` is given)."""
    cols = EXPORT_COLUMNS
    columns = [
        _times_ms(series["time_s"].to_numpy(), case.sample_rate_Hz, time_offset_s),
        _quantised(series["displacement_meas_m"].to_numpy(), rig.displacement_resolution_m, cols["displacement"][2]),
        _quantised(series["force_meas_N"].to_numpy(), rig.force_resolution_N, cols["force"][2],
                   -1.0 if invert_force else 1.0),
        _quantised(series["command_meas_m"].to_numpy(), rig.command_resolution_m, cols["command"][2]),
    ]
    header = ",".join(cols[k][0] for k in ("time", "displacement", "force", "command"))
    if temperature_K is not None:
        columns.append((np.rint(np.asarray(temperature_K) * 100.0) * 0.01 + 0.0, 2))
        header += "," + TEMPERATURE_COLUMN[0]
    return _csv_text(header, columns)


def _sig(x: float, digits: int = 4) -> float:
    """x rounded to ``digits`` significant digits, as a person would write it."""
    return float(f"{x:.{digits}g}")


def campaign_manifest(campaign: str, cases: Sequence[RigCase], damper, description: str = "",
                      temperature_C: float = 40.0, write_phase: bool = True, oil: OilTemperature | None = None,
                      charge_pressure_Pa: float | None = None) -> dict:
    """campaign.yaml content (raw-campaign format v1): nominal damper only, rounded numbers; the damper's
    ``charge_pressure_Pa`` (its precharge, a design datum) when given, to 3 significant digits."""
    rates = [c.sample_rate_Hz for c in cases]
    default_rate = max(rates, key=lambda r: (rates.count(r), -rates.index(r)))
    entries = []
    for c in cases:
        if isinstance(c, SineCase):   # Y sin(2 pi f t): no phase key; the record's length as duration_s
            e = {"id": c.case_id, "waveform": "sine", "frequency_Hz": _sig(c.frequency_Hz),
                 "amplitude_mm": _sig(c.amplitude_m * 1e3), "duration_s": _sig(c.duration_s)}
        else:
            e = {"id": c.case_id, "waveform": "triangle", "period_s": _sig(c.period_s),
                 "amplitude_mm": _sig(c.amplitude_m * 1e3)}
        if write_phase and not isinstance(c, SineCase):
            e["phase_rad"] = -1.5708
        if c.sample_rate_Hz != default_rate:
            e["sample_rate_Hz"] = float(c.sample_rate_Hz)
        e["file"] = f"{c.case_id}.csv"
        entries.append(e)
    columns = {k: {"name": v[0], "unit": v[1]} for k, v in EXPORT_COLUMNS.items()}
    design = {f: float(getattr(damper, f)) for f in (fl.name for fl in dataclasses.fields(DamperDesign))}
    if oil is not None:
        columns["temperature"] = {"name": TEMPERATURE_COLUMN[0], "unit": TEMPERATURE_COLUMN[1]}
        design["viscosity_law"] = oil.law(damper.viscosity_Pa_s, temperature_C)
    if charge_pressure_Pa is not None:
        design["charge_pressure_Pa"] = _sig(charge_pressure_Pa, 3)
    return {
        "format_version": 1,
        "campaign": campaign,
        "description": description,
        "source": "simulation",
        "temperature_C": float(temperature_C),
        "sample_rate_Hz": float(default_rate),
        "columns": columns,
        "damper": design,
        "cases": entries,
    }


def case_time_fractions(cases: Sequence[RigCase]) -> list[float]:
    """Where each case's middle lies in the campaign's time, as a fraction of it (the cases back to back, each
    lasting its record plus one sample interval, as :func:`write_campaign` counts campaign time)."""
    spans = [c.duration_s + 1.0 / c.sample_rate_Hz for c in cases]
    total = sum(spans)
    starts = np.concatenate([[0.0], np.cumsum(spans)[:-1]])
    return [float((s0 + 0.5 * c.duration_s) / total) for s0, c in zip(starts, cases, strict=True)]


def write_campaign(folder: str | os.PathLike, cases: Sequence[RigCase], damper=TABLE1,
                   effects: TrueEffects = NOMINAL_EFFECTS, rig: RigImperfections = IDEAL_RIG, seed: int = 0, *,
                   description: str = "Low-velocity mapping, triangular excitation", temperature_C: float = 40.0,
                   write_phase: bool = True, invert_force: bool = False, time_offset_s: float = 0.0,
                   rtol: float = 1e-10, oil: OilTemperature | None = None,
                   declare_charge_pressure: bool = False) -> dict[str, pd.DataFrame]:
    """Simulate ``cases`` (triangles and sines, :class:`SineCase`: manifest ``waveform: sine``) and write
    ``<folder>/campaign.yaml`` plus one CSV per case.

    The campaign id is the folder name; the folder must be absent or empty. Only the nominal
    ``damper`` block is written, nothing about ``effects`` or ``rig``. ``invert_force`` writes
    the force with the opposite sign without declaring ``invert: true``; ``time_offset_s`` is
    added to the time column; ``write_phase`` False omits phase_rad. Case i (0-based, in order) uses noise stream
    [seed, i] and the viscosity drift fraction i/(n-1). ``oil`` (:class:`OilTemperature`) runs case i at its
    temperature's viscosity, logs the temperature channel and writes the law's datasheet points.
    ``declare_charge_pressure`` writes the chambers' charge pressure (``effects.charge_pressure_Pa``, a design
    datum of the damper like its volumes) into the damper block. The effects' wear and warm-up
    (:func:`isokinetic.reference.rig.campaign_drift`) run each case at the fraction of the campaign's time where
    its middle lies (:func:`case_time_fractions`). Same inputs
    -> identical bytes.
    Returns {case id: true and measured series (SI, unshifted, force in this spec's sign)}.
    """
    folder = Path(folder)
    name = folder.name
    if not _CAMPAIGN_NAME.match(name):
        raise ValueError(f"campaign folder name {name!r} must match [a-z0-9][a-z0-9_-]*")
    ids = [c.case_id for c in cases]
    if not cases or len(set(ids)) != len(ids):
        raise ValueError("cases must be non-empty with unique ids")
    if folder.exists() and any(folder.iterdir()):
        raise FileExistsError(f"{folder}: campaign folder exists and is not empty")
    folder.mkdir(parents=True, exist_ok=True)
    series = {}
    if oil is not None and len(oil.case_temperatures_C) != len(cases):
        raise ValueError(f"oil: {len(oil.case_temperatures_C)} case temperatures for {len(cases)} cases")
    campaign_time_s = 0.0
    fractions = case_time_fractions(cases)
    for i, case in enumerate(cases):
        warm, area = campaign_drift(effects, fractions[i], temperature_C)
        ratio = warm * (1.0 if oil is None else oil.viscosity_ratio(i, temperature_C))
        s = dropped(simulate_case(case, damper, effects, rig, seed, i, len(cases), rtol, ratio, campaign_time_s,
                                  area), rig, seed, i)
        campaign_time_s += case.duration_s + 1.0 / case.sample_rate_Hz
        series[case.case_id] = s
        logged = None if oil is None else oil.logged_K(s["time_s"].to_numpy(), i, seed)
        with open(folder / f"{case.case_id}.csv", "w", encoding="utf-8", newline="\n") as fh:
            fh.write(case_csv(s, case, rig, invert_force, time_offset_s, logged))
    manifest = campaign_manifest(name, cases, damper, description, temperature_C, write_phase, oil,
                                 effects.charge_pressure_Pa if declare_charge_pressure else None)
    with open(folder / "campaign.yaml", "w", encoding="utf-8", newline="\n") as fh:
        yaml.safe_dump(manifest, fh, sort_keys=False, default_flow_style=False, allow_unicode=True, width=100)
    return series
