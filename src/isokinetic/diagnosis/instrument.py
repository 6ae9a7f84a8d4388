"""Instrument terms: load-cell gain and offset (and Coulomb friction) profiled in closed form; the delay.

The load cell reads F_meas = g·F + F_0 + r·(t - t_ref): a gain g (|g - 1| <= GAIN_BOUND), a zero offset
F_0 at the reference time t_ref (|F_0| bounded, :func:`offset_bound_N`) and, where each
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
:func:`displacement_scale`), the model then driven at the true speeds (:func:`rescaled_drives`). A sine-only
campaign has no ramp to set against its command: its LVDT scale and actuator delay come from each case's amplitude
and phase against the command channel's, read through a dead time and a first-order servo lag
(:func:`case_sine_response`, :func:`sine_servo_terms`). Where no command channel measures the scale, a declared
calibration of the LVDT (manifest ``columns.displacement.calibration``, format 1.6) is its scale
(:func:`calibrated_scale`).
"""

from __future__ import annotations

import dataclasses
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
#: Largest load-cell zero offset of a sine-only campaign, as a fraction of half the range of its bins' mean forces
#: (:func:`offset_bound_N`).
OFFSET_BOUND_SINE_REL = 0.25


def offset_bound_N(force_N: np.ndarray, is_window: np.ndarray, sine_only: bool) -> float:
    """The bound on the load-cell zero offset [N]: OFFSET_BOUND_REL of the largest window force |F|; for a
    sine-only campaign OFFSET_BOUND_SINE_REL of half the range (max - min) of all its bin means. A load cell's
    zero is a fraction of its full scale, which may be several times a campaign's largest force (a cell sized for
    the largest dampers tested): a sine sweep's offset of 15 % of its peak force is no gross error. On sine
    records a wider bound is safe: every cycle's bins sweep the force from near zero to its peak in both
    directions, so a constant offset is told apart from the even effects (an asymmetry, ∝ |F|) within each case.
    Half the range is unchanged by the offset it bounds (the largest |F| grows with it)."""
    force = np.asarray(force_N, dtype=float)
    if sine_only:
        return OFFSET_BOUND_SINE_REL * 0.5 * float(np.ptp(force)) if force.size else 0.0
    windows = np.abs(force[np.asarray(is_window, dtype=bool)])
    return OFFSET_BOUND_REL * float(windows.max()) if windows.size else 0.0


@dataclass(frozen=True)
class LinearTerms:
    """Terms linear in the measured means, profiled out of every fit in closed form.

    F_meas = g·(m + F_C·s) + F_0 + r·τ with m the hydraulic model (Eq. 8 without friction), s = ±1 the
    observation's direction (Coulomb friction, Eq. 8's F_f, is sign(v)·F_C over a constant-velocity
    segment), g the load-cell gain, F_0 its zero offset at the reference time and r its zero drift
    (τ: campaign time minus the reference time, ``time_s`` of :meth:`solve`). Solved as bounded weighted
    linear least squares in (g, g·F_C, F_0, r): the plain least squares where its solution lies within the
    bounds (the problem is convex, so that is the bounded minimum too), else scipy's ``lsq_linear``. ``free``
    names the instrument terms fitted (others fixed at g = 1, F_0 = 0, r = 0; the drift only where ``time_s`` is
    given). The drift is bounded so that it moves the zero by at most the offset bound at either end
    (``drift_bound_N_s``).

    A declared calibration of the load cell (manifest ``columns.force.calibration``, format 1.6) centres the gain:
    free, it lies within ``gain_centre`` ± ``gain_bound`` and, with ``gain_sd`` (the calibration's standard
    uncertainty of g), the calibration is one more observation of g, the row (g - gain_centre)/gain_sd of the
    weighted least squares; not free, g is ``gain_centre`` (a gain "held" is the gain as calibrated).
    """

    free: tuple[str, ...] = INSTRUMENT
    offset_bound_N: float = 0.0
    gain_bound: float = GAIN_BOUND
    friction_bound_N: float = math.inf
    drift_bound_N_s: float = 0.0
    gain_centre: float = 1.0
    gain_sd: float | None = None

    def prior_residuals(self, gain: float) -> np.ndarray:
        """The calibration's residual (g - gain_centre)/gain_sd as an array of one, where the gain is free and a
        calibration is declared (else empty): the fits' objective and χ² count it beside the observations, so that
        the gain profiled with it and the effects fitted around it minimise the same sum."""
        if "force_gain" not in self.free or not self.gain_sd:
            return np.zeros(0)
        return np.array([(gain - self.gain_centre) / self.gain_sd])

    @property
    def gain_range(self) -> tuple[float, float]:
        """The bounds of a free gain: ``gain_centre`` ± ``gain_bound``."""
        return self.gain_centre - self.gain_bound, self.gain_centre + self.gain_bound

    def solve(self, force_N: np.ndarray, model_N: np.ndarray, sign: np.ndarray, weight: np.ndarray,
              friction: bool, time_s: np.ndarray | None = None) -> tuple[float, float, float, float]:
        """(gain, coulomb_force_N, offset_N, drift_N_s) minimising Σ w (F - g (m + F_C s) - F_0 - r τ)² (plus
        ((g - gain_centre)/gain_sd)² with a calibration) within the bounds (τ = ``time_s``, relative to the reference
        time at which F_0 is the offset)."""
        root_w = np.sqrt(weight)
        y = force_N.copy()
        centre = self.gain_centre
        cols, lo, hi, names = [], [], [], []
        if "force_gain" in self.free:
            cols.append(model_N), lo.append(self.gain_range[0]), hi.append(self.gain_range[1]), names.append("g")
        else:
            y = y - centre * model_N
        if friction:
            cols.append(sign), lo.append(0.0), hi.append((centre + self.gain_bound) * self.friction_bound_N)
            names.append("c")
        if "force_offset" in self.free and self.offset_bound_N > 0:
            cols.append(np.ones_like(y)), lo.append(-self.offset_bound_N), hi.append(self.offset_bound_N)
            names.append("o")
        if DRIFT in self.free and time_s is not None and self.drift_bound_N_s > 0:
            cols.append(np.asarray(time_s, dtype=float)), lo.append(-self.drift_bound_N_s)
            hi.append(self.drift_bound_N_s), names.append("r")
        if not cols:
            return centre, 0.0, 0.0, 0.0
        a, b = np.column_stack(cols) * root_w[:, None], y * root_w
        if "g" in names and self.gain_sd:   # the calibration: one more observation of g, of standard error gain_sd
            row = np.zeros(len(names))
            row[names.index("g")] = 1.0 / self.gain_sd
            a, b = np.vstack([a, row]), np.append(b, centre / self.gain_sd)
        sol = np.linalg.lstsq(a, b, rcond=None)[0]
        if not np.all((sol >= lo) & (sol <= hi)):   # the unbounded minimum is the bounded one where it is inside
            from scipy.optimize import lsq_linear  # scipy.optimize: only where a bound is reached

            sol = lsq_linear(a, b, bounds=(lo, hi), method="bvls").x
        v = dict(zip(names, sol, strict=True))
        g = float(v.get("g", centre))
        return g, float(v.get("c", 0.0)) / g, float(v.get("o", 0.0)), float(v.get("r", 0.0))


#: |z| beyond which a channel's declared calibration and the campaign's own reading of the same factor disagree:
#: the two-sided normal quantile at the diagnosis' alpha, 10⁻³.
CALIBRATION_Z = 3.29


def calibration_z(reading: float, reading_se: float, declared: float, declared_sd: float) -> float:
    """(reading - declared)/√(reading_se² + declared_sd²): how many standard errors a campaign's own reading of a
    calibrated factor (the load cell's gain, the LVDT's scale) lies from its declared calibration; 0 where the
    reading has no finite standard error (nothing to tell them apart by)."""
    if reading_se is None or not math.isfinite(reading_se):
        return 0.0
    return (reading - declared) / math.sqrt(reading_se**2 + declared_sd**2)


def gain_reading(terms: LinearTerms, force_N: np.ndarray, model_N: np.ndarray, sign: np.ndarray,
                 weight: np.ndarray, time_s: np.ndarray | None = None) -> tuple[float, float]:
    """(g, its standard error) of the load-cell gain as the campaign's own data read it, ``model_N`` held and the
    calibration's row left out: the linear terms solved with the gain free and held at the calibration's centre;
    the weighted χ² rises by (g - centre)²/se² between the two (linear least squares), whence se (infinite where
    g is the centre)."""
    own = dataclasses.replace(terms, gain_sd=None)
    held = dataclasses.replace(terms, free=tuple(t for t in terms.free if t != "force_gain"))

    def chi2(t: LinearTerms) -> tuple[float, float]:
        g, _fc, offset, drift = t.solve(force_N, model_N, sign, weight, False, time_s)
        resid = force_N - g * model_N - offset - (0.0 if time_s is None else drift * np.asarray(time_s, float))
        return g, float(np.sum(weight * resid**2))

    g, chi2_own = chi2(own)
    rise = chi2(held)[1] - chi2_own
    return g, abs(g - terms.gain_centre) / math.sqrt(rise) if rise > 0.0 else math.inf


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
#: Names of the forms in diagnosis.json (``instrument_tests.force_lag.form``).
LAG_FORM_NAMES = {0: "delay", 1: "low-pass, 1st order", 2: "low-pass, 2nd order"}


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
        return dg.evaluator.read(effects, form, lags)

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


def _scale_report(k: float, se: float, n: int, source: str) -> dict:
    """The displacement-scale dict: the estimate k, its standard error, and whether it departs from 1 enough to
    apply (SCALE_MIN_DEPARTURE, SCALE_SIGMAS; never beyond SCALE_BOUND)."""
    out = {"estimate": k, "std_error": se if math.isfinite(se) else None, "n_cases": int(n),
           "applied": bool(abs(k - 1.0) > max(SCALE_MIN_DEPARTURE, SCALE_SIGMAS * se)), "source": source}
    if abs(k - 1.0) > SCALE_BOUND:
        out.update(applied=False, note=f"the LVDT and the command differ by {k - 1.0:+.1%}, beyond ±{SCALE_BOUND:.0%}: "
                                       "the command is no measure of the motion; not applied")
    return out


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
    se = float(1.2533 * np.std(r, ddof=1) / math.sqrt(r.size)) if r.size > 1 else math.inf
    return _scale_report(float(np.median(r)), se, r.size, "LVDT speed against the command channel")


def case_sine_response(series: pd.DataFrame, frequency_Hz: float) -> tuple[float, float, float, float]:
    """(frequency [Hz], LVDT amplitude / command amplitude, phase lag of the LVDT behind the command [rad], in
    [-π/4, 7π/4), the ratio's relative standard error (≈ the lag's, in rad) from the LVDT's residual noise:
    √(2σ²/n)/Y) of a sine case, from least-squares sines through both channels after the first cycle (the
    command's frequency refined, :func:`isokinetic.diagnosis.sine_observations.fit_sine`; the LVDT's at that
    frequency); NaNs without a command channel or a record of two cycles."""
    from isokinetic.diagnosis.sine_observations import SKIPPED_CYCLES, fit_sine, linear_sine

    nan = (math.nan, math.nan, math.nan, math.nan)
    if "command_m" not in series or not frequency_Hz > 0.0:
        return nan
    t = series["time_s"].to_numpy(dtype=float)
    x, c = series["displacement_m"].to_numpy(dtype=float), series["command_m"].to_numpy(dtype=float)
    sel = np.isfinite(t) & np.isfinite(x) & np.isfinite(c)
    if sel.sum() < 8 or t[sel][-1] - t[sel][0] < (SKIPPED_CYCLES + 1) / frequency_Hz:
        return nan
    sel &= t >= t[sel][0] + SKIPPED_CYCLES / frequency_Hz
    cmd = fit_sine(t[sel], c[sel], frequency_Hz)
    if cmd is None:
        return nan
    coef, _design, resid = linear_sine(t[sel], x[sel], 2.0 * math.pi * cmd.frequency_Hz)
    amp = math.hypot(coef[1], coef[2])
    phase_x = math.atan2(coef[2], coef[1])   # x ∝ sin(ωt + φ_x), as the command's φ
    lag = (cmd.phase_rad - phase_x + 0.25 * math.pi) % (2.0 * math.pi) - 0.25 * math.pi
    rel_se = math.sqrt(2.0 * float(resid @ resid) / max(resid.size - 3, 1) / resid.size) / amp
    return cmd.frequency_Hz, amp / cmd.amplitude_m, lag, math.hypot(rel_se, cmd.amplitude_rel_se)


#: What the sine path's servo terms assume (reported with them).
SINE_SERVO_SOURCE = ("LVDT amplitude and phase against the command channel's over the sine cases, through a "
                     "dead time d and a first-order servo lag τ: ratio = k/√(1 + ω²τ²), lag = ωd + atan(ωτ)")


def sine_servo_terms(frequency_Hz, ratio, lag_rad, rel_se) -> tuple[dict, dict]:
    """(displacement scale, delays) of a sine-only campaign from its cases' responses (:func:`case_sine_response`).

    The LVDT reads k·x and the servo follows the (undelayed) command through a dead time d and a first-order lag
    τ, so the amplitude ratio is r = k/√(1 + ω²τ²): 1/r² = 1/k² + (τ/k)²·ω² is a straight line in ω² (weighted
    least squares, each case by its ratio's standard error; k's from its intercept's, scaled by the reduced χ²
    where above 1), and the phase lag ωd + atan(ωτ) gives d (weighted least squares through the origin). The
    delay is reported as the triangle path reports it (a ramp follows its command late by d + τ): ``delay_s`` =
    d + τ, the motion's low-frequency group delay. Fewer than three cases: the scale is not applied (no
    standard error) and no delay is reported; so too where every case has the same frequency (k and τ
    cannot be told apart from one point of the amplitude response)."""
    f, r, lag, se = (np.asarray(a, dtype=float) for a in (frequency_Hz, ratio, lag_rad, rel_se))
    ok = np.isfinite(f) & np.isfinite(r) & np.isfinite(lag) & np.isfinite(se) & (r > 0) & (se > 0)
    if not ok.any():
        return displacement_scale([]), {"delay_s": None}
    w, r, lag, se = 2.0 * math.pi * f[ok], r[ok], lag[ok], se[ok]
    if w.size < 3 or np.ptp(w) <= 1e-3 * w.max():   # one frequency: the scale and the servo lag's loss are one
        return _scale_report(float(np.median(r)), math.inf, w.size, SINE_SERVO_SOURCE), {"delay_s": None}
    root_w = r * r / (2.0 * se)   # 1/sd of 1/r²
    design = np.column_stack([np.ones_like(w), w * w])
    y = 1.0 / (r * r)
    coef, *_ = np.linalg.lstsq(design * root_w[:, None], y * root_w, rcond=None)
    a, b = float(coef[0]), max(float(coef[1]), 0.0)
    chi2 = float(np.sum(((y - design @ coef) * root_w) ** 2))
    cov = max(chi2 / (w.size - 2), 1.0) * np.linalg.inv((design * root_w[:, None] ** 2).T @ design)
    k, tau = 1.0 / math.sqrt(a), math.sqrt(b / a)
    se_k = 0.5 * a ** -1.5 * math.sqrt(max(float(cov[0, 0]), 0.0))
    pw = w / se**2
    dead = float(np.dot(pw, lag - np.arctan(w * tau)) / np.dot(pw, w))
    scale = {**_scale_report(k, se_k, w.size, SINE_SERVO_SOURCE), "servo_lag_s": tau}
    delays = {"delay_s": dead + tau, "dead_time_s": dead, "servo_lag_s": tau, "n_cases": int(w.size),
              "source": SINE_SERVO_SOURCE}
    return scale, delays


#: The ``source`` of an LVDT scale taken from its declared calibration (:func:`calibrated_scale`).
CALIBRATION_SOURCE = "calibration"


def scale_measured(scale: dict) -> bool:
    """Whether a displacement-scale dict holds the LVDT's scale: an estimate (from a command channel that follows
    the LVDT, none beyond SCALE_BOUND: no ``note``, or from a declared calibration as good as SCALE_MIN_DEPARTURE,
    the departure below which no scale is applied: a looser one is applied, but a scale error within its
    uncertainty would still read as a load-cell gain plus C_D·√k, so the scale's confounding stays listed)."""
    if scale["estimate"] is None or "note" in scale:
        return False
    return scale.get("source") != CALIBRATION_SOURCE or float(scale["uncertainty_rel"]) <= SCALE_MIN_DEPARTURE


def calibrated_scale(scale: dict, calibration: tuple[float, float] | None) -> dict:
    """The displacement-scale dict with the LVDT's declared calibration (scale k, relative standard uncertainty u;
    manifest ``columns.displacement.calibration``): where no command channel measures the scale
    (:func:`scale_measured`), k is the scale: ``estimate`` k, applied where k is not 1 (the model then driven at
    the measured speeds divided by k, as with a measured scale), ``std_error`` k·u, ``uncertainty_rel`` u,
    ``source`` CALIBRATION_SOURCE, and the command's reading set aside, if any, under ``command``; where one
    does, the measurement stands, and the declaration gains ``z`` (:func:`calibration_z`, the measured scale against
    it) and ``agrees`` (|z| <= CALIBRATION_Z: a stale calibration, or a servo that closes on another transducer,
    is said, not taken silently). Either way the declaration is reported under ``calibration``."""
    if calibration is None:
        return scale
    k, u = (float(v) for v in calibration)
    declared = {"scale": k, "uncertainty_rel": u}
    if scale_measured(scale):
        z = calibration_z(float(scale["estimate"]), scale["std_error"], k, k * u)
        return {**scale, "calibration": {**declared, "z": z, "agrees": bool(abs(z) <= CALIBRATION_Z)}}
    out = {"estimate": k, "std_error": k * u, "uncertainty_rel": u, "n_cases": 0, "applied": k != 1.0,
           "source": CALIBRATION_SOURCE, "calibration": declared}
    return out if scale["estimate"] is None else {**out, "command": scale}


def rescaled_drives(obs, scale: float):
    """Observations whose model is driven at the measured speeds divided by the LVDT scale (the true
    speeds, when the LVDT reads ``scale`` times the motion)."""
    from dataclasses import replace

    # a sine's drive (no speeds_m_s) is scaled where its observations are built (build_observations)
    drives = tuple(d if d is None or not hasattr(d, "speeds_m_s")
                   else replace(d, speeds_m_s=tuple(v / scale for v in d.speeds_m_s)) for d in obs.drives)
    return replace(obs, drives=drives)
