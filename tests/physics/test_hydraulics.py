"""Segment tables of the virtual rig's quadrature (physics.hydraulics, Eq. 13-14 of the paper)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from isokinetic.physics import damper as dm
from isokinetic.physics import hydraulics as hyd_module
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.gas_law import compressibility_ratio
from isokinetic.physics.hydraulics import (
    Hydraulics,
    compressibility_time,
    compressibility_times,
    relaxation,
    relaxation_batch,
    relaxations,
    start_volumes,
    steady_pressure,
)


def test_segment_table_does_not_depend_on_the_other_problems_of_its_batch():
    """relaxations() builds many tables in one pass; each must be the table built alone. A table
    of large τ placed first must not cost the one after it any digits."""
    hyd = Hydraulics.from_damper(TABLE_1, dm.Effects())
    a = TABLE_1.piston_area_m2
    large, small = (0.0, a * 1.5e-3), (0.0, a * 5e-6)   # (Δp0, A_p W): 1.5 and 0.005 mm/s from rest
    alone = relaxations([small[0]], [small[1]], hyd)[0]
    batched = relaxations([large[0], small[0]], [large[1], small[1]], hyd)[1]
    assert relaxations([large[0]], [large[1]], hyd)[0].tau[-1] > 10 * alone.tau[-1]
    np.testing.assert_array_equal(batched.tau, alone.tau)
    np.testing.assert_array_equal(batched.coef, alone.coef)


# ------------------------------------------------------------------------------ batched tables

def _problem_set(hyd, rng, n=40):
    """Start pressures and piston flows of every kind the chain meets: from rest, across q = 0 (a
    reversal), from the same side, exactly at the steady state, the piston at rest (W = 0)."""
    a = TABLE_1.piston_area_m2
    qp = a * 10 ** rng.uniform(-6.5, -2.5, n) * rng.choice([-1.0, 1.0], n)
    qp[-3:] = 0.0
    steady = np.array([steady_pressure(q, hyd) for q in qp])
    other = np.array([steady_pressure(-a * 10 ** rng.uniform(-6.5, -2.5), hyd) for _ in range(n)])
    dp0 = np.where(rng.uniform(size=n) < 0.5, other, steady * rng.uniform(0.05, 0.95, n))
    dp0[::7] = 0.0
    dp0[3::9] = steady[3::9]                        # at (or an ulp from) the steady state
    dp0[-3] = 0.0                                   # at rest, no pressure: a constant table
    dp0[-2:] = other[-2:]                           # relaxing with the piston at rest
    return dp0, qp


HYDRAULICS = [Hydraulics.from_damper(TABLE_1, dm.Effects()),
              Hydraulics.from_damper(TABLE_1, dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06)),
              dataclasses.replace(Hydraulics.from_damper(TABLE_1, dm.Effects(asymmetry=-0.2)), laminar_coefficient=0.0),
              Hydraulics.from_damper(TABLE_1, dm.Effects(leakage_conductance_m3_s_Pa=1e-12, path_asymmetry=0.12))]
IDS = ["nominal", "leakage+asymmetry", "turbulent only", "leakage+one-sided path"]


@pytest.mark.parametrize("hyd", HYDRAULICS, ids=IDS)
def test_batched_tables_evaluate_every_sample_as_its_own_table(hyd):
    """relaxation_batch(): the tables of a batch are the tables built alone, and evaluating many tables' samples
    at once (in any order, or in runs) gives exactly what each table gives its own sorted samples."""
    rng = np.random.default_rng(11)
    dp0, qp = _problem_set(hyd, rng)
    batch = relaxation_batch(dp0, qp, hyd, 0.06)
    which, taus, expected = [], [], []
    for k, (p, q) in enumerate(zip(dp0, qp)):
        alone = relaxation(p, q, hyd, 0.06)
        np.testing.assert_array_equal(batch.relaxation(k).tau, alone.tau)
        np.testing.assert_array_equal(batch.relaxation(k).coef, alone.coef)
        end = alone.tau[-1] if alone.tau.size > 1 else 1.0
        tau = np.sort(np.concatenate([rng.uniform(0.0, 1.3 * end, 30), alone.tau[::5]]))
        which.append(np.full(tau.size, k))
        taus.append(tau)
        expected.append(alone.pressure(tau))
    assert 1 <= np.count_nonzero(batch.sizes == 1) < len(batch)   # constants among the tables
    which, taus, expected = np.concatenate(which), np.concatenate(taus), np.concatenate(expected)
    order = rng.permutation(taus.size)
    got = np.empty(taus.size)
    got[order] = batch.pressure(which[order], taus[order])
    np.testing.assert_array_equal(got, expected)
    live = taus < batch.end_tau[which]
    runs = np.flatnonzero(np.diff(which[live], prepend=-1))
    counts = np.diff(np.append(runs, live.sum()))
    np.testing.assert_array_equal(batch.pressure_runs(which[live][runs], counts, taus[live]), expected[live])


def _reference_nodes(u0, u_end, u_ref, step, special, graded_min):
    """The node construction of :func:`relaxations` for one problem, written out with np.linspace."""
    parts = []
    if u0 > u_ref:
        parts.append(np.linspace(u_ref, u0, math.ceil((u0 - u_ref) / step) + 1))
    top = min(u0, u_ref)
    zeta_top, zeta_cap = math.exp((top - u_ref) / 4.0), step / 0.5
    u_cap = max(u_end, u_ref + 4.0 * math.log(zeta_cap))
    if top > u_cap:
        zeta_lo = math.exp((u_cap - u_ref) / 4.0)
        zeta = np.linspace(zeta_lo, zeta_top, math.ceil((zeta_top - zeta_lo) / (step / 4.0)) + 1)
        parts.append(u_ref + 4.0 * np.log(zeta))
    lo_top = min(top, u_cap)
    parts.append(np.linspace(u_end, lo_top, max(2, math.ceil((lo_top - u_end) / 0.5) + 1)))
    if graded_min < 10.0 * step:
        off = 10.0 * step * 0.8 ** np.arange(0, math.ceil(math.log(graded_min / (10.0 * step)) / math.log(0.8)) + 1)
        for c in special:
            parts.append(np.concatenate([c - off, c + off, [c]]))
    u = np.unique(np.concatenate(parts))
    return np.concatenate([[u0], u[(u >= u_end) & (u < u0)][::-1]])


@pytest.mark.parametrize("hyd", HYDRAULICS, ids=IDS)
def test_nodes_of_a_batch_are_the_per_problem_construction(hyd):
    """The vectorised node generation reproduces, bit for bit, the construction problem by problem:
    u from ln|q* - q0| down, the crossing piece, the ζ-graded piece, the 0.5 panels, the cluster at q = 0."""
    rng = np.random.default_rng(12)
    dp0, qp = _problem_set(hyd, rng)
    q_star, _, _, q0, dist = hyd_module._problems(dp0, qp, hyd)
    moving = dist > 0
    nodes, sizes = hyd_module._node_sets(q_star[moving], q0[moving], dist[moving], hyd, 0.06)
    c2_max = max(hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg)
    expected = []
    for qs, q, d in zip(q_star[moving], q0[moving], dist[moving]):
        scale = max(abs(qs), d) if qs * q >= 0 else abs(qs)
        special = [math.log(d)] if q == 0 else ([math.log(abs(qs))] if qs * q < 0 else [])
        width = hyd.laminar_coefficient / (2 * c2_max * abs(qs)) if qs != 0 else math.inf
        expected.append(_reference_nodes(math.log(d), math.log(max(abs(qs), d) * 1e-17), math.log(scale), 0.06,
                                         special, max(1e-12, 1e-2 * width)))
    np.testing.assert_array_equal(sizes, [e.size for e in expected])
    np.testing.assert_array_equal(nodes, np.concatenate(expected))
    assert all(np.all(np.diff(e) < 0) for e in expected)


def test_compressibility_times_is_compressibility_time_per_element():
    hyd = HYDRAULICS[1]
    rng = np.random.default_rng(13)
    y0 = rng.uniform(-5e-3, 5e-3, 6)
    w = np.array([1e-3, -2e-4, 0.0, 5e-6, -1e-2, 0.0])
    dt = [np.sort(rng.uniform(0, 2, 50)) for _ in w]
    v1, v2 = start_volumes(np.repeat(y0, 50), hyd)
    got = compressibility_times(np.concatenate(dt), v1, v2, hyd.piston_area_m2 * np.repeat(w, 50), hyd)
    expected = np.concatenate([compressibility_time(t, y, v, hyd) for t, y, v in zip(dt, y0, w)])
    np.testing.assert_array_equal(got, expected)


def test_one_sided_path_scales_the_negative_steady_pressure_by_one_plus_b():
    """path_asymmetry b: Δp = (1 + b)(c1 q + c2 q|q|) for q < 0 (Eq. 7), the positive direction nominal."""
    b = 0.12
    hyd = Hydraulics.from_damper(TABLE_1, dm.Effects(path_asymmetry=b))
    nominal = Hydraulics.from_damper(TABLE_1, dm.Effects())
    for qp in (1e-9, 4e-8, 2e-6):   # laminar to turbulent
        assert steady_pressure(qp, hyd) == pytest.approx(steady_pressure(qp, nominal), rel=1e-13)
        assert steady_pressure(-qp, hyd) == pytest.approx((1 + b) * steady_pressure(-qp, nominal), rel=1e-12)
        assert hyd.flow(steady_pressure(-qp, hyd)) == pytest.approx(-qp, rel=1e-12)


@pytest.mark.parametrize("dp0, w", [(0.0, -1e-3), (3e5, -5e-4), (-3e5, 8e-4), (2e4, -2e-5)],
                         ids=["from rest", "reversal to -", "reversal to +", "slow reversal"])
def test_one_sided_path_table_matches_an_ode_solution(dp0, w):
    """The segment table of a one-sided path (c1 and c2 jump at q = 0) against solve_ivp of Eq. 13 itself."""
    from scipy.integrate import solve_ivp

    hyd = Hydraulics.from_damper(TABLE_1, dm.Effects(path_asymmetry=0.12, leakage_conductance_m3_s_Pa=1e-12))
    qp = hyd.piston_area_m2 * w
    t = np.linspace(0.0, 5.0, 300)
    got = relaxation(dp0, qp, hyd).pressure(compressibility_time(t, 0.0, w, hyd))

    def rate(tt, y):
        return [(qp - hyd.flow(y[0])) / (hyd.compressibility_1_Pa * hyd.composite_volume(w * tt))]

    sol = solve_ivp(rate, (0.0, 5.0), [dp0], t_eval=t, method="LSODA", rtol=1e-12, atol=1e-6)
    scale = max(abs(steady_pressure(qp, hyd)), abs(dp0))
    assert np.max(np.abs(got - sol.y[0])) < 1e-8 * scale


# --------------------------------------------------------------------------------------------
# air under the gas law (a damper with a charge pressure)
# --------------------------------------------------------------------------------------------

GAS_DAMPER = dataclasses.replace(TABLE_1, chamber_volume_2_m3=2.2e-4, charge_pressure_Pa=1.0e7)


def test_without_a_charge_pressure_air_keeps_the_constant_compressibility_of_eq_3():
    hyd = Hydraulics.from_damper(TABLE_1, dm.Effects(air_volume_fraction=3e-4))
    assert not hyd.gas_law and hyd.tau_compressibility_1_Pa == hyd.compressibility_1_Pa
    assert hyd.gas_volumes_m3 == (0.0, 0.0)
    ratio, slope = hyd.compressibility_ratio(np.array([-3e6, 0.0, 3e6]))
    assert np.array_equal(ratio, np.ones(3)) and np.array_equal(slope, np.zeros(3))


def test_the_gas_laws_compliance_at_rest_is_the_mixture_of_oil_and_gas_at_the_charge_pressure():
    """𝒞_i(p0) = β_oil V_i (1 - φ0) + φ0 V_i/p0 in series, φ0 = φ_cat 9.9e-6 p0 (Eq. 3 without its approximation)."""
    hyd = Hydraulics.from_damper(GAS_DAMPER, dm.Effects(air_volume_fraction=3e-4))
    phi0 = 3e-4 * 9.9e-6 * 1.0e7
    c1, c2 = ((3.8e-9 * (1 - phi0) + phi0 / 1.0e7) * v for v in (3.0e-4, 2.2e-4))
    assert hyd.rest_compliance(0.0) == pytest.approx(c1 * c2 / (c1 + c2), rel=1e-13)
    ratio, _ = hyd.compressibility_ratio(0.0)
    assert float(ratio) == pytest.approx(1.0, abs=1e-14)


def test_the_gas_laws_pure_gas_split_is_the_quadratic_of_boyles_law():
    """Without oil compressibility the chambers keep their gas volume: V1/p1 + V2/p2 = (V1 + V2)/p0, a quadratic in
    p1 solved here by hand; the compliance ratio is then that of G_i/p_i² in series."""
    p0, v1, v2, dp = 1.0e7, 3.0e-4, 2.2e-4, 4.0e6
    k = (v1 + v2) / p0
    b = k * dp + v1 + v2
    p1 = (b + math.sqrt(b * b - 4 * k * v1 * dp)) / (2 * k)
    p2 = p1 - dp
    c = [v * p0 / p**2 for v, p in ((v1, p1), (v2, p2))]
    c0 = [v / p0 for v in (v1, v2)]
    expected = (c[0] * c[1] / (c[0] + c[1])) / (c0[0] * c0[1] / (c0[0] + c0[1]))
    ratio, _ = compressibility_ratio(dp, 1e-30, 1.0 / p0, p0, v1, v2)
    assert float(ratio) == pytest.approx(expected, rel=1e-10)


def test_the_gas_laws_ratio_slope_is_its_derivative():
    hyd = Hydraulics.from_damper(GAS_DAMPER, dm.Effects(air_volume_fraction=3e-4))
    dp = np.array([-4e6, -5e5, 0.0, 2e6, 6e6])
    for y, stored in ((0.0, 0.0), (3e-3, 2e-7)):
        _, slope = hyd.compressibility_ratio(dp, y, stored)
        up, down = (hyd.compressibility_ratio(dp + h, y, stored)[0] for h in (1e2, -1e2))
        np.testing.assert_allclose(slope, (up - down) / 2e2, rtol=1e-6, atol=1e-16)


@pytest.mark.parametrize("dp0, w, y0, stored", [(0.0, 1e-3, -5e-3, 0.0), (5e6, -1e-3, 5e-3, 3e-7),
                                                (-2e6, 3e-4, -2e-3, -1e-7)],
                         ids=["from rest", "reversal to -", "reversal to +"])
def test_gas_law_table_matches_an_ode_solution(dp0, w, y0, stored):
    """The segment table with the gas law's r(Δp, y0, K) against solve_ivp of 𝒞(0, y) r dΔp/dt = A_p W - Q_N."""
    from scipy.integrate import solve_ivp

    hyd = Hydraulics.from_damper(GAS_DAMPER, dm.Effects(air_volume_fraction=3e-4, leakage_conductance_m3_s_Pa=1e-13))
    qp = hyd.piston_area_m2 * w
    t = np.linspace(0.0, 1.5, 300)
    table = hyd_module.relaxation_batch([dp0], [qp], hyd, y_start_m=[y0], stored_m3=[stored]).relaxation(0)
    got = table.pressure(compressibility_time(t, y0, w, hyd))

    def rate(tt, y):
        r = float(hyd.compressibility_ratio(y[0], y0, stored)[0])
        return [(qp - hyd.flow(y[0])) / (hyd.rest_compliance(y0 + w * tt) * r)]

    sol = solve_ivp(rate, (0.0, 1.5), [dp0], t_eval=t, method="LSODA", rtol=1e-12, atol=1e-4)
    scale = max(abs(steady_pressure(qp, hyd)), abs(dp0))
    assert np.max(np.abs(got - sol.y[0])) < 1e-8 * scale
