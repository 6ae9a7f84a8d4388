"""Harmonic and free-waveform analysis (paper Sec. 4.5, Fig. 13): smoothing derivative, loops,
peak-to-peak points, loop sense, binned and peak-velocity curves, backlash spikes, the stage (its
figure, Fig. 15, is tested in tests/plots/test_harmonic.py).

Simulated records come from the virtual rig without noise; steady references from the damper
formulas and a bracketing root finder (not from the virtual rig)."""

from __future__ import annotations

import dataclasses
import hashlib
import math

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq

from isokinetic.contracts import tables
from isokinetic.measurement.loops import (
    binned_characteristic,
    default_window_s,
    free_loop,
    loop,
    peak_to_peak,
    peak_velocity_characteristic,
    savgol_derivative,
    savgol_derivative_coeffs,
    signed_area,
    smooth_velocity,
)
from isokinetic.physics import damper as dm
from isokinetic.physics.damper import TABLE_1 as TABLE1
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.virtual_rig import Measurement, simulate_case
from isokinetic.stages.harmonic import harmonic_stage, write_harmonic

LEAKY = dm.Effects(leakage_conductance_m3_s_Pa=2.2e-12)
TRUTH = dm.Effects(coulomb_force_N=90.0, leakage_conductance_m3_s_Pa=2.2e-12, asymmetry=0.06)
F_HZ = 1.75


def sine(amp_m=0.45e-3, periods=4.0, rate_Hz=1000.0, case="H99"):
    return CasePlan(case=case, waveform="sine", sample_rate_Hz=rate_Hz, amplitude_m=amp_m, frequency_Hz=F_HZ,
                    phase_rad=0.0, duration_s=periods / F_HZ)


def steady_force(v_m_s: float, d: dm.Damper, e: dm.Effects) -> float:
    """Incompressible steady force A_p Δp(v) (Eq. 24 + leakage) by root finding on Eq. (7)."""
    c1 = dm.laminar_coefficient(d, e)

    def residual(p):
        return dm.orifice_flow(p, c1, dm.turbulent_coefficient(d, e, p)) + e.leakage_conductance_m3_s_Pa * p \
            - d.piston_area_m2 * v_m_s

    return d.piston_area_m2 * brentq(residual, 0.0, 1e9 * np.sign(v_m_s), xtol=1e-9, rtol=1e-14)


# ---------------------------------------------------------------------------------- smoothing

def test_smooth_velocity_recovers_the_derivative_of_a_noisy_sine():
    """Tolerance: with LVDT noise 1 µm and 0.1 µm quantisation (the paper campaign's sensor) the
    default window gives an RMS error <= 1 % and a max error <= 3 % of the velocity amplitude;
    noise free, a 5-sample window is exact to 1e-4 (cubic bias ~ (ω window)^4)."""
    rng = np.random.default_rng(11)
    amp, fs = 0.45e-3, 1000.0
    t = np.arange(int(10 / F_HZ * fs) + 1) / fs
    w = 2 * np.pi * F_HZ
    true_v, big_v = amp * w * np.cos(w * t), amp * w
    x = np.rint((amp * np.sin(w * t) + 1e-6 * rng.standard_normal(t.size)) / 1e-7) * 1e-7
    window = default_window_s(t, x)
    assert 5 / fs <= window <= 0.2 / F_HZ + 1 / fs          # between polyorder + 2 samples and T/5
    err = smooth_velocity(t, x) - true_v
    assert np.sqrt(np.mean(err**2)) <= 0.01 * big_v
    assert np.abs(err).max() <= 0.03 * big_v
    exact = smooth_velocity(t, amp * np.sin(w * t), window_s=5 / fs)
    assert np.abs(exact - true_v).max() <= 1e-4 * big_v
    # uneven time stamps (jitter 10 % of dt): resampled, same accuracy
    tj = t + rng.uniform(-0.05, 0.05, t.size) / fs
    xj = np.rint((amp * np.sin(w * tj) + 1e-6 * rng.standard_normal(t.size)) / 1e-7) * 1e-7
    errj = smooth_velocity(tj, xj) - amp * w * np.cos(w * tj)
    assert np.sqrt(np.mean(errj**2)) <= 0.01 * big_v


# ---------------------------------------------------------------------------------- sine loops

@pytest.fixture(scope="module")
def compressible():
    return simulate_case(sine(), TABLE1, LEAKY, Measurement.ideal(), 1)


def test_loop_keeps_whole_periods_after_the_transient(compressible):
    lp = loop(compressible, F_HZ)
    periods = sorted(lp["period"].unique())
    assert periods[0] >= 2 and periods == list(range(periods[0], periods[-1] + 1))
    n = lp.groupby("period").size()
    assert (abs(n - 1000.0 / F_HZ) <= 1).all()               # each period is one period of samples
    assert list(lp.columns) == ["time_s", "displacement_m", "velocity_m_s", "force_N", "period"]


def test_peak_to_peak_lies_below_the_steady_characteristic(compressible):
    pp = peak_to_peak(loop(compressible, F_HZ)).set_index("direction")
    v_cmd = 0.45e-3 * 2 * np.pi * F_HZ
    for direction, sign in (("+", 1.0), ("-", -1.0)):
        r = pp.loc[direction]
        assert r.velocity_m_s == pytest.approx(sign * v_cmd, rel=2e-3)
        steady = steady_force(r.velocity_m_s, TABLE1, LEAKY)
        assert 0 < r.force_N / steady < 0.8                   # well below: compressibility
        assert 0 < r.phase_lag_rad < np.pi / 2                # force after velocity, < a quarter period
        assert r.n_points >= 2


def test_peak_to_peak_of_an_incompressible_damper_approaches_the_steady_characteristic():
    stiff = dataclasses.replace(TABLE1, oil_compressibility_1_Pa=3.8e-14)
    pp = peak_to_peak(loop(simulate_case(sine(), stiff, LEAKY, Measurement.ideal(), 1), F_HZ))
    for r in pp.itertuples():
        assert r.force_N == pytest.approx(steady_force(r.velocity_m_s, stiff, LEAKY), rel=2e-3)
        assert abs(r.phase_lag_rad) < math.radians(1.0)


def test_compressible_loop_circulates_counter_clockwise_in_force_velocity(compressible):
    """Maxwell element (oil spring in series with the orifice): F lags v by 0 < φ < π/2, so
    (v, F) = (V cos θ, F0 cos(θ - φ)) encloses +π V F0 sin φ: counter-clockwise; (y, F) encloses
    minus the dissipated energy: clockwise."""
    theta = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
    phi = 0.6
    assert signed_area(np.cos(theta), 3 * np.cos(theta - phi)) == pytest.approx(np.pi * 3 * np.sin(phi), rel=1e-4)
    lp = loop(compressible, F_HZ)
    for _, per in lp.groupby("period"):
        ccw = signed_area(per["velocity_m_s"], per["force_N"])
        assert ccw > 0.1 * per["velocity_m_s"].abs().max() * per["force_N"].abs().max()
        assert signed_area(per["displacement_m"], per["force_N"]) < 0


# ---------------------------------------------------------------------------------- free records

def f_true(v):
    return 150.0 * np.tanh(v / 2e-4) + 4e5 * v + 3e8 * v * np.abs(v)


@pytest.fixture(scope="module")
def free_record():
    """A slider-crank dyno with a slow speed sweep (1.2 -> 2 rev/s), known F(v), noisy sensors."""
    rng = np.random.default_rng(7)
    fs, dur = 500.0, 12.0
    t = np.arange(int(dur * fs) + 1) / fs
    w0, w1 = 2 * np.pi * 1.2, 2 * np.pi * 2.0
    theta = w0 * t + (w1 - w0) * t**2 / (2 * dur)
    dtheta = w0 + (w1 - w0) * t / dur
    r, rod = 0.3e-3, 1.2e-3
    root = np.sqrt(rod**2 - (r * np.sin(theta)) ** 2)
    x = r * np.cos(theta) + root - rod
    v = -r * np.sin(theta) * dtheta - r**2 * np.sin(theta) * np.cos(theta) * dtheta / root
    series = pd.DataFrame({"row": np.arange(t.size), "time_s": t,
                           "displacement_m": np.rint((x + rng.normal(0, 1e-6, t.size)) / 1e-7) * 1e-7,
                           "force_N": f_true(v) + rng.normal(0, 5.0, t.size)})
    return series, v


def test_binned_characteristic_recovers_a_known_curve(free_record):
    """Every bin within 0.5 % of the largest force of F(v) at the bin's mean velocity."""
    series, v = free_record
    b = binned_characteristic(free_loop(series))
    assert set(b["direction"]) == {"+", "-"} and len(b) >= 30
    assert (np.sign(b["velocity_m_s"]) == np.where(b["direction"] == "+", 1, -1)).all()
    f_max = np.abs(f_true(v)).max()
    assert np.abs(b["force_N"] - f_true(b["velocity_m_s"])).max() <= 0.005 * f_max
    assert b["velocity_m_s"].abs().max() >= 0.9 * np.abs(v).max()


def test_peak_velocity_characteristic_gives_one_point_per_half_cycle(free_record):
    series, v = free_record
    lp = free_loop(series)
    pv = peak_velocity_characteristic(lp)
    t = series["time_s"].to_numpy()
    inside = (t >= lp["time_s"].iloc[0]) & (t <= lp["time_s"].iloc[-1])
    crossings = np.flatnonzero(np.diff(np.sign(v[inside])) != 0)
    assert len(pv) == len(crossings) - 1                      # complete half-cycles between crossings
    assert (pv["direction"].to_numpy()[1:] != pv["direction"].to_numpy()[:-1]).all()
    tc = t[inside][crossings]
    for k, r in enumerate(pv.itertuples()):
        assert tc[k] < r.time_s < tc[k + 1]                   # its own half-cycle
        i = np.searchsorted(t, tc[k]), np.searchsorted(t, tc[k + 1])
        peak = v[i[0]:i[1]][np.argmax(np.abs(v[i[0]:i[1]]))]
        assert r.velocity_m_s == pytest.approx(peak, rel=0.02)
        assert abs(r.force_N - f_true(r.velocity_m_s)) <= 0.02 * np.abs(f_true(v)).max()


# ---------------------------------------------------------------------------------- backlash spikes

def spike_samples(series: pd.DataFrame):
    """LVDT velocity (5 ms Savitzky-Golay window, short enough to resolve a b/|v| gap) minus its
    trend (window T/5), relative to the command velocity amplitude; and the force zero crossings."""
    t, x, f = (series[c].to_numpy() for c in ("time_s", "displacement_m", "force_N"))
    big_v = 0.45e-3 * 2 * np.pi * F_HZ
    v = smooth_velocity(t, x, window_s=5e-3)
    excess = (v - smooth_velocity(t, x, window_s=0.2 / F_HZ)) / big_v
    nz = np.flatnonzero(f != 0.0)
    flips = np.flatnonzero(np.sign(f[nz[1:]]) != np.sign(f[nz[:-1]]))
    crossings = 0.5 * (t[nz[flips]] + t[nz[flips + 1]])
    # after the first period (start-up), clear of the trend filter's end (half its window)
    steady = (t > 1 / F_HZ) & (t < t[-1] - 0.1 / F_HZ)
    crossings = crossings[(crossings > 1 / F_HZ) & (crossings < t[-1] - 0.1 / F_HZ - 0.02)]
    return t[steady], v[steady], excess[steady], crossings


@pytest.mark.parametrize("gap_m, stiffness_N_m, spikes", [
    (0.05e-3, 5e7, True),
    (0.0, 5e7, False),          # no backlash: the servo lag alone makes no spike
    (0.05e-3, math.inf, False),  # rigid servo: the LVDT sees the command
], ids=["backlash-servo", "no-backlash", "rigid-servo"])
def test_backlash_with_servo_compliance_gives_lvdt_velocity_spikes_at_force_zero_crossings(gap_m, stiffness_N_m,
                                                                                           spikes):
    """A spike: the LVDT velocity exceeds its trend by more than 15 % of the velocity amplitude.
    With backlash and a finite servo stiffness there is one within 20 ms of every force zero
    crossing, in the direction of motion (the unloaded actuator catches up), and none elsewhere."""
    effects = dataclasses.replace(TRUTH, backlash_m=gap_m)
    m = Measurement(servo_stiffness_N_m=stiffness_N_m)         # noise free, default ADC steps
    t, v, excess, crossings = spike_samples(simulate_case(sine(), TABLE1, effects, m, 1))
    hit = np.abs(excess) > 0.15
    if not spikes:
        assert not hit.any(), np.abs(excess).max()
        return
    assert len(crossings) >= 5
    near = np.array([np.abs(crossings - tt).min() <= 0.02 for tt in t])
    assert hit.any() and near[hit].all()                      # nowhere else
    for tc in crossings:                                       # at every crossing
        window = hit & (np.abs(t - tc) <= 0.02)
        assert window.any(), tc
        assert (np.sign(excess[window]) == np.sign(v[window])).all()


# ---------------------------------------------------------------------------------- stage

@pytest.mark.slow
def test_harmonic_stage_on_a_campaign_with_sine_and_free_cases(raw_campaign, tmp_path):
    cases, _ = raw_campaign.run()
    table, loops = harmonic_stage(raw_campaign.root)
    tables.validate_table(table, tables.HARMONIC)
    assert set(loops) == {"H01", "F01"}
    kinds = table.groupby("case")["kind"].agg(lambda s: sorted(set(s))).to_dict()
    assert kinds == {"H01": ["peak_to_peak"], "F01": ["binned", "peak_velocity"]}
    h = table[table["case"] == "H01"].set_index("direction")
    assert h.loc["+", "velocity_m_s"] > 0 > h.loc["-", "velocity_m_s"] and h.loc["+", "force_N"] > 0
    assert (table["campaign"] == "demo").all() and table["frequency_Hz"].notna().all()
    a = write_harmonic(raw_campaign.root, tmp_path / "a")
    b = write_harmonic(raw_campaign.root, tmp_path / "b")
    assert [p.name for p in a] == ["harmonic.parquet", "fig15_harmonic_loops.png"]
    for pa_, pb_ in zip(a, b, strict=True):
        assert hashlib.sha256(pa_.read_bytes()).digest() == hashlib.sha256(pb_.read_bytes()).digest()
    pd.testing.assert_frame_equal(pd.read_parquet(a[0]), table)


def test_campaign_without_sine_or_free_cases_gives_an_empty_table_and_says_so(raw_campaign, tmp_path):
    raw_campaign.edit_manifest(lambda m: m.update(cases=[c for c in m["cases"] if c["waveform"] == "triangle"]))
    raw_campaign.run()
    table, loops = harmonic_stage(raw_campaign.root)
    assert table.empty and not loops
    tables.validate_table(table, tables.HARMONIC)
    paths = write_harmonic(raw_campaign.root, tmp_path / "out")
    assert all(p.is_file() for p in paths) and pd.read_parquet(paths[0]).empty


@pytest.mark.parametrize(("n", "polyorder"), [(5, 2), (5, 3), (7, 3), (31, 3), (101, 2)])
def test_savgol_derivative_equals_scipy_savgol_filter(n, polyorder):
    from scipy.signal import savgol_coeffs, savgol_filter  # the independent reference

    x = np.cumsum(np.random.default_rng(n).normal(size=400))
    expected = savgol_filter(x, n, polyorder, deriv=1, delta=0.01, mode="interp")
    np.testing.assert_allclose(savgol_derivative(x, n, polyorder, 0.01), expected,
                               rtol=0, atol=1e-12 * np.abs(expected).max())
    weights = savgol_coeffs(n, polyorder, deriv=1, delta=0.01, use="dot")
    np.testing.assert_allclose(savgol_derivative_coeffs(n, polyorder, 0.01), weights,
                               rtol=0, atol=1e-12 * np.abs(weights).max())


def test_savgol_derivative_of_a_cubic_is_exact_to_the_ends():
    t = np.linspace(0.0, 2.0, 41)
    x = 1.0 - 2.0 * t + 0.5 * t**2 - 0.3 * t**3
    np.testing.assert_allclose(savgol_derivative(x, 9, 3, t[1] - t[0]), -2.0 + t - 0.9 * t**2, atol=1e-10)
