"""The peak-velocity method and the energy per cycle (measurement.peak_velocity) on an analytic damper
F = c1 v + c2 v|v| driven by x = X0 + X sin(wt): references from the formulas, not from the method."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.measurement.peak_velocity import (
    PeakSpec,
    crossings,
    cycle_energies,
    peak_points,
    settled,
    steady_range,
    summarise,
)

C1, C2 = 200.0, 3000.0          # N s/m, N s^2/m^2
X, X0, FREQ = 12.7e-3, 1.0e-3, 2.0
W = 2.0 * math.pi * FREQ
V_PEAK = X * W


def damper_force(v):
    return C1 * v + C2 * v * np.abs(v)


def record(rate_Hz=2000.0, seconds=6.0, force_noise_N=0.0, disp_noise_m=0.0, seed=1, c1=C1, c2=C2):
    t = np.arange(0.0, seconds, 1.0 / rate_Hz)
    x = X0 + X * np.sin(W * t)
    v = X * W * np.cos(W * t)
    f = c1 * v + c2 * v * np.abs(v)
    rng = np.random.default_rng(seed)
    return t, x + disp_noise_m * rng.standard_normal(t.size), f + force_noise_N * rng.standard_normal(t.size)


def drop_samples(n: int, fraction: float, seed: int) -> np.ndarray:
    """Keep-mask with ``fraction`` of the samples missing: half as singles, half as bursts of 5-40."""
    rng = np.random.default_rng(seed)
    keep = np.ones(n, dtype=bool)
    target = int(fraction * n)
    while (~keep).sum() < target // 2:
        i = int(rng.integers(50, n - 50))
        keep[i:i + int(rng.integers(5, 41))] = False
    singles = rng.choice(np.flatnonzero(keep), target - int((~keep).sum()), replace=False)
    keep[singles] = False
    return keep


def test_force_at_peak_velocity_matches_the_noise_free_force_within_1_percent():
    t, x, f = record(force_noise_N=5.0, disp_noise_m=2e-6)
    a, b = steady_range(t, f, 1.0 / FREQ)
    s = summarise(peak_points(t, x, f, 1.0 / FREQ, t_start=a, t_stop=b)).set_index("direction")
    expected = damper_force(V_PEAK)
    assert s.loc["+", "force_N"] == pytest.approx(expected, rel=0.01)
    assert s.loc["-", "force_N"] == pytest.approx(-expected, rel=0.01)
    assert s.loc["+", "velocity_m_s"] == pytest.approx(V_PEAK, rel=0.001)
    assert s.loc["-", "velocity_m_s"] == pytest.approx(-V_PEAK, rel=0.001)


def test_noise_free_record_gives_the_force_at_peak_velocity_to_within_its_fit_bias():
    t, x, f = record()
    s = summarise(peak_points(t, x, f, 1.0 / FREQ)).set_index("direction")
    assert s.loc["+", "force_N"] == pytest.approx(damper_force(V_PEAK), rel=3e-4)
    # rising crossings at k / f, k = 1..11 (the one at t = 0 has no samples before it), falling ones at
    # (k + 1/2) / f, k = 0..11
    assert s.loc["+", "n_cycles"] == 11 and s.loc["-", "n_cycles"] == 12


def test_standard_error_is_the_cycle_scatter_over_root_n():
    t, x, f = record(force_noise_N=5.0, seed=3)
    s = summarise(peak_points(t, x, f, 1.0 / FREQ))
    p = peak_points(t, x, f, 1.0 / FREQ)
    plus = p.loc[p["direction"] == "+", "force_N"].to_numpy()
    row = s.set_index("direction").loc["+"]
    assert row["force_std_N"] == pytest.approx(np.std(plus, ddof=1))
    assert row["force_se_N"] == pytest.approx(np.std(plus, ddof=1) / math.sqrt(plus.size))


def test_dropped_samples_give_the_same_result_within_the_standard_error():
    t, x, f = record(force_noise_N=5.0, disp_noise_m=2e-6, seed=5)
    keep = drop_samples(t.size, 0.01, seed=9)
    assert 0.009 <= 1 - keep.mean() <= 0.011
    full = summarise(peak_points(t, x, f, 1.0 / FREQ)).set_index("direction")
    thin = summarise(peak_points(t[keep], x[keep], f[keep], 1.0 / FREQ)).set_index("direction")
    for d in ("+", "-"):
        se = math.hypot(full.loc[d, "force_se_N"], thin.loc[d, "force_se_N"])
        assert abs(thin.loc[d, "force_N"] - full.loc[d, "force_N"]) <= 2.0 * se
        assert thin.loc[d, "force_N"] == pytest.approx(math.copysign(damper_force(V_PEAK), full.loc[d, "force_N"]),
                                                        rel=0.01)


def test_a_burst_over_a_crossing_leaves_that_cycle_out():
    t, x, f = record()
    crossing = 1.0 / FREQ                 # a rising crossing of the centre (x = X0 at t = k / f)
    keep = np.abs(t - crossing) > 0.03   # 60 ms missing around it
    p = peak_points(t[keep], x[keep], f[keep], 1.0 / FREQ, spec=PeakSpec(fit_fraction=0.01))
    assert not np.any(np.abs(p["time_s"] - crossing) < 0.02)
    assert (p["direction"] == "+").sum() == 10         # of 11 (see the noise-free test)


def test_linear_damper_energy_per_cycle_is_pi_c_omega_x_squared():
    t, x, f = record(c2=0.0)
    e = cycle_energies(t, x, f, 1.0 / FREQ)
    assert len(e) == 10                      # between the 11 rising crossings
    np.testing.assert_allclose(e["energy_J"], math.pi * C1 * W * X ** 2, rtol=1e-4)
    np.testing.assert_allclose(e["amplitude_m"], X, rtol=1e-4)


def test_quadratic_damper_energy_per_cycle_is_eight_thirds_c2_omega_squared_x_cubed():
    t, x, f = record(c1=0.0)
    e = cycle_energies(t, x, f, 1.0 / FREQ)
    np.testing.assert_allclose(e["energy_J"], 8.0 / 3.0 * C2 * W ** 2 * X ** 3, rtol=1e-4)


def test_energy_with_dropped_samples_stays_within_a_thousandth():
    t, x, f = record(c2=0.0)
    keep = drop_samples(t.size, 0.01, seed=2)
    e = cycle_energies(t[keep], x[keep], f[keep], 1.0 / FREQ)
    assert len(e) >= 9
    np.testing.assert_allclose(e["energy_J"], math.pi * C1 * W * X ** 2, rtol=1e-3)


def test_steady_range_skips_the_start_up_drift():
    t, x, f = record()
    drift = 40.0 * np.exp(-t / 0.6)          # a decaying offset on the force
    a, b = steady_range(t, f + drift, 1.0 / FREQ)
    tolerance = 0.01 * damper_force(V_PEAK)  # 1 % of the last period's force amplitude
    period = 1.0 / FREQ
    before = (t >= a - period) & (t < a)
    assert drift[before].mean() > tolerance
    assert np.all(drift[t >= a] <= drift[(t >= a) & (t < a + period)].mean() + tolerance)
    assert drift[(t >= a) & (t < a + period)].mean() <= tolerance + drift[t >= 5.5].mean()
    assert b == pytest.approx(6.0)


def test_crossings_alternate_and_ignore_noise_near_the_centre():
    t = np.linspace(0.0, 2.0, 4001)
    x = np.sin(2 * math.pi * t) + 0.02 * np.sin(2 * math.pi * 400 * t)
    found = crossings(x, 0.0, 0.25)
    signs = [s for _, s in found]
    assert signs == [-1.0, 1.0, -1.0]


def test_settled_drops_leading_cycles_off_the_later_median_only():
    t, x, f = record(force_noise_N=1.0, seed=4)
    p = peak_points(t, x, f, 1.0 / FREQ)
    first_plus = p.index[p["direction"] == "+"][0]
    later_plus = p.index[p["direction"] == "+"][4]
    p.loc[first_plus, "force_N"] *= 0.95           # a start-up cycle 5 % low
    p.loc[later_plus, "force_N"] *= 0.95           # the same later on is scatter, not start-up
    s = settled(p)
    assert first_plus not in set(p.index[p["time_s"].isin(s["time_s"])])
    assert (s["direction"] == "+").sum() == (p["direction"] == "+").sum() - 1
    assert (s["direction"] == "-").sum() == (p["direction"] == "-").sum()


def test_an_off_nominal_frequency_and_a_span_of_no_whole_periods_leave_a_lagging_force_unbiased():
    # F = F0 cos(wt - phi) lags v = X w cos(wt) by phi: at peak velocity F = F0 cos(phi)
    t = np.arange(0.0, 3.3, 1e-3)
    x = X0 + X * np.sin(W * t)
    f = 1000.0 * np.cos(W * t - 0.5)
    s = summarise(peak_points(t, x, f, 1.0 / 1.9)).set_index("direction")   # nominal 1.9 Hz, record 2 Hz
    assert s.loc["+", "force_N"] == pytest.approx(1000.0 * math.cos(0.5), rel=2e-4)
    assert s.loc["-", "force_N"] == pytest.approx(-1000.0 * math.cos(0.5), rel=2e-4)
