"""Structure in the verdict's residuals along every axis the observations carry (issue 35, part 2).

The verdict explains the gap when its χ² is consistent with noise; a χ² spreads its power over every
observation, so an effect outside the catalogue that a catalogue effect absorbs on average can pass it
and still leave its residuals ordered along an axis the fit never looked at: piston position, campaign
time, temperature, frequency, acceleration, the phase of the cycle, the direction. This module tests the
verdict's residuals for such order, after the fit, with stated tests:

Residuals. z = sign(v)·(F_meas - F_verdict)/σ per observation (positive: the damper is stronger than the
verdict). Observations are pooled into *units* that share what correlates them (a case for a case-level
axis; a case's direction for the direction; a case's direction and phase slot for the phase axis) as
U = Σz/√n, N(0, 1) per unit when the z are independent standard normal.

Tests of one axis (:func:`axis_test`), on the units ordered by the axis' value x:
- *binned means* (:func:`binned_test`): the units in at most MAX_BINS bins of equal count along x (ties
  never split), the between-bin sum of squares of U about the grand mean over its degrees of freedom,
  divided by the within-bin mean square floored at 1 (the stated standard errors are never made smaller;
  a larger scatter between units, as between-case errors leave, is not taken for structure), referred to
  χ²_{B-1}/(B - 1) where the floor binds, else to F(B - 1, N - B) (the two sums are independent: at most
  alpha either way);
- *trend* (:func:`trend_test`): the least-squares slope of U on the rank of x, its t statistic with the
  residual mean square floored at 1, referred to the normal where the floor binds, else to Student's
  t (N - 2), two-sided.
- on a case-level axis (CASE_AXES) also the *trend of the relative residuals* (:func:`unit_relative`): each
  case's mean relative residual over √(its SE² + τ²), τ² the scatter between cases beyond a trend
  (DerSimonian and Laird's estimate in a meta-regression), tested as the trend above but always against
  Student's t (τ² is estimated: Knapp and Hartung's reference): a case's own errors and
  an effect that changes the force by a share weigh every case alike, where U weighs them by their force.
The axis' p-value is the smallest of its tests' times their number (Bonferroni); the p-values of all the
tests made (with the position within the windows, below) are adjusted by Holm's step-down procedure
(:func:`holm`), so the family-wise false-alarm rate over them is at most alpha. The grand mean is taken
off (the verdict's load-cell offset and gain leave none to find); what the verdict's fit removes along an axis
(a speed dependence, a lag's transient shape) makes the residuals along it smaller, so the tests are conservative
there.

Axes (vocabulary agreed in issue 35): ``position`` (the case's stroke amplitude: a triangle's window spans
-0.1 to 0.9 of it in the direction of motion, a sine's bins all of it, so a position-dependent force moves
the windows' means with the amplitude), ``time`` (campaign time, bins in run order),
``temperature`` (the case's logged temperature), ``frequency`` (a sine's frequency, a triangle's 1/period),
``acceleration`` (a sine's peak acceleration (2πf)²Y), ``phase`` (of the half cycle from the reversal,
[0, π): a triangle's transient bins against its window, a sine's phase bins) and ``direction``. An axis
with fewer than two distinct values, or too few units, is not tested (``structure.skipped`` says why).

Within the windows. The piston's position inside each triangle window (its WINDOW_PARTS parts,
:attr:`isokinetic.diagnosis.observations.Observations.subwindows`) is an axis of its own (:func:`within_window_test`,
axis ``position``, in the Holm family like the others): a groove or a worn band at mid-stroke, a gas spring, change
the force *within* each window as the piston passes, where the windows' means hide it. The parts of a window share
the coloured noise, so they are weighed by their covariance under the pooled noise model (generalised least
squares, :func:`part_covariance`), and each window's own level, a shape common to all windows of a direction and
each case's own scale of the verdict's shape inside its windows (a transient tail the verdict places imperfectly
at slow speeds) are taken out before the position is looked at.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.diagnosis.observations import Observations
from isokinetic.physics.sine_drive import SineDrive

#: The axes tested, in the order they are reported (issue 35's vocabulary; "speed" is the gap bands').
AXES = ("position", "time", "temperature", "frequency", "acceleration", "phase", "direction")
#: The axes whose units are cases (:func:`axis_data`): their trend is also tested in relative terms
#: (:func:`unit_relative`).
CASE_AXES = ("position", "time", "temperature", "frequency", "acceleration")
#: The damper parameters whose drift over the campaign's time is tested (:func:`drift_test`), and what a drift of
#: each is on a real damper.
DRIFT_PARAMETERS = {"orifice_area": "the orifice's flow area A_O (an orifice wearing: c1 and c2 of Eq. 7 both as "
                                    "1/A_O²)",
                    "viscosity_Pa_s": "the oil's viscosity (its temperature: an unlogged warm-up)"}
#: Relative step of a parameter for its sensitivity (:func:`drift_sensitivities`).
DRIFT_STEP_REL = 0.01
#: How ``structure_note`` names a test that is not its axis' own.
TEST_NAMES = {"within_window": " (within the windows)", "drift": " (a drift of {parameter})"}
#: Unit of each axis' range in a ``where`` entry.
AXIS_UNITS = {"position": "m", "time": "s", "temperature": "degC", "frequency": "Hz", "acceleration": "m/s2",
              "phase": "rad", "direction": ""}
#: What each test's value is.
QUANTITIES = {"position": "stroke amplitude of the case (a triangle's window spans -0.1 to 0.9 of it)",
              "position_within": "piston position within the triangle windows (each window's level, a shape common "
                                 "to its direction and its case's scale of the verdict's shape off)",
              "time": "campaign time of the case's windows (bins in run order)",
              "temperature": "logged temperature of the case", "frequency": "sine frequency, or 1/period",
              "acceleration": "peak acceleration of a sine, (2πf)²Y",
              "phase": "phase of the half cycle from the last reversal (transient bins against windows)",
              "direction": "direction of motion (+1 / -1)"}
#: Most bins of a binned-means test (the phase axis takes one bin per distinct slot up to PHASE_BINS).
MAX_BINS = 5
PHASE_BINS = 8
#: Phases [rad] closer than this are one slot (the same bin of different cases and cycles).
PHASE_TOLERANCE_RAD = 0.05
#: Bins of the piston's position (signed) in the within-window test (:func:`within_window_test`,
#: :func:`position_bins`): the edges of half as many bins of equal counts and of half as many of equal widths
#: together; at most 11 bins, about 0.4 mm wide at the reference rig's largest strokes (±2.4 mm of window) and finer
#: near mid-stroke, finer than the groove or worn band a bore has there.
WITHIN_BINS = 12
#: |z| of a bin's mean beyond which it is named in ``where`` besides the strongest one.
Z_BIN = 3.0
STRUCTURE_NOTE = ("the verdict's residuals are ordered along {axes} beyond noise (Holm-adjusted p {p}): an effect "
                  "the catalogue lacks, or one the verdict does not reproduce, lies there; the verdict is not "
                  "an explanation")


@dataclass(frozen=True)
class AxisData:
    """One test's units: each observation used (``rows``), its unit label and the unit's axis value."""

    axis: str
    rows: np.ndarray     # indices of the observations used
    unit: np.ndarray     # unit label per used observation (int)
    x: np.ndarray        # axis value per used observation (equal within a unit)
    categorical: bool = False   # binned by distinct value only, no trend (direction)


def unit_sums(unit: np.ndarray, z: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(U, x, n) per unit: U = Σz/√n over the unit's observations (N(0, 1) for independent standard normal z),
    its axis value (the mean of its observations') and its number of observations."""
    labels, inverse = np.unique(unit, return_inverse=True)
    n = np.bincount(inverse, minlength=labels.size).astype(float)
    u = np.bincount(inverse, weights=z, minlength=labels.size) / np.sqrt(n)
    xs = np.bincount(inverse, weights=x, minlength=labels.size) / n
    return u, xs, n


def unit_relative(unit: np.ndarray, rel: np.ndarray, s_rel: np.ndarray, x: np.ndarray) -> np.ndarray:
    """u per unit of a case-level axis in relative terms: R = the mean relative residual of the unit's observations
    (``rel``, standard errors ``s_rel``), SE = √(Σ s²)/n, u = R/√(SE² + τ²), τ² the relative scatter between units
    beyond their errors and beyond a trend along the rank of x (:func:`between_unit_variance`). A case's own error
    (a speed or gain error) and an effect that changes the force by a share (an orifice's wear) are relative: the
    units are then weighed alike, where U (:func:`unit_sums`) weighs them by their force (a random-effects
    meta-regression's weights)."""
    labels, inverse = np.unique(unit, return_inverse=True)
    n = np.bincount(inverse, minlength=labels.size).astype(float)
    mean = np.bincount(inverse, weights=rel, minlength=labels.size) / n
    se2 = np.bincount(inverse, weights=s_rel**2, minlength=labels.size) / n**2
    xs = np.bincount(inverse, weights=x, minlength=labels.size) / n
    rank = pd.Series(xs).rank().to_numpy(dtype=float)
    return mean / np.sqrt(se2 + between_unit_variance(mean, se2, rank))


def between_unit_variance(mean: np.ndarray, se2: np.ndarray, covariate: np.ndarray) -> float:
    """DerSimonian and Laird's moment estimate of the variance τ² between units beyond their own (``se2``) and
    beyond a weighted least-squares line in ``covariate`` (meta-regression): max(0, (Q_E - (k - p))/tr P),
    Q_E = Σ w e², w = 1/SE², P = W - W X (Xᵀ W X)⁻¹ Xᵀ W, X = [1, covariate] (p its rank)."""
    design = np.column_stack([np.ones_like(mean), covariate - covariate.mean()])
    w = 1.0 / se2
    xtwx = design.T @ (w[:, None] * design)
    p = np.linalg.matrix_rank(xtwx)
    if mean.size <= p:
        return 0.0
    inv = np.linalg.pinv(xtwx)
    resid = mean - design @ (inv @ (design.T @ (w * mean)))
    q = float(np.sum(w * resid**2))
    trace = float(np.sum(w) - np.trace(inv @ (design.T @ ((w**2)[:, None] * design))))
    return max(0.0, (q - (mean.size - p)) / trace) if trace > 0.0 else 0.0


def tie_bins(x: np.ndarray, max_bins: int) -> np.ndarray:
    """Bin label (0 ..) of each value: at most ``max_bins`` bins of about equal counts in the order of x,
    equal values always in one bin."""
    values, inverse, counts = np.unique(x, return_inverse=True, return_counts=True)
    if values.size <= max_bins:
        return inverse
    before = np.concatenate([[0], np.cumsum(counts)[:-1]]) + 0.5 * counts   # each value's middle rank
    value_bin = np.minimum((before / x.size * max_bins).astype(int), max_bins - 1)
    _, dense = np.unique(value_bin, return_inverse=True)
    return dense[inverse]


def width_bins(x: np.ndarray, n_bins: int) -> np.ndarray:
    """Bin label (0 ..) of each value: ``n_bins`` bins of equal width over [min x, max x], the empty ones dropped
    (labels dense, in the order of x). Equal values share a bin."""
    lo, span = float(np.min(x)), float(np.ptp(x))
    if span <= 0.0:
        return np.zeros(x.size, dtype=int)
    raw = np.minimum(((x - lo) / span * n_bins).astype(int), n_bins - 1)
    return np.unique(raw, return_inverse=True)[1].reshape(x.shape)


def position_bins(x: np.ndarray, n_bins: int) -> np.ndarray:
    """Bin label (0 .., dense, in the order of x) of each piston position: the bins between the edges of
    ``n_bins // 2`` bins of equal counts (:func:`tie_bins`) and of ``n_bins // 2`` of equal widths
    (:func:`width_bins`) together. Equal counts resolve mid-stroke, where every stroke puts parts; equal widths
    resolve the outer stroke, which only the largest strokes reach with a few parts (bins of equal counts give those
    one bin, which a feature at a fixed position, a groove's edge, straddles)."""
    half = max(1, n_bins // 2)
    pair = tie_bins(x, half) * (half + 1) + width_bins(x, half)
    return np.unique(pair, return_inverse=True)[1].reshape(x.shape)


def binned_test(u: np.ndarray, labels: np.ndarray) -> dict:
    """Binned-means test of the unit residuals ``u`` (N(0, 1) under no structure) across bins ``labels``:
    F = [Σ_b m_b (ū_b - ū)²/(B - 1)] / s², s² = max(1, Σ (u - ū_b)²/(N - B)); p from χ²_{B-1}/(B-1) where the
    floor binds (the stated errors hold: the between-bin sum is χ²_{B-1} whatever the within-bin one, independent
    of it), else from F(B - 1, N - B) (conditional on a within-bin scatter above 1, conservative). Also each
    bin's z = (ū_b - ū)·√(m_b/s²)."""
    from scipy import special

    bins, inverse = np.unique(labels, return_inverse=True)
    m = np.bincount(inverse).astype(float)
    means = np.bincount(inverse, weights=u) / m
    grand = float(u.mean())
    b, n = bins.size, u.size
    between = float(np.sum(m * (means - grand) ** 2))
    within = float(np.sum((u - means[inverse]) ** 2))
    scale = max(1.0, within / (n - b)) if n > b else 1.0
    stat = between / (b - 1) / scale
    p = float(special.fdtrc(b - 1, n - b, stat)) if scale > 1.0 else float(special.chdtrc(b - 1, stat * (b - 1)))
    return {"F": stat, "df": [int(b - 1), int(n - b)], "p": p, "scale": scale,
            "bin_z": (means - grand) * np.sqrt(m / scale), "bin_of_unit": inverse}


def trend_test(u: np.ndarray, x: np.ndarray, student: bool = False) -> dict:
    """Trend of the unit residuals ``u`` along the rank of ``x`` (ties share their mean rank): the least-squares
    slope over its standard error, residual mean square s² floored at 1; p two-sided from the normal where the
    floor binds, else (or always, ``student``: units scaled by an estimated variance) from Student's t (N - 2)."""
    from scipy import special

    r = pd.Series(x).rank().to_numpy(dtype=float)
    rc = r - r.mean()
    sxx = float(rc @ rc)
    if u.size < 3 or sxx <= 0.0:
        return {"t": 0.0, "df": 0, "p": 1.0}
    slope = float(rc @ (u - u.mean())) / sxx
    resid = u - u.mean() - slope * rc
    scale = max(1.0, float(resid @ resid) / (u.size - 2))
    t = slope / math.sqrt(scale / sxx)
    p = special.stdtr(u.size - 2, -abs(t)) if scale > 1.0 or student else special.ndtr(-abs(t))
    return {"t": t, "df": int(u.size - 2), "p": float(2.0 * p)}


def holm(p: Sequence[float]) -> np.ndarray:
    """Holm's step-down adjusted p-values: the k-th smallest of m times (m - k + 1), made monotone, at most 1.
    Rejecting where the adjusted p < alpha keeps the family-wise error rate at most alpha."""
    p = np.asarray(p, dtype=float)
    order = np.argsort(p)
    m = p.size
    adjusted = np.maximum.accumulate((m - np.arange(m)) * p[order])
    out = np.empty(m)
    out[order] = np.minimum(adjusted, 1.0)
    return out


def axis_test(data: AxisData, z: np.ndarray, rel: np.ndarray | None = None,
              s_rel: np.ndarray | None = None) -> dict | None:
    """The test of one axis on the signed residuals ``z`` of all observations: binned means (and, unless
    categorical, the rank trend), p = min(1, 2·min(p_bins, p_trend)); a case-level axis (CASE_AXES) with the
    relative residuals ``rel`` and their errors ``s_rel`` has a second trend, on the relative units
    (:func:`unit_relative`), and p = min(1, 3·min(p_bins, p_trend, p_trend_rel)). None where the axis cannot be
    tested (fewer than two bins, or no unit left for the within-bin scatter and the trend)."""
    u, x, _n = unit_sums(data.unit, z[data.rows], data.x)
    labels = tie_bins(x, len(np.unique(x)) if data.categorical else
                      PHASE_BINS if data.axis == "phase" else MAX_BINS)
    if np.unique(labels).size < 2 or u.size < np.unique(labels).size + 2:
        return None
    bins = binned_test(u, labels)
    trend = None if data.categorical else trend_test(u, x)
    relative = (trend_test(unit_relative(data.unit, rel[data.rows], s_rel[data.rows], data.x), x, student=True)
                if data.axis in CASE_AXES and rel is not None else None)
    ps = [bins["p"]] + [t["p"] for t in (trend, relative) if t is not None]
    p = min(1.0, len(ps) * min(ps))
    return {"axis": data.axis, "quantity": QUANTITIES[data.axis], "unit": AXIS_UNITS[data.axis],
            "n_units": int(u.size), "n_bins": int(np.unique(labels).size), "bins_F": bins["F"],
            "bins_df": bins["df"], "bins_p": bins["p"], "scale": bins["scale"],
            "trend_t": None if trend is None else trend["t"], "trend_p": None if trend is None else trend["p"],
            **({} if relative is None else {"trend_rel_t": relative["t"], "trend_rel_p": relative["p"]}),
            "p": p, "_x": x, "_bins": bins}


def where_entries(test: Mapping, data: AxisData, rel: np.ndarray) -> list[dict]:
    """The ``where`` entries of a significant axis: its strongest bin, and every other bin with |z| > Z_BIN,
    each with the range of the axis' value, the mean signed relative residual of its observations, its z and
    the axis' Holm-adjusted p-value."""
    bins = test["_bins"]
    x = test["_x"]
    labels, inverse = np.unique(data.unit, return_inverse=True)
    unit_bin = bins["bin_of_unit"][inverse]            # bin of each used observation
    bin_z = bins["bin_z"]
    strongest = int(np.argmax(np.abs(bin_z)))
    out = []
    for b in sorted({strongest, *np.flatnonzero(np.abs(bin_z) > Z_BIN).tolist()}):
        xb = x[bins["bin_of_unit"] == b]
        entry = {"axis": test["axis"], "quantity": test["quantity"], "range": [float(xb.min()), float(xb.max())],
                 "unit": test["unit"],
                 "mean_rel": float(np.mean(rel[data.rows][unit_bin == b])),
                 "z": float(bin_z[b]), "p_adjusted": test["p_adjusted"], "significant": True,
                 "n_units": int(xb.size)}
        if test["axis"] == "direction":
            entry["direction"] = "+" if xb[0] > 0 else "-"
        out.append(entry)
    return out


def plan_time_s(obs: Observations) -> np.ndarray:
    """Each observation's middle in its case's plan time [s] (its model samples' middle)."""
    offsets = []
    for drive in (obs.drives or (None,) * len(obs.plans)):
        offsets.append(drive.grid_start_s if isinstance(drive, SineDrive)
                       else getattr(drive, "grid_offset_s", 0.0) if drive is not None else 0.0)
    fs = np.array([p.sample_rate_Hz for p in obs.plans])[obs.case_index]
    return np.asarray(offsets, dtype=float)[obs.case_index] + 0.5 * (obs.start + obs.stop - 1) / fs


def half_cycle_phase(obs: Observations) -> np.ndarray:
    """Each observation's phase within its half cycle from the last reversal, in [0, π) [rad]: a triangle's
    π·(τ mod T/2)/(T/2), a sine's (2πfτ + π/2) mod π (y = Y sin 2πfτ reverses at 2πfτ = ±π/2)."""
    tau = plan_time_s(obs)
    out = np.empty(len(obs))
    for i, plan in enumerate(obs.plans):
        at = obs.case_index == i
        if plan.waveform == "sine":
            out[at] = np.mod(2.0 * math.pi * plan.frequency_Hz * tau[at] + 0.5 * math.pi, math.pi)
        else:
            half = 0.5 * plan.period_s
            out[at] = math.pi * np.mod(tau[at], half) / half
    return out


def phase_slots(phase: np.ndarray, tolerance: float = PHASE_TOLERANCE_RAD) -> np.ndarray:
    """Each phase replaced by its slot's median: sorted phases split where they are more than ``tolerance``
    apart (the same bin of different cases and cycles lies within a few samples)."""
    order = np.argsort(phase)
    cluster = np.concatenate([[0], np.cumsum(np.diff(phase[order]) > tolerance)])
    medians = pd.Series(phase[order]).groupby(cluster).transform("median").to_numpy()
    out = np.empty_like(phase)
    out[order] = medians
    return out


def case_values(obs: Observations, time_s: np.ndarray | None,
                temperature_C: Mapping[str, float] | None) -> dict[str, np.ndarray]:
    """Per observation, the value of each case-level axis that it has (NaN where a case lacks it): stroke
    amplitude, campaign time, temperature, frequency, a sine's peak acceleration."""
    amp = np.array([p.amplitude_m for p in obs.plans])[obs.case_index]
    sine = np.array([p.waveform == "sine" for p in obs.plans])[obs.case_index]
    freq = np.array([p.frequency_Hz if p.waveform == "sine" else 1.0 / p.period_s for p in obs.plans])[obs.case_index]
    temps = temperature_C or {}
    out = {"position": amp, "frequency": freq,
           "acceleration": np.where(sine, (2.0 * math.pi * freq) ** 2 * amp, np.nan),
           "temperature": np.array([float(temps.get(c, math.nan)) for c in obs.case], dtype=float)}
    if time_s is not None and len(time_s) == len(obs):
        out["time"] = np.asarray(time_s, dtype=float)
    return out


def axis_data(obs: Observations, time_s: np.ndarray | None = None,
              temperature_C: Mapping[str, float] | None = None) -> list[AxisData]:
    """The units of every axis the observations carry: the case-level axes on the steady windows, one unit per
    case (its two directions share the case's own error: they are no two replicates of the axis' value); the
    direction on the steady windows, one unit per case and direction; the phase on every observation, one unit
    per case, direction and slot."""
    win = obs.is_window
    case = pd.factorize(pd.Series(obs.case).astype(str))[0]
    case_dir = pd.factorize(pd.Series(obs.case).astype(str) + np.where(obs.sign > 0, "/+", "/-"))[0]
    values = case_values(obs, time_s, temperature_C)
    out = []
    for axis in AXES:
        if axis == "phase":
            slot = phase_slots(half_cycle_phase(obs))
            unit = pd.factorize(pd.Series(case_dir.astype(str)) + "@" + pd.Series(slot).round(6).astype(str))[0]
            out.append(AxisData(axis, np.arange(len(obs)), unit, slot))
            continue
        x = obs.sign.astype(float) if axis == "direction" else values.get(axis)
        if x is None:
            continue
        rows = np.flatnonzero(win & np.isfinite(x))
        if axis == "direction":
            out.append(AxisData(axis, rows, case_dir[rows], x[rows], categorical=True))
            continue
        if axis == "time" and rows.size:   # a unit's value: its windows' mean time
            x = pd.Series(x[rows]).groupby(case[rows]).transform("mean").to_numpy()
            out.append(AxisData(axis, rows, case[rows], x))
            continue
        out.append(AxisData(axis, rows, case[rows], x[rows]))
    return out


def window_position_m(parts: Observations) -> np.ndarray:
    """The piston's position at the middle of each triangle window part [m]: sign(v)·(2c - 1)·Y, c the part's
    middle as a fraction of its half-period (the triangle starts at -Y moving up)."""
    c = half_cycle_phase(parts) / math.pi
    amp = np.array([p.amplitude_m for p in parts.plans])[parts.case_index]
    return parts.sign * (2.0 * c - 1.0) * amp


def ar1_block_factor(n_i: np.ndarray, n_j: np.ndarray, gap: np.ndarray, a: float) -> np.ndarray:
    """Mean of exp(-a|s - t|) over s in a block of n_i samples and t in one of n_j samples starting ``gap`` >= n_i
    samples after it: ρ^(gap - n_i + 1)·G(n_i)·G(n_j)/(n_i n_j), ρ = e^-a, G(n) = (1 - ρ^n)/(1 - ρ) (the sums of the
    two geometric series); the covariance of two block means of unit-variance AR(1) noise (a = 1/(fs τ_c)). A gap
    shorter than n_i (a block with itself) is not such a pair: its value is then meaningless but finite."""
    om = -math.expm1(-a)
    g = lambda n: -np.expm1(-a * n) / om   # noqa: E731
    return np.exp(-a * np.maximum(gap - n_i + 1.0, 0.0)) * g(n_i) * g(n_j) / (n_i * n_j)


def part_covariance(parts: Observations, models: Mapping | None) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per window: (its parts' rows in time order, the covariance of their means [N²]) under the pooled noise model
    of their sample rate (:class:`isokinetic.measurement.noise.NoiseModel`): the white part (s_w² + s_q² F²)/n on
    the diagonal, the coloured part (s_a² + s_r² |F_i F_j|)·c_ij with c_ij the AR(1) factor of the two blocks
    (:func:`isokinetic.measurement.noise.ar1_mean_factor` on the diagonal, :func:`ar1_block_factor` off it). Where
    no model holds the rate, the parts' own σ² on the diagonal."""
    from isokinetic.measurement.noise import ar1_mean_factor

    window = pd.factorize(pd.Series(parts.case).astype(str) + "/" + pd.Series(parts.segment).astype(str))[0]
    fs = np.array([p.sample_rate_Hz for p in parts.plans])[parts.case_index]
    n = np.maximum(parts.stop - parts.start, 1).astype(float)
    out = []
    for w in range(window.max() + 1):
        rows = np.flatnonzero(window == w)
        rows = rows[np.argsort(parts.start[rows], kind="stable")]
        model = (models or {}).get(float(fs[rows[0]]))
        if model is None:
            out.append((rows, np.diag(parts.sigma_N[rows] ** 2)))
            continue
        a = 1.0 / (model.fs_Hz * model.tau_c_s)
        m, s, f = n[rows], parts.start[rows].astype(float), np.abs(parts.force_N[rows])
        lo, hi = np.minimum.outer(np.arange(rows.size), np.arange(rows.size)), np.maximum.outer(
            np.arange(rows.size), np.arange(rows.size))
        c = ar1_block_factor(m[lo], m[hi], s[hi] - s[lo], a)
        c[np.diag_indices(rows.size)] = ar1_mean_factor(m, a)
        cov = (model.coloured_var_N2 + model.coloured_rel_var * np.outer(f, f)) * c
        out.append((rows, cov + np.diag(model.white_variance_N2(f * f) / m)))
    return out


def within_window_design(parts: Observations, prediction: np.ndarray, n_bins: int) -> tuple[np.ndarray, ...]:
    """(nuisance columns, position columns, position bin of each part) of :func:`within_window_test`: each window's
    level; per part index and direction a share and a force common to all windows (what a servo's or the oil's
    settling leaves along every window alike); per case and direction the verdict's own force sign(v)·P (its
    within-window shape, a transient tail, scaled freely); and, per bin of the signed position y
    (:func:`position_bins` of ``n_bins``), a share 1{y in bin}·|P| and a force 1{y in bin}."""
    window = pd.factorize(pd.Series(parts.case).astype(str) + "/" + pd.Series(parts.segment).astype(str))[0]
    case_dir = pd.factorize(pd.Series(parts.case).astype(str) + np.where(parts.sign > 0, "/+", "/-"))[0]
    part = pd.Series(parts.start).groupby(window).rank(method="first").to_numpy().astype(int) - 1
    size, sign = np.abs(prediction)[:, None], parts.sign[:, None]
    one_hot = lambda k: (k[:, None] == np.arange(k.max() + 1)[None, :]).astype(float)   # noqa: E731
    shape = one_hot(part)
    nuisance = np.hstack([one_hot(window), shape * size, shape, shape * size * sign, shape * sign,
                          one_hot(case_dir) * (parts.sign * prediction)[:, None]])
    labels = position_bins(window_position_m(parts), n_bins)
    bins = one_hot(labels)
    return nuisance, np.hstack([bins * size, bins]), labels


def within_window_test(parts: Observations | None, prediction: np.ndarray, models: Mapping | None = None,
                       drift_N: np.ndarray | None = None, n_bins: int = WITHIN_BINS) -> dict | None:
    """The test of a force that depends on the piston's position inside the triangle windows.

    Residuals r = sign(v)(F - P - D) of the window parts (P the verdict's model, D its zero drift, ``drift_N``),
    whitened window by window with the Cholesky factor of their covariance (:func:`part_covariance`); the position
    columns (a share f(y) and a force g(y) in ``n_bins`` bins of y, :func:`within_window_design`) beyond the
    nuisance columns: the χ² drop over their added rank, divided by the residual mean square floored at 1, referred
    to F(rank, N - rank of the full design). Each bin's z (``bins``, for ``where``): the signed square root of the
    χ² drop its two columns alone give, over the same mean square. None without parts or with no degree of
    freedom left."""
    if parts is None or len(parts) == 0:
        return None
    from scipy import special

    nuisance, position, labels = within_window_design(parts, prediction, n_bins)
    r = parts.sign * (parts.force_N - prediction - (0.0 if drift_N is None else drift_N))
    y, xn, xp = np.empty_like(r), np.empty_like(nuisance), np.empty_like(position)
    for rows, cov in part_covariance(parts, models):
        chol = np.linalg.cholesky(cov + np.diag(1e-12 * np.diag(cov) + 1e-300))   # a ridge far below the noise
        y[rows], xn[rows], xp[rows] = (np.linalg.solve(chol, m[rows]) for m in (r, nuisance, position))
    k0, (y0, xp0) = off_span(xn, y, xp)                     # the nuisance columns' part taken off
    r1, rank = least_squares_residual(xp0, y0)
    dof = int(len(parts) - k0 - rank)
    if rank < 1 or dof < 1:
        return None
    scale = max(1.0, float(r1 @ r1) / dof)
    stat = (float(y0 @ y0) - float(r1 @ r1)) / rank / scale
    rel = r / np.abs(parts.force_N)
    y_m = window_position_m(parts)
    bins = []
    for b in range(int(labels.max() + 1)):
        rb, _ = least_squares_residual(xp0[:, [b, b + labels.max() + 1]], y0)
        mean_rel = float(np.mean(rel[labels == b]) - np.mean(rel))
        z = math.copysign(math.sqrt(max(float(y0 @ y0) - float(rb @ rb), 0.0) / scale), mean_rel)
        bins.append({"range": [float(y_m[labels == b].min()), float(y_m[labels == b].max())], "z": z,
                     "mean_rel": mean_rel})
    return {"quantity": QUANTITIES["position_within"], "n_parts": int(len(parts)), "n_bins": len(bins),
            "F": stat, "df": [int(rank), dof], "scale": scale, "p": float(special.fdtrc(rank, dof, stat)),
            "decides": True, "bins": bins, "_labels": labels, "_rel": rel}


def within_window_where(test: Mapping) -> list[dict]:
    """The ``where`` entries of a significant within-window test: each run of neighbouring position bins
    (``test['bins']``, in the order of the position) whose |z| exceeds Z_BIN with one sign, and the strongest bin
    (a run of its own if none exceeds it): the range of the piston's position [m], the mean signed relative
    residual of its parts about all parts' mean, the largest |z| of the run (signed) and the Holm-adjusted p."""
    z = np.array([b["z"] for b in test["bins"]])
    keep = np.abs(z) > Z_BIN
    keep[int(np.argmax(np.abs(z)))] = True
    runs, start = [], None
    for b in range(z.size + 1):
        same = b < z.size and keep[b] and start is not None and np.sign(z[b]) == np.sign(z[start])
        if start is not None and not same:
            runs.append((start, b))
            start = None
        if b < z.size and keep[b] and start is None:
            start = b
    labels, rel = test["_labels"], test["_rel"]
    out = []
    for lo, hi in runs:
        at = (labels >= lo) & (labels < hi)
        strongest = lo + int(np.argmax(np.abs(z[lo:hi])))
        out.append({"axis": "position", "quantity": test["quantity"],
                    "range": [test["bins"][lo]["range"][0], test["bins"][hi - 1]["range"][1]], "unit": "m",
                    "mean_rel": float(np.mean(rel[at]) - np.mean(rel)), "z": float(z[strongest]),
                    "p_adjusted": test["p_adjusted"], "significant": True, "n_units": int(at.sum())})
    return out


def within_window_entry(within: Mapping) -> dict:
    """The within-window test as one of the family's ``tests`` (axis ``position``, ``test: within_window``)."""
    return {"axis": "position", "test": "within_window", "quantity": within["quantity"], "unit": "m",
            "n_units": within["n_parts"], "n_bins": within["n_bins"], "bins_F": within["F"], "bins_df": within["df"],
            "bins_p": within["p"], "scale": within["scale"], "trend_t": None, "trend_p": None, "p": within["p"]}


def off_span(design: np.ndarray, *arrays: np.ndarray) -> tuple[int, list[np.ndarray]]:
    """(the rank of ``design``, each array less its projection on the span of its columns: its left singular
    vectors above numpy's rank tolerance)."""
    u, sv, _ = np.linalg.svd(design, full_matrices=False)
    u = u[:, sv > sv.max() * max(design.shape) * np.finfo(float).eps] if sv.size else u[:, :0]
    return u.shape[1], [a - u @ (u.T @ a) for a in arrays]


def least_squares_residual(design: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, int]:
    """(z less its least-squares fit on the columns of ``design``, the design's rank)."""
    beta, _res, rank, _sv = np.linalg.lstsq(design, z, rcond=None)
    return z - design @ beta, int(rank)


def drift_test(obs: Observations, z: np.ndarray, time_s: np.ndarray | None, sensitivity_N: np.ndarray,
               parameter: str, jacobian: np.ndarray | None = None) -> dict | None:
    """The test of a damper parameter θ that drifts over the campaign's time, on the verdict's residuals ``z``
    (sign·(F - F_verdict)/σ of the observations ``obs``, the verdict's fit's), a linear mixed model:

        z = J β + b0 g + b1 (t - t̄) g + Σ_c u_c g_c + ε,   u_c ~ N(0, τ²),  ε ~ N(0, 1),

    g = sign·∂F/∂ln θ/σ (``sensitivity_N`` the derivative [N], :func:`drift_sensitivities`), g_c its part in case
    c, t its case's campaign time (the mean of ``time_s`` over the case: within a case the observations' order
    follows the cycle's phase, where an effect of position or phase lies, not a drift), J the columns of every
    parameter the verdict fitted (its effects, force channel, load-cell terms: ``jacobian``, the derivatives of its
    fit's residuals, in the sign of z). b1 is θ's relative drift per second: what the verdict's constant θ (b0,
    and its parameters: β) cannot follow. u_c is each case's own change of θ (its temperature, its speed, its
    mounting), which takes a case that lies off the line: τ² by restricted maximum likelihood. b1's variance from
    the GLS fit, its factor floored at 1 (the stated errors are never made smaller), t referred to Student's t
    (C - 2), the factor Knapp and Hartung's on the cases' changes left by the fit (as a meta-regression's: a τ²
    from a few cases is often too small). Within each case the observations differ in how they respond to θ and to
    the verdict's parameters (windows and transient bins, both directions), which separates a case's change of θ
    from a refit of the verdict; the scatter of those changes between the cases is what a drift must stand out
    from. None without times or with fewer than four cases."""
    from scipy import optimize, special

    if time_s is None or len(time_s) != len(obs):
        return None
    case = obs.case_index
    g = obs.sign * sensitivity_N / obs.sigma_N
    n_cases = int(case.max()) + 1 if case.size else 0
    info = np.bincount(case, weights=g * g, minlength=n_cases)
    used = info > 0.0
    if np.count_nonzero(used) < 4:
        return None
    t = np.asarray(time_s, dtype=float)
    t = (np.bincount(case, weights=t, minlength=n_cases) / np.maximum(np.bincount(case, minlength=n_cases), 1))[case]
    x = t - t.mean()
    cols = [] if jacobian is None else [obs.sign[:, None] * np.asarray(jacobian, dtype=float)[:len(obs)]]
    others = np.column_stack([*cols, g])   # the verdict's parameters and b0 (a fitted θ spans b0: A⁻¹ is a pinv)
    drift = x * g
    off = drift - others @ np.linalg.lstsq(others, drift, rcond=None)[0]
    if float(off @ off) <= 1e-12 * float(drift @ drift):
        return None   # the drift's column is spanned by the others: not testable
    design = np.column_stack([others, drift])

    def solve(tau2):   # V⁻¹ = I - Σ_c g_c g_cᵀ τ²/(1 + τ² I_c) (Woodbury); (β, A⁻¹, Q, -2 log L_R)
        shrink = (tau2 / (1.0 + tau2 * info))[case] * g

        def v_inv(m):
            proj = np.stack([np.bincount(case, weights=g * m[:, j], minlength=n_cases) for j in range(m.shape[1])], 1)
            return m - shrink[:, None] * proj[case]
        vx, vz = v_inv(design), v_inv(z[:, None])[:, 0]
        a = design.T @ vx
        inv = np.linalg.pinv(a)
        beta = inv @ (design.T @ vz)
        r = z - design @ beta
        q = float(r @ v_inv(r[:, None])[:, 0])
        logdet = float(np.sum(np.log1p(tau2 * info[used])))
        return beta, inv, q, logdet + float(np.linalg.slogdet(a)[1]) + q

    best = optimize.minimize_scalar(lambda s: solve(math.exp(s))[3], bounds=(-30.0, 10.0), method="bounded")
    tau2 = math.exp(best.x) if best.fun < solve(0.0)[3] else 0.0
    beta, inv, _q, _obj = solve(tau2)
    dof = int(np.count_nonzero(used)) - 2
    # Knapp and Hartung's factor on the cases: each one's change of θ left by the fit, δ_c = Σ g r/Σ g², against its
    # variance 1/Σ g² + τ², floored at 1
    resid = np.bincount(case, weights=g * (z - design @ beta), minlength=n_cases)[used] / info[used]
    factor = max(1.0, float(np.sum(resid**2 / (1.0 / info[used] + tau2))) / dof)
    t_stat = float(beta[-1] / math.sqrt(factor * inv[-1, -1]))
    p = 2.0 * float(special.stdtr(dof, -abs(t_stat)))
    return {"axis": "time", "test": "drift", "parameter": parameter,
            "quantity": f"a drift over campaign time of {DRIFT_PARAMETERS[parameter]}", "unit": "s",
            "n_units": int(np.count_nonzero(used)), "n_bins": 0, "bins_F": None, "bins_p": None, "scale": factor,
            "between_cases_rel": math.sqrt(tau2), "trend_t": t_stat, "trend_p": p, "p": p,
            "change_rel": float(beta[-1] * np.ptp(t)), "range": [float(t.min()), float(t.max())]}


def drift_where(test: Mapping) -> list[dict]:
    """The ``where`` entry of a significant drift test: the campaign's time span, ``mean_rel`` the parameter's
    fitted relative change from the first case to the last, z its t."""
    return [{"axis": "time", "quantity": test["quantity"], "range": test["range"], "unit": "s",
             "mean_rel": test["change_rel"], "z": test["trend_t"], "p_adjusted": test["p_adjusted"],
             "significant": True, "n_units": test["n_units"], "parameter": test["parameter"]}]


def drifted(params: Mapping, damper, parameter: str, factor: float) -> dict:
    """The verdict's effect values ``params`` with the damper parameter of DRIFT_PARAMETERS scaled by ``factor``
    (each value the verdict's, else the damper's): the viscosity μ, or the orifice's area A_O, which Eq. (7) holds as
    c1 = 8πμl_O/A_O² and c2 = ρ/(2C_D²A_O²), the same as μ/k² and C_D·k for an area k·A_O."""
    def value(key):
        return float(params.get(key) or getattr(damper, key))
    if parameter == "orifice_area":
        return {**params, "discharge_coefficient": value("discharge_coefficient") * factor,
                "viscosity_Pa_s": value("viscosity_Pa_s") / factor**2}
    return {**params, parameter: value(parameter) * factor}


def drift_sensitivities(obs: Observations, damper, best) -> dict[str, np.ndarray]:
    """∂F/∂ln θ [N] of the verdict ``best``'s measured force at each observation, for each parameter θ of
    DRIFT_PARAMETERS (:func:`drifted`), by a forward difference of DRIFT_STEP_REL through the verdict's force
    channel and gain. One model run per parameter and one at the verdict."""
    from isokinetic.diagnosis.model import Evaluator
    from isokinetic.physics.damper import Effects

    ev = Evaluator(obs, damper)
    params = {k: v for k, v in best.params.items() if k != "coulomb_force_N"}

    def run(effects):
        return ev.predict(effects) if best.channel is None else ev.read(effects, best.channel[0], [best.channel[1]])[0]

    base = run(Effects(**params))
    return {key: best.gain * (run(Effects(**drifted(params, damper, key, 1.0 + DRIFT_STEP_REL))) - base)
            / math.log1p(DRIFT_STEP_REL) for key in DRIFT_PARAMETERS}


def residual_structure(obs: Observations, prediction: np.ndarray, alpha: float, time_s: np.ndarray | None = None,
                       temperature_C: Mapping[str, float] | None = None,
                       parts_prediction: np.ndarray | None = None, parts_drift_N: np.ndarray | None = None,
                       drift_sensitivity_N: Mapping[str, np.ndarray] | None = None,
                       drift_jacobian: np.ndarray | None = None, fit_mask: np.ndarray | None = None) -> dict:
    """The structure tests of the residuals of ``prediction`` (the verdict's measured prediction) on every axis
    (:func:`axis_data`, :func:`axis_test`) and, with ``parts_prediction`` (the verdict's model at the windows' parts
    ``obs.subwindows``; ``parts_drift_N``, its zero drift there), of the position within the windows
    (:func:`within_window_test`, its details also as "within_window") and, with ``drift_sensitivity_N``
    (:func:`drift_sensitivities`), of each parameter's drift over campaign time (:func:`drift_test`, on the
    observations of the verdict's fit, ``fit_mask``, beside the columns of its parameters, ``drift_jacobian``),
    Holm-adjusted together (:func:`holm`):
    {"alpha", "tests": per test made, "skipped": axis -> why, "where": entries of the significant tests, "axes":
    the axes with structure}."""
    z = obs.sign * (obs.force_N - prediction) / obs.sigma_N
    rel = obs.sign * (obs.force_N - prediction) / np.abs(obs.force_N)
    s_rel = obs.sigma_N / np.abs(obs.force_N)
    datas = {d.axis: d for d in axis_data(obs, time_s, temperature_C)}
    tests, skipped = [], {}
    for axis in AXES:
        data = datas.get(axis)
        test = None if data is None or data.rows.size == 0 else axis_test(data, z, rel, s_rel)
        if test is None:
            skipped[axis] = ("not recorded" if data is None or data.rows.size == 0
                             else "fewer than two distinct values or too few units")
        else:
            tests.append(test)
    within = None if parts_prediction is None else within_window_test(
        obs.subwindows, parts_prediction, (obs.noise or {}).get("objects"), parts_drift_N)
    if within is not None:
        tests.append(within_window_entry(within))
    if drift_sensitivity_N and time_s is not None and len(time_s) == len(obs):
        fm = np.ones(len(obs), dtype=bool) if fit_mask is None else np.asarray(fit_mask, dtype=bool)
        fit_obs, fit_t = obs.subset(fm), np.asarray(time_s, dtype=float)[fm]
        tests += [t for key, sens in drift_sensitivity_N.items()
                  if (t := drift_test(fit_obs, z[fm], fit_t, sens[fm], key, drift_jacobian)) is not None]
    for test, p_adj in zip(tests, holm([t["p"] for t in tests]), strict=True):
        test["p_adjusted"] = float(p_adj)
        test["significant"] = bool(p_adj < alpha)
    where = [e for t in tests if t["significant"] for e in
             (within_window_where({**within, **t}) if t.get("test") == "within_window"
              else drift_where(t) if t.get("test") == "drift" else where_entries(t, datas[t["axis"]], rel))]
    public = [{k: v for k, v in t.items() if not k.startswith("_") and k != "range"} for t in tests]
    out = {"alpha": alpha, "tests": public, "skipped": skipped, "where": where,
           "axes": list(dict.fromkeys(t["axis"] for t in tests if t["significant"]))}
    if parts_prediction is not None:
        out["within_window"] = {k: v for k, v in within.items() if not k.startswith("_")} if within else {
            "note": "fewer than two position bins or too few window parts: not tested"}
    return out


def axis_units(obs: Observations, prediction: np.ndarray, time_s: np.ndarray | None = None,
               temperature_C: Mapping[str, float] | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """axis -> (value, U) of each unit of the axes the observations carry (:func:`axis_data`,
    :func:`unit_sums`): what Fig. 16's structure panels show."""
    z = obs.sign * (obs.force_N - prediction) / obs.sigma_N
    out = {}
    for data in axis_data(obs, time_s, temperature_C):
        if data.rows.size:
            u, x, _n = unit_sums(data.unit, z[data.rows], data.x)
            out[data.axis] = (x, u)
    return out


def parts_prediction(obs: Observations, damper, best) -> np.ndarray | None:
    """The verdict ``best`` (a :class:`isokinetic.diagnosis.candidate.Candidate`) at the windows' parts
    (``obs.subwindows``, driven as ``obs``' cases are): gain·(F_model + F_C·friction column) through its force
    channel; the load-cell's offset and zero drift are left out (:func:`parts_drift`). None without parts. One model
    run."""
    parts = obs.subwindows
    if parts is None or len(parts) == 0:
        return None
    from dataclasses import replace

    from isokinetic.diagnosis.model import Evaluator
    from isokinetic.physics.damper import Effects

    ev = Evaluator(replace(parts, plans=obs.plans, drives=obs.drives, viscosity_scale=obs.viscosity_scale), damper)
    effects = Effects(**{k: v for k, v in best.params.items() if k != "coulomb_force_N"})
    friction_N = float(best.params.get("coulomb_force_N", 0.0))
    if best.channel is None:
        hydraulic, column = ev.predict(effects), ev.friction_ideal()
    else:
        form, lag = best.channel
        hydraulic, column = ev.read(effects, form, [lag])[0], ev.friction_read(form, lag)
    return best.gain * (hydraulic + friction_N * column)


def parts_drift(obs: Observations, best) -> np.ndarray | None:
    """The verdict's load-cell zero drift at the windows' parts [N], from each case's start (the offset and the
    drift's level at a case's start are constant within a window: :func:`within_window_test` takes each window's
    level off); None without parts."""
    parts = obs.subwindows
    if parts is None or len(parts) == 0:
        return None
    fs = np.array([p.sample_rate_Hz for p in obs.plans])[parts.case_index]
    return float(best.drift_N_s or 0.0) * 0.5 * (parts.start + parts.stop) / fs


def structure_note(structure: Mapping) -> str | None:
    """The note of a verdict whose residuals show structure (None where they show none): the axes, with
    their Holm-adjusted p-values."""
    hits = [t for t in structure.get("tests", []) if t.get("significant")]
    if not hits:
        return None
    return STRUCTURE_NOTE.format(axes=", ".join(t["axis"] + TEST_NAMES.get(t.get("test"), "").format(**t)
                                                for t in hits),
                                 p=", ".join(f"{t['p_adjusted']:.2g}" for t in hits))


def case_temperatures(cases: pd.DataFrame) -> dict[str, float]:
    """case -> logged temperature [°C] of cases.parquet (``temperature_C``), finite ones only; empty without."""
    if cases is None or "temperature_C" not in cases or cases.empty:
        return {}
    t = pd.to_numeric(cases["temperature_C"], errors="coerce")
    return {str(c): float(v) for c, v in zip(cases["case"], t, strict=True) if np.isfinite(v)}
