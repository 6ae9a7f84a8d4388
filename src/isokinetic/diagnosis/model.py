"""The damper model over the observations' samples, and what it says about the observations.

Model. The nominal damper of ``campaign.json`` simulated noise-free through each case *driven by its
measured kinematics* (:class:`isokinetic.physics.responses.Drive`: the measured speed of each
half-period, on the measured samples' plan times), reduced over the same samples as the measured
means; a candidate adds damper effects with fitted parameters. With a viscosity law and case temperatures
(format 1.1) each case runs at its temperature's viscosity, times the candidate's viscosity deviation. Simulation:
:func:`isokinetic.physics.responses.triangle_responses` (Eq. 13-14 of "A method for the
identification of hydraulic damper characteristics from steady velocity inputs", Titurus et al.),
force from Eq. 8. A sine case (:class:`isokinetic.physics.sine_drive.SineDrive`) is driven by its fitted
measured sine: its runs are made on a grid set by the physics, not by the record's samples
(:class:`isokinetic.diagnosis.sine_model.GridEvaluator`, the bins' means read off it; the cost of a run does not
grow with the sampling rate, and a record's cycles after its response repeats cost nothing); a run with a Stribeck
friction, and ``grid=False``, integrate Eq. (1) on the record's own sample times instead
(:func:`isokinetic.physics.sine_drive.sine_drive_response`), the reference the grid is tested against. A campaign
without sine cases keeps the closed-form sums of the triangle windows
(:class:`isokinetic.physics.responses.PressureSums`).

Before the fits, the nominal model marks the windows that are still relaxing
(:func:`unsteady_windows`, kept out of the noise fit) and the variance the measured drive speed's
own error propagates into the model means (:func:`drive_input_variance`).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.sine_model import GridEvaluator
from isokinetic.physics.damper import NOMINAL, Damper, Effects, friction_force
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.responses import PressureSums, drive_times, scaled_viscosity, triangle_responses_at
from isokinetic.physics.sine_drive import SineDrive, sine_drive_response

#: Panel width of the model's segment tables (isokinetic.physics.hydraulics.DEFAULT_STEP is 0.03): on the paper
#: campaign the means differ from DEFAULT_STEP's by < 3e-5 of their standard errors, with about a third of the nodes.
MODEL_STEP = 0.09
#: Relative step of the drive speeds for the model's speed sensitivity (:func:`drive_input_variance`).
SPEED_STEP = 1e-4
#: Phase step of a sine drive for the model's phase sensitivity [rad] (:func:`drive_input_variance`).
PHASE_STEP = 1e-4
#: Step of a harmonic's sine or cosine component, relative to the fundamental's amplitude, for its sensitivity.
HARMONIC_STEP = 1e-4
#: A window whose nominal-model force varies by more than this fraction of the per-sample noise
#: (standard deviations) is still relaxing and is kept out of the noise fit (:func:`unsteady_windows`).
UNSTEADY_FRACTION = 0.25
#: Model runs an evaluator remembers, the least recent dropped first (a run is a pure function of the effects): a
#: fit's Jacobian column of the force channel's lag, its second starting lag and a refit from a fitted candidate
#: run effects already simulated. Mean forces: RUN_CACHE; running sums (:class:`PressureSums`): RUN_CACHE_SUMS;
#: the forces on every sample: as many as fit in RUN_CACHE_SAMPLES values (at least 4).
RUN_CACHE = 64
RUN_CACHE_SUMS = 32
RUN_CACHE_SAMPLES = 3_000_000


class Evaluator:
    """Noise-free model means over the observations' sample ranges, for any effects."""

    def __init__(self, obs: Observations, damper: Damper, grid: bool = True):
        self.obs = obs
        self.damper = damper
        drives = obs.drives or (None,) * len(obs.plans)
        self._sine = [isinstance(d, SineDrive) for d in drives]
        sizes = np.array([d.n_samples if isinstance(d, SineDrive) else drive_times(p, d).size
                          for p, d in zip(obs.plans, drives, strict=True)], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes + 1)])  # +1: a leading zero per case in the cumsum
        self._lo = offsets[obs.case_index] + obs.start
        self._hi = offsets[obs.case_index] + obs.stop
        self._first = offsets[obs.case_index]   # each observation's case: the index of its leading zero
        # the model samples the records dropped (Observations.holes): their observation, case, sample, running-sum index
        self._hole_row, self._hole_at = obs.holes[:, 0], obs.holes[:, 1]
        self._hole_case = obs.case_index[self._hole_row]
        self._hole_abs = self._first[self._hole_row] + self._hole_at
        self._n = (obs.stop - obs.start - np.bincount(self._hole_row, minlength=len(obs))).astype(float)
        self._fs = np.array([p.sample_rate_Hz for p in obs.plans])[obs.case_index] if len(obs) else np.zeros(0)
        self._sums = np.empty(int(offsets[-1]))  # per case: 0, then the running sum of its samples
        self._calls = 0   # model runs (simulations of the damper) on the samples, remembered ones not counted
        self._unit: list[np.ndarray] | None = None   # sign(v) per case (:meth:`friction_read`)
        self._friction_reads: dict = {}             # (form, lag) -> friction_read
        # effects -> mean forces, and -> forces on every sample, least recent first; how many of each are kept
        self._runs = {"mean": OrderedDict(), "sums": OrderedDict(), "forces": OrderedDict()}
        self._kept = {"mean": RUN_CACHE, "sums": RUN_CACHE_SUMS,
                      "forces": max(4, RUN_CACHE_SAMPLES // max(int(sizes.sum()), 1))}
        self._split = None   # triangles and sines: each part's own evaluator, the triangles' closed-form sums kept
        if any(self._sine) and not all(self._sine):
            rows = np.array([self._sine[i] for i in obs.case_index], dtype=bool)
            self._split = (rows, Evaluator(obs.subset(~rows), damper, grid), Evaluator(obs.subset(rows), damper, grid))
        # sine cases: runs without friction on the physics' grids (:mod:`isokinetic.diagnosis.sine_model`)
        self._grid = GridEvaluator(obs, damper) if grid and len(obs) and all(self._sine) else None

    @property
    def calls(self) -> int:
        """Model runs (simulations of the damper), remembered ones not counted."""
        return self._calls + (self._grid.calls if self._grid is not None else 0)

    def _on_grid(self, effects: Effects) -> bool:
        """Whether a run of ``effects`` is made on the sine cases' grids: without a Stribeck term (a Coulomb
        friction is added as its profiled column, :meth:`friction_read`: the force channel is linear)."""
        return self._grid is not None and not effects.stribeck_force_N

    def _grid_read(self, effects: Effects, form: int, lags: np.ndarray) -> np.ndarray:
        """The sine cases' model means on their grids through the channel ``form``, one row per lag; a Coulomb
        friction F_C added as F_C times its column through the same channel."""
        coulomb = effects.coulomb_force_N
        hydraulic = replace(effects, coulomb_force_N=0.0)
        out = self._grid.lagged(hydraulic, lags) if form == 0 else self._grid.filtered(hydraulic, lags, form)
        if coulomb:
            out = out + coulomb * np.array([self.friction_read(form, float(lag)) if (form or lag)
                                            else self.friction_ideal() for lag in lags])
        return out

    def share_forces(self, other: Evaluator) -> bool:
        """Remember the forces on every sample together with ``other`` where both run the same damper, cases, sample
        grids and viscosities (a sine-only campaign's period-1 evaluator: its bins reach the last cycle, so it
        integrates every sample as the full one does), so that a run either makes serves both (the fit's last run
        is the candidate's score run). Whether they now share."""
        o, p = self.obs, other.obs
        same = (self.damper == other.damper and o.plans == p.plans and o.drives == p.drives
                and o.viscosity_scale == p.viscosity_scale and self._kept["forces"] == other._kept["forces"])
        if same:
            self._runs["forces"] = other._runs["forces"]
            if self._grid is not None and other._grid is not None:
                self._grid.share_runs(other._grid)
        return same

    def _remembered(self, kind: str, effects: Effects, run: Callable):
        """``run()``, or its result for the same ``kind`` and ``effects`` where still remembered (RUN_CACHE)."""
        runs = self._runs[kind]
        hit = runs.get(effects)
        if hit is not None:
            runs.move_to_end(effects)
            return hit
        out = runs[effects] = run()
        if len(runs) > self._kept[kind]:
            runs.popitem(last=False)
        return out

    def predict(self, effects: Effects = NOMINAL) -> np.ndarray:
        """Model mean force of every observation [N] (Eq. 8 with Δp from Eq. 13-14); without friction
        from the sums of Δp over the triangle observations' samples (:class:`PressureSums`: the samples at steady
        state summed in closed form), the sine cases' from their forces."""
        return self._remembered("mean", effects, lambda: self._predict(effects)).copy()

    def _predict(self, effects: Effects) -> np.ndarray:
        if self._on_grid(effects):
            return self._grid_read(effects, 0, np.zeros(1))[0]
        friction = bool(effects.coulomb_force_N or effects.stribeck_force_N)
        if self._split is not None and not friction:
            self._calls += 1
            rows, triangles, sines = self._split
            out = np.empty(len(self.obs))
            out[~rows], out[rows] = triangles.predict(effects), sines.predict(effects)
            return out
        if friction or any(self._sine):
            return self._moments(effects, 1)[0]
        area, run = self._pressure_sums(effects)
        sums = run.sums(self.obs.case_index, self.obs.start, self.obs.stop)
        if self._hole_row.size:
            sums = sums - self._per_row(run.sums(self._hole_case, self._hole_at, self._hole_at + 1))
        return area * sums / self._n

    def _per_row(self, hole_values: np.ndarray) -> np.ndarray:
        """Sums over each observation's holes of ``hole_values`` (last axis: the holes; leading axes kept)."""
        n = len(self.obs)
        lead = hole_values.shape[:-1]
        flat = (np.arange(int(np.prod(lead)))[:, None] * n + self._hole_row).ravel()
        return np.bincount(flat, hole_values.ravel(), minlength=n * int(np.prod(lead))).reshape(*lead, n)

    def _pressure_sums(self, effects: Effects) -> tuple[float, PressureSums]:
        """(A_p, the running sums of Δp of the triangle cases) of a run without friction (remembered)."""
        def run():
            self._calls += 1
            hyd = Hydraulics.from_damper(self.damper, effects)
            return hyd.piston_area_m2, PressureSums(self.obs.plans, hyd, self.obs.viscosity_scale, 0.0, MODEL_STEP,
                                                    self.obs.drives or None)
        return self._remembered("sums", effects, run)

    def lagged(self, effects: Effects, lags_s) -> np.ndarray:
        """Model mean force of every observation as a force channel lagging by each of ``lags_s`` would
        read it [N], one row per lag: the mean over the observation's samples shifted back by lag·fs
        (linear interpolation between whole samples; the model is at rest, force 0, before its first
        sample). One simulation for all lags (a pure delay: the force channel's low-frequency group delay);
        triangle cases without friction from the running sums of Δp (:class:`PressureSums`), as :meth:`predict`."""
        lags = np.atleast_1d(np.asarray(lags_s, dtype=float))
        if self._on_grid(effects):
            return self._grid_read(effects, 0, lags)
        if effects.coulomb_force_N or effects.stribeck_force_N or any(self._sine):
            return self._shifted_means(self.forces(effects), lags)
        k, frac = self._lag_steps(lags)
        area, run = self._pressure_sums(effects)
        obs = self.obs
        case = np.broadcast_to(obs.case_index, k.shape).ravel()
        means = []
        for j in (k, k + 1):
            sums = run.sums(case, np.maximum(obs.start - j, 0).ravel(), np.maximum(obs.stop - j, 0).ravel())
            sums = sums.reshape(k.shape)
            if self._hole_row.size:
                jh = j[:, self._hole_row]
                at = np.broadcast_to(self._hole_case, jh.shape).ravel()
                sums = sums - self._per_row(run.sums(at, np.maximum(self._hole_at - jh, 0).ravel(),
                                                     np.maximum(self._hole_at + 1 - jh, 0).ravel()
                                                     ).reshape(jh.shape))
            means.append(area * sums / self._n)
        return (1.0 - frac) * means[0] + frac * means[1]

    def _lag_steps(self, lags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each lag in whole samples k and the fraction of the next, per lag (rows) and observation (columns):
        lag·fs = k + frac, the means of :meth:`lagged` interpolated between shifts k and k + 1."""
        shift = lags[:, None] * self._fs
        k = np.floor(shift).astype(np.int64)
        return k, shift - k

    def read(self, effects: Effects, form: int, lags_s) -> np.ndarray:
        """Model mean force of every observation as a force channel of ``form`` reads it, one row per group
        delay of ``lags_s``: 0 a pure delay (:meth:`lagged`), 1 or 2 a Butterworth low-pass of that order
        (:meth:`filtered`)."""
        return self.lagged(effects, lags_s) if form == 0 else self.filtered(effects, lags_s, form)

    def _shifted_means(self, forces: list[np.ndarray], lags: np.ndarray) -> np.ndarray:
        """Means of ``forces`` (per case, on its sample grid) over every observation's samples shifted back by
        each lag·fs, one row per lag (:meth:`lagged`)."""
        k, frac = self._lag_steps(lags)
        self._means(forces, 1)
        cs, first = self._sums, self._first[self._hole_row]
        means = [(cs[np.maximum(self._hi - j, self._first)] - cs[np.maximum(self._lo - j, self._first)]
                  - (self._per_row(cs[np.maximum(self._hole_abs + 1 - j[:, self._hole_row], first)]
                                   - cs[np.maximum(self._hole_abs - j[:, self._hole_row], first)])
                     if self._hole_row.size else 0.0)) / self._n
                 for j in (k, k + 1)]
        return (1.0 - frac) * means[0] + frac * means[1]

    def friction_ideal(self) -> np.ndarray:
        """The column of a profiled Coulomb friction through an ideal force channel: each observation's direction
        ``obs.sign``; where a sine drive has harmonics, which reverse the motion where its own velocity does, not
        where its phase bins' sine does, the mean of sign(v) over each observation's samples."""
        if not any(isinstance(d, SineDrive) and d.harmonics for d in self.obs.drives):
            return self.obs.sign
        return self.friction_read(0, 0.0)

    def friction_read(self, form: int, lag_s: float) -> np.ndarray:
        """Mean of each observation's unit Coulomb friction sign(v) (Eq. 8's F_f per newton of F_C, on the model's
        sample grid) as a force channel of ``form`` (0: a delay, 1 or 2: a Butterworth low-pass, as :meth:`lagged`
        and :meth:`filtered`) and group delay ``lag_s`` reads it: the column of a profiled friction, which passes
        through the channel as the hydraulic force does (near a reversal the channel still reads the other sign).
        An ideal channel reads :meth:`friction_ideal`."""
        key = (int(form), float(lag_s))
        hit = self._friction_reads.get(key)
        if hit is None:
            if self._grid is not None and (form or lag_s):   # sine cases: on the drive's reversals
                hit = self._grid.friction_read(form, lag_s)
            else:
                unit = self._unit_friction()
                lags = np.array([float(lag_s)])
                hit = self._shifted_means(unit, lags)[0] if form == 0 else self._filtered_means(unit, lags, form)[0]
            if len(self._friction_reads) >= RUN_CACHE:
                self._friction_reads.pop(next(iter(self._friction_reads)))
            self._friction_reads[key] = hit
        return hit

    def _unit_friction(self) -> list[np.ndarray]:
        """sign(v) of the driven piston on every case's sample grid (one nominal run, remembered)."""
        if self._unit is None and self._grid is not None:   # sine drives: their velocity needs no model run
            times = [d.times(p.sample_rate_Hz) for d, p in zip(self.obs.drives, self.obs.plans, strict=True)]
            self._unit = [np.sign(np.where(t > 0.0, d.velocity(t), 0.0)) for d, t in zip(self.obs.drives, times,
                                                                                         strict=True)]
        if self._unit is None:
            self._calls += 1
            unit_friction = Effects(coulomb_force_N=1.0)
            self._unit = [friction_force(vel, unit_friction)
                          for _t, _dp, vel in self._responses(Hydraulics.from_damper(self.damper, NOMINAL))]
        return self._unit

    def spread(self, effects: Effects = NOMINAL) -> np.ndarray:
        """Standard deviation of the model force over each observation's samples [N]: how far the
        window is from steady (a window that starts before convergence, Eq. 28-29, is not)."""
        grid = self._on_grid(effects) and not effects.coulomb_force_N
        mean, square = self._grid.moments(effects) if grid else self._moments(effects, 2)
        return np.sqrt(np.maximum(square - mean * mean, 0.0))

    def filtered(self, effects: Effects, group_delays_s, order: int) -> np.ndarray:
        """Model mean force of every observation as a force channel behind a Butterworth low-pass of
        ``order`` (1 or 2) would read it [N], one row per low-frequency group delay L of ``group_delays_s``
        (one simulation for all). The analog filter of group delay L has the corner Ω = c/L (c = 1, √2);
        each case's digital filter is its bilinear transform at the case's sample rate (same DC group
        delay), at rest before the record (scipy.signal ``butter``/``lfilter``)."""
        if self._on_grid(effects):
            return self._grid_read(effects, order, np.atleast_1d(np.asarray(group_delays_s, dtype=float)))
        return self._filtered_means(self.forces(effects), group_delays_s, order)

    def _filtered_means(self, forces: list[np.ndarray], group_delays_s, order: int) -> np.ndarray:
        """Means of ``forces`` (per case, on its sample grid) over every observation's samples behind the
        low-pass of :meth:`filtered`, one row per group delay."""
        from scipy import signal  # scipy.signal: only where a force channel's low-pass is fitted

        c = 1.0 if order == 1 else math.sqrt(2.0)
        rates = [p.sample_rate_Hz for p in self.obs.plans]
        rows = []
        for lag in np.atleast_1d(np.asarray(group_delays_s, dtype=float)):
            design = {fs: signal.butter(order, fs / math.pi * math.atan(c / (2.0 * fs * lag)), fs=fs)
                      for fs in set(rates)}   # one design per sample rate
            out = [signal.lfilter(*design[fs], f) for f, fs in zip(forces, rates, strict=True)]
            rows.append(self._means(out, 1)[0])
        return np.array(rows)

    def forces(self, effects: Effects) -> list[np.ndarray]:
        """The model force of every case on its sample grid [N] (Eq. 8 with Δp from Eq. 13-14 for a
        triangle, from Eq. 1 driven by the fitted sine for a sine case); read-only arrays."""
        return self._remembered("forces", effects, lambda: self._forces(effects))

    def _forces(self, effects: Effects) -> list[np.ndarray]:
        self._calls += 1
        hyd = Hydraulics.from_damper(self.damper, effects)
        friction = bool(effects.coulomb_force_N or effects.stribeck_force_N)
        forces = []
        for _t, dp, vel in self._responses(hyd):
            force = hyd.piston_area_m2 * dp
            if friction:  # the search profiles friction linearly (LinearTerms): its runs carry none
                force = force + friction_force(vel, effects)
            force.flags.writeable = False
            forces.append(force)
        return forces

    def _responses(self, hyd: Hydraulics) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(t, Δp, piston velocity) of every case, in the order of the plans; each case at its own
        temperature's viscosity (none given: all at the damper's)."""
        obs = self.obs
        drives = obs.drives if obs.drives else None
        if not any(self._sine):
            return list(triangle_responses_at(obs.plans, hyd, obs.viscosity_scale, 0.0, MODEL_STEP, drives))
        scales = obs.viscosity_scale or (1.0,) * len(obs.plans)
        tri = [i for i, sine in enumerate(self._sine) if not sine]
        out: list = [None] * len(obs.plans)
        if tri:
            pick = tuple(obs.drives[i] for i in tri)
            runs = triangle_responses_at([obs.plans[i] for i in tri], hyd,
                                         tuple(scales[i] for i in tri) if obs.viscosity_scale else (), 0.0,
                                         MODEL_STEP, pick if any(d is not None for d in pick) else None)
            for i, run in zip(tri, runs, strict=True):
                out[i] = run
        for i, sine in enumerate(self._sine):
            if sine:
                out[i] = sine_drive_response(obs.drives[i], obs.plans[i].sample_rate_Hz,
                                             scaled_viscosity(hyd, scales[i]))
        return out

    def _moments(self, effects: Effects, order: int) -> list[np.ndarray]:
        return self._means(self.forces(effects), order)

    def _means(self, forces: list[np.ndarray], order: int) -> list[np.ndarray]:
        """Means of the forces' powers 1..order over every observation's samples (the running sums of
        the last power stay in ``self._sums``)."""
        out = []
        cs = self._sums
        for k in range(order):
            at = 0
            for force in forces:
                cs[at] = 0.0
                np.cumsum(force if k == 0 else force ** (k + 1), out=cs[at + 1:at + 1 + force.size])
                at += force.size + 1
            sums = cs[self._hi] - cs[self._lo]
            if self._hole_row.size:
                sums = sums - self._per_row(cs[self._hole_abs + 1] - cs[self._hole_abs])
            out.append(sums / self._n)
        return out


def drive_input_variance(obs: Observations, damper: Damper, nominal_N: np.ndarray) -> np.ndarray:
    """Variance [N²] that the error of each measured drive propagates into the model means:
    (∂F/∂ln v · se(v)/v)², ∂F/∂ln v from the nominal model with every speed scaled by 1 + SPEED_STEP; for a sine
    drive also its phase's, (∂F/∂φ · se(φ))², with se(φ) = se(Y)/Y (a least-squares sine through white noise
    pins its phase in radians as well as its relative amplitude), ∂F/∂φ from the drive shifted by PHASE_STEP:
    near the reversals, where the force turns fastest, a phase error moves the bins most."""
    if obs.speed_rel_se is None or not obs.drives or not any(obs.drives):
        return np.zeros(len(obs))
    scaled = tuple(None if d is None else d.scaled(1.0 + SPEED_STEP) if isinstance(d, SineDrive)
                   else replace(d, speeds_m_s=tuple(v * (1.0 + SPEED_STEP) for v in d.speeds_m_s))
                   for d in obs.drives)
    shifted = Evaluator(replace(obs, drives=scaled), damper).predict(NOMINAL)
    variance = ((shifted - nominal_N) / SPEED_STEP * obs.speed_rel_se) ** 2
    sine = np.array([isinstance(obs.drives[i], SineDrive) for i in obs.case_index], dtype=bool)
    if sine.any():
        later = tuple(replace(d, grid_start_s=d.grid_start_s + PHASE_STEP / (2.0 * math.pi * d.frequency_Hz))
                      if isinstance(d, SineDrive) else d for d in obs.drives)
        turned = Evaluator(replace(obs, drives=later), damper).predict(NOMINAL)
        variance[sine] += ((turned - nominal_N) / PHASE_STEP * obs.speed_rel_se)[sine] ** 2
        variance += harmonic_input_variance(obs, damper, nominal_N)
    return variance


def _measured(drive, k: int) -> bool:
    """Whether ``drive`` is a sine drive whose harmonic ``k`` was measured (has a standard error)."""
    return isinstance(drive, SineDrive) and k - 2 < len(drive.harmonic_se_m)


def harmonic_input_variance(obs: Observations, damper: Damper, nominal_N: np.ndarray) -> np.ndarray:
    """Variance [N²] that the measured motion's harmonics propagate into a sine case's model means: Σ over the
    sine and cosine components of harmonics 2 .. of (∂F/∂c · se(c))², the sensitivities from the nominal model
    with that component of every sine drive moved by HARMONIC_STEP of its fundamental's amplitude (one run per
    component for all cases). Those the drive holds are known to within se(c); those it leaves out (within
    :data:`isokinetic.diagnosis.sine_observations.HARMONIC_SIGMAS` of their errors) are zero to within about as
    much: on a short fast record, where the LVDT's noise is a large share of the amplitude, this is what its
    bins can tell least."""
    variance = np.zeros(len(obs))
    n_harmonics = max((len(d.harmonic_se_m) for d in obs.drives if isinstance(d, SineDrive)), default=0)
    for j in range(n_harmonics):
        se = np.array([d.harmonic_se_m[j] / d.amplitude_m if _measured(d, j + 2) else 0.0
                       for d in obs.drives])[obs.case_index]
        if not np.any(se > 0.0):
            continue
        for cosine in (False, True):
            moved = tuple(d.with_harmonic_step(j + 2, cosine, HARMONIC_STEP * d.amplitude_m)
                          if _measured(d, j + 2) else d for d in obs.drives)
            changed = Evaluator(replace(obs, drives=moved), damper).predict(NOMINAL)
            variance += ((changed - nominal_N) / HARMONIC_STEP * se) ** 2
    return variance


def unsteady_windows(obs: Observations, model_spread_N: np.ndarray) -> frozenset:
    """(case, segment) of the windows whose nominal-model force is not steady: its spread over the
    window exceeds UNSTEADY_FRACTION of the per-sample noise the first noise fit estimated (at most
    half of the windows, the least steady first, so that the noise fit keeps data)."""
    # the triangles' windows: a sine's bins vary by design, and its noise is fitted on other samples
    win = np.flatnonzero(obs.is_window & np.array([obs.plans[i].waveform == "triangle" for i in obs.case_index],
                                                  dtype=bool))
    models = obs.noise.get("objects") or {}
    rates = [obs.plans[obs.case_index[i]].sample_rate_Hz for i in win]
    per_sample = np.array([math.sqrt(max(models[fs].sample_variance_N2(obs.force_N[i] ** 2), 1e-300))
                           if fs in models else math.inf for i, fs in zip(win, rates, strict=True)])
    spread = model_spread_N[win]
    least_steady = np.argsort(-spread / per_sample)[: len(win) // 2]
    bad = [win[j] for j in least_steady if spread[j] > UNSTEADY_FRACTION * per_sample[j]]
    return frozenset((str(obs.case[i]), int(obs.segment[i])) for i in bad)
