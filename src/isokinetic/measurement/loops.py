"""Sine and free-waveform records: their loops, peak-to-peak and binned curves (the method of the rule ``harmonic``,
run by :mod:`isokinetic.stages.harmonic`).

Sec. 4.5 and Fig. 13 of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.): harmonic excitation tests (1.75 Hz,
amplitudes 0.23-0.64 mm) give hysteresis loops; their summary is the 'peak-to-peak'
characteristic, one point per test and direction made of the extreme velocity and the extreme
force of the test. The two extremes are not simultaneous: the force lags the velocity because of
the effective compressibility, and the point lies below the steady characteristic of the triangle
tests (:func:`peak_to_peak` records the lag).

Velocity
    All velocities here are the derivative of the measured displacement by a Savitzky-Golay filter
    (:func:`smooth_velocity`): a least-squares cubic over a sliding window, differentiated at the
    window centre. The default window (:func:`default_window_s`) is the shortest one whose noise
    gain keeps the velocity noise at ``NOISE_TARGET`` (0.5 %) of the velocity scale, estimated from
    the record itself, and at most ``MAX_PERIOD_FRACTION`` (1/5) of the dominant period, where a
    cubic's bias on a sine is below 3.2e-4. Noise-free records thus keep sharp features (backlash
    spikes), noisy ones are smoothed as much as the bias bound allows.

Loop sense (derived)
    A compressible damper is, to first order, a spring (the oil, k_h = A_p^2 / (beta_eff V)) in
    series with a dashpot (the orifice): a Maxwell element, whose force lags the velocity by a
    phase 0 < phi < pi/2. Over one period v = V cos(theta), F = F0 cos(theta - phi); the signed
    area of the (v, F) curve (v on the horizontal axis) is pi V F0 sin(phi) > 0: the loop circulates
    **counter-clockwise** in the force-velocity plane (as the paper observes). In the
    force-displacement plane the signed area of (y, F) is -(dissipated energy) < 0: clockwise.
    :func:`signed_area` gives the sense of any loop.

Free records
    ``free`` cases (e.g. a crank-driven dyno) have no period or amplitude: :func:`free_loop` keeps
    the whole record, :func:`binned_characteristic` averages the force in velocity bins per
    direction, :func:`peak_velocity_characteristic` takes the force at each velocity peak (one
    point per half-cycle, half-cycles from the sign changes of the velocity).

Row-level lineage
    Every row names the samples its point was computed from: ``row_start``/``row_stop`` (stop
    exclusive, the raw file's data rows as in the time series' ``row`` column) and
    ``loop_start_s``/``loop_end_s`` of the loop (:func:`loop` / :func:`free_loop`: all the
    half-cycles a peak-to-peak point averages, every sample of the bins, every half-cycle of the
    peak-velocity points), with the case's ``raw_file`` and ``raw_sha256``. The velocity of a
    sample uses the displacement ``window_s``/2 either side of it.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pandas as pd

from isokinetic.measurement.crossings import hysteresis_crossings

log = logging.getLogger("isokinetic")

#: Default smoothing: velocity noise at most this fraction of the velocity scale ...
NOISE_TARGET = 0.005
#: ... with a window of at most this fraction of the dominant period (cubic bias on a sine < 3.2e-4).
MAX_PERIOD_FRACTION = 0.2
#: Start-up periods dropped by :func:`loop` at least (records start from rest with Delta p = 0) ...
SKIP_PERIODS = 1
#: ... and more while a period's mean force differs from the last period's by more than this
#: fraction of the last period's force amplitude. The start-up transient of a compressible damper
#: is the decaying offset of a Maxwell element, time constant c/k (damping over oil and rig
#: stiffness): ~0.25 s for the paper's damper, half a period at 1.75 Hz, so one period is not
#: always enough.
STEADY_TOLERANCE = 0.01
#: Hysteresis of the half-cycle detection, as a fraction of the 99th percentile of |v|.
HYSTERESIS = 0.05
#: Velocity bins per direction of :func:`binned_characteristic`.
N_BINS = 20
#: :func:`binned_characteristic` bins only speeds above this many standard deviations of the velocity estimate's
#: noise: below it a sample's velocity sign is uncertain (one in 740 samples at 3 sigma), and a force that reverses
#: with the velocity (friction) would be averaged with its reversal.
RESOLVE_SIGMA = 3.0


# ----------------------------------------------------------------------------------------------
# smoothing derivative
# ----------------------------------------------------------------------------------------------

def _odd_window(n: int, polyorder: int, n_max: int) -> int:
    """An odd window length in [polyorder + 2 (odd), n_max (odd)] nearest to n."""
    lo = polyorder + 2 + (polyorder + 2 + 1) % 2
    hi = n_max if n_max % 2 else n_max - 1
    if hi < lo:
        raise ValueError(f"record too short for a polyorder-{polyorder} smoothing derivative "
                         f"({n_max} samples, {lo} needed)")
    n = int(n) if int(n) % 2 else int(n) + 1
    return min(max(n, lo), hi)


def savgol_derivative_coeffs(n: int, polyorder: int, delta: float) -> np.ndarray:
    """Weights w of the Savitzky-Golay first derivative at a window's centre: v_i = sum_k w_k
    x_(i-n//2+k), the slope at the centre of the least-squares polynomial of degree ``polyorder``
    through the n (odd) samples spaced ``delta`` (Savitzky & Golay 1964; the weights of
    ``scipy.signal.savgol_coeffs(n, polyorder, deriv=1, delta=delta, use='dot')``)."""
    offsets = np.arange(n, dtype=float) - n // 2
    powers = offsets[:, None] ** np.arange(polyorder + 1)
    return np.linalg.pinv(powers)[1] / delta


def savgol_derivative(x: np.ndarray, n: int, polyorder: int, delta: float) -> np.ndarray:
    """The first derivative of ``x`` (x's unit per delta's) by a Savitzky-Golay filter of n (odd, <= len(x))
    samples; the first and last n//2 samples use the polynomial fitted to the first and last n samples
    (``scipy.signal.savgol_filter(x, n, polyorder, deriv=1, delta=delta, mode='interp')``, which the
    tests compare it with; here in numpy because importing scipy.signal costs a job about 0.45 s)."""
    x = np.asarray(x, dtype=float)
    half = n // 2
    out = np.empty_like(x)
    out[half:x.size - half] = np.correlate(x, savgol_derivative_coeffs(n, polyorder, delta), mode="valid")
    if half:
        offsets = np.arange(n, dtype=float) - half
        fit = np.linalg.pinv(offsets[:, None] ** np.arange(polyorder + 1))     # polynomial coefficients
        coef = fit @ np.column_stack([x[:n], x[x.size - n:]])                   # (polyorder + 1, 2 edges)
        slope = np.arange(1, polyorder + 1)[:, None] * coef[1:]                 # derivative's coefficients
        at = offsets[:half, None] ** np.arange(polyorder)                       # the first half samples
        out[:half] = at @ slope[:, 0] / delta
        out[x.size - half:] = (-offsets[:half][::-1, None]) ** np.arange(polyorder) @ slope[:, 1] / delta
    return out


def _uniform(time_s: np.ndarray) -> tuple[np.ndarray, float, bool]:
    """(grid, dt, is_uniform): the record's own times if evenly spaced (to 1e-3 of dt), else an
    even grid over the same span with the median interval."""
    dt_all = np.diff(time_s)
    if dt_all.size == 0 or not np.all(dt_all > 0):
        raise ValueError("time must be strictly increasing with at least two samples")
    dt = float(np.median(dt_all))
    if np.abs(dt_all - dt).max() <= 1e-3 * dt:
        return time_s, dt, True
    n = int(round((time_s[-1] - time_s[0]) / dt)) + 1
    return time_s[0] + dt * np.arange(n), dt, False


def dominant_period_s(time_s, displacement_m) -> float:
    """The period [s] of the largest spectral peak of the (linearly detrended, Hann-windowed) displacement.

    The record length when no peak other than DC exists.
    """
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(displacement_m, dtype=float)
    grid, dt, same = _uniform(t)
    if not same:
        x = np.interp(grid, t, x)
    n = x.size
    span = dt * n
    if n < 4:
        return span
    x = x - np.polyval(np.polyfit(np.arange(n), x, 1), np.arange(n))
    spec = np.abs(np.fft.rfft(x * np.hanning(n)))
    if spec.size < 3 or not np.any(spec[1:] > 0):
        return span
    k = 1 + int(np.argmax(spec[1:]))
    # parabolic refinement of the peak bin (log magnitude), bounded to +/- half a bin
    if 1 < k < spec.size - 1 and np.all(spec[k - 1:k + 2] > 0):
        a, b, c = np.log(spec[k - 1:k + 2])
        denom = a - 2 * b + c
        k = k + (0.5 * (a - c) / denom if denom < 0 else 0.0)
    return float(span / k)


def noise_sigma(x: np.ndarray) -> float:
    """The 1-sigma of white noise on x (in x's unit) from its third differences (variance 20 sigma^2 for white
    noise; the signal's share is ~ (omega dt)^3 of its amplitude). RMS of the differences without their
    largest 1 % (kinks, spikes), so that coarse quantisation (mostly zero differences) still counts."""
    if x.size < 8:
        return 0.0
    d3 = np.abs(np.diff(x, 3))
    d3 = d3[d3 <= np.percentile(d3, 99)]
    return float(np.sqrt(np.mean(d3 * d3) / 20.0)) if d3.size else 0.0


def default_window_s(time_s, displacement_m, polyorder: int = 3, period_s: float | None = None) -> float:
    """Default Savitzky-Golay window [s] of :func:`smooth_velocity` (module docstring).

    1. Bias bound: at most ``MAX_PERIOD_FRACTION`` x the period (``period_s``, else the dominant
       period of the displacement, :func:`dominant_period_s`).
    2. Noise: the displacement noise sigma is estimated from third differences (trimmed RMS), the
       velocity scale V as the 99th percentile of |v| from a first pass with the longest window;
       the window is the shortest whose noise gain sqrt(sum c_i^2)/dt gives sigma_v <= NOISE_TARGET V.
    The result lies between polyorder + 2 samples and the bias bound.
    """
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(displacement_m, dtype=float)
    grid, dt, same = _uniform(t)
    if not same:
        x = np.interp(grid, t, x)
    period = float(period_s) if period_s is not None and math.isfinite(period_s) and period_s > 0 \
        else dominant_period_s(grid, x)
    n_cap = _odd_window(int(MAX_PERIOD_FRACTION * period / dt), polyorder, x.size)
    n_min = _odd_window(0, polyorder, x.size)
    sigma = noise_sigma(x)
    if sigma == 0.0:
        return n_min * dt
    v = savgol_derivative(x, n_cap, polyorder, dt)
    scale = float(np.percentile(np.abs(v), 99))
    if scale == 0.0:
        return n_cap * dt
    for n in range(n_min, n_cap + 1, 2):
        gain = float(np.sqrt(np.sum(savgol_derivative_coeffs(n, polyorder, dt) ** 2)))
        if gain * sigma <= NOISE_TARGET * scale:
            return n * dt
    return n_cap * dt


def velocity_noise_m_s(time_s, displacement_m, window_s: float, polyorder: int = 3) -> float:
    """The 1-sigma [m/s] of the noise of :func:`smooth_velocity` with this window, measured on the record: the
    displacement's white noise (:func:`noise_sigma`, on the even grid the derivative uses, so rounded time stamps
    count) times the Savitzky-Golay derivative's noise gain sqrt(sum c_i^2)."""
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(displacement_m, dtype=float)
    grid, dt, same = _uniform(t)
    xg = x if same else np.interp(grid, t, x)
    n = _odd_window(int(round(window_s / dt)), polyorder, xg.size)
    return noise_sigma(xg) * float(np.sqrt(np.sum(savgol_derivative_coeffs(n, polyorder, dt) ** 2)))


def smooth_velocity(time_s, displacement_m, window_s: float | None = None, polyorder: int = 3,
                    period_s: float | None = None) -> np.ndarray:
    """Velocity [m/s] as the Savitzky-Golay derivative of the displacement.

    :func:`savgol_derivative` (``scipy.signal.savgol_filter(x, n, polyorder, deriv=1, delta=dt)``): a
    least-squares polynomial of degree ``polyorder`` over n samples (n the odd sample count nearest
    ``window_s``, at least polyorder + 2) differentiated at the centre; the ends use the polynomial
    fitted to the first / last window (mode 'interp'). ``window_s=None`` picks :func:`default_window_s` (``period_s``
    sets its bias bound). Unevenly sampled records (interval spread > 1e-3) are interpolated onto
    an even grid of the median interval, differentiated, and interpolated back.
    """
    t = np.asarray(time_s, dtype=float)
    x = np.asarray(displacement_m, dtype=float)
    if t.shape != x.shape or t.ndim != 1:
        raise ValueError("time_s and displacement_m must be 1-D arrays of equal length")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise ValueError("time_s and displacement_m must be finite")
    grid, dt, same = _uniform(t)
    xg = x if same else np.interp(grid, t, x)
    if window_s is None:
        window_s = default_window_s(grid, xg, polyorder, period_s)
    if not (window_s > 0):
        raise ValueError(f"window_s must be > 0, got {window_s!r}")
    n = _odd_window(int(round(window_s / dt)), polyorder, xg.size)
    v = savgol_derivative(xg, n, polyorder, dt)
    return v if same else np.interp(t, grid, v)


# ----------------------------------------------------------------------------------------------
# loops
# ----------------------------------------------------------------------------------------------

LOOP_COLUMNS = ["time_s", "displacement_m", "velocity_m_s", "force_N", "period"]


def _channels(series: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    s = series.sort_values("time_s", kind="stable")
    return (s["time_s"].to_numpy(dtype=float), s["displacement_m"].to_numpy(dtype=float),
            s["force_N"].to_numpy(dtype=float))


def _steady_start(k: np.ndarray, f: np.ndarray, n_whole: int) -> int:
    """First period index (0-based) from which every period's mean force is within
    STEADY_TOLERANCE x the last period's force amplitude of the last period's mean force."""
    last = f[k == n_whole - 1]
    if last.size < 2:
        return 0
    tol = STEADY_TOLERANCE * 0.5 * float(last.max() - last.min())
    ref = float(last.mean())
    start = n_whole - 1
    for j in range(n_whole - 2, -1, -1):
        if abs(float(f[k == j].mean()) - ref) > tol:
            break
        start = j
    return start


def _row_range(series: pd.DataFrame, keep: np.ndarray) -> dict:
    """Source rows of the kept samples: {row_start, row_stop} (stop exclusive) in the series' ``row``
    numbering (the raw file's data rows; positions when the series has no ``row`` column), in the
    time order of :func:`_channels`. The kept samples are one contiguous run."""
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        return {"row_start": -1, "row_stop": -1}
    if "row" in series:
        rows = series.sort_values("time_s", kind="stable")["row"].to_numpy(dtype=np.int64)
    else:
        rows = np.arange(len(series), dtype=np.int64)
    return {"row_start": int(rows[idx[0]]), "row_stop": int(rows[idx[-1]]) + 1}


def loop(series: pd.DataFrame, frequency_Hz: float | None = None, skip_periods: int | None = None,
         window_s: float | None = None, polyorder: int = 3) -> pd.DataFrame:
    """The hysteresis loop of a sine record over whole periods after the start-up transient.

    Velocity: :func:`smooth_velocity` of the whole record (so the loop's ends are not filter ends)
    with the period 1/f as bias bound. The loop is [t0 + s/f, t0 + (s + n)/f) with t0 the first
    sample, n the whole periods after the s skipped ones that end half a filter window before the
    record does (the filter's end fit is less accurate). ``skip_periods`` None (default): s is at
    least SKIP_PERIODS (records start from rest, Delta p = 0) and grows until the period-mean
    force has settled (STEADY_TOLERANCE of the last period's amplitude: the start-up transient is
    a decaying offset); an int fixes s. At least one whole period is kept, so a short record skips
    fewer. ``frequency_Hz`` None: the dominant frequency of the displacement.

    Returns columns time_s, displacement_m, velocity_m_s, force_N and ``period`` (1-based index of
    the period in the record: the first kept period is s + 1). ``attrs``: frequency_Hz, window_s,
    skip_periods.
    """
    t, x, f = _channels(series)
    if frequency_Hz is None or not math.isfinite(frequency_Hz) or frequency_Hz <= 0:
        frequency_Hz = 1.0 / dominant_period_s(t, x)
    period = 1.0 / float(frequency_Hz)
    if window_s is None:
        window_s = default_window_s(t, x, polyorder, period)
    v = smooth_velocity(t, x, window_s, polyorder)
    dt = float(np.median(np.diff(t)))
    n_whole = int(math.floor((t[-1] - t[0] + dt) / period + 1e-6))
    if n_whole < 1:
        raise ValueError(f"record of {t[-1] - t[0] + dt:.4g} s holds no whole period of {period:.4g} s")
    k = np.floor((t - t[0] + 0.5 * dt) / period + 1e-9).astype(np.int64)   # period index from 0
    # periods clear of the filter's ends (half a window), unless the record is too short for that
    half = _odd_window(int(round(window_s / dt)), polyorder, t.size) // 2 * dt
    clear = [j for j in range(n_whole)
             if t[0] + j * period >= t[0] + half - 0.5 * dt and t[0] + (j + 1) * period - dt <= t[-1] - half + 0.5 * dt]
    first, n_end = (clear[0], clear[-1] + 1) if clear else (0, n_whole)
    if skip_periods is None:
        skip_periods = max(SKIP_PERIODS, _steady_start(k, f, n_end))
    skip = max(first, min(int(skip_periods), n_end - 1))
    keep = (k >= skip) & (k < n_end)
    out = pd.DataFrame({"time_s": t[keep], "displacement_m": x[keep], "velocity_m_s": v[keep],
                        "force_N": f[keep], "period": k[keep] + 1})
    out.attrs.update(frequency_Hz=float(frequency_Hz), window_s=float(window_s), skip_periods=skip,
                     **_row_range(series, keep))
    return out.reset_index(drop=True)


def free_loop(series: pd.DataFrame, window_s: float | None = None, polyorder: int = 3) -> pd.DataFrame:
    """A free record as a loop: the whole record less half a smoothing window at each end.

    Columns as :func:`loop` (``period`` = 0); ``attrs``: frequency_Hz (dominant), window_s, velocity_noise_m_s
    (:func:`velocity_noise_m_s`).
    """
    t, x, f = _channels(series)
    period = dominant_period_s(t, x)
    if window_s is None:
        window_s = default_window_s(t, x, polyorder, period)
    v = smooth_velocity(t, x, window_s, polyorder)
    dt = float(np.median(np.diff(t)))
    half = int(round(window_s / dt)) // 2
    keep = np.zeros(t.size, dtype=bool)
    keep[half:t.size - half] = True
    out = pd.DataFrame({"time_s": t[keep], "displacement_m": x[keep], "velocity_m_s": v[keep],
                        "force_N": f[keep], "period": np.zeros(int(keep.sum()), dtype=np.int64)})
    out.attrs.update(frequency_Hz=1.0 / period, window_s=float(window_s), skip_periods=0, **_row_range(series, keep),
                     velocity_noise_m_s=velocity_noise_m_s(t, x, window_s, polyorder))
    return out.reset_index(drop=True)


def signed_area(x, y) -> float:
    """The shoelace signed area of the closed curve (x, y), x's unit times y's: > 0 counter-clockwise, < 0 clockwise."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# ----------------------------------------------------------------------------------------------
# half-cycles and extremes
# ----------------------------------------------------------------------------------------------

def half_cycles(velocity_m_s, hysteresis: float = HYSTERESIS) -> list[tuple[int, int, float]]:
    """The runs of one velocity sign: (start, stop, sign), stop exclusive, in order.

    A run changes sign when v crosses the opposite threshold ±h, h = ``hysteresis`` x the 99th
    percentile of |v| (noise and spikes near v = 0 do not split a half-cycle); the boundary is put
    at the last sign change of v before that crossing. The first and last runs are usually
    incomplete (cut by the record).
    """
    v = np.asarray(velocity_m_s, dtype=float)
    if v.size == 0:
        return []
    h = hysteresis * float(np.percentile(np.abs(v), 99))
    if h == 0.0:
        return []
    decided = np.flatnonzero(np.abs(v) > h)
    if decided.size == 0:
        return []
    bounds, signs = hysteresis_crossings(v, h)
    edges = [0, *bounds.tolist(), v.size]
    run_signs = [float(np.sign(v[decided[0]])), *signs.tolist()]
    return [(int(a), int(b), s) for a, b, s in zip(edges[:-1], edges[1:], run_signs, strict=True) if b > a]


def _vertex(t: np.ndarray, y: np.ndarray, i: int, half: int) -> tuple[float, float]:
    """Extreme near sample i refined by a least-squares parabola over i ± half samples.

    Falls back to the sample (t[i], y[i]) when the vertex lies outside the fitted span or the
    parabola has the wrong curvature.
    """
    lo, hi = max(0, i - half), min(t.size, i + half + 1)
    if hi - lo < 3:
        return float(t[i]), float(y[i])
    tc = t[lo:hi] - t[i]
    c2, c1, c0 = np.polyfit(tc, y[lo:hi], 2)
    if c2 == 0.0:
        return float(t[i]), float(y[i])
    tv = -c1 / (2.0 * c2)
    s = np.sign(y[i] - np.mean(y[lo:hi])) or 1.0
    if not (tc[0] <= tv <= tc[-1]) or np.sign(c2) == s:
        return float(t[i]), float(y[i])
    return float(t[i] + tv), float(c0 - c1 * c1 / (4.0 * c2))


def _at(t: np.ndarray, y: np.ndarray, t0: float, half: int) -> float:
    """y at time t0 from a least-squares parabola over the samples around t0 (± half samples)."""
    i = int(np.clip(np.searchsorted(t, t0), 0, t.size - 1))
    lo, hi = max(0, i - half), min(t.size, i + half + 1)
    if hi - lo < 3:
        return float(np.interp(t0, t, y))
    c = np.polyfit(t[lo:hi] - t0, y[lo:hi], 2)
    return float(c[-1])


def peak_to_peak(lp: pd.DataFrame, frequency_Hz: float | None = None) -> pd.DataFrame:
    """The peak-to-peak points of a sine loop (paper Fig. 13): one row per direction '+', '-'.

    For each complete half-cycle of velocity sign s (:func:`half_cycles`; the loop, whole periods
    in steady state, is treated as periodic so that every half-cycle counts once): the velocity
    extreme max(s v) and the force extreme max(s F) searched in [t_v - T/4, t_v + 3T/8] (the force
    lags by less than a quarter period for a passive damper), both refined by a parabola over
    ± T/20. The row holds the means over the half-cycles: velocity_m_s, force_N (signed), their
    standard deviations, n_points (half-cycles), lag_s = mean(t_F - t_v) (> 0: force after
    velocity) and phase_lag_rad = 2 pi f lag_s. The two extremes are *not* simultaneous: the point
    is not on the loop.
    """
    cols = ["direction", "velocity_m_s", "force_N", "velocity_std_m_s", "force_std_N", "n_points",
            "lag_s", "phase_lag_rad"]
    if lp.empty:
        return pd.DataFrame(columns=cols)
    t = lp["time_s"].to_numpy(dtype=float)
    v = lp["velocity_m_s"].to_numpy(dtype=float)
    f = lp["force_N"].to_numpy(dtype=float)
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    if frequency_Hz is None or not math.isfinite(frequency_Hz) or frequency_Hz <= 0:
        frequency_Hz = lp.attrs.get("frequency_Hz")
    if frequency_Hz is None:
        n_per = max(1, lp["period"].nunique()) if "period" in lp else 1
        frequency_Hz = n_per / (t[-1] - t[0] + dt)
    period = 1.0 / float(frequency_Hz)
    span = n * dt                                             # whole periods: the loop repeats after span
    t3 = np.concatenate([t - span, t, t + span])
    v3, f3 = np.tile(v, 3), np.tile(f, 3)
    half = max(1, int(round(period / 20.0 / dt)))
    rows = []
    found: dict[float, list[tuple[float, float, float, float]]] = {1.0: [], -1.0: []}
    for a, b, s in half_cycles(v3):
        if a == 0 or b == v3.size:
            continue
        i_v = a + int(np.argmax(s * v3[a:b]))
        if not (n <= i_v < 2 * n):
            continue
        tv, vv = _vertex(t3, s * v3, i_v, half)
        lo = int(np.searchsorted(t3, tv - period / 4.0))
        hi = int(np.searchsorted(t3, tv + 3.0 * period / 8.0))
        if hi <= lo:
            continue
        i_f = lo + int(np.argmax(s * f3[lo:hi]))
        tf, ff = _vertex(t3, s * f3, i_f, half)
        found[s].append((s * vv, s * ff, tv, tf))
    for s, label in ((1.0, "+"), (-1.0, "-")):
        pts = np.array(found[s], dtype=float).reshape(-1, 4)
        if not len(pts):
            continue
        lag = float(np.mean(pts[:, 3] - pts[:, 2]))
        rows.append({"direction": label, "velocity_m_s": float(pts[:, 0].mean()), "force_N": float(pts[:, 1].mean()),
                     "velocity_std_m_s": float(pts[:, 0].std()), "force_std_N": float(pts[:, 1].std()),
                     "n_points": int(len(pts)), "lag_s": lag, "phase_lag_rad": 2.0 * math.pi * lag / period})
    return pd.DataFrame(rows, columns=cols)


def peak_velocity_characteristic(lp: pd.DataFrame) -> pd.DataFrame:
    """The force at each velocity peak: one point per complete half-cycle (free records).

    Half-cycles from the sign changes of the velocity (:func:`half_cycles`, with hysteresis); the
    first and last runs, cut by the record, are dropped. The peak is refined by a parabola over
    ± 1/10 of the half-cycle's samples (at least ± 2); the force is the value at the peak time of a
    parabola fitted over the same samples (averaging the force noise).
    Columns: direction, velocity_m_s, force_N, time_s, half_cycle (0-based, record order).
    """
    cols = ["direction", "velocity_m_s", "force_N", "time_s", "half_cycle"]
    t = lp["time_s"].to_numpy(dtype=float)
    v = lp["velocity_m_s"].to_numpy(dtype=float)
    f = lp["force_N"].to_numpy(dtype=float)
    rows = []
    runs = half_cycles(v)
    for k, (a, b, s) in enumerate(runs):
        if k == 0 or k == len(runs) - 1:
            continue
        half = max(2, (b - a) // 10)
        i_v = a + int(np.argmax(s * v[a:b]))
        tv, vv = _vertex(t, s * v, i_v, half)
        rows.append({"direction": "+" if s > 0 else "-", "velocity_m_s": s * vv, "force_N": _at(t, f, tv, half),
                     "time_s": tv, "half_cycle": k})
    out = pd.DataFrame(rows, columns=cols)
    return out.astype({"half_cycle": "int64"}) if len(out) else out


def binned_characteristic(lp: pd.DataFrame, n_bins: int = N_BINS, min_samples: int | None = None,
                          min_speed_m_s: float | None = None) -> pd.DataFrame:
    """The mean force in velocity bins, per direction (free records).

    Per direction s, the samples with s v at least ``min_speed_m_s`` (default ``RESOLVE_SIGMA`` times the
    velocity estimate's noise, ``lp.attrs['velocity_noise_m_s']``, 0 when absent: below it the sign of v is not
    resolved, and a bin there averages a friction force with its reversal) and up to the 99.5th percentile of
    s v (a few outliers, e.g. backlash spikes, do not stretch the bins) go into ``n_bins`` equal bins of |v|
    from that lowest speed. A point is the mean velocity and mean force of its bin (the mean velocity, not the
    bin centre, so the binning adds no bias where F(v) is curved); bins with fewer than ``min_samples`` samples
    (default: a quarter of an even share, at least 5) are dropped. Averaging many samples per bin makes the
    curve robust to the noise of the derivative; loading and unloading branches of a hysteretic loop are
    averaged together.
    Columns: direction, velocity_m_s, force_N, velocity_std_m_s, force_std_N, n_points,
    bin_low_m_s, bin_high_m_s (signed bin edges, |low| < |high|).
    """
    cols = ["direction", "velocity_m_s", "force_N", "velocity_std_m_s", "force_std_N", "n_points",
            "bin_low_m_s", "bin_high_m_s"]
    if n_bins < 1:
        raise ValueError(f"n_bins must be >= 1, got {n_bins}")
    if min_speed_m_s is None:
        min_speed_m_s = RESOLVE_SIGMA * float(lp.attrs.get("velocity_noise_m_s", 0.0))
    v = lp["velocity_m_s"].to_numpy(dtype=float)
    f = lp["force_N"].to_numpy(dtype=float)
    rows = []
    for s, label in ((1.0, "+"), (-1.0, "-")):
        sel = s * v > max(0.0, min_speed_m_s)
        if not sel.any():
            continue
        av, fv = s * v[sel], f[sel]
        top = float(np.percentile(av, 99.5))
        inside = av <= top
        av, fv = av[inside], fv[inside]
        need = max(5, int(math.ceil(0.25 * av.size / n_bins))) if min_samples is None else int(min_samples)
        edges = np.linspace(max(0.0, min_speed_m_s), top, n_bins + 1)
        k = np.clip(np.searchsorted(edges, av, side="right") - 1, 0, n_bins - 1)
        for j in range(n_bins):
            m = k == j
            if m.sum() < need:
                continue
            rows.append({"direction": label, "velocity_m_s": s * float(av[m].mean()), "force_N": float(fv[m].mean()),
                         "velocity_std_m_s": float(av[m].std()), "force_std_N": float(fv[m].std()),
                         "n_points": int(m.sum()), "bin_low_m_s": s * float(edges[j]),
                         "bin_high_m_s": s * float(edges[j + 1])})
    return pd.DataFrame(rows, columns=cols)
