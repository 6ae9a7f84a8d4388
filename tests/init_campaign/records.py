"""Small damper records made from physics for the column and step tests: a known displacement (sine or triangle
steps, standstills, dwells) and the force of a damper F = c1 v + c2 v|v| resisting the velocity, with seeded
noise. Written as text by the tests themselves (plain string formatting), never by the code under test."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from isokinetic.physics.plan import triangle_displacement

#: Linear and quadratic damping of the test damper [N s/m], [N s²/m²].
C1, C2 = 1500.0, 800.0


def damper_force(v_m_s: np.ndarray) -> np.ndarray:
    """A damper's force resisting the velocity (positive with positive velocity, raw-campaign spec)."""
    return C1 * v_m_s + C2 * v_m_s * np.abs(v_m_s)


@dataclass(frozen=True)
class Step:
    """One planned step of a record: ``sine`` (frequency), ``triangle`` (period) or ``standstill``, with its
    amplitude, cycles, and where it lies on the record's time axis (filled in by :func:`stepped_record`)."""

    kind: str
    frequency_Hz: float = 0.0
    amplitude_m: float = 0.0
    cycles: int = 0
    duration_s: float = 0.0
    start_s: float = 0.0
    end_s: float = 0.0


def stepped_record(steps: list[Step], rate_Hz: float, dwell_s: float = 0.5, seed: int = 7,
                   t0_s: float = 0.0) -> tuple[dict[str, np.ndarray], list[Step]]:
    """(columns time_s, displacement_m, velocity_m_s, force_N; the steps with their times). Each moving step
    starts and ends at mid-stroke (a sine at phase 0, a triangle from mid-stroke rising), a ``dwell_s`` pause
    at rest follows it; standstills last ``duration_s``. Noise: 2 µm on the displacement, 2 N on the force."""
    pieces_y, pieces_v, placed, n = [], [], [], 0
    for step in steps:
        start = n / rate_Hz
        if step.kind == "standstill":
            m = int(round(step.duration_s * rate_Hz))
            pieces_y.append(np.zeros(m))
            pieces_v.append(np.zeros(m))
        else:
            m = int(round(step.cycles / step.frequency_Hz * rate_Hz))
            tau = np.arange(m) / rate_Hz
            if step.kind == "sine":
                w = 2.0 * np.pi * step.frequency_Hz
                pieces_y.append(step.amplitude_m * np.sin(w * tau))
                pieces_v.append(step.amplitude_m * w * np.cos(w * tau))
            else:
                y = triangle_displacement(tau, step.amplitude_m, 1.0 / step.frequency_Hz, phase_rad=0.0)
                pieces_y.append(y)
                pieces_v.append(np.gradient(y, tau))
            k = int(round(dwell_s * rate_Hz))
            pieces_y.append(np.zeros(k))
            pieces_v.append(np.zeros(k))
        placed.append(Step(step.kind, step.frequency_Hz, step.amplitude_m, step.cycles, step.duration_s, start,
                           start + m / rate_Hz))
        n = sum(p.size for p in pieces_y)
    y, v = np.concatenate(pieces_y), np.concatenate(pieces_v)
    rng = np.random.default_rng(seed)
    t = t0_s + np.arange(y.size) / rate_Hz
    return ({"time_s": t, "displacement_m": y + 2e-6 * rng.standard_normal(y.size), "velocity_m_s": v,
             "force_N": damper_force(v) + 2.0 * rng.standard_normal(y.size)},
            [Step(s.kind, s.frequency_Hz, s.amplitude_m, s.cycles, s.duration_s, s.start_s + t0_s, s.end_s + t0_s)
             for s in placed])


def sine_record(frequency_Hz: float, amplitude_m: float, cycles: int, rate_Hz: float, seed: int = 5
                ) -> dict[str, np.ndarray]:
    """One steady sine record (no dwell): time_s, displacement_m, velocity_m_s, force_N."""
    record, _ = stepped_record([Step("sine", frequency_Hz, amplitude_m, cycles)], rate_Hz, dwell_s=0.0, seed=seed)
    return record


def write_table(path: Path, columns: dict[str, list[str] | np.ndarray], encoding: str = "utf-8",
                delimiter: str = ",", units: list[str] | None = None) -> Path:
    """A delimited case file: header, optionally a units row, then the rows (numbers with 9 significant digits)."""
    cells = [[f"{x:.9g}" for x in np.asarray(v, float).tolist()] if not isinstance(v, list) else v
             for v in columns.values()]
    lines = [delimiter.join(columns)] + ([delimiter.join(units)] if units else [])
    lines += [delimiter.join(row) for row in zip(*cells)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(("\n".join(lines) + "\n").encode(encoding))
    return path
