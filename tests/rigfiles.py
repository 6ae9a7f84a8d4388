"""Test instruments: raw files written the way real rigs write them, for the acceptance tests.

Everything here writes bytes itself (plain string formatting, ``open``): nothing uses the package's
readers or writers, so a test of a reader never makes its input with the code under test. The
physics of the records is the virtual rig's (:mod:`isokinetic.physics.responses`: the compressible
damper of Titurus et al., Eq. 1-8), with its own seeded sensor noise here, and every writer keeps the
noise-free force beside the measured one, so a test can compare a result with the rig's truth.

Formats
    - MTS 793 / TestSuite text export (:func:`write_mts793`): a ``MTS793|...`` first line, blocks of
      rows each with a ``Data Acquisition`` line, a header row and a units row, tab separated, CRLF,
      inch and lbf with six significant digits.
    - A crank (Scotch-yoke) dyno folder (:func:`write_crank_folder`): 300 Hz CSVs with voltage and
      scaled twins of every channel.
    - Plain CSV campaigns (:func:`write_csv`, :func:`write_manifest`) and what real acquisition does
      to them: dropped rows (:func:`drop_rows`), a Windows-1252 header, a gas force offset.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from isokinetic.physics.damper import Damper, Effects
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import true_response

INCH_M = 0.0254
LBF_N = 4.4482216152605
MTS793_FIRST_LINE = "MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A"

#: A passenger-car shock absorber (the paper's Eq. 1-8 model): 0.8 m/s gives about 2.6 kN, 16 mm/s
#: about 36 N (seal friction and the laminar bleed dominate at low speed).
SHOCK_ABSORBER = Damper(piston_area_m2=8.0e-4, chamber_volume_1_m3=1.5e-4, chamber_volume_2_m3=1.5e-4,
                        orifice_area_m2=1.2e-5, orifice_length_m=0.3, discharge_coefficient=0.7,
                        density_kg_m3=850.0, viscosity_Pa_s=0.02, oil_compressibility_1_Pa=6.0e-10)
SHOCK_EFFECTS = Effects(coulomb_force_N=25.0)


# --------------------------------------------------------------------------------------------
# Number formatting (the writers' own, not the package's)
# --------------------------------------------------------------------------------------------

def significant(values, digits: int = 6) -> list[str]:
    """Each value with ``digits`` significant digits, positional (no exponent), as a controller prints it."""
    out = []
    for v in np.asarray(values, dtype=float).tolist():
        if v == 0.0:
            out.append("0")
            continue
        decimals = max(0, digits - 1 - math.floor(math.log10(abs(v))))
        out.append(f"{v:.{decimals}f}")
    return out


def fixed(values, decimals: int) -> list[str]:
    """Each value with a fixed number of decimals (never ``-0.000``)."""
    return [f"{v + 0.0:.{decimals}f}" for v in np.round(np.asarray(values, dtype=float), decimals).tolist()]


# --------------------------------------------------------------------------------------------
# MTS 793 / TestSuite text export
# --------------------------------------------------------------------------------------------

def write_mts793(path: str | Path, time_s, displacement_m, force_N, block_rows: int = 1024,
                 acquisition: str = "Stepped sine sweep", start: dt.datetime = dt.datetime(2026, 11, 25, 14, 15, 7),
                 names: Sequence[str] = ("Time", "Axial Displacement", "Axial Force")) -> Path:
    """An MTS 793 / TestSuite text export of one record: the ``MTS793|...`` line, then blocks of ``block_rows``
    rows, each opened by ``Data Acquisition: <name>   Time: <h:mm:ss AM> <m/d/yyyy>``, a blank line, the
    tab-separated header row and the units row ``Sec in lbf``; time with 6 decimals, inch and lbf with 6
    significant digits; CRLF line ends. Returns ``path``."""
    t = np.asarray(time_s, dtype=float)
    cols = [fixed(t, 6), significant(np.asarray(displacement_m) / INCH_M), significant(np.asarray(force_N) / LBF_N)]
    rows = ["\t".join(r) for r in zip(*cols)]
    lines = [MTS793_FIRST_LINE]
    for first in range(0, len(rows), block_rows):
        stamp = start + dt.timedelta(seconds=float(t[first] - t[0]))
        clock = f"{(stamp.hour - 1) % 12 + 1}:{stamp:%M:%S} {'AM' if stamp.hour < 12 else 'PM'}"
        lines += [f"Data Acquisition: {acquisition}   Time: {clock} {stamp.month}/{stamp.day}/{stamp.year}", "",
                  "\t".join(names), "Sec\tin\tlbf"]
        lines += rows[first:first + block_rows]
    path = Path(path)
    path.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))
    return path


# --------------------------------------------------------------------------------------------
# A stepped sine sweep from the virtual rig
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SweepStep:
    """One sine step of a sweep, on the record's time axis [s]; peaks are the peak-velocity instants."""

    frequency_Hz: float
    amplitude_m: float
    start_s: float
    end_s: float
    positive_peaks_s: tuple[float, ...]
    negative_peaks_s: tuple[float, ...]

    @property
    def peak_velocity_m_s(self) -> float:
        return 2.0 * math.pi * self.frequency_Hz * self.amplitude_m


def _sine_step(frequency_Hz: float, cycles: int, amplitude_m: float, sample_rate_Hz: float, damper: Damper,
               effects: Effects) -> tuple[np.ndarray, pd.DataFrame]:
    """The virtual rig's noise-free sine y = Y sin(2πft) from its first turning point (t = 1/(4f)) to the
    turning point ``cycles`` periods later: (the sine's own times of the kept samples, the rows)."""
    duration = (cycles + 0.25) / frequency_Hz
    plan = CasePlan(case="step", waveform="sine", sample_rate_Hz=sample_rate_Hz, amplitude_m=amplitude_m,
                    frequency_Hz=frequency_Hz, phase_rad=0.0, duration_s=duration)
    truth = true_response(plan, damper, effects)
    keep = truth["time_s"].to_numpy() >= 0.25 / frequency_Hz - 1e-12
    return truth["time_s"].to_numpy()[keep], truth[keep].reset_index(drop=True)


def stepped_sine_sweep(frequencies_Hz: Sequence[float] = (0.2, 0.5, 1.0, 2.0, 5.0, 10.0),
                       cycles: Sequence[int] = (5, 6, 8, 10, 15, 20), amplitude_m: float = 0.0127,
                       standstill_s: float = 8.0, dwell_s: float = 1.0, sample_rate_Hz: float = 1024.0,
                       damper: Damper = SHOCK_ABSORBER, effects: Effects = SHOCK_EFFECTS,
                       force_noise_N: float = 0.2, force_noise_rel: float = 0.001,
                       displacement_noise_m: float = 2.0e-6, seed: int = 19
                       ) -> tuple[pd.DataFrame, list[SweepStep]]:
    """A servo-hydraulic stepped sine sweep: ``standstill_s`` at rest, then one sine step per frequency at
    ±``amplitude_m``, each from a turning point to a turning point, with ``dwell_s`` at rest after each.

    Returns the record (time_s, displacement_m, force_N measured; force_true_N, velocity_true_m_s noise
    free) and the steps. The rest position is the first step's start (+Y); at rest the noise-free force is
    zero (the default damper's pressure difference relaxes within a millisecond, and seal friction needs
    motion). Each step is the virtual rig's sine from Δp = 0, so its first cycle settles. Noise: Gaussian,
    seeded, additive plus |F|-proportional on the force, additive on the displacement.
    """
    if len(cycles) != len(frequencies_Hz):
        raise ValueError("one cycle count per frequency")
    dt_s = 1.0 / sample_rate_Hz
    pieces, steps = [], []
    n = int(round(standstill_s * sample_rate_Hz))
    pieces.append((np.full(n, amplitude_m), np.zeros(n), np.zeros(n)))
    for f, k in zip(frequencies_Hz, cycles):
        start_index = sum(len(p[0]) for p in pieces)
        t_sine, rows = _sine_step(f, k, amplitude_m, sample_rate_Hz, damper, effects)
        # the sine's time t_sine[j] lies at record time start + (t_sine[j] - t_sine[0])
        start = start_index * dt_s
        shift = start - t_sine[0]
        positive = tuple(j / f + shift for j in range(1, k + 1))
        negative = tuple((j + 0.5) / f + shift for j in range(k))
        pieces.append((rows["command_m"].to_numpy(), rows["force_N"].to_numpy(),
                       rows["piston_velocity_m_s"].to_numpy()))
        steps.append(SweepStep(f, amplitude_m, start, start + (len(rows) - 1) * dt_s, positive, negative))
        n = int(round(dwell_s * sample_rate_Hz))
        pieces.append((np.full(n, rows["command_m"].iloc[-1]), np.zeros(n), np.zeros(n)))
    y = np.concatenate([p[0] for p in pieces])
    force = np.concatenate([p[1] for p in pieces])
    velocity = np.concatenate([p[2] for p in pieces])
    rng = np.random.default_rng(seed)
    measured_force = force + force_noise_N * rng.standard_normal(y.size) \
        + force_noise_rel * np.abs(force) * rng.standard_normal(y.size)
    record = pd.DataFrame({"time_s": np.arange(y.size) * dt_s,
                           "displacement_m": y + displacement_noise_m * rng.standard_normal(y.size),
                           "force_N": measured_force, "force_true_N": force, "velocity_true_m_s": velocity})
    return record, steps


def force_at_peaks(record: pd.DataFrame, instants_s: Sequence[float]) -> np.ndarray:
    """The noise-free force at the given instants (linear interpolation between samples)."""
    return np.interp(np.asarray(instants_s), record["time_s"].to_numpy(), record["force_true_N"].to_numpy())


def energy_per_cycle_J(record: pd.DataFrame, start_s: float, stop_s: float, cycles: int,
                       points: int = 200_000) -> float:
    """The noise-free energy dissipated per cycle, the integral of F v dt from ``start_s`` to ``stop_s`` (whole
    cycles apart) over ``cycles``: F v interpolated onto ``points`` even instants, trapezoids."""
    t = np.linspace(start_s, stop_s, points)
    power = np.interp(t, record["time_s"].to_numpy(),
                      (record["force_true_N"] * record["velocity_true_m_s"]).to_numpy())
    return float(np.trapezoid(power, t)) / cycles


# --------------------------------------------------------------------------------------------
# Plain CSV campaigns
# --------------------------------------------------------------------------------------------

def write_csv(path: str | Path, columns: Mapping[str, Sequence[str]], encoding: str = "utf-8",
              delimiter: str = ",", newline: str = "\n") -> Path:
    """A delimited file: one header row of the column names, then the rows (cells already formatted)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [delimiter.join(columns)] + [delimiter.join(r) for r in zip(*columns.values())]
    path.write_bytes((newline.join(lines) + newline).encode(encoding))
    return path


def write_manifest(folder: str | Path, manifest: Mapping) -> Path:
    """``folder/campaign.yaml`` (UTF-8) of a manifest mapping."""
    path = Path(folder) / "campaign.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(dict(manifest), sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


def triangle_record(period_s: float, velocity_m_s: float, sample_rate_Hz: float, damper: Damper = SHOCK_ABSORBER,
                    effects: Effects = SHOCK_EFFECTS, force_noise_N: float = 1.0, force_noise_rel: float = 0.005,
                    displacement_noise_m: float = 2.0e-6, temperature_C: float = 40.0, seed: int = 0
                    ) -> pd.DataFrame:
    """Two periods of the virtual rig's triangle (phase -π/2), seeded noise: time_s, displacement_m, force_N,
    force_true_N, temperature_C (a slow drift of 0.5 C over the record)."""
    plan = CasePlan(case="T", waveform="triangle", sample_rate_Hz=sample_rate_Hz,
                    amplitude_m=velocity_m_s * period_s / 4.0, period_s=period_s, duration_s=2.0 * period_s)
    truth = true_response(plan, damper, effects)
    rng = np.random.default_rng(seed)
    f = truth["force_N"].to_numpy()
    n = f.size
    t = truth["time_s"].to_numpy()
    return pd.DataFrame({
        "time_s": t,
        "displacement_m": truth["command_m"].to_numpy() + displacement_noise_m * rng.standard_normal(n),
        "force_N": f + force_noise_N * rng.standard_normal(n) + force_noise_rel * np.abs(f) * rng.standard_normal(n),
        "force_true_N": f,
        "temperature_C": temperature_C + 0.5 * t / t[-1],
    })


#: Three triangle cases of the shock absorber (steady within a millisecond): (id, period s, velocity m/s);
#: at 1000 Hz each record has 16 001 rows and each window 2 001.
TRIANGLE_CASES = (("T01", 8.0, 5.0e-3), ("T02", 8.0, 10.0e-3), ("T03", 8.0, 20.0e-3))


def triangle_campaign(folder: str | Path, sample_rate_Hz: float = 1000.0, temperature_header: str = "oil_C",
                      encoding: str = "utf-8", gas_force_N: Mapping[str, float] | None = None,
                      cases=TRIANGLE_CASES, seed: int = 11) -> dict[str, pd.DataFrame]:
    """A raw triangle campaign folder (manifest and one CSV per case: time_s, disp_mm, force_N and a
    temperature column named ``temperature_header``), in ``encoding`` (declared in the manifest's csv block
    when not UTF-8). ``gas_force_N`` {case: N} adds that constant to the case's force in its file and declares
    it on the case. Returns the records {case: frame} (forces without gas force)."""
    folder = Path(folder)
    gas = dict(gas_force_N or {})
    records, entries = {}, []
    for i, (case, period, velocity) in enumerate(cases):
        rec = triangle_record(period, velocity, sample_rate_Hz, seed=seed + i)
        records[case] = rec
        write_csv(folder / f"{case}.csv", {
            "time_s": fixed(rec["time_s"], 3),
            "disp_mm": fixed(rec["displacement_m"] * 1e3, 5),
            "force_N": fixed(rec["force_N"] + gas.get(case, 0.0), 2),
            temperature_header: fixed(rec["temperature_C"], 2),
        }, encoding=encoding)
        entry = {"id": case, "waveform": "triangle", "period_s": period,
                 "amplitude_mm": round(velocity * period / 4.0 * 1e3, 9), "file": f"{case}.csv"}
        if case in gas:
            entry["gas_force_N"] = float(gas[case])
        entries.append(entry)
    manifest = {"format_version": 1, "campaign": folder.name, "description": "triangle campaign (test instrument)",
                "source": "rig", "temperature_C": 40.0, "sample_rate_Hz": sample_rate_Hz,
                "columns": {"time": {"name": "time_s", "unit": "s"}, "displacement": {"name": "disp_mm", "unit": "mm"},
                            "force": {"name": "force_N", "unit": "N"},
                            "temperature": {"name": temperature_header, "unit": "C"}},
                "damper": {k: float(v) for k, v in SHOCK_ABSORBER.to_dict().items()}}
    if encoding.lower().replace("-", "") not in ("utf8",):
        manifest["csv"] = {"encoding": encoding}
    manifest["cases"] = entries
    write_manifest(folder, manifest)
    return records


# --------------------------------------------------------------------------------------------
# Dropped samples
# --------------------------------------------------------------------------------------------

def dropout_rows(n_rows: int, fraction: float = 0.01, seed: int = 0, burst: tuple[int, int] = (5, 40),
                 single_share: float = 0.5, margin: int = 50) -> np.ndarray:
    """Sorted 0-based data-row indices to drop: ``fraction`` of ``n_rows`` in single rows and bursts of
    ``burst`` rows (about ``single_share`` of the events single), never within ``margin`` rows of either
    end, never touching another dropout; seeded."""
    rng = np.random.default_rng(seed)
    target = int(round(fraction * n_rows))
    dropped = np.zeros(n_rows, dtype=bool)
    while dropped.sum() < target:
        left = target - int(dropped.sum())
        length = 1 if rng.random() < single_share else int(rng.integers(burst[0], burst[1] + 1))
        if length > left:       # the last event: a shorter burst, or singles when too few rows are left
            length = left if left >= burst[0] else 1
        start = int(rng.integers(margin, n_rows - margin - length))
        if dropped[max(0, start - 2):start + length + 2].any():
            continue
        dropped[start:start + length] = True
    return np.flatnonzero(dropped)


def drop_rows(src: str | Path, dst: str | Path, fraction: float = 0.01, seed: int = 0, header_lines: int = 1,
              encoding: str = "utf-8") -> np.ndarray:
    """Copy the delimited file ``src`` to ``dst`` less ``fraction`` of its data rows (:func:`dropout_rows`);
    the text of every kept line is unchanged. Returns the dropped data-row indices."""
    text = Path(src).read_bytes().decode(encoding)
    newline = "\r\n" if "\r\n" in text else "\n"
    lines = text.split(newline)
    if lines and lines[-1] == "":
        lines = lines[:-1]
    head, data = lines[:header_lines], lines[header_lines:]
    drop = dropout_rows(len(data), fraction, seed)
    keep = np.ones(len(data), dtype=bool)
    keep[drop] = False
    kept = [line for line, k in zip(data, keep) if k]
    Path(dst).parent.mkdir(parents=True, exist_ok=True)
    Path(dst).write_bytes((newline.join(head + kept) + newline).encode(encoding))
    return drop


# --------------------------------------------------------------------------------------------
# A crank (Scotch-yoke) dyno folder
# --------------------------------------------------------------------------------------------

#: Voltage = offset + scaled / gain of each channel of the crank dyno (load cell amplifier, LVDT, RTD transmitter).
CRANK_VOLTS = {"Force": (0.0123, -500.0), "Displacement": (0.0415, 10.0), "Temperature": (0.5, 50.0)}


@dataclass(frozen=True)
class CrankRun:
    """One file of a crank dyno folder and its noise-free truth (time_s, force_true_N, velocity_true_m_s)."""

    path: Path
    frequency_Hz: float
    amplitude_m: float
    truth: pd.DataFrame

    def force_at_peak_velocity_N(self, sign: float) -> float:
        """The noise-free force at the peaks of velocity of one sign, cycles 2 .. (the first settles), averaged."""
        cycles = int(round(self.truth["time_s"].iloc[-1] * self.frequency_Hz))
        k = np.arange(1, cycles) + (0.0 if sign > 0 else 0.5)
        return float(np.interp(k / self.frequency_Hz, self.truth["time_s"], self.truth["force_true_N"]).mean())


def write_crank_folder(folder: str | Path, frequencies_Hz: Sequence[float] = (0.5, 1.0, 2.0, 3.0, 4.0),
                       stroke_amplitude_m: float = 0.025, cycles: int = 5, sample_rate_Hz: float = 300.0,
                       damper: Damper = SHOCK_ABSORBER, effects: Effects = SHOCK_EFFECTS,
                       temperature_C: float = 32.0, seed: int = 3) -> list[CrankRun]:
    """A crank dyno's folder: one CSV per crank speed (``run_<i>.csv``), columns ``Timestamp, Force (V),
    Force (N), Displacement (V), Displacement (mm), Temperature (V), Temperature (C)``, 300 Hz, CRLF, the
    Scotch yoke's pure sine of the virtual rig (force positive resisting positive velocity), seeded noise.
    Every voltage column is an affine map of its scaled twin (:data:`CRANK_VOLTS`). No manifest."""
    folder = Path(folder)
    rng = np.random.default_rng(seed)
    runs = []
    for i, f in enumerate(frequencies_Hz, start=1):
        plan = CasePlan(case=f"run_{i}", waveform="sine", sample_rate_Hz=sample_rate_Hz,
                        amplitude_m=stroke_amplitude_m, frequency_Hz=f, phase_rad=0.0, duration_s=cycles / f)
        truth = true_response(plan, damper, effects)
        n = len(truth)
        force = truth["force_N"].to_numpy() + 0.5 * rng.standard_normal(n)
        disp_mm = truth["command_m"].to_numpy() * 1e3 + 0.005 * rng.standard_normal(n)
        temp = temperature_C + 0.2 * i + 0.05 * rng.standard_normal(n)
        scaled = {"Force": force, "Displacement": disp_mm, "Temperature": temp}
        volts = {k: CRANK_VOLTS[k][0] + v / CRANK_VOLTS[k][1] for k, v in scaled.items()}
        cols = {"Timestamp": fixed(truth["time_s"], 6),
                "Force (V)": fixed(volts["Force"], 5), "Force (N)": fixed(force, 2),
                "Displacement (V)": fixed(volts["Displacement"], 5), "Displacement (mm)": fixed(disp_mm, 3),
                "Temperature (V)": fixed(volts["Temperature"], 5), "Temperature (C)": fixed(temp, 2)}
        path = write_csv(folder / f"run_{i}.csv", cols, newline="\r\n")
        runs.append(CrankRun(path, float(f), stroke_amplitude_m,
                             pd.DataFrame({"time_s": truth["time_s"], "force_true_N": truth["force_N"],
                                           "velocity_true_m_s": truth["piston_velocity_m_s"]})))
    return runs


# --------------------------------------------------------------------------------------------
# A damper law of the test instruments' own (for records the virtual rig cannot drive)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class LaggedDamper:
    """A damper whose force follows its steady law F_ss(v) = c1 v + c2 v|v| + F_c tanh(v / v_c) through a
    first-order lag of time constant ``tau_s`` (the oil's compressibility, linearised: tau dF/dt = F_ss - F).

    The virtual rig drives pure sines and triangles only; the servo-distorted sweep and the random record
    need an arbitrary displacement, so they use this law, written here and nowhere in the package. The
    defaults are a passenger-car shock absorber (0.8 m/s: about 2.8 kN; 16 mm/s: about 49 N)."""

    c1_N_s_m: float = 1500.0
    c2_N_s2_m2: float = 2500.0
    coulomb_N: float = 25.0
    coulomb_velocity_m_s: float = 2.0e-4
    tau_s: float = 1.5e-3

    def steady_force_N(self, velocity_m_s):
        """F_ss(v), the steady characteristic."""
        v = np.asarray(velocity_m_s, dtype=float)
        friction = self.coulomb_N * np.tanh(v / self.coulomb_velocity_m_s)
        return self.c1_N_s_m * v + self.c2_N_s2_m2 * v * np.abs(v) + friction

    def force_N(self, time_s, velocity_m_s) -> np.ndarray:
        """The lagged force on an even time grid, from F = F_ss(v(0)): the lag's exact solution for an input
        linear between samples (tau = 0: the steady force)."""
        from scipy.signal import lfilter

        steady = self.steady_force_N(velocity_m_s)
        if self.tau_s <= 0.0:
            return steady
        h = float(time_s[1] - time_s[0])
        a = math.exp(-h / self.tau_s)
        c = (1.0 - a) * self.tau_s / h
        out, _ = lfilter([1.0 - c, c - a], [1.0, -a], steady, zi=[c * steady[0]])   # F(0) = F_ss(v(0))
        return out


# --------------------------------------------------------------------------------------------
# An MTS-style stepped sweep whose servo distorts the fast steps, 2-3 cycles a step
# --------------------------------------------------------------------------------------------

#: (frequency Hz, cycles, second-harmonic share, third-harmonic share) of each step: the servo distorts the steps at
#: 5 and 10 Hz by 2-4 % harmonics of the displacement (6-12 % of the velocity).
SERVO_STEPS = ((0.2, 2, 0.0, 0.0), (0.5, 3, 0.0, 0.0), (1.0, 2, 0.0, 0.0), (2.0, 3, 0.01, 0.0),
               (5.0, 3, 0.03, 0.02), (10.0, 2, 0.04, 0.02))


@dataclass(frozen=True)
class ServoStep:
    """One step of :func:`servo_sweep`: record times [s], and per direction the noise-free velocity extrema of
    its cycles (instants, velocities) and the noise-free force at them."""

    frequency_Hz: float
    cycles: int
    harmonics: tuple[float, float]
    start_s: float
    end_s: float
    peak_times_s: Mapping[str, tuple[float, ...]]
    peak_velocities_m_s: Mapping[str, tuple[float, ...]]
    peak_forces_N: Mapping[str, tuple[float, ...]]


def distorted_sine(theta, amplitude_m: float, h2: float, h3: float):
    """Displacement Y [sin θ + h2 (cos 2θ + 1) + h3 (sin 3θ + 1)] and dy/dθ: at the fundamental's turning point
    θ = π/2 (mod 2π) the harmonics add neither displacement nor velocity, so a step joins its rests smoothly."""
    y = amplitude_m * (np.sin(theta) + h2 * (np.cos(2 * theta) + 1.0) + h3 * (np.sin(3 * theta) + 1.0))
    dy = amplitude_m * (np.cos(theta) - 2.0 * h2 * np.sin(2 * theta) + 3.0 * h3 * np.cos(3 * theta))
    return y, dy


def _servo_motion(steps, amplitude_m: float, standstill_s: float, dwell_s: float, rate_Hz: float):
    """(t, y, v, [(f, k, h2, h3, start, end)]) of the sweep on a grid of ``rate_Hz``: at rest at +Y, then each step
    from θ = π/2 for k cycles, ``dwell_s`` at rest after each."""
    total = standstill_s + sum(k / f + dwell_s for f, k, _, _ in steps)
    t = np.arange(int(math.floor(total * rate_Hz)) + 1) / rate_Hz
    y, v = np.full(t.size, amplitude_m), np.zeros(t.size)
    start, spans = standstill_s, []
    for f, k, h2, h3 in steps:
        end = start + k / f
        inside = (t >= start) & (t <= end)
        theta = 2.0 * math.pi * f * (t[inside] - start) + 0.5 * math.pi
        y[inside], dy = distorted_sine(theta, amplitude_m, h2, h3)
        v[inside] = 2.0 * math.pi * f * dy
        spans.append((f, k, h2, h3, start, end))
        start = end + dwell_s
    return t, y, v, spans


def _step_extrema(f: float, k: int, h2: float, h3: float, start: float, amplitude_m: float, t_fine, force_fine):
    """Per direction, each cycle's noise-free velocity extremum (instant, value) and the force there."""
    out = {"+": ([], [], []), "-": ([], [], [])}
    for j in range(k):
        theta = 0.5 * math.pi + 2.0 * math.pi * (j + np.linspace(0.0, 1.0, 200_001))
        v = 2.0 * math.pi * f * distorted_sine(theta, amplitude_m, h2, h3)[1]
        instants = start + (theta - 0.5 * math.pi) / (2.0 * math.pi * f)
        for d, i in (("+", int(np.argmax(v))), ("-", int(np.argmin(v)))):
            out[d][0].append(float(instants[i]))
            out[d][1].append(float(v[i]))
            out[d][2].append(float(np.interp(instants[i], t_fine, force_fine)))
    return {d: tuple(map(tuple, lists)) for d, lists in out.items()}


def servo_sweep(steps=SERVO_STEPS, amplitude_m: float = 0.0127, standstill_s: float = 4.0, dwell_s: float = 1.0,
                sample_rate_Hz: float = 1024.0, damper: LaggedDamper = LaggedDamper(), force_noise_N: float = 0.5,
                force_noise_rel: float = 0.002, displacement_noise_m: float = 2.0e-6, seed: int = 23
                ) -> tuple[pd.DataFrame, list[ServoStep]]:
    """An MTS-style stepped sine sweep at ±``amplitude_m`` whose steps hold 2-3 cycles and whose fast steps carry
    servo harmonics (:data:`SERVO_STEPS`, :func:`distorted_sine`), on :class:`LaggedDamper`.

    Returns the record (time_s, displacement_m, force_N measured; force_true_N, velocity_true_m_s noise free) and
    the steps with their truth: the noise-free force at each cycle's noise-free velocity extremum (found on a grid
    of 200 000 points a cycle; the force computed on a grid 16 times finer than the samples, interpolated).
    Noise: Gaussian, seeded, additive plus |F|-proportional on the force, additive on the displacement."""
    fine = 16
    t_f, y_f, v_f, spans = _servo_motion(steps, amplitude_m, standstill_s, dwell_s, sample_rate_Hz * fine)
    force_f = damper.force_N(t_f, v_f)
    out = []
    for f, k, h2, h3, start, end in spans:
        ext = _step_extrema(f, k, h2, h3, start, amplitude_m, t_f, force_f)
        out.append(ServoStep(f, k, (h2, h3), start, end, {d: e[0] for d, e in ext.items()},
                             {d: e[1] for d, e in ext.items()}, {d: e[2] for d, e in ext.items()}))
    t, y, v, force = t_f[::fine], y_f[::fine], v_f[::fine], force_f[::fine]
    rng = np.random.default_rng(seed)
    measured = force + force_noise_N * rng.standard_normal(t.size) \
        + force_noise_rel * np.abs(force) * rng.standard_normal(t.size)
    record = pd.DataFrame({"time_s": t, "displacement_m": y + displacement_noise_m * rng.standard_normal(t.size),
                           "force_N": measured, "force_true_N": force, "velocity_true_m_s": v})
    return record, out


# --------------------------------------------------------------------------------------------
# A random-excitation record with a switching control voltage
# --------------------------------------------------------------------------------------------

RANDOM_HEADER = ("Time [s]", "X [cm]", "F [N]", "Y [V]")


def random_motion(duration_s: float, rate_Hz: float, band_Hz: tuple[float, float] = (0.1, 2.0),
                  rms_m: float = 0.004, taper_s: float = 2.0, seed: int = 29):
    """White-noise-like displacement: the sum of sines of every frequency k/T in ``band_Hz`` with equal amplitudes
    and seeded random phases, scaled to ``rms_m``, tapered in and out (raised cosine over ``taper_s``).
    Returns (t, displacement, its exact derivative)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration_s * rate_Hz)) + 1) / rate_Hz
    freqs = np.arange(math.ceil(band_Hz[0] * duration_s), math.floor(band_Hz[1] * duration_s) + 1) / duration_s
    phases = rng.uniform(0.0, 2.0 * math.pi, freqs.size)
    arg = 2.0 * math.pi * freqs[None, :] * t[:, None] + phases[None, :]
    s, ds = np.sin(arg).sum(axis=1), (2.0 * math.pi * freqs[None, :] * np.cos(arg)).sum(axis=1)
    scale = rms_m / float(np.sqrt(np.mean(s ** 2)))
    u = np.clip(np.minimum(t, t[-1] - t) / taper_s, 0.0, 1.0)
    w = 0.5 - 0.5 * np.cos(math.pi * u)
    side = np.where(t < 0.5 * t[-1], 1.0, -1.0)
    dw = np.where((u > 0) & (u < 1), 0.5 * math.pi / taper_s * np.sin(math.pi * u), 0.0) * side
    return t, scale * w * s, scale * (dw * s + w * ds)


def switching_levels(t, levels_V=(0.0, 1.5, 3.0), mean_hold_s: float = 4.0, noise_V: float = 0.002,
                     seed: int = 31) -> np.ndarray:
    """A control voltage holding each of ``levels_V`` for random spans (exponential, mean ``mean_hold_s``), seeded,
    with a little noise."""
    rng = np.random.default_rng(seed)
    out = np.empty(t.size)
    start, level = 0.0, 0
    while start <= t[-1]:
        stop = start + max(0.5, rng.exponential(mean_hold_s))
        out[(t >= start) & (t < stop)] = levels_V[level]
        level = (level + int(rng.integers(1, len(levels_V)))) % len(levels_V)
        start = stop
    return out + noise_V * rng.standard_normal(t.size)


def random_record(duration_s: float = 60.0, sample_rate_Hz: float = 300.0,
                  damper: LaggedDamper = LaggedDamper(tau_s=0.0), force_noise_N: float = 0.5,
                  displacement_noise_m: float = 2.0e-6, seed: int = 37) -> pd.DataFrame:
    """A random-excitation test of a passive damper (:func:`random_motion`, quasi-static by construction: the
    default damper has no lag) while the logger also records a controller's switching voltage (the semi-active
    valve command of another set-up; it does not act on this damper). Columns: time_s, displacement_m, force_N,
    voltage_V measured; velocity_true_m_s, force_true_N noise free."""
    t, y, v = random_motion(duration_s, sample_rate_Hz)
    force = damper.force_N(t, v)
    rng = np.random.default_rng(seed)
    return pd.DataFrame({"time_s": t, "displacement_m": y + displacement_noise_m * rng.standard_normal(t.size),
                         "force_N": force + force_noise_N * rng.standard_normal(t.size),
                         "voltage_V": switching_levels(t), "velocity_true_m_s": v, "force_true_N": force})


def write_random_csv(path: str | Path, record: pd.DataFrame) -> Path:
    """The random record as its logger writes it: ``Time [s], X [cm], F [N], Y [V]``, time stamps with 5 significant
    digits (so intervals vary by up to ±10 % of a step once t >= 10 s), displacement in cm with 5 decimals."""
    return write_csv(path, {RANDOM_HEADER[0]: significant(record["time_s"], 5),
                            RANDOM_HEADER[1]: fixed(record["displacement_m"] * 100.0, 5),
                            RANDOM_HEADER[2]: fixed(record["force_N"], 2),
                            RANDOM_HEADER[3]: fixed(record["voltage_V"], 3)})
