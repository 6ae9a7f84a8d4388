"""What a sine record offers the diagnosis: its measured motion, its phase bins and its noise.

Drive. The measured displacement of a sine case is fitted by least squares with y = c + Y sin(2πf t + φ)
(offset, amplitude, frequency, phase; :func:`fit_sine`), on the record after its first cycle (the servo's
start-up transient), plus the harmonics 2 and 3 of that frequency that the motion holds beyond its noise (a
servo's distortion, a crank's kinematics: :func:`significant_harmonics`); the model is then driven by that motion
from rest, from where the fitted sine starts
the cycle in which the record starts (:class:`isokinetic.physics.sine_drive.SineDrive`), so it is driven
by the measured kinematics, not the plan's.

Bins. Every steady cycle (all but the first: the drive's start-up is not the rig's) is cut into
``n_bins`` equal phase bins (a multiple of 4, so that no bin straddles a reversal: reversals lie at a
quarter and three quarters of a cycle). A bin's ``sign`` is the direction of motion, its speed the mean
|dy/dt| of the fitted sine over it. Bins whose centre lies within 45° of peak speed are kind ``window``
(the characteristic's part of the cycle), the others, around the reversals, kind ``transient``, so that
the verdict's steady-versus-transient logic applies unchanged. Steady cycles alternate between period
1 and period 2 (the search fits period 1 and scores period 2, as with a triangle's two periods).

Noise. A steady periodic force cancels in the difference of the same bin's means in consecutive
cycles, which leaves noise: half its square estimates the variance of one bin mean, whatever the noise's
colour within a bin. These are pooled into var = a/n + b·F² (white plus force-proportional;
:func:`bin_variance_model`), from the cases whose period is at least the campaign's median (noise slower
than a short period would cancel in its differences and be missed). A variogram fit
(:func:`isokinetic.measurement.noise.fit_noise_model`) does not serve here: within any stretch of a sine the
proportional noise's level changes with the force, and its variogram reads that as slow noise. Where a
model is at hand (the nominal model, in the second pass), its own cycle-to-cycle convergence is taken off
the differences (seconds, for a stiff low-speed damper). Noise slower than a short record is one draw per
case: a common error s·|F| in all its bins, which cycle differences cannot see. Its size is measured as the
between-case scatter of each case's even mode against that model (:func:`between_case_scatter`; a symmetric
damper's force and every symmetric effect are odd over a cycle) and added to the bins' variances; the errors
of one case's bins stay correlated, which diagonal standard errors do not describe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from isokinetic.physics.sine_drive import SineDrive

#: Phase bins per cycle (a multiple of 4).
N_SINE_BINS = 16
#: Cycles left out at the start of a record: the servo's start-up, which the fitted sine does not describe.
SKIPPED_CYCLES = 1
#: A bin whose centre lies within this phase of peak speed is a ``window`` [rad].
WINDOW_HALF_WIDTH_RAD = math.pi / 4
#: Gauss-Newton iterations of the frequency refinement (quadratic convergence from the linear fit's start).
FIT_ITERATIONS = 6
#: Harmonics 2 .. MAX_HARMONIC of the fundamental are fitted to what the sine leaves of the motion (a servo's
#: distortion is mostly its second and third, a slider crank's its second; each costs a sine campaign's diagnosis
#: two model runs for its error, :func:`isokinetic.diagnosis.model.harmonic_input_variance`) ...
MAX_HARMONIC = 3
#: ... and those whose amplitude exceeds this many of its standard errors drive the model too (the others' share
#: of the motion, within their standard errors, is in the bins' errors: ``harmonic_se_m``).
HARMONIC_SIGMAS = 3.0
#: A harmonic whose share of the speed, k A_k / Y, is below this is left out however clear (a noise-free record's
#: quantisation steps show as harmonics of about 1e-5 of its speed).
HARMONIC_FLOOR = 1e-4
#: A free record is diagnosed as a periodic motion (:func:`periodic_motion`) where its fitted sine and harmonics
#: leave at most this share of its amplitude unexplained beyond the LVDT's noise ...
PERIODIC_RESIDUAL = 0.005
#: ... over at least this many cycles of its dominant period (the first one is the drive's start-up).
PERIODIC_MIN_CYCLES = 3.0


@dataclass(frozen=True)
class SineFit:
    """y = offset + Y sin(2π f t + φ), fitted to a displacement record; ``amplitude_rel_se`` the relative
    standard error of Y (LVDT noise). ``harmonics``: the motion's significant harmonics (k, A_k, θ_k), the
    terms A_k sin(k u + θ_k) of the fundamental's phase u = 2π f t + φ (a servo's distortion, a crank's
    kinematics; :func:`significant_harmonics`)."""

    offset_m: float
    amplitude_m: float
    frequency_Hz: float
    phase_rad: float
    amplitude_rel_se: float
    harmonics: tuple[tuple[int, float, float], ...] = ()
    harmonic_se_m: tuple[float, ...] = ()   # standard error of each component of harmonics 2, 3, ... [m]

    def position(self, time_s) -> np.ndarray:
        """The fitted motion y(t) [m]: offset, sine and harmonics."""
        u = 2.0 * math.pi * self.frequency_Hz * np.asarray(time_s, dtype=float) + self.phase_rad
        y = self.offset_m + self.amplitude_m * np.sin(u)
        for k, a_k, theta in self.harmonics:
            y = y + a_k * np.sin(k * u + theta)
        return y

    def divided(self, scale: float) -> SineFit:
        """The fit with its amplitudes divided by ``scale`` (an LVDT scale's correction)."""
        return replace(self, amplitude_m=self.amplitude_m / scale,
                       harmonics=tuple((k, a_k / scale, theta) for k, a_k, theta in self.harmonics),
                       harmonic_se_m=tuple(se / scale for se in self.harmonic_se_m))

    def start_s(self, t0_s: float) -> float:
        """The fitted sine's cycle start (phase 0, rising) nearest to ``t0_s``: in [t0 - 1/(2f), t0 + 1/(2f)) (a
        record that starts at rest shortly before the motion: the motion's start)."""
        period = 1.0 / self.frequency_Hz
        first = -self.phase_rad / (2.0 * math.pi * self.frequency_Hz)
        return first + math.floor((t0_s - first) / period + 0.5) * period


def linear_sine(t: np.ndarray, y: np.ndarray, omega: float, ks: tuple[int, ...] = ()
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of y = c + a sin ωt + b cos ωt (+ a_k sin kωt + b_k cos kωt for k in ``ks``): (coefficients,
    design, residuals)."""
    cols = [np.ones_like(t), np.sin(omega * t), np.cos(omega * t)]
    for k in ks:
        cols += [np.sin(k * omega * t), np.cos(k * omega * t)]
    design = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    return coef, design, y - design @ coef


def gauss_newton_sine(tc: np.ndarray, y: np.ndarray, omega: float, ks: tuple[int, ...] = ()):
    """:func:`linear_sine` with its frequency refined by Gauss-Newton (the harmonics ``ks`` move with it):
    (ω, coefficients, design, residuals)."""
    coef, design, resid = linear_sine(tc, y, omega, ks)
    for _ in range(FIT_ITERATIONS):
        d_omega = tc * (coef[1] * np.cos(omega * tc) - coef[2] * np.sin(omega * tc))
        for j, k in enumerate(ks):
            d_omega = d_omega + k * tc * (coef[3 + 2 * j] * np.cos(k * omega * tc)
                                          - coef[4 + 2 * j] * np.sin(k * omega * tc))
        jac = np.column_stack([design, d_omega])
        step, *_ = np.linalg.lstsq(jac, resid, rcond=None)
        omega += step[-1]
        coef, design, resid = linear_sine(tc, y, omega, ks)
        if abs(step[-1]) < 1e-12 * omega:
            break
    return omega, coef, design, resid


def fit_sine(time_s, displacement_m, frequency_Hz: float) -> SineFit | None:
    """Least-squares sine through a displacement record: the linear fit at the planned frequency, then
    Gauss-Newton on (c, a, b, ω) (times centred for conditioning); where the motion holds significant
    harmonics (:func:`significant_harmonics`), the fit again with them. None for fewer than 8 samples or no
    motion."""
    t = np.asarray(time_s, dtype=float)
    y = np.asarray(displacement_m, dtype=float)
    if t.size < 8 or not np.all(np.isfinite(y)):
        return None
    mid = 0.5 * (t[0] + t[-1])
    tc = t - mid
    omega, coef, design, resid = gauss_newton_sine(tc, y, 2.0 * math.pi * frequency_Hz)
    amp = math.hypot(coef[1], coef[2])
    ks, harmonic_se = significant_harmonics(tc, resid, omega, 4, amp) if amp > 0.0 else ((), ())
    if ks:
        omega, coef, design, resid = gauss_newton_sine(tc, y, omega, ks)
    amp = math.hypot(coef[1], coef[2])
    if not (amp > 0.0 and omega > 0.0):
        return None
    s2 = float(resid @ resid) / max(t.size - 4 - 2 * len(ks), 1)
    cov = s2 * np.linalg.pinv(design.T @ design)
    grad = np.zeros(design.shape[1])
    grad[1:3] = np.array([coef[1], coef[2]]) / amp
    rel_se = math.sqrt(max(float(grad @ cov @ grad), 0.0)) / amp
    # a sin ωtc + b cos ωtc = Y sin(ω t + φ) with φ = atan2(b, a) - ω mid; a harmonic a_k sin kωtc + b_k cos kωtc
    # = A_k sin(k u + θ_k) of the fundamental's phase u = ωtc + ψ_1, θ_k = atan2(b_k, a_k) - k ψ_1
    psi_1 = math.atan2(coef[2], coef[1])
    phase = math.remainder(psi_1 - omega * mid, 2.0 * math.pi)
    harmonics = tuple((k, math.hypot(coef[3 + 2 * j], coef[4 + 2 * j]),
                       math.remainder(math.atan2(coef[4 + 2 * j], coef[3 + 2 * j]) - k * psi_1, 2.0 * math.pi))
                      for j, k in enumerate(ks))
    return SineFit(float(coef[0]), amp, omega / (2.0 * math.pi), phase, rel_se, harmonics, harmonic_se)


def periodic_motion(time_s, displacement_m) -> tuple[SineFit | None, float]:
    """A free record's motion as a periodic one: (the sine and harmonics fitted after its first cycle of the
    dominant period, :func:`isokinetic.measurement.loops.dominant_period_s` and :func:`fit_sine`; the share of its
    amplitude they leave unexplained beyond the noise, sqrt(r² - s²)/Y with r the residual's rms and s its noise
    from successive differences, 0 where r² - s² is within 3 of its standard errors, about 2 s²/√n for n samples of
    white noise: a short record's noise hides a small departure). (None, inf) for a record of fewer than
    PERIODIC_MIN_CYCLES cycles or without motion. A crank's motion is periodic; a road profile or a random input
    is not."""
    from isokinetic.measurement.loops import dominant_period_s

    t = np.asarray(time_s, dtype=float)
    y = np.asarray(displacement_m, dtype=float)
    if t.size < 8 or not np.all(np.isfinite(y)):
        return None, math.inf
    period = dominant_period_s(t, y)
    if not (period > 0.0 and t[-1] - t[0] >= PERIODIC_MIN_CYCLES * period):
        return None, math.inf
    after = t >= t[0] + SKIPPED_CYCLES * period
    fit = fit_sine(t[after], y[after], 1.0 / period)
    if fit is None:
        return None, math.inf
    resid = y[after] - fit.position(t[after])
    noise2 = 0.5 * float(np.mean(np.diff(resid) ** 2))
    excess = float(np.mean(resid ** 2)) - noise2
    return fit, (math.sqrt(excess) / fit.amplitude_m if excess > 6.0 * noise2 / math.sqrt(resid.size) else 0.0)


def significant_harmonics(tc: np.ndarray, resid: np.ndarray, omega: float, n_fitted: int, amplitude_m: float,
                          max_harmonic: int = MAX_HARMONIC, sigmas: float = HARMONIC_SIGMAS
                          ) -> tuple[tuple[int, ...], tuple[float, ...]]:
    """The harmonics k of what a fitted sine (``n_fitted`` parameters, amplitude Y) leaves of a motion that stand
    out of its noise, and the standard error of each harmonic's sine and cosine components (k = 2 ..
    ``max_harmonic``, those below the sampling's Nyquist frequency; the mean of the two variances): least squares
    of a_k sin kωtc + b_k cos kωtc; kept where A_k = hypot(a_k, b_k) exceeds ``sigmas`` of its standard errors
    (from the residual's scatter) and k A_k / Y exceeds :data:`HARMONIC_FLOOR`."""
    step = float(np.median(np.diff(tc))) if tc.size > 1 else math.inf
    below_nyquist = math.ceil(math.pi / (omega * step)) - 1 if step > 0.0 else 0
    ks = range(2, min(max_harmonic, below_nyquist) + 1)
    if not ks:
        return (), ()
    design = np.column_stack([f(k * omega * tc) for k in ks for f in (np.sin, np.cos)])
    coef, *_ = np.linalg.lstsq(design, resid, rcond=None)
    rest = resid - design @ coef
    s2 = float(rest @ rest) / max(tc.size - n_fitted - design.shape[1], 1)
    cov = s2 * np.linalg.pinv(design.T @ design)
    kept, component_se = [], []
    for j, k in enumerate(ks):
        block = cov[2 * j:2 * j + 2, 2 * j:2 * j + 2]
        component_se.append(math.sqrt(max(0.5 * float(np.trace(block)), 0.0)))
        a, b = coef[2 * j], coef[2 * j + 1]
        amp = math.hypot(a, b)
        if not amp > 0.0:
            continue
        grad = np.array([a, b]) / amp
        se = math.sqrt(max(float(grad @ block @ grad), 0.0))
        if amp > sigmas * se and k * amp > HARMONIC_FLOOR * amplitude_m:
            kept.append(k)
    return tuple(kept), tuple(component_se)


def phase_bins(n_bins: int = N_SINE_BINS) -> list[tuple[float, float, float, str]]:
    """(start, end, sign, kind) of each phase bin of one cycle, as fractions of the period."""
    if n_bins % 4 or n_bins <= 0:
        raise ValueError(f"n_bins must be a positive multiple of 4, got {n_bins}")
    out = []
    for j in range(n_bins):
        centre = 2.0 * math.pi * (j + 0.5) / n_bins
        kind = "window" if abs(math.cos(centre)) >= math.cos(WINDOW_HALF_WIDTH_RAD) else "transient"
        out.append((j / n_bins, (j + 1) / n_bins, 1.0 if math.cos(centre) > 0.0 else -1.0, kind))
    return out


#: Points of the midpoint rule that averages |dy/dt| over a phase bin of a motion with harmonics.
SPEED_POINTS = 256


def mean_speed(drive: SineDrive, a_s: float, b_s: float) -> float:
    """Mean |dy/dt| of a sine record's drive over plan times [a, b) [m/s]: of a sine inside one direction of
    motion, |y(b) - y(a)| / (b - a); with harmonics (whose reversals need not be the sine's) by the midpoint rule."""
    w = 2.0 * math.pi * drive.frequency_Hz
    if not drive.harmonics:
        return abs(drive.amplitude_m * (math.sin(w * b_s) - math.sin(w * a_s))) / (b_s - a_s)
    u = w * (a_s + (np.arange(SPEED_POINTS) + 0.5) * (b_s - a_s) / SPEED_POINTS)
    return float(w * np.mean(np.abs(drive.phase_velocity(u))))


#: A bin with at least this many steady cycles has its noise read from the later half of them
#: (:func:`bin_variance_model`).
LATER_HALF_CYCLES = 4


def bin_variance_model(key: np.ndarray, cycle: np.ndarray, force_N: np.ndarray, n: np.ndarray, long: np.ndarray,
                       model_N: np.ndarray | None = None) -> tuple[float, float]:
    """(a [N²], b [-]) of the variance of a bin mean, a/n + b·F², from the differences of the same bin's means
    in consecutive cycles (``key``: the bin's case and phase slot; a periodic force cancels, so
    E[d²]/2 is the variance of one mean), less the differences of ``model_N`` (a model's bin means: its own
    cycle-to-cycle convergence is no noise) where given. Only the bins of ``long`` cases enter (periods long
    against the noise's correlation; a shorter one would cancel slow noise). Where a bin has at least
    LATER_HALF_CYCLES cycles, only the differences of their later half enter (from the middle of its first and
    last cycle on): a damper whose effects the model lacks converges from rest over several cycles in its own
    way (a leakage or an asymmetry shifts the mean pressure slowly), and those early differences are no noise
    either; a shorter record has none to spare. Non-negative least squares, weighted by the fitted variance
    once (the variance of d² is twice its square)."""
    from scipy.optimize import nnls

    g = force_N - (0.0 if model_N is None else model_N)
    order = np.lexsort((cycle, key))
    k, c, gg, f, nn, lg = key[order], cycle[order], g[order], force_N[order], n[order], long[order]
    names, at = np.unique(k, return_inverse=True)
    first, last = np.full(names.size, np.inf), np.full(names.size, -np.inf)
    np.minimum.at(first, at, c)
    np.maximum.at(last, at, c)
    many = (last - first + 1 >= LATER_HALF_CYCLES)[at[:-1]]
    later = ~many | (c[:-1] >= 0.5 * (first + last)[at[:-1]])
    pair = (k[1:] == k[:-1]) & (c[1:] == c[:-1] + 1) & lg[1:] & later
    if not pair.any():
        return 0.0, 0.0
    y = 0.5 * (gg[1:] - gg[:-1])[pair] ** 2
    design = np.column_stack([0.5 * (1.0 / nn[1:] + 1.0 / nn[:-1])[pair], (0.5 * (f[1:] + f[:-1])[pair]) ** 2])
    weight = np.ones(y.size)
    for _ in range(2):
        coef, _ = nnls(design * weight[:, None], y * weight)
        fitted = design @ coef
        if not np.any(fitted > 0.0):
            break
        weight = 1.0 / np.maximum(fitted, 1e-12 * float(fitted.max()))
    return float(coef[0]), float(coef[1])


def between_case_scatter(case: np.ndarray, residual_N: np.ndarray, model_N: np.ndarray, var_N2: np.ndarray) -> float:
    """Relative scatter s of a common even error per case, s·|F| in every bin of a case, beyond the bins' own
    variances: the noise slower than a short record (a proportional noise correlated over longer than the
    record is one draw per case). Each case's even mode e = Σ r|M|/var / Σ M²/var (``residual_N`` r = F - M,
    against a model M: a symmetric damper's force and every symmetric effect are odd over a cycle and leave
    it) is regressed on a common term and an offset's 1/|F| pattern (an asymmetry or a load-cell offset are
    common to all cases, not scatter); s² = the residual variance beyond the e's own, 0 for fewer than four
    cases."""
    names = list(dict.fromkeys(case.tolist()))
    if len(names) < 4:
        return 0.0
    rows = []
    for c in names:
        m = case == c
        u, w = np.abs(model_N[m]), 1.0 / var_N2[m]
        norm = float(np.sum(w * u * u))
        if norm <= 0.0:
            continue
        rows.append((float(np.sum(w * residual_N[m] * u)) / norm, float(np.sum(w * u)) / norm, 1.0 / norm))
    if len(rows) < 4:
        return 0.0
    e, offset, own = (np.array(x) for x in zip(*rows, strict=True))
    design = np.column_stack([np.ones_like(e), offset])
    coef, *_ = np.linalg.lstsq(design, e, rcond=None)
    resid = e - design @ coef
    return math.sqrt(max(float(resid @ resid) / (e.size - 2) - float(np.mean(own)), 0.0))
