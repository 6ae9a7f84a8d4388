"""Instrument terms: load-cell gain and offset (and Coulomb friction) profiled in closed form; the delay.

The load cell reads F_meas = g·F + F_0 + r·(t - t_ref): a gain g (|g - 1| <= GAIN_BOUND), a zero offset
F_0 at the reference time t_ref (|F_0| <= OFFSET_BOUND_REL of the largest window force) and, where each
observation's campaign time t is known, a zero drift r linear in campaign time, are profiled out of every
fit in closed form (bounded weighted least squares, :class:`LinearTerms`). Coulomb friction, sign(v)·F_C over a
constant-velocity segment (Eq. 8's F_f in "A method for the identification of hydraulic damper
characteristics from steady velocity inputs", Titurus et al.), is linear in the means too and is
profiled alongside. The actuator delay is measured, not fitted: the median over cases of
``delay_s`` (motion start minus the record's first time stamp, :func:`case_delays`). They are
reported under ``instrument`` and never count as damper effects.

The sensor chain (issue 21): the force channel's dynamics between the force and the displacement
channels, fitted on the nominal model as a lag (:func:`fit_force_lag`: a delay, or a first- or
second-order Butterworth low-pass, each by its low-frequency group delay), and the LVDT's scale,
measured as its speed against the command channel's (:func:`case_speed_ratio`,
:func:`displacement_scale`), the model then driven at the true speeds (:func:`rescaled_drives`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

#: Instrument terms profiled out of every fit (load cell): F_meas = gain·F + offset.
INSTRUMENT = ("force_offset", "force_gain")
#: The load-cell zero drift, linear in campaign time, profiled beside them where each observation's campaign
#: time is known: F_meas = gain·F + offset + drift·(t - t_ref).
DRIFT = "force_drift"
#: Largest load-cell gain error |g - 1| a calibrated load cell is allowed.
GAIN_BOUND = 0.02
#: Largest load-cell zero offset, as a fraction of the largest window force |F|.
OFFSET_BOUND_REL = 0.05


@dataclass(frozen=True)
class LinearTerms:
    """Terms linear in the measured means, profiled out of every fit in closed form.

    F_meas = g·(m + F_C·s) + F_0 + r·τ with m the hydraulic model (Eq. 8 without friction), s = ±1 the
    observation's direction (Coulomb friction, Eq. 8's F_f, is sign(v)·F_C over a constant-velocity
    segment), g the load-cell gain, F_0 its zero offset at the reference time and r its zero drift
    (τ: campaign time minus the reference time, ``time_s`` of :meth:`solve`). Solved as bounded weighted
    linear least squares in (g, g·F_C, F_0, r) (scipy ``lsq_linear``). ``free`` names the instrument terms
    fitted (others fixed at g = 1, F_0 = 0, r = 0; the drift only where ``time_s`` is given). The drift is
    bounded so that it moves the zero by at most the offset bound at either end (``drift_bound_N_s``).
    """

    free: tuple[str, ...] = INSTRUMENT
    offset_bound_N: float = 0.0
    gain_bound: float = GAIN_BOUND
    friction_bound_N: float = math.inf
    drift_bound_N_s: float = 0.0

    def solve(self, force_N: np.ndarray, model_N: np.ndarray, sign: np.ndarray, weight: np.ndarray,
              friction: bool, time_s: np.ndarray | None = None) -> tuple[float, float, float, float]:
        """(gain, coulomb_force_N, offset_N, drift_N_s) minimising Σ w (F - g (m + F_C s) - F_0 - r τ)² within
        the bounds (τ = ``time_s``, relative to the reference time at which F_0 is the offset)."""
        root_w = np.sqrt(weight)
        y = force_N.copy()
        cols, lo, hi, names = [], [], [], []
        if "force_gain" in self.free:
            cols.append(model_N), lo.append(1.0 - self.gain_bound), hi.append(1.0 + self.gain_bound), names.append("g")
        else:
            y = y - model_N
        if friction:
            cols.append(sign), lo.append(0.0), hi.append((1.0 + self.gain_bound) * self.friction_bound_N)
            names.append("c")
        if "force_offset" in self.free and self.offset_bound_N > 0:
            cols.append(np.ones_like(y)), lo.append(-self.offset_bound_N), hi.append(self.offset_bound_N)
            names.append("o")
        if DRIFT in self.free and time_s is not None and self.drift_bound_N_s > 0:
            cols.append(np.asarray(time_s, dtype=float)), lo.append(-self.drift_bound_N_s)
            hi.append(self.drift_bound_N_s), names.append("r")
        if not cols:
            return 1.0, 0.0, 0.0, 0.0
        a = np.column_stack(cols) * root_w[:, None]
        from scipy.optimize import lsq_linear  # scipy.optimize: only where the instrument is fitted

        sol = lsq_linear(a, y * root_w, bounds=(lo, hi), method="bvls").x
        v = dict(zip(names, sol, strict=True))
        g = float(v.get("g", 1.0))
        return g, float(v.get("c", 0.0)) / g, float(v.get("o", 0.0)), float(v.get("r", 0.0))


def case_delays(cases: pd.DataFrame) -> dict:
    """Measured actuator delay over the status-ok triangle cases (``delay_s`` of cases.parquet)."""
    if "delay_s" not in cases:
        return {"delay_s": None}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    d = ok["delay_s"].to_numpy(dtype=float)
    d = d[np.isfinite(d)]
    if not d.size:
        return {"delay_s": None}
    return {"delay_s": float(np.median(d)), "delay_min_s": float(d.min()), "delay_max_s": float(d.max()),
            "n_cases": int(d.size)}


#: Largest force-channel lag searched [s] (a 2nd-order Butterworth anti-alias filter at 1 Hz lags ~0.23 s).
LAG_MAX_S = 0.25
#: Grid step of the force-lag search [s], refined by a parabola through the best three grid points.
LAG_STEP_S = 0.0025
#: Forms of the force channel's dynamics fitted: 0 a pure delay, 1 and 2 Butterworth low-passes of that order.
LAG_FORMS = (0, 1, 2)


def fit_force_lag(dg, forms: tuple[int, ...] = LAG_FORMS, instrument: tuple[str, ...] | None = None,
                  effects=None) -> tuple[float, int, np.ndarray]:
    """(lag [s], form, the model as that force channel reads it): the force channel's dynamics between the
    force and the displacement channels that minimise the χ² of the model of ``effects`` (default the
    nominal damper) over all observations (an instrument term, like the delay, measured on all the data)
    with the load-cell terms (and the zero drift, where campaign times are known) profiled.

    Forms (``forms``, of :data:`LAG_FORMS`): a pure delay, or a first- or second-order Butterworth low-pass (an
    anti-alias filter), each parametrised by its low-frequency group delay, the lag reported:
    1/(2π f_c) for a first-order, √2/(2π f_c) for a second-order low-pass of corner f_c
    (:meth:`isokinetic.diagnosis.model.Evaluator.lagged`, :meth:`~isokinetic.diagnosis.model.Evaluator.filtered`).
    ``dg``: a :class:`isokinetic.diagnosis.search.Diagnoser` (its unlagged ``evaluator``).
    """
    from isokinetic.physics.damper import NOMINAL

    effects = NOMINAL if effects is None else effects
    obs = dg.obs
    terms = dg.terms(dg.instrument if instrument is None else instrument)
    force, sign, weight, sigma = obs.force_N, obs.sign, dg.weight, obs.sigma_N

    def chi2(pred: np.ndarray) -> float:
        g, _c, o, r = terms.solve(force, pred, sign, weight, False, dg.time_s)
        drift = 0.0 if dg.time_s is None else r * dg.time_s
        return float(np.sum(((force - g * pred - o - drift) / sigma) ** 2))

    def model(form: int, lags) -> np.ndarray:
        return dg.evaluator.lagged(effects, lags) if form == 0 else dg.evaluator.filtered(effects, lags, form)

    grid = np.arange(LAG_STEP_S, LAG_MAX_S + LAG_STEP_S / 2, LAG_STEP_S)
    best = (math.inf, 0.0, 0, None)
    for form in forms:
        preds = model(form, grid)
        costs = np.array([chi2(p) for p in preds])
        i = int(np.argmin(costs))
        if costs[i] < best[0]:
            best = (float(costs[i]), float(grid[i]), form, preds[i])
        if 0 < i < grid.size - 1:
            c0, c1, c2 = costs[i - 1:i + 2]
            curvature = c0 - 2.0 * c1 + c2
            if curvature > 0:
                lag = float(grid[i] + 0.5 * LAG_STEP_S * (c0 - c2) / curvature)
                pred = model(form, [lag])[0]
                cost = chi2(pred)
                if cost < best[0]:
                    best = (cost, lag, form, pred)
    return best[1], best[2], best[3]


#: Part of each half-period (after the measured motion start) over which the LVDT's speed is set
#: against the command's: clear of the reversals and of a delay of up to 0.15 T/2 between them.
SCALE_WINDOW = (0.3, 0.85)
#: A displacement scale is applied only when it departs from 1 by more than this and by more than
#: SCALE_SIGMAS standard errors (a calibrated LVDT is good to about 0.1 %).
SCALE_MIN_DEPARTURE = 1e-3
SCALE_SIGMAS = 4.0
#: Largest LVDT scale error taken as one: beyond it the command channel is no measure of the motion (a
#: servo that does not follow it, another unit), and the scale is not applied.
SCALE_BOUND = 0.05


def _slope(t: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of y(t) (NaN with fewer than three finite points)."""
    ok = np.isfinite(t) & np.isfinite(y)
    if ok.sum() < 3:
        return math.nan
    tc = t[ok] - t[ok].mean()
    return float(np.dot(tc, y[ok] - y[ok].mean()) / np.dot(tc, tc))


def case_speed_ratio(series: pd.DataFrame, period_s: float, motion_start_s: float) -> float:
    """Median over the four half-periods of |speed of the LVDT| / |speed of the command| over the same
    record times (SCALE_WINDOW of each half-period); NaN without a command channel."""
    if "command_m" not in series or not np.isfinite(series["command_m"].to_numpy(dtype=float)).any():
        return math.nan
    t = series["time_s"].to_numpy(dtype=float)
    x, c = series["displacement_m"].to_numpy(dtype=float), series["command_m"].to_numpy(dtype=float)
    half = period_s / 2.0
    ratios = []
    for k in range(4):
        a, b = motion_start_s + (k + SCALE_WINDOW[0]) * half, motion_start_s + (k + SCALE_WINDOW[1]) * half
        sel = (t >= a) & (t < b)
        sx, sc = _slope(t[sel], x[sel]), _slope(t[sel], c[sel])
        if math.isfinite(sx) and math.isfinite(sc) and sc != 0.0:
            ratios.append(abs(sx / sc))
    return float(np.median(ratios)) if ratios else math.nan


def displacement_scale(ratios: np.ndarray) -> dict:
    """The LVDT's scale k (measured = k·true, the command taken as the truth of the motion) from the
    cases' speed ratios (:func:`case_speed_ratio`): their median, its standard error (1.2533·sd/√n),
    and whether it departs from 1 enough to apply (SCALE_MIN_DEPARTURE, SCALE_SIGMAS; never beyond
    SCALE_BOUND). Without a
    command channel (no finite ratio) the scale cannot be measured: where the servo closes on the
    LVDT itself, the record shows the command, whatever the LVDT's scale."""
    r = np.asarray(ratios, dtype=float)
    r = r[np.isfinite(r) & (r > 0)]
    if not r.size:
        return {"estimate": None, "std_error": None, "n_cases": 0, "applied": False, "source": "no command channel"}
    k = float(np.median(r))
    se = float(1.2533 * np.std(r, ddof=1) / math.sqrt(r.size)) if r.size > 1 else math.inf
    out = {"estimate": k, "std_error": se if math.isfinite(se) else None, "n_cases": int(r.size),
           "applied": bool(abs(k - 1.0) > max(SCALE_MIN_DEPARTURE, SCALE_SIGMAS * se)),
           "source": "LVDT speed against the command channel"}
    if abs(k - 1.0) > SCALE_BOUND:
        out.update(applied=False, note=f"the LVDT and the command differ by {k - 1.0:+.1%}, beyond ±{SCALE_BOUND:.0%}: "
                                       "the command is no measure of the motion; not applied")
    return out


def rescaled_drives(obs, scale: float):
    """Observations whose model is driven at the measured speeds divided by the LVDT scale (the true
    speeds, when the LVDT reads ``scale`` times the motion)."""
    from dataclasses import replace

    # a sine's drive (no speeds_m_s) is scaled where its observations are built (build_observations)
    drives = tuple(d if d is None or not hasattr(d, "speeds_m_s")
                   else replace(d, speeds_m_s=tuple(v / scale for v in d.speeds_m_s)) for d in obs.drives)
    return replace(obs, drives=drives)
