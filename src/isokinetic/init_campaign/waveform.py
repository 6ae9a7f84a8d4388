"""The excitation of one record: a triangle's period, amplitude and phase, a sine's frequency and amplitude, or free.

Frequency: the peak of the zero-padded spectrum, refined by least squares of a mean plus
:data:`HARMONICS` harmonics (on block means of the record, for speed). The harmonics tell the shape: the
triangle y = Y tri(2πt/T + φ) (raw-campaign spec, Eq. 26) has the Fourier series
(8Y/π²) Σ (-1)^n sin((2n+1)(2πt/T + φ))/(2n+1)², so relative to its fundamental (phase removed) its
third harmonic is -1/9 and its fifth +1/25, with no even ones; a sine has none. A record whose harmonic
fit leaves more than :data:`FREE_FRACTION` of its amplitude unexplained, or whose harmonics fit neither
shape, is ``free``.

A triangle is then measured like :mod:`isokinetic.measurement.motion` measures it: least-squares lines over
the central part [0.1, 0.9]·T/2 of each half-period; each crosses the mid-stroke at the middle of its
half-period, so the crossing times, spaced T/2, give the period (and its standard error from the lines'
noise), the slopes give the amplitude Y = |v|·T/4 (Eq. 26), and the first crossing the phase. The
pipeline cuts its windows from the plan's period and phase (:mod:`isokinetic.measurement.windows`): a period off
by 1e-6 moves a window edge of a 100 Hz record past a sample. So a period is rounded to the value with
the fewest significant digits within :data:`ROUND_SIGMAS` standard errors (:func:`round_to_uncertainty`):
a rig's planned 20 s is recovered exactly, not as 20.000013 s. A turning point within
:data:`SNAP_FRACTION` of a period of the first sample makes the phase exactly ±π/2 (the record starts at a
reversal; a small delay is measured by the pipeline, ``motion_start_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from isokinetic.measurement.motion import line_fit, noise_level

#: Harmonics fitted to tell a triangle from a sine.
HARMONICS = 5
#: Points of the block-averaged record the frequency search runs on.
SEARCH_POINTS = 4096
#: Third and fifth harmonic of a triangle relative to its fundamental (phase removed), and the tolerances.
TRIANGLE_H3, TRIANGLE_H5 = -1.0 / 9.0, 1.0 / 25.0
H3_TOLERANCE, H5_TOLERANCE, EVEN_TOLERANCE = 0.03, 0.02, 0.03
#: A sine's harmonics (relative to its fundamental) stay below this: a servo distorts a fast sine by 2-4 %
#: (an MTS sweep's 5-10 Hz steps), a triangle's third harmonic is 11 %.
SINE_TOLERANCE = 0.05
#: A harmonic fit that leaves more than this fraction of the amplitude unexplained (noise removed): free.
FREE_FRACTION = 0.10
#: Fewest periods a record must hold for its waveform to be detected.
MIN_PERIODS = 1.0
#: Half-period part each line is fitted over (away from the reversals), as in the motion check.
LINE_FRACTIONS = (0.1, 0.9)
#: Fewest samples of a line fit.
MIN_LINE_SAMPLES = 10
#: An estimate is rounded to the coarsest value within this many standard errors ...
ROUND_SIGMAS = 4.0
#: ... or within this fraction of itself (float rounding of the record).
ROUND_FLOOR = 1e-9
#: A turning point this close to the first sample (fraction of the period) puts the phase at ±π/2.
SNAP_FRACTION = 0.02
#: An amplitude is rounded within this fraction too: the pipeline's speed check allows 5 %, a manifest amplitude
#: rounded to four digits adds 0.05 % (:data:`isokinetic.stages.validate.MAX_VELOCITY_ERROR`), and a measured
#: displacement's amplitude differs from the commanded one by about as much (servo compliance).
AMPLITUDE_FLOOR = 5e-4
#: Relative standard error below which a period or frequency is sure, likely.
SURE_SE, LIKELY_SE = 1e-4, 1e-3


@dataclass(frozen=True)
class Estimate:
    """A measured value with its standard error."""

    value: float
    se: float

    @property
    def rounded(self) -> float:
        return round_to_uncertainty(self.value, self.se)

    @property
    def rounded_amplitude(self) -> float:
        return round_to_uncertainty(self.value, self.se, floor=AMPLITUDE_FLOOR)

    @property
    def relative_se(self) -> float:
        return self.se / abs(self.value) if self.value else math.inf

    @property
    def sure(self) -> str:
        rel = self.relative_se
        return "sure" if rel < SURE_SE else "likely" if rel < LIKELY_SE else "guess"


def round_to_uncertainty(value: float, se: float, sigmas: float = ROUND_SIGMAS, floor: float = ROUND_FLOOR,
                         min_digits: int = 2) -> float:
    """``value`` with the fewest significant digits (at least ``min_digits``) that stays within
    max(sigmas·se, floor·|value|) of it: 20.0000131 ± 1e-5 -> 20.0, 1.21996 ± 1e-4 -> 1.22."""
    if not math.isfinite(value) or value == 0:
        return value
    tolerance = max(sigmas * se if math.isfinite(se) else 0.0, floor * abs(value))
    for digits in range(min_digits, 17):
        rounded = float(f"{value:.{digits}g}")
        if abs(rounded - value) <= tolerance:
            return rounded
    return value


@dataclass(frozen=True)
class Waveform:
    """The detected excitation of one record (SI). Triangle: period, amplitude, phase; sine: frequency and
    amplitude; free: none. ``how`` says what was found, ``sure`` how sure (sure / likely / guess)."""

    kind: str
    how: str
    sure: str
    period_s: Estimate | None = None
    frequency_Hz: Estimate | None = None
    amplitude_m: Estimate | None = None
    phase_rad: float | None = None
    phase_note: str = ""
    phase_sure: str = "likely"
    periods: float = math.nan


def block_means(tau: np.ndarray, y: np.ndarray, points: int = SEARCH_POINTS) -> tuple[np.ndarray, np.ndarray]:
    k = max(1, tau.size // points)
    n = (tau.size // k) * k
    return tau[:n].reshape(-1, k).mean(axis=1), y[:n].reshape(-1, k).mean(axis=1)


def coarse_frequency(tau: np.ndarray, y: np.ndarray) -> float:
    """The peak of the zero-padded amplitude spectrum (uniform sampling at the median step assumed) [Hz]."""
    step = float(np.median(np.diff(tau)))
    n = int(2 ** math.ceil(math.log2(max(16 * y.size, 1024))))
    spectrum = np.abs(np.fft.rfft(y - y.mean(), n=min(n, 1 << 22)))
    freqs = np.fft.rfftfreq(min(n, 1 << 22), step)
    duration = tau[-1] - tau[0]
    spectrum[freqs < 0.5 / duration] = 0.0
    return float(freqs[int(np.argmax(spectrum))])


def harmonic_fit(tau: np.ndarray, y: np.ndarray, frequency_Hz: float, harmonics: int = HARMONICS):
    """Least squares of y ≈ c0 + Σ_k a_k sin(kωτ) + b_k cos(kωτ): (complex amplitudes a_k + i b_k, k = 1..,
    residual sum of squares). a + ib = A e^{iφ} for the term A sin(kωτ + φ)."""
    x = 2.0 * math.pi * frequency_Hz * tau
    columns = [np.ones_like(tau)]
    for k in range(1, harmonics + 1):
        columns += [np.sin(k * x), np.cos(k * x)]
    design = np.column_stack(columns)
    gram = design.T @ design
    try:
        coef = np.linalg.solve(gram, design.T @ y)        # normal equations: sines and cosines are well conditioned
    except np.linalg.LinAlgError:
        coef = np.linalg.lstsq(design, y, rcond=None)[0]
    residual = y - design @ coef
    return coef[1::2] + 1j * coef[2::2], float(residual @ residual)


def refine_frequency(tau: np.ndarray, y: np.ndarray, f0: float) -> float:
    """The frequency that minimises the harmonic fit's residual: a grid over ±1 spectral bin around ``f0`` (above
    0.75 f0: in a record of two periods f0/2 lies within a bin, and its second harmonic fits f0 as well), then
    golden-section search (on block means of the record)."""
    tb, yb = block_means(tau, y)
    bin_Hz = 1.0 / (tau[-1] - tau[0])

    def rss(f: float) -> float:
        return harmonic_fit(tb, yb, f)[1]

    grid = f0 + np.linspace(-1.0, 1.0, 41) * bin_Hz
    grid = grid[(grid > 0.25 * bin_Hz) & (grid > 0.75 * f0)]     # a short record: f0/2 would fit f0 as harmonic 2
    best = grid[int(np.argmin([rss(f) for f in grid]))]
    lo, hi = best - 0.05 * bin_Hz, best + 0.05 * bin_Hz
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - g * (hi - lo), lo + g * (hi - lo)
    fa, fb = rss(a), rss(b)
    for _ in range(40):
        if fa < fb:
            hi, b, fb = b, a, fa
            a = hi - g * (hi - lo)
            fa = rss(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = rss(b)
    return 0.5 * (lo + hi)


def relative_harmonics(c: np.ndarray) -> np.ndarray:
    """Harmonic k relative to the fundamental with the fundamental's phase removed: c_k conj(c_1)^k / |c_1|^(k+1)."""
    c1 = c[0]
    k = np.arange(1, c.size + 1)
    return c * np.conj(c1) ** k / abs(c1) ** (k + 1)


def shape_of(h: np.ndarray) -> str:
    """'triangle', 'sine' or '' from relative harmonics (k = 1..)."""
    even = np.abs(h[1::2]).max(initial=0.0)
    if (abs(h[2] - TRIANGLE_H3) < H3_TOLERANCE and abs(h[4] - TRIANGLE_H5) < H5_TOLERANCE
            and even < EVEN_TOLERANCE):
        return "triangle"
    if np.abs(h[1:]).max() < SINE_TOLERANCE:
        return "sine"
    return ""


def detect_waveform(t_s: np.ndarray, y: np.ndarray) -> Waveform:
    """The excitation of a record (time [s], motion channel [m]: the command when there is one)."""
    ok = np.isfinite(t_s) & np.isfinite(y)
    tau, y = t_s[ok] - t_s[ok][0], y[ok]
    if tau.size < 20 or np.ptp(y) == 0 or tau[-1] <= 0:
        return Waveform("free", "no motion to detect" if tau.size >= 20 else f"{tau.size} samples only", "guess")
    f0 = coarse_frequency(tau, y)
    periods = f0 * tau[-1]
    if periods < MIN_PERIODS:
        return Waveform("free", f"less than {MIN_PERIODS:g} period of motion at any frequency", "likely",
                        periods=periods)
    f = refine_frequency(tau, y, f0)
    c, rss = harmonic_fit(tau, y, f)
    noise = noise_level(y)
    amplitude = abs(c[0])
    unexplained = math.sqrt(max(rss / tau.size - noise ** 2, 0.0)) / amplitude
    h = relative_harmonics(c)
    periods = f * tau[-1]
    if unexplained > FREE_FRACTION:
        return Waveform("free", f"no single frequency: a periodic fit at {f:.4g} Hz leaves {unexplained:.0%} of the "
                                "amplitude unexplained", "likely", periods=periods)
    shape = shape_of(h)
    if shape == "triangle":
        return triangle(tau, y, f, f"harmonics 3 and 5 {h[2].real:+.3f}, {h[4].real:+.3f} of the fundamental "
                                   "(a triangle's: -0.111, +0.040)", periods)
    if shape == "sine":
        return sine(tau, y, f, f"harmonics 2-5 at most {np.abs(h[1:]).max():.3f} of the fundamental (a sine's: 0)",
                    periods)
    said = ", ".join(f"{abs(v):.3f}" for v in h[1:5])
    return Waveform("free", f"periodic at {f:.4g} Hz but neither a triangle nor a sine: harmonics 2-5 {said} of the "
                            "fundamental (a triangle's: 0, 0.111, 0, 0.040; a sine's: 0)", "likely", periods=periods)


def chunk_phases(tau: np.ndarray, y: np.ndarray, f: float, chunks: int) -> tuple[np.ndarray, np.ndarray]:
    """(mid time, phase of the fundamental at ``f``) of ``chunks`` consecutive parts of the record."""
    edges = np.linspace(0, tau.size, chunks + 1).astype(int)
    mids, phases = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        c, _ = harmonic_fit(tau[a:b], y[a:b], f, harmonics=1)
        mids.append(tau[a:b].mean())
        phases.append(np.angle(c[0]))
    return np.asarray(mids), np.unwrap(np.asarray(phases))


def sine(tau: np.ndarray, y: np.ndarray, f: float, harmonics: str, periods: float) -> Waveform:
    """A sine's frequency and amplitude. The frequency's standard error is the larger of the white-noise bound
    (var ω = 12σ²/(A²N D²)) and the scatter of the fundamental's phase over parts of the record (a start
    transient, a distortion), whose drift also corrects the frequency."""
    chunks = min(int(periods), 20)
    se_drift = 0.0
    if chunks >= 3:
        mids, phases = chunk_phases(tau, y, f, chunks)
        (slope, _), cov = np.polyfit(mids, phases, 1, cov="unscaled")
        resid = phases - np.polyval([slope, _], mids)
        scale = float(resid @ resid) / (chunks - 2)
        f += slope / (2.0 * math.pi)
        se_drift = math.sqrt(cov[0, 0] * scale) / (2.0 * math.pi)
    c, rss = harmonic_fit(tau, y, f, harmonics=1)
    amplitude = abs(c[0])
    sigma = math.sqrt(rss / max(tau.size - 3, 1))
    se_f = max(math.sqrt(12.0 / tau.size) * sigma / (amplitude * tau[-1]) / (2.0 * math.pi), se_drift)
    se_a = sigma * math.sqrt(2.0 / tau.size)
    phase = math.atan2(c[0].imag, c[0].real)
    note = "" if abs(phase) < 0.05 else f"the record starts at phase {phase:+.2f} rad, the spec's sine at 0"
    return Waveform("sine", harmonics, Estimate(f, se_f).sure, frequency_Hz=Estimate(f, se_f),
                    amplitude_m=Estimate(amplitude, se_a), phase_rad=phase, phase_note=note, periods=periods)


def line_fits(tau: np.ndarray, y: np.ndarray, period: float, phase: float) -> np.ndarray:
    """Lines over the central part of every half-period of Y tri(2πτ/T + φ) inside the record: rows of
    (index k of the turning point that starts it, slope, value at mean time, mean time, se of the value,
    se of the slope)."""
    half = period / 2.0
    first = math.floor((phase - math.pi / 2) / math.pi)
    # only the half-periods that hold samples: bounded by the record's samples, whatever its time stamps
    with np.errstate(over="ignore", invalid="ignore"):      # a broken time stamp (1e308) holds no line
        held = np.unique(np.floor((2.0 * math.pi * tau / period + phase - math.pi / 2) / math.pi))
    rows = []
    for k in held[np.isfinite(held) & (held >= first) & (held < 2.0**53)].astype(np.int64).tolist():
        start = (math.pi / 2 + k * math.pi - phase) * period / (2.0 * math.pi)
        a, b = np.searchsorted(tau, [start + LINE_FRACTIONS[0] * half, start + LINE_FRACTIONS[1] * half])
        if b - a >= MIN_LINE_SAMPLES:
            rows.append((k, *line_fit(tau[a:b], y[a:b])))
    return np.array(rows, dtype=float).reshape(-1, 6)


def solve_crossings(fits: np.ndarray, period: float) -> tuple[float, float, float, float] | None:
    """(first crossing time, period, mid-stroke, se of the period) from lines that cross the mid-stroke c at
    τ0 + j·T/2 (j counted from the first line): b_j τ0 + b_j (j/2) T - c = b_j t_j - a_j, weighted by the
    lines' noise. Fewer than three lines or one direction only: the period is kept (se inf)."""
    k, b, a, tm, se = fits[:, 0], fits[:, 1], fits[:, 2], fits[:, 3], fits[:, 4]
    j = k - k[0]
    rhs = (b * tm - a) / se
    if fits.shape[0] >= 3 and (b > 0).any() and (b < 0).any():
        design = np.column_stack([b, b * j / 2.0, -np.ones_like(b)]) / se[:, None]
        sol, *_ = np.linalg.lstsq(design, rhs, rcond=None)
        cov = np.linalg.pinv(design.T @ design)
        resid = design @ sol - rhs
        dof = fits.shape[0] - 3
        scale = max(1.0, float(resid @ resid) / dof) if dof > 0 else 1.0
        return float(sol[0]), float(sol[1]), float(sol[2]), math.sqrt(cov[1, 1] * scale)
    if fits.shape[0] >= 2 and (b > 0).any() and (b < 0).any():
        design = np.column_stack([b, -np.ones_like(b)]) / se[:, None]
        sol, *_ = np.linalg.lstsq(design, rhs - (b * j / 2.0 * period) / se, rcond=None)
        return float(sol[0]), period, float(sol[1]), math.inf
    return None


def phase_from_crossing(crossing: float, rising: bool, period: float) -> float:
    """φ in (-π, π] of a triangle that crosses its mid-stroke at τ = ``crossing``, rising or falling (Eq. 26)."""
    phase = (0.0 if rising else math.pi) - 2.0 * math.pi * crossing / period
    return float(math.pi - (math.pi - phase) % (2.0 * math.pi))


def start_phase(phase: float, period: float, step: float) -> tuple[float, str, str]:
    """(phase, note, how sure): ±π/2 exactly when a turning point lies within SNAP_FRACTION of a period of the
    first sample (the record starts at a reversal, Eq. 26), else the fitted phase."""
    k = round((phase - math.pi / 2) / math.pi)
    turn = (math.pi / 2 + k * math.pi - phase) * period / (2.0 * math.pi)   # the nearest reversal, from τ = 0
    if abs(turn) > SNAP_FRACTION * period:
        return phase, "no reversal at the first sample: the fitted phase", "likely"
    snapped = math.pi / 2 if k % 2 == 0 else -math.pi / 2
    start = "-Y, rising" if snapped < 0 else "+Y, falling"
    if abs(turn) < 1e-6 * period:
        return snapped, f"starts at {start}: first reversal at the first sample", "sure"
    return snapped, (f"starts at {start}: first reversal {turn:+.3g} s from the first sample (the pipeline measures "
                     "this delay)"), "sure" if abs(turn) <= 2.0 * step else "likely"


def triangle(tau: np.ndarray, y: np.ndarray, f: float, harmonics: str, periods: float) -> Waveform:
    """Period, amplitude and phase of a triangle record from the lines of its half-periods (from its harmonics
    when the half-periods are too short for lines: amplitude π²/8 of the fundamental's)."""
    c, _ = harmonic_fit(tau, y, f)
    period, phase, period_se = 1.0 / f, float(np.angle(c[0])), math.inf
    for _ in range(3):
        fits = line_fits(tau, y, period, phase)
        solved = solve_crossings(fits, period) if fits.shape[0] else None
        if solved is None:
            break
        crossing, period, _mid, period_se = solved
        phase = phase_from_crossing(crossing, fits[0, 1] > 0, period)
    estimate = Estimate(period, period_se if math.isfinite(period_se) else period * 1e-3)
    rounded = estimate.rounded
    fits = line_fits(tau, y, rounded, phase)
    solved = solve_crossings(fits, rounded) if fits.shape[0] else None
    if solved is not None:
        phase = phase_from_crossing(solved[0], fits[0, 1] > 0, rounded)
    if fits.shape[0] >= 2:
        speeds, speed_se = np.abs(fits[:, 1]), fits[:, 5]
        se_speed = max(float(np.sqrt(np.sum(speed_se ** 2))) / speeds.size,
                       float(speeds.std(ddof=1)) / math.sqrt(speeds.size))
        amplitude = Estimate(float(speeds.mean()) * rounded / 4.0, se_speed * rounded / 4.0)
    else:
        amplitude = Estimate(abs(c[0]) * math.pi ** 2 / 8.0, abs(c[0]) * 1e-2)
    phase, note, sure = start_phase(phase, rounded, float(np.median(np.diff(tau))))
    return Waveform("triangle", harmonics, estimate.sure, period_s=estimate, amplitude_m=amplitude, phase_rad=phase,
                    phase_note=note, phase_sure=sure, periods=tau[-1] / rounded)
