"""Noise-free responses of the virtual rig: Δp, piston velocity and force of a planned case.

Implements the damper model of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.); equation numbers are the paper's.
The force is Eq. (8) with a massless piston: F = A_p Δp + F_f(dy/dt) (Coulomb + Stribeck).

Triangle excitation
    Segment quadrature (:mod:`isokinetic.physics.hydraulics`, Eq. 13-14): segments of constant
    piston velocity from the play operator (:func:`excitation.piston_segments`), chained with Δp
    continuous; the cases advance in lockstep, the tables of the j-th segments of all cases built in
    one vectorised pass, then all samples evaluated at once (:func:`triangle_responses`).

Sine excitation
    Stiff integration with ``scipy.integrate.solve_ivp`` (LSODA, analytic Jacobian, rtol 1e-12:
    ~2e-10 relative to a Radau rtol 1e-13 solution, an order of magnitude faster than Radau at
    equal accuracy), split at every velocity discontinuity (turning points, gap contacts), t_eval
    at the samples (:func:`sine_response`).

A rigid servo (stiffness inf) uses these fast paths; a finite stiffness the coupled
actuator-gap-damper model of :mod:`isokinetic.physics.servo`.
"""

from __future__ import annotations

import math
import operator
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from isokinetic.physics.damper import NOMINAL, Damper, Effects, friction_force
from isokinetic.physics.excitation import (
    Segment,
    check_stroke,
    command_displacement,
    direction_between,
    piston_segments,
    record_end,
    sample_times,
    segment_index,
    turning_times,
)
from isokinetic.physics.gas_law import stored_volume_rate
from isokinetic.physics.hydraulics import (
    DEFAULT_STEP,
    Hydraulics,
    RelaxationBatch,
    compressibility_divisors,
    compressibility_logs,
    compressibility_times,
    relaxation_batch,
    start_volumes,
    steady_pressure,
    tau_volumes,
)
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.servo import check_stiffness, servo_response
from isokinetic.physics.sine_drive import fused_segment_system, initial_state, state_pressure


def triangle_response(case: CasePlan, hyd: Hydraulics, backlash_m: float = 0.0, step: float = DEFAULT_STEP):
    """Δp and piston velocity of a triangle case by segment quadrature, Eq. (13)-(14).

    Returns (t_s, dp_Pa, piston_velocity_m_s); Δp(0) = 0. See :func:`triangle_responses`.
    """
    return triangle_responses([case], hyd, backlash_m, step)[0]


@dataclass(frozen=True)
class Drive:
    """The piston motion a triangle case really had, measured from its displacement record.

    The model is then run "on equal terms" with the rig (paper Sec. 4.5): half-period j (1-based)
    moves at the measured speed ``speeds_m_s[j-1]`` (later half-periods repeat the last measured
    one of the same direction) between the plan's turning points (Eq. 26), the piston position
    chained from -Y; ``grid_offset_s`` in [0, 1/fs) is the plan time of the first sample, so that
    model samples fall at the measured samples' plan times (record time minus motion start).
    """

    speeds_m_s: tuple[float, ...]
    grid_offset_s: float = 0.0

    def __post_init__(self):
        if not self.speeds_m_s or any(not (math.isfinite(v) and v > 0) for v in self.speeds_m_s):
            raise ValueError(f"drive: speeds must be positive and finite, got {self.speeds_m_s}")
        if not (math.isfinite(self.grid_offset_s) and self.grid_offset_s >= 0):
            raise ValueError(f"drive: grid offset must be >= 0, got {self.grid_offset_s}")

    def speed(self, j: int) -> float:
        """The speed [m/s] of half-period j (0-based); beyond the measured ones, the last of the same direction."""
        n = len(self.speeds_m_s)
        if j < n:
            return self.speeds_m_s[j]
        k = n - 1 if (j - (n - 1)) % 2 == 0 else n - 2
        return self.speeds_m_s[max(k, 0)]


def drive_times(case: CasePlan, drive: Drive | None = None) -> np.ndarray:
    """Model sample times: k / fs (plan grid), or grid_offset + k / fs up to the duration [s]."""
    if drive is None or drive.grid_offset_s == 0.0:
        return sample_times(case)
    n = int(math.floor((case.duration_s - drive.grid_offset_s) * case.sample_rate_Hz + 1e-9))
    return drive.grid_offset_s + np.arange(max(n, 0) + 1, dtype=float) / case.sample_rate_Hz


def driven_segments(case: CasePlan, drive: Drive, times: np.ndarray | None = None) -> list[Segment]:
    """The contact segments between the plan's turning points at the drive's measured speeds.

    The piston starts at the command's start -Y (Eq. 26) and its position is chained through the
    segments, so amplitude follows from the measured speeds. ``times``: the case's
    :func:`drive_times`, if already at hand.
    """
    last = float((drive_times(case, drive) if times is None else times)[-1])
    edges = [0.0, *turning_times(case), max(record_end(case), last)]
    omega, phase = 2.0 * math.pi / case.period_s, case.phase_rad
    y = float(command_displacement(case, 0.0))
    segs = []
    for j, (ta, tb) in enumerate(zip(edges[:-1], edges[1:])):
        d = direction_between(omega, phase, ta, tb)
        segs.append(Segment(ta, tb, True, y, 0.0, d))
        y += d * drive.speed(j) * (tb - ta)
    return segs


def _check_positions(case: CasePlan, segs: Sequence[Segment], flows: Sequence[float], hyd: Hydraulics) -> None:
    """A driven piston must not empty a chamber anywhere on its path (Eq. 12)."""
    limit = min(hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3) / hyd.piston_area_m2
    for seg, qp in zip(segs, flows):
        end = seg.piston_start_m + qp / hyd.piston_area_m2 * (seg.t_end_s - seg.t_start_s)
        if max(abs(seg.piston_start_m), abs(end)) >= limit:
            raise ValueError(f"case {case.case}: the measured motion reaches the end of the cylinder "
                             f"(V0/A_p = {limit:g} m)")


def _triangle_plan(case: CasePlan, drive: Drive | None, hyd: Hydraulics, backlash_m: float,
                   times: np.ndarray | None = None):
    """(segments, piston flows A_p W of each) of a triangle case, from its plan or its drive
    (``times``: its :func:`drive_times`, if at hand)."""
    if case.waveform != "triangle":
        raise ValueError(f"case {case.case}: not a triangle")
    a = hyd.piston_area_m2
    if drive is None:
        check_stroke(case, hyd)
        w = 4.0 * case.amplitude_m / case.period_s
        segs = piston_segments(case, backlash_m)
        return segs, [a * seg.direction * w if seg.contact else 0.0 for seg in segs]
    if backlash_m:
        raise ValueError(f"case {case.case}: a measured drive has no backlash model")
    segs = driven_segments(case, drive, times)
    flows = [a * seg.direction * drive.speed(j) for j, seg in enumerate(segs)]
    _check_positions(case, segs, flows, hyd)
    return segs, flows


@dataclass(frozen=True)
class _Layout:
    """What a batch of triangle cases needs besides the damper coefficients: their sample grids
    and their segments (arrays, case after case, all read-only)."""

    times: tuple[np.ndarray, ...]   # sample times of each case [s]
    times_all: np.ndarray           # all of them, concatenated
    case: np.ndarray                # segment -> case
    j: np.ndarray                   # segment -> its number within its case
    t0: np.ndarray                  # start [s]
    t1: np.ndarray                  # end [s]
    flow: np.ndarray                # piston flow A_p W of the plan [m³/s]
    w: np.ndarray                   # velocity W = flow / A_p [m/s]
    qp: np.ndarray                  # A_p W as Eq. (14) computes it from W [m³/s]
    v1: np.ndarray                  # chamber volumes at the start (Eq. 2) [m³]
    v2: np.ndarray
    y0: np.ndarray                  # piston position at the start [m]
    lo: np.ndarray                  # first sample (index in times_all)
    count: np.ndarray               # samples
    rate_Hz: np.ndarray             # sample rate of the segment's case [Hz]
    steps: tuple[np.ndarray, ...]   # the segments of step j (the j-th of each case), case after case
    memo: dict = field(default_factory=lambda: {"lock": threading.Lock()}, compare=False, repr=False)
    # ^ what depends on the layout alone (and the gas law's gas volumes), computed when first needed
    # (:func:`_sample_logs`, :meth:`volumes`)

    def volumes(self, hyd: Hydraulics) -> tuple[np.ndarray, np.ndarray]:
        """The start volumes of Eq. (14)'s τ: (v1, v2), plus the gas law's gas volumes
        (:attr:`Hydraulics.gas_volumes_m3`; remembered for the last ones)."""
        if not hyd.gas_law:
            return self.v1, self.v2
        gas = hyd.gas_volumes_m3
        with self.memo["lock"]:
            hit = self.memo.get("gas")
            if hit is None or hit[0] != gas:
                hit = self.memo["gas"] = (gas, *tau_volumes(self.v1, self.v2, hyd))
        return hit[1], hit[2]


def _build_layout(cases: Sequence[CasePlan], drives: Sequence[Drive | None], hyd: Hydraulics,
                  backlash_m: float) -> _Layout:
    """The :class:`_Layout` of cases (uses only the geometry of ``hyd``: A_p, V0,1, V0,2)."""
    times = [drive_times(case, drive) for case, drive in zip(cases, drives)]
    plans = [_triangle_plan(case, drive, hyd, backlash_m, t) for case, drive, t in zip(cases, drives, times)]
    segs = [seg for case_segs, _ in plans for seg in case_segs]
    n_seg = np.array([len(case_segs) for case_segs, _ in plans], dtype=np.int64)
    sizes = np.array([t.size for t in times], dtype=np.int64)
    lo, count = [], []
    for (case_segs, _), t, first in zip(plans, times, (np.cumsum(sizes) - sizes).tolist()):
        index = segment_index(t, case_segs)
        if index and index[0].start != 0 or any(sl.stop < sl.start for sl in index):
            raise ValueError("triangle segments must cover the samples in order")
        lo += [first + sl.start for sl in index]
        count += [sl.stop - sl.start for sl in index]
    flow = np.array([q for _, flows in plans for q in flows], dtype=float)
    w = flow / hyd.piston_area_m2
    y0 = np.array([x.piston_start_m for x in segs], dtype=float)
    v1, v2 = start_volumes(y0, hyd)
    case = np.repeat(np.arange(n_seg.size), n_seg)
    j = np.arange(case.size) - np.repeat(np.cumsum(n_seg) - n_seg, n_seg)
    by_step = np.argsort(j, kind="stable")
    bounds = np.searchsorted(j[by_step], np.arange(int(j.max(initial=-1)) + 2)).tolist()
    out = _Layout(times=tuple(times), times_all=np.concatenate(times) if times else np.zeros(0), case=case,
                  j=j,
                  t0=np.array([x.t_start_s for x in segs], dtype=float),
                  t1=np.array([x.t_end_s for x in segs], dtype=float), flow=flow, w=w,
                  qp=hyd.piston_area_m2 * w, v1=v1, v2=v2, y0=y0, lo=np.array(lo, dtype=np.int64),
                  count=np.array(count, dtype=np.int64),
                  rate_Hz=np.array([c.sample_rate_Hz for c in cases], dtype=float)[case],
                  steps=tuple(by_step[a:b] for a, b in zip(bounds[:-1], bounds[1:])))
    for array in (*out.times, *out.steps,
                  *(getattr(out, f) for f in out.__dataclass_fields__ if f not in ("times", "steps", "memo"))):
        array.flags.writeable = False
    return out


_LAYOUTS: OrderedDict = OrderedDict()
_LAYOUTS_LOCK = threading.Lock()
#: Layouts kept (a fit calls :func:`triangle_responses` hundreds of times on the same cases).
LAYOUT_CACHE = 8


def _layout(cases: Sequence[CasePlan], drives: Sequence[Drive | None], hyd: Hydraulics, backlash_m: float) -> _Layout:
    """:func:`_build_layout`, remembered for the last few (cases, drives, backlash, geometry); the very case and
    drive objects of a remembered layout (a fit's runs) are found without hashing them."""
    cases, drives = tuple(cases), tuple(drives)
    geometry = (float(backlash_m), hyd.piston_area_m2, hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3)
    with _LAYOUTS_LOCK:
        for key in reversed(_LAYOUTS):
            if key[2:] == geometry and _same_objects(key[0], cases) and _same_objects(key[1], drives):
                _LAYOUTS.move_to_end(key)
                return _LAYOUTS[key]
    key = (cases, drives, *geometry)
    with _LAYOUTS_LOCK:
        hit = _LAYOUTS.get(key)
        if hit is not None:
            _LAYOUTS.move_to_end(key)
            return hit
    out = _build_layout(cases, drives, hyd, backlash_m)
    with _LAYOUTS_LOCK:
        _LAYOUTS[key] = out
        while len(_LAYOUTS) > LAYOUT_CACHE:
            _LAYOUTS.popitem(last=False)
    return out


def _same_objects(a: tuple, b: tuple) -> bool:
    """Whether two tuples hold the very same objects, in order."""
    return len(a) == len(b) and all(map(operator.is_, a, b))


def _sample_logs(lay: _Layout, n_live: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """Eq. (14) without β_eff (:func:`compressibility_logs`) at the samples of the layout, each with its
    segment's start volumes (:meth:`_Layout.volumes`) and flow, valid for the first ``n_live`` samples of every
    segment (at least): it holds no damper coefficient (but the gas law's gas volumes), so each sample is computed
    once per layout (and gas volumes), when a run first needs it."""
    v1, v2 = lay.volumes(hyd)
    with lay.memo["lock"]:
        logs, done = lay.memo.get("logs"), lay.memo.get("done")
        if logs is None or lay.memo.get("logs_volumes") is not v1:
            logs, done = lay.memo["logs"], lay.memo["done"] = np.empty(lay.times_all.size), np.zeros_like(lay.count)
            lay.memo["logs_volumes"] = v1
        more = (n_live > done).nonzero()[0]
        if more.size:
            grow = n_live.take(more) - done.take(more)
            seg = more.repeat(grow)
            at = (lay.lo.take(more) + done.take(more)).repeat(grow) + _ranks(grow)
            logs[at] = compressibility_logs(lay.times_all.take(at) - lay.t0.take(seg), v1.take(seg), v2.take(seg),
                                            lay.qp.take(seg))
            done[more] = n_live.take(more)
    return logs


def _sample_tau(lay: _Layout, seg: np.ndarray, at: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """τ (Eq. 14, as :func:`compressibility_time`) of the samples ``times_all[at]``, sample i in segment ``seg[i]``."""
    v1, v2 = lay.volumes(hyd)
    return compressibility_times(lay.times_all.take(at) - lay.t0.take(seg), v1.take(seg), v2.take(seg),
                                 lay.qp.take(seg), hyd)


def _live_counts(lay: _Layout, tau_end: np.ndarray, table_end: np.ndarray, hyd: Hydraulics) -> np.ndarray:
    """Samples of each segment before its table's end (τ < τ_end), i.e. not yet at Δp* exactly.

    τ grows with time, so this is the first sample with τ >= τ_end: guessed from the inverse of
    Eq. (14) and settled by evaluating τ exactly as for the samples themselves (then bisection).
    """
    lo = np.zeros(lay.count.size, dtype=np.int64)
    hi = lay.count.copy()
    done = tau_end < table_end                      # the whole segment is before its table's end
    lo[done] = hi[done]
    hi[table_end == -np.inf] = 0                    # a constant table: Δp* throughout
    act = (lo < hi).nonzero()[0]
    if act.size == 0:
        return lo
    v1, v2 = lay.volumes(hyd)
    beta, v1, v2, qp, x = hyd.tau_compressibility_1_Pa, v1[act], v2[act], lay.qp[act], table_end[act]
    with np.errstate(all="ignore"):
        dt = np.where(qp == 0.0, beta * x / (1.0 / v1 + 1.0 / v2),
                      np.expm1(beta * qp * x) / (qp * (1.0 / v2 + np.exp(beta * qp * x) / v1)))
        guess = np.ceil((lay.t0[act] + dt - lay.times_all[lay.lo[act]]) * lay.rate_Hz[act])
    mid = np.clip(np.where(np.isfinite(guess), guess, hi[act]), lo[act], hi[act]).astype(np.int64)
    probe, who = np.concatenate([mid - 1, mid]), np.concatenate([act, act])   # the guess and the sample before
    while act.size:
        inside = (probe >= lo[who]) & (probe < hi[who])
        probe, who = probe[inside], who[inside]
        below = _sample_tau(lay, who, lay.lo[who] + probe, hyd) < table_end[who]
        np.maximum.at(lo, who[below], probe[below] + 1)
        np.minimum.at(hi, who[~below], probe[~below])
        act = act[lo[act] < hi[act]]
        probe, who = (lo[act] + hi[act]) // 2, act
    return lo


def _chain(lay: _Layout, tau_end: np.ndarray, hyd: Hydraulics, step: float) -> tuple[RelaxationBatch, np.ndarray]:
    """Tables of all segments, chained from Δp(0) = 0 with Δp continuous: (the tables, index of each
    segment's table). Step j of all cases at once; one table per distinct (start Δp, flow), and with the gas law
    start position and stored volume K (which the compliance depends on; K carried from segment to segment,
    :func:`_stored_change`)."""
    start = np.zeros(len(lay.times))
    stored = np.zeros(len(lay.times)) if hyd.gas_law else None
    batches: list[RelaxationBatch] = []
    known: dict[tuple, int] = {}
    table = np.empty(lay.j.size, dtype=np.int64)
    built = 0
    for live in lay.steps:
        cases = lay.case.take(live)
        columns = [start.take(cases), lay.flow.take(live)]
        if stored is not None:
            columns += [lay.y0.take(live), stored.take(cases)]
        keys = list(zip(*(c.tolist() for c in columns)))
        new = list(dict.fromkeys(key for key in keys if key not in known))
        if new:
            known.update(zip(new, range(built, built + len(new))))
            batches.append(_batch(new, hyd, step))
            built += len(new)
        ref = np.array([known[key] for key in keys], dtype=np.int64)
        table[live] = ref
        first_new = built - len(new)
        if ref.min() >= first_new:                  # all from this step's batch (the usual case)
            tabs, ref_in = batches[-1], ref - first_new
        else:
            tabs, ref_in = RelaxationBatch.concatenate(batches), ref
        if stored is not None:
            stored[cases] += _stored_change(tabs, ref_in, lay, live, start.take(cases), hyd)
        start[cases] = tabs.pressure(ref_in, tau_end.take(live))
    return RelaxationBatch.concatenate(batches), table


def _batch(keys: list[tuple], hyd: Hydraulics, step: float) -> RelaxationBatch:
    """The tables of problems ``keys``: (start Δp, flow) or (start Δp, flow, start position, stored volume)."""
    columns = [list(c) for c in zip(*keys)]
    return relaxation_batch(columns[0], columns[1], hyd, step, *columns[2:])


#: Intervals of the composite Simpson rule of :func:`_stored_change`.
STORED_INTERVALS = 16


def _stored_change(tabs: RelaxationBatch, ref: np.ndarray, lay: _Layout, live: np.ndarray, dp_start: np.ndarray,
                   hyd: Hydraulics) -> np.ndarray:
    """ΔK = -β_oil A_p W ∫ Δp dt over each segment ``live`` (:func:`isokinetic.physics.gas_law.stored_volume_rate`;
    composite Simpson on :data:`STORED_INTERVALS`, Δp from the segment's table ``ref``)."""
    n = STORED_INTERVALS
    dt = lay.t1.take(live) - lay.t0.take(live)
    frac = np.arange(1, n + 1) / n
    v1, v2 = lay.volumes(hyd)
    tau = compressibility_times(np.outer(dt, frac).ravel(), v1.take(live).repeat(n), v2.take(live).repeat(n),
                                lay.qp.take(live).repeat(n), hyd)
    dp = np.empty((live.size, n + 1))
    dp[:, 0] = dp_start
    dp[:, 1:] = tabs.pressure(ref.repeat(n), tau).reshape(live.size, n)
    weights = np.ones(n + 1)
    weights[1:-1:2], weights[2:-1:2] = 4.0, 2.0
    integral = dp @ weights * (dt / (3.0 * n))
    return stored_volume_rate(integral, lay.w.take(live), hyd.tau_compressibility_1_Pa, hyd.piston_area_m2)


#: Samples evaluated together (numpy passes over arrays that stay in cache).
CHUNK_SAMPLES = 8192


def _live_pressures(tabs: RelaxationBatch, table: np.ndarray, lay: _Layout, n_live: np.ndarray,
                    hyd: Hydraulics) -> np.ndarray:
    """Δp of the first ``n_live`` samples of every segment, segment after segment (Eq. 14 then the table), in
    runs of ascending samples of one table grouped into cache-sized chunks."""
    owners = n_live.nonzero()[0]
    counts = n_live.take(owners)
    logs = _sample_logs(lay, n_live, hyd)
    tau = np.concatenate([logs[a:a + n] for a, n in zip(lay.lo.take(owners).tolist(), counts.tolist())]) \
        if owners.size else np.zeros(0)
    tau /= compressibility_divisors(lay.qp.take(owners), hyd).repeat(counts)   # τ: Eq. (14), as _sample_tau
    runs = -(-counts // CHUNK_SAMPLES)
    run_seg = np.repeat(owners, runs)
    run_len = np.minimum(n_live.take(run_seg) - _ranks(runs) * CHUNK_SAMPLES, CHUNK_SAMPLES)
    ends = np.cumsum(run_len)
    chunk = (ends - 1) // CHUNK_SAMPLES
    cuts = [0, *((chunk[1:] != chunk[:-1]).nonzero()[0] + 1).tolist(), run_seg.size]
    bounds = [0, *ends.tolist()]
    dp = np.empty(tau.size)
    for a, b in zip(cuts[:-1], cuts[1:]):
        lo, hi = bounds[a], bounds[b]
        dp[lo:hi] = tabs.pressure_runs(table.take(run_seg[a:b]), run_len[a:b], tau[lo:hi])
    return dp


def _ranks(counts: np.ndarray) -> np.ndarray:
    """0..counts[k]-1 for every k, concatenated."""
    return np.arange(int(counts.sum())) - (counts.cumsum() - counts).repeat(counts)


def _segment_tables(cases: Sequence[CasePlan], hyd: Hydraulics, backlash_m: float, step: float,
                    drives: Sequence[Drive | None] | None) -> tuple[_Layout, RelaxationBatch, np.ndarray, np.ndarray]:
    """The layout of (non-empty) ``cases``, the chained tables, each segment's table and its live samples
    (those before the table's end; the rest are at Δp*)."""
    drives = [None] * len(cases) if drives is None else list(drives)
    if len(drives) != len(cases):
        raise ValueError(f"{len(drives)} drives for {len(cases)} cases")
    try:
        lay = _layout(cases, drives, hyd, backlash_m)
    except TypeError:                               # unhashable cases or drives: not remembered
        lay = _build_layout(cases, drives, hyd, backlash_m)
    tau_end = compressibility_times(lay.t1 - lay.t0, *lay.volumes(hyd), lay.qp, hyd)
    tabs, table = _chain(lay, tau_end, hyd, step)
    return lay, tabs, table, _live_counts(lay, tau_end, tabs.end_tau[table], hyd)


def triangle_pressure_sums(cases: Sequence[CasePlan], hyd: Hydraulics, case_index: np.ndarray, start: np.ndarray,
                           stop: np.ndarray, viscosity_scales: Sequence[float] = (), backlash_m: float = 0.0,
                           step: float = DEFAULT_STEP, drives: Sequence[Drive | None] | None = None) -> np.ndarray:
    """Σ Δp [Pa] of :func:`triangle_responses_at` over the samples ``start[k]:stop[k]`` of case ``case_index[k]``,
    for every k, without evaluating the samples one by one where they need no evaluation: a segment's samples
    after its table's end are all at Δp* (Eq. 13 steady state), their sum is count·Δp*. Equal to summing the
    samples up to rounding (the partial sums run over each case, as a cumulative sum of its samples would).
    The same as ``PressureSums(...).sums(case_index, start, stop)``."""
    return PressureSums(cases, hyd, viscosity_scales, backlash_m, step, drives).sums(case_index, start, stop)


class PressureSums:
    """One run of the model over triangle cases (:func:`triangle_responses_at`'s Δp), kept as running sums:
    Σ Δp over any sample ranges of its cases (:meth:`sums`) without running it again. The segments' tables are
    chained (Eq. 13-14), the samples before each table's end evaluated, the rest counted at Δp*."""

    def __init__(self, cases: Sequence[CasePlan], hyd: Hydraulics, viscosity_scales: Sequence[float] = (),
                 backlash_m: float = 0.0, step: float = DEFAULT_STEP, drives: Sequence[Drive | None] | None = None):
        if viscosity_scales and len(viscosity_scales) != len(cases):
            raise ValueError(f"{len(viscosity_scales)} viscosity scales for {len(cases)} cases")
        self.n_cases = len(cases)
        drives = [None] * len(cases) if drives is None else list(drives)
        groups: dict[Hydraulics, list[int]] = {}
        for i, scale in enumerate(viscosity_scales or [1.0] * len(cases)):
            groups.setdefault(scaled_viscosity(hyd, scale), []).append(i)
        self.groups = []   # (the group's cases, local index of every case or -1, its running sums)
        for group_hyd, idx in groups.items():
            local = np.full(len(cases), -1, dtype=np.int64)
            local[idx] = np.arange(len(idx))
            group_drives = [drives[i] for i in idx]
            tables = _segment_tables([cases[i] for i in idx], group_hyd, backlash_m, step,
                                     group_drives if any(d is not None for d in group_drives) else None)
            self.groups.append((local, _RunningSums(*tables, group_hyd)))

    def sums(self, case_index: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
        """Σ Δp [Pa] over the samples ``start[k]:stop[k]`` of case ``case_index[k]``, for every k."""
        case_index, start, stop = (np.asarray(a, dtype=np.int64) for a in (case_index, start, stop))
        out = np.zeros(case_index.size)
        for local, run in self.groups:
            mine = (local[case_index] >= 0).nonzero()[0]
            out[mine] = run.range_sums(local[case_index[mine]], start[mine], stop[mine])
        return out


class _RunningSums:
    """Σ Δp of the samples of a layout's cases, per segment (the live samples evaluated, :func:`_live_pressures`;
    the rest count·Δp*), ready for sums over any sample ranges (:meth:`range_sums`)."""

    def __init__(self, lay: _Layout, tabs: RelaxationBatch, table: np.ndarray, n_live: np.ndarray, hyd: Hydraulics):
        live = _live_pressures(tabs, table, lay, n_live, hyd)
        self.live_sum = np.empty(live.size + 1)                                 # live samples, segment by segment
        self.live_sum[0] = 0.0
        np.cumsum(live, out=self.live_sum[1:])
        self.live_first = np.cumsum(n_live) - n_live                            # each segment's first in live_sum
        self.n_live = n_live
        self.steady = tabs.steady_Pa[table]
        totals = (self.live_sum[self.live_first + n_live] - self.live_sum[self.live_first]) \
            + self.steady * (lay.count - n_live)
        self.before = np.cumsum(totals) - totals                                # Σ of the segments before
        n_seg = np.bincount(lay.case, minlength=len(lay.times))
        self.first_seg = np.cumsum(n_seg) - n_seg
        self.last_seg = self.first_seg + n_seg - 1
        sizes = np.array([t.size for t in lay.times], dtype=np.int64)
        self.case_first = np.cumsum(sizes) - sizes
        self.lo = lay.lo

    def prefix(self, case: np.ndarray, local_at: np.ndarray) -> np.ndarray:
        """Σ Δp of the case's samples before ``local_at``."""
        at = self.case_first[case] + local_at
        seg = np.minimum(np.searchsorted(self.lo, at, side="right") - 1, self.last_seg[case])
        seg = np.maximum(seg, self.first_seg[case])
        into = at - self.lo[seg]
        k = np.minimum(into, self.n_live[seg])
        first = self.live_first[seg]
        return (self.before[seg] - self.before[self.first_seg[case]] + self.live_sum[first + k]
                - self.live_sum[first] + self.steady[seg] * (into - k))

    def range_sums(self, case: np.ndarray, start: np.ndarray, stop: np.ndarray) -> np.ndarray:
        """Σ Δp over samples [start, stop) of each ``case`` of the layout."""
        return self.prefix(case, stop) - self.prefix(case, start)


def triangle_responses(cases: Sequence[CasePlan], hyd: Hydraulics, backlash_m: float = 0.0,
                       step: float = DEFAULT_STEP, drives: Sequence[Drive | None] | None = None
                       ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`triangle_response` of many cases, their segment tables built in batches.

    Every case is chained segment after segment from Δp(0) = 0, Δp continuous; the cases advance in
    lockstep, so that the tables of the j-th segments of all cases (from their actual start Δp) are
    built in one vectorised :func:`relaxation_batch` call, shared by cases with the same start and flow. The
    chain evaluates the segments' ends only; then the samples of all segments at once, where those
    after their table's end are Δp* without evaluating their τ. ``drives`` (one per case, None: the
    plan) runs a case with its measured half-period speeds on its measured sample grid
    (:class:`Drive`; no backlash). The sample grids and segments of the last few case sets are
    remembered (fits call this hundreds of times on the same cases).
    """
    if not cases:
        return []
    lay, tabs, table, n_live = _segment_tables(cases, hyd, backlash_m, step, drives)
    dp = np.repeat(tabs.steady_Pa[table], lay.count)
    dp[lay.lo.repeat(n_live) + _ranks(n_live)] = _live_pressures(tabs, table, lay, n_live, hyd)
    vel = np.repeat(lay.w, lay.count)
    ends = np.cumsum([t.size for t in lay.times]).tolist()
    return [(t.copy(), dp[e - t.size:e], vel[e - t.size:e]) for t, e in zip(lay.times, ends)]


def triangle_responses_at(cases: Sequence[CasePlan], hyd: Hydraulics, viscosity_scales: Sequence[float] = (),
                          backlash_m: float = 0.0, step: float = DEFAULT_STEP,
                          drives: Sequence[Drive | None] | None = None
                          ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """:func:`triangle_responses` with each case's oil viscosity times its ``viscosity_scales`` entry (the
    viscosity at the case's temperature, :func:`scaled_viscosity`); empty: every case at ``hyd``. The cases
    that share coefficients run in one batch, results in case order."""
    if not viscosity_scales:
        return triangle_responses(cases, hyd, backlash_m, step, drives)
    if len(viscosity_scales) != len(cases):
        raise ValueError(f"{len(viscosity_scales)} viscosity scales for {len(cases)} cases")
    drives = [None] * len(cases) if drives is None else list(drives)
    groups: dict[Hydraulics, list[int]] = {}
    for i, scale in enumerate(viscosity_scales):
        groups.setdefault(scaled_viscosity(hyd, scale), []).append(i)
    out: list = [None] * len(cases)
    for hyd, idx in groups.items():
        group_drives = [drives[i] for i in idx]
        runs = triangle_responses([cases[i] for i in idx], hyd, backlash_m, step,
                                  group_drives if any(d is not None for d in group_drives) else None)
        for i, run in zip(idx, runs, strict=True):
            out[i] = run
    return out


def scaled_viscosity(hyd: Hydraulics, scale: float) -> Hydraulics:
    """``hyd`` with the oil's viscosity multiplied by ``scale``: c1 = 8 π μ l_O / A_O² scales with it
    (Sec. 2.2); c2 does not hold μ."""
    if scale == 1.0:
        return hyd
    neg = None if hyd.laminar_coefficient_neg is None else hyd.laminar_coefficient_neg * scale
    return replace(hyd, laminar_coefficient=hyd.laminar_coefficient * scale, laminar_coefficient_neg=neg)


def sine_response(case: CasePlan, hyd: Hydraulics, backlash_m: float = 0.0, rtol: float = 1e-12,
                  method: str = "LSODA"):
    """Δp and piston velocity of a sine case by stiff integration of Eq. (1) (solve_ivp).

    Split at turning points and gap contacts; atol = rtol × the steady Δp at peak velocity.
    Returns (t_s, dp_Pa, piston_velocity_m_s); Δp(0) = 0.
    """
    from scipy.integrate import solve_ivp  # ~0.4 s of imports: only sine cases are integrated

    if case.waveform != "sine":
        raise ValueError(f"case {case.case}: not a sine")
    check_stroke(case, hyd)
    t = sample_times(case)
    omega = 2.0 * math.pi * case.frequency_Hz
    amp = case.amplitude_m
    a = hyd.piston_area_m2
    atol = rtol * max(abs(steady_pressure(a * amp * omega, hyd)), abs(steady_pressure(-a * amp * omega, hyd)), 1.0)
    segs = piston_segments(case, backlash_m)
    dp = np.empty(t.size)
    vel = np.zeros(t.size)
    state = initial_state(hyd)
    for seg, idx in zip(segs, segment_index(t, segs)):
        rhs, jac = fused_segment_system(seg, hyd, amp, omega)
        t_eval = t[idx]
        t0, t1 = seg.t_start_s, seg.t_end_s
        sol = solve_ivp(rhs, (t0, t1), state, method=method, jac=jac, rtol=rtol, atol=atol,
                        t_eval=np.append(t_eval, t1) if t_eval.size == 0 or t_eval[-1] < t1 else t_eval)
        if not sol.success:
            raise RuntimeError(f"case {case.case}: sine integration failed: {sol.message}")
        dp[idx] = state_pressure(sol.y[:, :t_eval.size].T, hyd)
        state = [float(x) for x in sol.y[:, -1]]
        if seg.contact:
            vel[idx] = amp * omega * np.cos(omega * t_eval)
    return t, dp, vel


def true_response(case: CasePlan, damper: Damper, effects: Effects = NOMINAL,
                  hydraulics: Hydraulics | None = None, servo_stiffness_N_m: float = math.inf) -> pd.DataFrame:
    """The noise-free record: time_s, command_m, actuator_m, piston_velocity_m_s, dp_Pa, force_N (Eq. 8).

    ``hydraulics`` overrides the coefficients derived from damper and effects (e.g. c2 = 0);
    friction and backlash always come from ``effects``. ``actuator_m`` is what the LVDT sees: the
    command itself for a rigid servo (k = inf), command - F/k otherwise (:func:`servo.servo_response`).
    """
    return true_responses([case], damper, effects, hydraulics, servo_stiffness_N_m)[0]


def true_responses(cases: Sequence[CasePlan], damper: Damper, effects: Effects = NOMINAL,
                   hydraulics: Hydraulics | None = None,
                   servo_stiffness_N_m: float = math.inf) -> list[pd.DataFrame]:
    """:func:`true_response` of many cases (triangle tables built in one batch).

    A rigid servo (k = inf) uses the quadrature (triangle) and the LSODA play-operator model
    (sine); a finite k integrates the coupled actuator-gap-damper system (:func:`servo.servo_response`)
    for both waveforms.
    """
    hyd = Hydraulics.from_damper(damper, effects) if hydraulics is None else hydraulics
    servo = check_stiffness(servo_stiffness_N_m, "servo_stiffness_N_m")
    for c in cases:
        if c.waveform not in ("triangle", "sine"):
            raise ValueError(f"case {c.case}: the virtual rig cannot simulate waveform {c.waveform!r}")
    rigid = math.isinf(servo)
    tri = iter(triangle_responses([c for c in cases if c.waveform == "triangle"] if rigid else [], hyd,
                                  effects.backlash_m))
    out = []
    for case in cases:
        command = command_displacement(case, sample_times(case))
        if rigid:
            t, dp, vel = next(tri) if case.waveform == "triangle" else sine_response(case, hyd, effects.backlash_m)
            force = hyd.piston_area_m2 * dp + friction_force(vel, effects)
            actuator = command
        else:
            t, dp, vel, force, actuator, _ = servo_response(case, hyd, effects, servo)
        out.append(pd.DataFrame({"time_s": t, "command_m": command, "actuator_m": actuator,
                                 "piston_velocity_m_s": vel, "dp_Pa": dp, "force_N": force}))
    return out
