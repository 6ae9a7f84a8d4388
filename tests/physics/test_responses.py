"""Noise-free responses of the virtual rig (physics.responses, physics.servo): physics against the
paper's closed forms and independent integrations, effects, the default campaign's behaviour.
References are computed here from isokinetic.physics.damper formulas, scipy root finders and
solve_ivp, never from the rig itself."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from isokinetic.physics import damper as dm
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.excitation import piston_segments, segment_index
from isokinetic.physics.hydraulics import Hydraulics, compressibility_time, relaxation
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import (
    Drive,
    drive_times,
    driven_segments,
    triangle_pressure_sums,
    triangle_responses,
    triangle_responses_at,
    true_response,
)
from isokinetic.physics.servo import servo_response
from isokinetic.physics.virtual_rig import Measurement, simulate_case
from isokinetic.stages.virtual_rig import VirtualCampaign
from testconfig import TEST_CONFIG as CONFIG

TRUTH = dm.Effects(coulomb_force_N=90.0, leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06)


@pytest.fixture(scope="module")
def config_mapping():
    return yaml.safe_load(CONFIG.read_text())["virtual_campaigns"]["paper-lag-damper"]


@pytest.fixture(scope="module")
def paper(config_mapping):
    return VirtualCampaign.from_config("paper-lag-damper", config_mapping)


def triangle(w_m_s=1.0e-3, period_s=20.0, rate_Hz=100.0, periods=2.0, case="T99"):
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=w_m_s * period_s / 4,
                    period_s=period_s, phase_rad=-math.pi / 2, duration_s=periods * period_s)


def sine(amp_m=0.45e-3, f_Hz=1.75, rate_Hz=1000.0, periods=2.0, case="H99"):
    return CasePlan(case=case, waveform="sine", sample_rate_Hz=rate_Hz, amplitude_m=amp_m, frequency_Hz=f_Hz,
                    phase_rad=0.0, duration_s=periods / f_Hz)


def start_damper(d: dm.Damper, y_m: float) -> dm.Damper:
    """The damper whose nominal volumes are those at piston position y (Eq. 2)."""
    return dataclasses.replace(d, chamber_volume_1_m3=d.chamber_volume_1_m3 - d.piston_area_m2 * y_m,
                               chamber_volume_2_m3=d.chamber_volume_2_m3 + d.piston_area_m2 * y_m)


def first_half(df: pd.DataFrame, case: CasePlan) -> pd.DataFrame:
    return df[(df.time_s > 0) & (df.time_s <= case.period_s / 2)]


def steady_dp(w_m_s: float, d: dm.Damper, e: dm.Effects) -> float:
    """Incompressible Δp (Eq. 24 + leakage + asymmetry) by bracketing root finding on Eq. (7)."""
    qp = d.piston_area_m2 * w_m_s
    c1 = dm.laminar_coefficient(d, e)

    def residual(p):
        return dm.orifice_flow(p, c1, dm.turbulent_coefficient(d, e, p)) + e.leakage_conductance_m3_s_Pa * p - qp

    hi = 1e9 * np.sign(w_m_s)
    return brentq(residual, 0.0, hi, xtol=1e-9, rtol=1e-15, maxiter=500)


def windows(df: pd.DataFrame, case: CasePlan, sign: float) -> pd.DataFrame:
    """Samples in [0.45, 0.95] of every half-period with velocity sign ``sign`` (Sec. 4.4)."""
    half = case.period_s / 2
    k = np.floor(df.time_s / half)
    frac = df.time_s / half - k
    seg_sign = np.where(k % 2 == 0, 1.0, -1.0)
    return df[(frac >= 0.45) & (frac <= 0.95) & (seg_sign == sign)]


def independent_dp(case: CasePlan, d: dm.Damper, e: dm.Effects, rtol=1e-12):
    """Δp of Eq. (1) by solve_ivp Radau on each monotone piece (no backlash)."""
    c1 = dm.laminar_coefficient(d, e)
    beta = dm.effective_compressibility(d, e)
    g = e.leakage_conductance_m3_s_Pa
    t = np.arange(int(round(case.duration_s * case.sample_rate_Hz)) + 1) / case.sample_rate_Hz
    end = max(case.duration_s, t[-1])
    if case.waveform == "triangle":
        def y(tt):
            return case.amplitude_m * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * tt / case.period_s + case.phase_rad))
        w = 4 * case.amplitude_m / case.period_s
        edges = np.arange(0.0, case.duration_s + 1e-9, case.period_s / 2)
        vel = [w if k % 2 == 0 else -w for k in range(len(edges) - 1)]
    else:
        def y(tt):
            return case.amplitude_m * np.sin(2 * np.pi * case.frequency_Hz * tt)
        edges = np.array([0.0, end])
        vel = [None]
    out = np.empty(t.size)
    p = 0.0
    for k, (ta, tb) in enumerate(zip(edges[:-1], edges[1:])):
        def rhs(tt, z, k=k):
            v = vel[k] if vel[k] is not None else case.amplitude_m * 2 * np.pi * case.frequency_Hz * np.cos(
                2 * np.pi * case.frequency_Hz * tt)
            c2 = dm.turbulent_coefficient(d, e, z[0])
            q = (np.sign(z[0]) * np.sqrt(abs(z[0]) / c2) if c1 == 0 else dm.orifice_flow(z[0], c1, c2)) + g * z[0]
            return [(d.piston_area_m2 * v - q) / (beta * dm.composite_volume(y(tt), d))]
        sel = (t >= ta) & ((t < tb) if k < len(edges) - 2 else (t <= tb))
        te = t[sel] if t[sel][-1] == tb else np.append(t[sel], tb)
        sol = solve_ivp(rhs, (ta, tb), [p], method="Radau", rtol=rtol, atol=1e-6, t_eval=te)
        out[sel] = sol.y[0, :sel.sum()]
        p = sol.y[0, -1]
    return t, out


# ---------------------------------------------------------------------------------- physics

def test_laminar_first_half_period_matches_eq18():
    effects = dm.Effects(air_volume_fraction=0.005)     # slow transient: many samples resolve it
    case = triangle(w_m_s=1.0e-3, period_s=20.0)
    hyd = dataclasses.replace(Hydraulics.from_damper(TABLE_1, effects), turbulent_coefficient_pos=0.0,
                              turbulent_coefficient_neg=0.0)
    df = first_half(true_response(case, TABLE_1, effects, hydraulics=hyd), case)
    ref = dm.laminar_step_pressure(df.time_s.to_numpy(), 1.0e-3, start_damper(TABLE_1, -case.amplitude_m), effects)
    assert ref[-1] > 0.99 * 1.0e-3 * TABLE_1.piston_area_m2 * dm.laminar_coefficient(TABLE_1)
    np.testing.assert_allclose(df.dp_Pa.to_numpy(), ref, rtol=1e-4, atol=0)


def test_turbulent_first_half_period_matches_eq20():
    effects = dm.Effects(viscosity_Pa_s=0.0, air_volume_fraction=0.002)   # c1 = 0
    case = triangle(w_m_s=0.5e-3, period_s=20.0)
    assert Hydraulics.from_damper(TABLE_1, effects).laminar_coefficient == 0.0
    df = first_half(true_response(case, TABLE_1, effects), case)
    ref = dm.turbulent_step_pressure(df.time_s.to_numpy(), 0.5e-3, start_damper(TABLE_1, -case.amplitude_m), effects)
    assert ref[0] < 0.5 * ref[-1]
    np.testing.assert_allclose(df.dp_Pa.to_numpy(), ref, rtol=1e-4, atol=0)


@pytest.mark.parametrize("effects", [
    TRUTH,
    dm.Effects(viscosity_Pa_s=0.0, asymmetry=0.1),                       # pure turbulent
    dm.Effects(discharge_coefficient=1e9, leakage_conductance_m3_s_Pa=5e-12),  # ~pure laminar
], ids=["mixed-leakage-asymmetry", "turbulent", "laminar"])
def test_triangle_record_matches_independent_solve_ivp(effects):
    effects = dataclasses.replace(effects, air_volume_fraction=0.001)
    case = triangle(w_m_s=1.2e-3, period_s=4.0, rate_Hz=200.0)
    t, ref = independent_dp(case, TABLE_1, effects)
    dp = true_response(case, TABLE_1, effects).dp_Pa.to_numpy()
    assert np.abs(dp - ref).max() < 1e-7 * np.abs(ref).max()


def test_sine_matches_independent_solve_ivp():
    case = sine(amp_m=0.45e-3, periods=2.0)
    t, ref = independent_dp(case, TABLE_1, TRUTH)
    df = true_response(case, TABLE_1, TRUTH)
    assert np.abs(df.dp_Pa.to_numpy() - ref).max() < 1e-7 * np.abs(ref).max()
    v = case.amplitude_m * 2 * np.pi * case.frequency_Hz * np.cos(2 * np.pi * case.frequency_Hz * t)
    expected_force = TABLE_1.piston_area_m2 * ref + 90.0 * np.sign(v)
    np.testing.assert_allclose(df.force_N.to_numpy(), expected_force, rtol=0, atol=1e-7 * np.abs(expected_force).max())


@pytest.mark.parametrize("w_m_s", [1.0e-5, 2.0e-4, 1.5e-3])
def test_steady_force_equals_incompressible_solution(w_m_s):
    case = triangle(w_m_s=w_m_s, period_s=20.0)
    df = true_response(case, TABLE_1, TRUTH)
    for sign in (1.0, -1.0):
        expected = TABLE_1.piston_area_m2 * steady_dp(sign * w_m_s, TABLE_1, TRUTH) + sign * 90.0
        np.testing.assert_allclose(windows(df, case, sign).force_N, expected, rtol=1e-9)


def test_reversal_keeps_pressure_continuous():
    case = triangle(w_m_s=1.5e-3, period_s=20.0, rate_Hz=1000.0)
    df = true_response(case, TABLE_1, dataclasses.replace(TRUTH, air_volume_fraction=0.01))
    jumps = np.abs(np.diff(df.dp_Pa.to_numpy()))
    # the largest step is the compressibility slope |A_p W| / (β 𝒱) times dt, never a jump
    beta = dm.effective_compressibility(TABLE_1, dataclasses.replace(TRUTH, air_volume_fraction=0.01))
    max_slope = 2 * TABLE_1.piston_area_m2 * 1.5e-3 / (beta * dm.composite_volume(case.amplitude_m, TABLE_1))
    assert jumps.max() < max_slope * 1e-3


def test_triangle_with_backlash_matches_independent_play_model():
    """Gap b: after each reversal (and at the start) the piston rests for b/W, then follows x ∓ b/2."""
    gap, w, period = 0.15e-3, 1.0e-3, 4.0
    effects = dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06, air_volume_fraction=0.002,
                         backlash_m=gap)
    case = triangle(w_m_s=w, period_s=period, rate_Hz=500.0)
    c1, beta = dm.laminar_coefficient(TABLE_1, effects), dm.effective_compressibility(TABLE_1, effects)
    amp, t_gap = case.amplitude_m, gap / w
    t = np.arange(int(round(case.duration_s * case.sample_rate_Hz)) + 1) / case.sample_rate_Hz
    expected, p = np.empty(t.size), 0.0
    for k in range(4):
        d = 1.0 if k % 2 == 0 else -1.0
        t0 = k * period / 2
        x0 = -d * amp                               # actuator at the turning point
        rest_y = x0 + d * gap / 2                   # piston left at the far side of the gap
        for ta, tb, moving in ((t0, t0 + t_gap, False), (t0 + t_gap, t0 + period / 2, True)):
            def rhs(tt, z, t0=t0, moving=moving, d=d, x0=x0, rest_y=rest_y):
                y = x0 + d * w * (tt - t0) - d * gap / 2 if moving else rest_y
                v = d * w if moving else 0.0
                q = dm.orifice_flow(z[0], c1, dm.turbulent_coefficient(TABLE_1, effects, z[0]))
                q = q + effects.leakage_conductance_m3_s_Pa * z[0]
                return [(TABLE_1.piston_area_m2 * v - q) / (beta * dm.composite_volume(y, TABLE_1))]
            last = k == 3 and moving
            sel = (t >= ta) & ((t <= tb) if last else (t < tb))
            te = t[sel] if (sel.any() and t[sel][-1] == tb) else np.append(t[sel], tb)
            sol = solve_ivp(rhs, (ta, tb), [p], method="Radau", rtol=1e-12, atol=1e-6, t_eval=te)
            expected[sel] = sol.y[0, :sel.sum()]
            p = sol.y[0, -1]
    dp = true_response(case, TABLE_1, effects).dp_Pa.to_numpy()
    assert np.abs(dp - expected).max() < 1e-7 * np.abs(expected).max()


def test_sine_backlash_holds_force_at_zero_until_the_gap_is_crossed():
    gap = 0.1e-3
    case = sine(amp_m=0.45e-3, periods=1.0)
    df = true_response(case, TABLE_1, dm.Effects(backlash_m=gap, coulomb_force_N=90.0))
    t_contact = math.asin(gap / case.amplitude_m) / (2 * math.pi * case.frequency_Hz)
    before = df[df.time_s < t_contact - 1e-9]
    after = df[df.time_s > t_contact + 1e-3]
    assert len(before) > 10 and (before.force_N == 0).all() and (before.piston_velocity_m_s == 0).all()
    assert after.force_N.iloc[0] > 90.0 and after.piston_velocity_m_s.iloc[0] > 0


def test_stroke_that_empties_a_chamber_is_refused():
    limit = TABLE_1.chamber_volume_1_m3 / TABLE_1.piston_area_m2
    with pytest.raises(ValueError, match="end of the cylinder"):
        true_response(triangle(w_m_s=1e-3, period_s=4 * limit / 1e-3), TABLE_1)


# ---------------------------------------------------------------------------------- batched quadrature

def chained_segments(case: CasePlan, hyd: Hydraulics, backlash_m: float, drive: Drive | None, step: float):
    """The quadrature one segment after the other through the single-table API: Eq. (14) for the
    samples and the segment's end, the table from the previous segment's end Δp."""
    t = drive_times(case, drive)
    a = hyd.piston_area_m2
    if drive is None:
        segs = piston_segments(case, backlash_m)
        flows = [a * seg.direction * 4.0 * case.amplitude_m / case.period_s if seg.contact else 0.0 for seg in segs]
    else:
        segs = driven_segments(case, drive)
        flows = [a * seg.direction * drive.speed(j) for j, seg in enumerate(segs)]
    dp, vel, p = np.empty(t.size), np.zeros(t.size), 0.0
    for seg, qp, idx in zip(segs, flows, segment_index(t, segs)):
        tau = compressibility_time(np.append(t[idx], seg.t_end_s) - seg.t_start_s, seg.piston_start_m, qp / a, hyd)
        values = relaxation(p, qp, hyd, step).pressure(tau)
        dp[idx], vel[idx], p = values[:-1], qp / a, float(values[-1])
    return t, dp, vel


BATCH = [triangle(w_m_s=1.0e-3, period_s=4.0, rate_Hz=200.0, case="T1"),
         triangle(w_m_s=5.0e-6, period_s=40.0, rate_Hz=20.0, periods=1.3, case="T2"),
         triangle(w_m_s=2.0e-4, period_s=2.0, rate_Hz=500.0, periods=2.6, case="T3"),
         triangle(w_m_s=1.0e-3, period_s=4.0, rate_Hz=200.0, case="T4")]   # T1 again: tables shared


@pytest.mark.parametrize("effects, backlash_m", [(dm.Effects(), 0.0), (TRUTH, 0.0),
                                                 (dm.Effects(air_volume_fraction=0.01, asymmetry=-0.1), 0.0),
                                                 (TRUTH, 4.0e-5)], ids=["nominal", "truth", "air", "backlash"])
def test_batched_triangles_equal_the_segment_by_segment_chain(effects, backlash_m):
    """triangle_responses advances all cases in lockstep, evaluates only the segments' ends in the chain,
    then every sample at once and Δp* without τ after a table's end: the same numbers, bit for bit, as
    chaining single tables segment by segment; with measured drives (speeds per half-period, an offset
    sample grid) too."""
    hyd = Hydraulics.from_damper(TABLE_1, effects)
    drives = [None] * len(BATCH)
    if not backlash_m:
        drives[1] = Drive((5.1e-6, 4.9e-6, 5.2e-6), grid_offset_s=0.0137)
        drives[2] = Drive((2.1e-4, 1.9e-4), grid_offset_s=0.0004)
    got = triangle_responses(BATCH, hyd, backlash_m, 0.06, drives)
    for case, drive, out in zip(BATCH, drives, got):
        for x, y in zip(out, chained_segments(case, hyd, backlash_m, drive, 0.06)):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(got[3][1], got[0][1])


def test_a_remembered_layout_gives_every_run_the_segment_by_segment_chain():
    """A batch's layout remembers the part of Eq. (14) without β_eff for the samples a run needed (extended when a
    later run needs more): runs of the same cases with other coefficients (air: another β_eff, so other samples
    before the tables' ends; leakage and asymmetry), the same case objects or equal copies, each give the
    numbers of chaining single tables, bit for bit."""
    copies = [dataclasses.replace(case) for case in BATCH]
    for effects, cases in [(dm.Effects(), BATCH), (dm.Effects(air_volume_fraction=0.02), BATCH),
                           (dm.Effects(), copies), (TRUTH, BATCH)]:
        hyd = Hydraulics.from_damper(TABLE_1, dataclasses.replace(effects, coulomb_force_N=0.0))
        for case, out in zip(cases, triangle_responses(cases, hyd, 0.0, 0.06)):
            for x, y in zip(out, chained_segments(case, hyd, 0.0, None, 0.06)):
                np.testing.assert_array_equal(x, y)


def test_repeated_batches_do_not_share_their_arrays():
    """The sample grids of a batch are remembered between calls; what a call returns is its own."""
    hyd = Hydraulics.from_damper(TABLE_1, TRUTH)
    first = triangle_responses(BATCH, hyd, 0.0, 0.06)
    expected = [tuple(x.copy() for x in out) for out in first]
    for out in first:
        for x in out:
            x[:] = -1.0
    again = triangle_responses(BATCH, hyd, 0.0, 0.06)
    for x, y in zip(again, expected):
        for a, b in zip(x, y):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("effects", [dm.Effects(), TRUTH, dm.Effects(air_volume_fraction=0.01, asymmetry=-0.1)],
                         ids=["nominal", "truth", "air"])
def test_pressure_sums_equal_the_sums_of_the_samples(effects):
    """triangle_pressure_sums (Δp* summed in closed form after a table's end) gives the sums of
    triangle_responses_at's samples over arbitrary ranges: within a segment, across segments, a whole
    case, empty; with measured drives and per-case viscosity scales (two groups of coefficients)."""
    hyd = Hydraulics.from_damper(TABLE_1, dataclasses.replace(effects, coulomb_force_N=0.0))
    drives = [None, Drive((5.1e-6, 4.9e-6, 5.2e-6), grid_offset_s=0.0137), None, None]
    scales = (1.0, 1.3, 1.0, 0.8)
    runs = triangle_responses_at(BATCH, hyd, scales, 0.0, 0.06, drives)
    rng = np.random.default_rng(4)
    case, start, stop = [], [], []
    for k, (t, _dp, _v) in enumerate(runs):
        ends = np.sort(rng.integers(0, t.size + 1, size=(12, 2)), axis=1)
        ends = np.vstack([ends, [[0, t.size], [3, 3], [t.size - 1, t.size]]])
        case += [k] * len(ends)
        start += ends[:, 0].tolist()
        stop += ends[:, 1].tolist()
    got = triangle_pressure_sums(BATCH, hyd, np.array(case), np.array(start), np.array(stop), scales, 0.0, 0.06,
                                 drives)
    expected = np.array([runs[k][1][a:b].sum() for k, a, b in zip(case, start, stop)])
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


# ---------------------------------------------------------------------------------- servo stiffness

def independent_servo_dp(case: CasePlan, d: dm.Damper, e: dm.Effects, k: float):
    """Δp with a servo of stiffness k, no play, no friction: x = c - A_p Δp / k = y and
    (β 𝒱(y) + A_p²/k) dΔp/dt = A_p dc/dt - Q_N (Eq. 1 with the fixture compliance), Radau."""
    a, c1, g = d.piston_area_m2, dm.laminar_coefficient(d, e), e.leakage_conductance_m3_s_Pa
    beta = dm.effective_compressibility(d, e)
    t = np.arange(int(round(case.duration_s * case.sample_rate_Hz)) + 1) / case.sample_rate_Hz
    if case.waveform == "sine":
        w = 2 * np.pi * case.frequency_Hz
        edges, rates = [0.0, t[-1]], [lambda tt: case.amplitude_m * w * np.cos(w * tt)]

        def cmd(tt):
            return case.amplitude_m * np.sin(w * tt)
    else:
        speed = 4 * case.amplitude_m / case.period_s
        edges = list(np.arange(0.0, case.duration_s + 1e-9, case.period_s / 2))
        rates = [(lambda tt, s=(1.0 if k_ % 2 == 0 else -1.0): s * speed) for k_ in range(len(edges) - 1)]

        def cmd(tt):
            return case.amplitude_m * (2 / np.pi) * np.arcsin(np.sin(2 * np.pi * tt / case.period_s + case.phase_rad))
    out, p = np.empty(t.size), 0.0
    for n, (ta, tb) in enumerate(zip(edges[:-1], edges[1:])):
        def rhs(tt, z, rate=rates[n]):
            y = cmd(tt) - a * z[0] / k
            q = dm.orifice_flow(z[0], c1, dm.turbulent_coefficient(d, e, z[0])) + g * z[0]
            return [(a * rate(tt) - q) / (beta * dm.composite_volume(y, d) + a * a / k)]
        sel = (t >= ta) & ((t <= tb) if n == len(edges) - 2 else (t < tb))
        te = t[sel] if t[sel][-1] == tb else np.append(t[sel], tb)
        sol = solve_ivp(rhs, (ta, tb), [p], method="Radau", rtol=1e-12, atol=1e-6, t_eval=te)
        out[sel], p = sol.y[0, :sel.sum()], sol.y[0, -1]
    return out


@pytest.mark.parametrize("case", [sine(amp_m=0.45e-3, periods=2.0),
                                  triangle(w_m_s=1.2e-3, period_s=4.0, rate_Hz=200.0)],
                         ids=["sine", "triangle"])
def test_servo_stiffness_without_play_matches_independent_solve_ivp(case):
    effects = dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06)
    k = 3e7
    df = true_response(case, TABLE_1, effects, servo_stiffness_N_m=k)
    ref = independent_servo_dp(case, TABLE_1, effects, k)
    assert np.abs(df.dp_Pa.to_numpy() - ref).max() < 1e-7 * np.abs(ref).max()
    np.testing.assert_allclose(df.force_N, TABLE_1.piston_area_m2 * df.dp_Pa, rtol=1e-12)
    np.testing.assert_allclose(df.actuator_m, df.command_m - df.force_N / k, rtol=0, atol=1e-15)
    # the compliance adds to the compressibility: the force is lower than with a rigid servo
    rigid = true_response(case, TABLE_1, effects)
    assert df.force_N.abs().max() < rigid.force_N.abs().max()


def test_stiff_servo_approaches_the_rigid_rig():
    case = sine(amp_m=0.45e-3, periods=2.0)
    effects = dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06)
    rigid = true_response(case, TABLE_1, effects)
    stiff = true_response(case, TABLE_1, effects, servo_stiffness_N_m=1e16)
    assert (rigid.actuator_m == rigid.command_m).all()
    assert np.abs(stiff.force_N - rigid.force_N).max() < 1e-7 * rigid.force_N.abs().max()


@pytest.mark.parametrize("case", [sine(amp_m=0.45e-3, periods=3.0),
                                  triangle(w_m_s=1.0e-3, period_s=4.0, rate_Hz=200.0)],
                         ids=["sine", "triangle"])
def test_servo_with_backlash_and_friction_keeps_the_play_and_friction_laws(case):
    """Play: |x - y| <= b/2, = b/2 with x - y of the sign of F while loaded; F = 0 only in the gap,
    where x follows the command and the piston stands. Friction: a standing loaded piston needs
    |F - A_p Δp| <= F_C, a sliding one F - A_p Δp = F_C sign(dy/dt). Servo: x = c - F/k."""
    gap, k = 0.05e-3, 5e7
    effects = dataclasses.replace(TRUTH, backlash_m=gap)
    hyd = Hydraulics.from_damper(TABLE_1, effects)
    t, dp, yd, force, x, y = servo_response(case, hyd, effects, k)
    c = true_response(case, TABLE_1).command_m.to_numpy()
    fc, a = effects.coulomb_force_N, TABLE_1.piston_area_m2
    np.testing.assert_allclose(x, c - force / k, rtol=0, atol=1e-15)
    assert (np.abs(x - y) <= gap / 2 * (1 + 1e-9)).all()
    loaded = force != 0
    assert 0.005 < (~loaded).mean() < 0.3                      # the gap is crossed, briefly
    np.testing.assert_allclose(np.abs(x - y)[loaded], gap / 2, rtol=1e-9)
    assert (np.sign(x - y)[loaded] == np.sign(force[loaded])).all()
    assert (yd[~loaded] == 0).all() and (x[~loaded] == c[~loaded]).all()
    friction = force - a * dp
    tol = 1e-6 * np.abs(force).max()
    standing, sliding = loaded & (yd == 0), loaded & (yd != 0)
    assert standing.any() and (np.abs(friction[standing]) <= fc + tol).all()
    np.testing.assert_allclose(friction[sliding], fc * np.sign(yd[sliding]), rtol=0, atol=tol)


def test_servo_does_not_change_the_steady_triangle_force():
    """At constant velocity the load is constant, the servo lag too: F = A_p Δp* + F_C as rigid."""
    case = triangle(w_m_s=1.0e-3, period_s=20.0)
    effects = dataclasses.replace(TRUTH, backlash_m=0.05e-3)
    rigid = true_response(case, TABLE_1, effects)
    servo = true_response(case, TABLE_1, effects, servo_stiffness_N_m=5e7)
    for sign in (1.0, -1.0):
        np.testing.assert_allclose(windows(servo, case, sign).force_N, windows(rigid, case, sign).force_N, rtol=1e-6)


def test_lvdt_measures_the_lagging_actuator():
    m = Measurement(force_resolution_N=0.0, displacement_resolution_m=0.0, command_resolution_m=0.0,
                    servo_stiffness_N_m=5e7)
    case = sine(amp_m=0.45e-3, periods=1.0)
    rec = simulate_case(case, TABLE_1, TRUTH, m, 1)
    np.testing.assert_allclose(rec.displacement_m, rec.command_m - rec.force_N / 5e7, rtol=0, atol=1e-15)
    assert (rec.displacement_m - rec.command_m).abs().max() > 1e-5


def test_servo_stiffness_config_key():
    assert Measurement().servo_stiffness_N_m == math.inf
    assert Measurement.from_config({"servo_stiffness_N_m": 2e8}).servo_stiffness_N_m == 2e8
    assert Measurement.from_config({"servo_stiffness_N_m": float("inf")}).servo_stiffness_N_m == math.inf
    for bad in (0.0, -1e8, True, "stiff", float("nan")):
        with pytest.raises(ValueError, match="servo_stiffness_N_m"):
            Measurement.from_config({"servo_stiffness_N_m": bad})


def test_servo_refuses_stribeck_friction():
    effects = dm.Effects(coulomb_force_N=90.0, stribeck_force_N=30.0)
    with pytest.raises(ValueError, match="Coulomb friction only"):
        true_response(sine(periods=1.0), TABLE_1, effects, servo_stiffness_N_m=5e7)


# ---------------------------------------------------------------------------------- effects

def steady_levels(effects: dm.Effects, w_m_s: float) -> tuple[float, float]:
    case = triangle(w_m_s=w_m_s, period_s=20.0, rate_Hz=20.0)
    df = true_response(case, TABLE_1, effects)
    return windows(df, case, 1.0).force_N.mean(), windows(df, case, -1.0).force_N.mean()


def test_friction_offsets_force_by_coulomb_force():
    base = steady_levels(dm.NOMINAL, 3e-4)
    fric = steady_levels(dm.Effects(coulomb_force_N=90.0), 3e-4)
    assert fric[0] - base[0] == pytest.approx(90.0, rel=1e-9)
    assert fric[1] - base[1] == pytest.approx(-90.0, rel=1e-9)


def test_leakage_lowers_force_both_directions():
    base = steady_levels(dm.NOMINAL, 1e-3)
    leak = steady_levels(dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12), 1e-3)
    assert 0 < leak[0] < 0.5 * base[0] and 0 > leak[1] > 0.5 * base[1]


LEAKY = dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12)    # fast settling baseline


def test_asymmetry_makes_negative_branch_stronger():
    fp, fm = steady_levels(dataclasses.replace(LEAKY, asymmetry=0.06), 1.5e-3)
    sym_p, sym_m = steady_levels(LEAKY, 1.5e-3)
    assert sym_p == pytest.approx(-sym_m, rel=1e-9)
    assert abs(fm) > abs(fp) and fp < sym_p < abs(fm)


def test_higher_discharge_coefficient_lowers_turbulent_force():
    cd08 = dataclasses.replace(LEAKY, discharge_coefficient=0.8)
    f06 = steady_levels(LEAKY, 1.5e-3)[0]
    f08 = steady_levels(cd08, 1.5e-3)[0]
    assert f08 < 0.9 * f06
    assert f08 / f06 == pytest.approx(steady_dp(1.5e-3, TABLE_1, cd08) / steady_dp(1.5e-3, TABLE_1, LEAKY), rel=1e-9)


def test_higher_viscosity_raises_laminar_force():
    f = steady_levels(dm.NOMINAL, 1e-6)[0]
    f2 = steady_levels(dm.Effects(viscosity_Pa_s=0.06), 1e-6)[0]
    assert f2 / f == pytest.approx(2.0, rel=0.02)       # laminar regime: F ∝ μ (Eq. 31, c1 term)


def rise_time(df: pd.DataFrame, case: CasePlan, fraction: float) -> float:
    half = df[df.time_s <= case.period_s / 2]
    target = fraction * half.force_N.iloc[-1]
    return float(half.time_s[half.force_N >= target].iloc[0])


def test_air_slows_the_transient():
    case = triangle(w_m_s=1e-3, period_s=20.0, rate_Hz=1000.0)
    t_oil = rise_time(true_response(case, TABLE_1, LEAKY), case, 0.95)
    t_air = rise_time(true_response(case, TABLE_1, dataclasses.replace(LEAKY, air_volume_fraction=0.01)), case, 0.95)
    assert t_air > 10 * t_oil


def test_backlash_delays_the_transient_by_gap_over_speed():
    case = triangle(w_m_s=1e-3, period_s=20.0, rate_Hz=1000.0)
    gap = 0.2e-3
    plain = true_response(case, TABLE_1, dm.NOMINAL)
    play = true_response(case, TABLE_1, dm.Effects(backlash_m=gap))
    delay = rise_time(play, case, 0.5) - rise_time(plain, case, 0.5)
    assert delay == pytest.approx(gap / 1e-3, abs=2e-3)
    assert (play.force_N[play.time_s < gap / 1e-3 - 1e-9] == 0).all()
    # after the reversal the pressure relaxes (piston at rest) before the new push
    after = play[(play.time_s > 10.0) & (play.time_s < 10.0 + gap / 1e-3)]
    assert (np.diff(after.dp_Pa) < 0).all() and after.dp_Pa.iloc[-1] > 0


# ---------------------------------------------------------------------------------- paper behaviour

def test_default_campaign_behaves_like_the_paper(paper):
    hyd_rows = {}
    for cid in ("T01", "T23"):
        c = paper.case(cid)
        df = true_response(c, paper.damper, paper.effects)
        hyd_rows[cid] = (windows(df, c, 1.0).force_N.mean(), windows(df, c, -1.0).force_N.mean())
    coulomb = paper.effects.coulomb_force_N
    # v -> 0: non-zero force ≈ friction, both directions
    assert hyd_rows["T01"][0] == pytest.approx(coulomb, rel=0.15)
    assert hyd_rows["T01"][1] == pytest.approx(-coulomb, rel=0.15)
    # 1.5 mm/s: asymmetric, |F-| > |F+|
    fp, fm = hyd_rows["T23"]
    assert abs(fm) > abs(fp) > 1000.0
    # nominal Eq. (31) over-predicts the top force several-fold
    nominal = dm.nominal_force(paper.case("T23").velocity_m_s, paper.damper)
    assert nominal > 3 * abs(fm)
