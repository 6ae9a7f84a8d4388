"""Test plans: the cases of a campaign and the geometry of their excitation (Eq. 26-27).

Equation numbers are those of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Waveforms of a case; ``standstill`` (format 1.2): a stretch with no motion, for the zero and static force.
WAVEFORMS = ("triangle", "sine", "free", "standstill")


@dataclass(frozen=True)
class CasePlan:
    """One planned test case, SI units. Unused quantities of a waveform are NaN."""

    case: str
    waveform: str
    sample_rate_Hz: float
    amplitude_m: float = math.nan
    period_s: float = math.nan
    frequency_Hz: float = math.nan
    phase_rad: float = -math.pi / 2
    duration_s: float = math.nan

    def __post_init__(self):
        if self.waveform not in WAVEFORMS:
            raise ValueError(f"case {self.case}: waveform must be one of {WAVEFORMS}, got {self.waveform!r}")

    @property
    def velocity_m_s(self) -> float:
        """Planned constant piston speed W_p = 4 Y_p / T, Eq. (26); NaN unless triangle."""
        return 4.0 * self.amplitude_m / self.period_s if self.waveform == "triangle" else math.nan

    @property
    def required_duration_s(self) -> float:
        """The record length [s] the plan needs: two periods for a triangle (Sec. 4.3), one for a sine."""
        if self.waveform == "triangle":
            return 2.0 * self.period_s
        if self.waveform == "sine":
            return 1.0 / self.frequency_Hz
        return 0.0


def triangle_wave(x):
    """tri(x) [-] of x [rad], tri(0) = 0, tri(π/2) = +1, tri(3π/2) = -1 (raw-campaign spec, Eq. 26)."""
    return (2.0 / np.pi) * np.arcsin(np.sin(x))


def triangle_displacement(t_s, amplitude_m: float, period_s: float, phase_rad: float = -math.pi / 2):
    """y(t) = Y tri(2πt/T + φ), Eq. (26) [m]."""
    return amplitude_m * triangle_wave(2.0 * np.pi * np.asarray(t_s, dtype=float) / period_s + phase_rad)


def sine_displacement(t_s, amplitude_m: float, frequency_Hz: float):
    """y(t) = Y sin(2πft) (raw-campaign spec) [m]."""
    return amplitude_m * np.sin(2.0 * np.pi * frequency_Hz * np.asarray(t_s, dtype=float))


#: Without a sample interval, a turning point this close to t = 0 (as a phase, rad) lies at t = 0: a
#: phase rounded to three decimals (-1.571) still means -π/2 (raw-campaign spec).
PHASE_TOLERANCE_RAD = 1e-3


def _tolerance_s(period_s: float, tolerance_s: float | None) -> float:
    return PHASE_TOLERANCE_RAD / (2.0 * math.pi) * period_s if tolerance_s is None else float(tolerance_s)


def snapped_phase_rad(period_s: float, phase_rad: float, tolerance_s: float | None = None) -> float:
    """The phase of Eq. (26) with a turning point within ``tolerance_s`` of t = 0 moved onto t = 0.

    A manifest's rounded ``-1.5707963`` or ``-1.5708`` means -π/2 (raw-campaign spec): the record
    starts at a turning point, and its half-periods are exactly those of -π/2. Turning points lie
    where 2πt/T + φ = π/2 + kπ; the nearest to t = 0 is snapped (φ becomes π/2 + kπ exactly), a
    phase with none that close is returned as it is. Default tolerance: PHASE_TOLERANCE_RAD of phase.
    """
    k = round((phase_rad - math.pi / 2) / math.pi)
    t_turn = (math.pi / 2 + k * math.pi - phase_rad) * period_s / (2.0 * math.pi)
    return math.pi / 2 + k * math.pi if abs(t_turn) <= _tolerance_s(period_s, tolerance_s) else phase_rad


#: Most half-periods :func:`half_periods` lists when no ``max_count`` bounds it: a record of a million
#: half-periods lies far beyond any plan (a time stamp of 1e308 s, a year typo in an ISO stamp); longer
#: spans raise ValueError instead of looping (and allocating) without bound.
MAX_HALF_PERIODS = 1_000_000


def half_periods(period_s: float, phase_rad: float, duration_s: float, tolerance_s: float | None = None,
                 max_count: int | None = None):
    """The complete constant-velocity half-periods of a triangle record on [0, duration_s], at most
    ``max_count`` of them (the plan's need: the windows use four).

    Returns an array of rows (t_start_s, t_end_s, sign), sign = +1 for rising displacement.
    Turning points of Y tri(2πt/T + φ) lie where the argument is π/2 + kπ. A turning point within
    ``tolerance_s`` of t = 0 (one sample interval for a record, :func:`snapped_phase_rad`) lies at
    t = 0: a rounded phase loses no half-period. The work is bounded by ``max_count`` whatever the
    record's last time stamp; without it, a span of more than :data:`MAX_HALF_PERIODS` half-periods
    (or a non-finite one) raises ValueError.
    """
    limit = MAX_HALF_PERIODS if max_count is None else int(max_count)
    if max_count is None and not duration_s / period_s < 0.5 * MAX_HALF_PERIODS:
        raise ValueError(f"a record of {duration_s:g} s holds more than {MAX_HALF_PERIODS} half-periods of "
                         f"T = {period_s:g} s: bound it by the plan (max_count)")
    tol = _tolerance_s(period_s, tolerance_s)
    phase_rad = snapped_phase_rad(period_s, phase_rad, tol)
    half = period_s / 2.0
    k0 = math.ceil((phase_rad - math.pi / 2) / math.pi - 1e-9)  # first turning point at t >= 0
    rows = []
    k = k0
    while len(rows) < limit and k <= k0 + limit + 1:     # at most one turning point before t = 0 skipped
        t0 = (math.pi / 2 + k * math.pi - phase_rad) * period_s / (2.0 * math.pi)
        t0 = max(t0, 0.0) if t0 > -1e-9 * period_s else t0
        t1 = t0 + half
        if not t1 <= duration_s * (1 + 1e-9):
            break
        if t0 >= -1e-9 * period_s:
            # between turning points k and k+1 the argument rises from π/2 + kπ: falling for even k
            rows.append((t0, t1, -1.0 if k % 2 == 0 else 1.0))
        k += 1
    return np.array(rows, dtype=float).reshape(-1, 3)


def first_half_period(case: CasePlan) -> tuple[float, float]:
    """(start position y0 [m], direction ±1) of the first complete half-period of a triangle case.

    From :func:`half_periods`; a record too short for one falls back to the phase -π/2 convention
    (start at -Y moving up). The stroke to converge (Eq. 28) assumes Δp = 0 there, which holds for a
    record starting at a turning point (phase ±π/2, the paper's -π/2); otherwise it is a guide.
    """
    duration = case.duration_s if math.isfinite(case.duration_s) else case.period_s
    rows = half_periods(case.period_s, case.phase_rad, max(duration, case.period_s), max_count=1)
    direction = float(rows[0, 2]) if len(rows) else 1.0
    return -direction * case.amplitude_m, direction

def paper_plan(velocities_m_s, periods_s, sine_amplitudes_m, sine_frequency_Hz: float,
               triangle_rate_Hz: float, sine_rate_Hz: float, sine_periods: float,
               phase_rad: float = -math.pi / 2, acquisition_periods: float = 2.0) -> list[CasePlan]:
    """Triangle cases T01.. (Y = W T/4, acquisition 2T) then sine cases H01.. (Sec. 4.3, Fig. 6, 13)."""
    cases = []
    for i, (w, period) in enumerate(zip(velocities_m_s, periods_s, strict=True), start=1):
        cases.append(CasePlan(case=f"T{i:02d}", waveform="triangle", sample_rate_Hz=triangle_rate_Hz,
                              amplitude_m=w * period / 4.0, period_s=float(period), phase_rad=phase_rad,
                              duration_s=acquisition_periods * period))
    for i, amp in enumerate(sine_amplitudes_m, start=1):
        cases.append(CasePlan(case=f"H{i:02d}", waveform="sine", sample_rate_Hz=sine_rate_Hz,
                              amplitude_m=amp, frequency_Hz=sine_frequency_Hz, phase_rad=0.0,
                              duration_s=sine_periods / sine_frequency_Hz))
    return cases
