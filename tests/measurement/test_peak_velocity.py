"""The peak-velocity method and the energy per cycle (measurement.peak_velocity) on an analytic damper
F = c1 v + c2 v|v| driven by x = X0 + X sin(wt), by a servo-distorted sine and by a slider-crank: references
from the formulas (the analytic velocity's extremum found on a fine grid), not from the method."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.measurement.peak_velocity import (
    PeakSpec,
    cycle_energies,
    peak_points,
    periodicity,
    settled,
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
    s = summarise(settled(peak_points(t, x, f, 1.0 / FREQ))).set_index("direction")
    expected = damper_force(V_PEAK)
    assert s.loc["+", "force_N"] == pytest.approx(expected, rel=0.01)
    assert s.loc["-", "force_N"] == pytest.approx(-expected, rel=0.01)
    assert s.loc["+", "velocity_m_s"] == pytest.approx(V_PEAK, rel=0.001)
    assert s.loc["-", "velocity_m_s"] == pytest.approx(-V_PEAK, rel=0.001)


def test_noise_free_record_gives_the_force_at_peak_velocity_to_within_its_fit_bias():
    t, x, f = record()
    s = summarise(peak_points(t, x, f, 1.0 / FREQ)).set_index("direction")
    assert s.loc["+", "force_N"] == pytest.approx(damper_force(V_PEAK), rel=3e-4)
    # + peaks at k / f, k = 1..11 (the one at t = 0 has no samples before it), - peaks at (k + 1/2) / f,
    # k = 0..11
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


def test_a_burst_over_a_peak_leaves_that_cycle_out():
    t, x, f = record()
    crossing = 1.0 / FREQ                 # a + peak of velocity (x = X0 rising at t = k / f)
    keep = np.abs(t - crossing) > 0.03   # 60 ms missing around it
    p = peak_points(t[keep], x[keep], f[keep], 1.0 / FREQ)
    assert not np.any(np.abs(p["time_s"] - crossing) < 0.02)
    assert (p["direction"] == "+").sum() == 10         # of 11 (see the noise-free test)


def test_linear_damper_energy_per_cycle_is_pi_c_omega_x_squared():
    t, x, f = record(c2=0.0)
    e = cycle_energies(t, x, f, 1.0 / FREQ)
    assert len(e) == 11                      # between the 12 negative velocity peaks (the 11 positive give 10)
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


def test_settled_drops_the_start_up_drift_measured_on_the_cycles():
    t, x, f = record()
    drift = 40.0 * np.exp(-t / 0.6)          # a decaying offset on the force
    p = peak_points(t, x, f + drift, 1.0 / FREQ)
    s = settled(p)
    limit = 0.005 * damper_force(V_PEAK)     # force_tolerance of the later cycles' force
    at = np.interp(s["time_s"], t, drift)
    dropped = np.interp(p.loc[~p["time_s"].isin(s["time_s"]), "time_s"], t, drift)
    assert len(dropped) >= 2 and np.all(dropped > limit)
    assert np.all(at - at.min() <= 2.0 * limit)
    assert s["time_s"].max() == p["time_s"].max()  # the cycles run to the record's end


def test_settled_drops_leading_cycles_off_the_later_median_only():
    t, x, f = record(force_noise_N=1.0, seed=4)
    p = peak_points(t, x, f, 1.0 / FREQ)
    first_plus = p.index[p["direction"] == "+"][0]
    later_plus = p.index[p["direction"] == "+"][4]
    p.loc[first_plus, "force_N"] *= 0.95           # a start-up cycle 5 % low
    p.loc[later_plus, "force_N"] *= 0.95           # the same later on is scatter, not start-up
    s = settled(p)
    assert len(s) < len(p) and first_plus not in set(p.index[p["time_s"].isin(s["time_s"])])
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


# --------------------------------------------------------------------------------------------
# distorted and crank records: the method follows the measured velocity's extremum (issue 33)
# --------------------------------------------------------------------------------------------

def distorted(t, phi=0.8, third=0.03, fourth=0.0, phi4=1.9):
    """x = X sin(wt) + 3 % X sin(3wt + phi) (+ a fourth harmonic), the servo's distortion, and its velocity."""
    x = X * (np.sin(W * t) + third * np.sin(3 * W * t + phi) + fourth * np.sin(4 * W * t + phi4))
    v = X * W * (np.cos(W * t) + 3 * third * np.cos(3 * W * t + phi) + 4 * fourth * np.cos(4 * W * t + phi4))
    return x, v


def analytic_peaks(velocity, period_s: float) -> dict[str, float]:
    """The extremum of each sign of an analytic periodic velocity, on a grid of a million points a period."""
    grid = np.linspace(0.0, period_s, 1_000_001)
    v = velocity(grid)
    return {"+": float(v.max()), "-": float(v.min())}


@pytest.mark.parametrize("third, fourth", [(0.03, 0.0), (0.02, 0.04)])
def test_distorted_sine_gives_the_force_at_the_measured_velocitys_extremum(third, fourth):
    t = np.arange(0.0, 4.0, 1.0 / 1024.0)
    x, v = distorted(t, third=third, fourth=fourth)
    f = damper_force(v)
    ref = analytic_peaks(lambda g: distorted(g, third=third, fourth=fourth)[1], 1.0 / FREQ)
    s = summarise(settled(peak_points(t, x, f, 1.0 / FREQ))).set_index("direction")
    for d in ("+", "-"):
        assert s.loc[d, "velocity_m_s"] == pytest.approx(ref[d], rel=2e-4)       # the peak speed, not x's centre's
        assert s.loc[d, "force_N"] == pytest.approx(damper_force(ref[d]), rel=1e-3)
    # the speed where x crosses its centre (the old method's) is a distinct, lower speed here
    assert abs(ref["+"] - X * W * (1 + 3 * third * math.cos(0.8) + 4 * fourth * math.cos(1.9))) > 0.005 * ref["+"]


def test_slider_crank_record_gives_each_directions_own_peak():
    # x = r cos(wt) + sqrt(l^2 - r^2 sin^2(wt)) - l: the rod's second harmonic lifts the peak speed above r w
    r, rod = 0.02, 0.06
    def crank(tt):
        th = W * tt
        root = np.sqrt(rod ** 2 - (r * np.sin(th)) ** 2)
        return r * np.cos(th) + root - rod, -r * W * np.sin(th) - (r * r * W * np.sin(th) * np.cos(th)) / root
    t = np.arange(0.0, 3.0, 1.0 / 500.0)
    x, v = crank(t)
    rng = np.random.default_rng(11)
    f = damper_force(v) + 0.5 * rng.standard_normal(t.size)
    ref = analytic_peaks(lambda g: crank(g)[1], 1.0 / FREQ)
    assert ref["+"] > 1.03 * r * W
    s = summarise(settled(peak_points(t, x + 1e-6 * rng.standard_normal(t.size), f, 1.0 / FREQ)))
    s = s.set_index("direction")
    for d in ("+", "-"):
        assert s.loc[d, "velocity_m_s"] == pytest.approx(ref[d], rel=2e-3)
        assert s.loc[d, "force_N"] == pytest.approx(damper_force(ref[d]), rel=5e-3)


def test_ramped_cycles_are_dropped_at_both_ends():
    t = np.arange(0.0, 6.0, 1.0 / 1000.0)
    envelope = np.clip(np.minimum(t, 6.0 - t) / 1.0, 0.0, 1.0)    # 1 s ramp in, 1 s ramp out
    x = X * envelope * np.sin(W * t)
    v = np.gradient(x, t)
    p = peak_points(t, x, damper_force(v), 1.0 / FREQ)
    s = settled(p)
    assert len(s) < len(p)
    assert s["time_s"].min() > 1.0 - 0.1 and s["time_s"].max() < 5.0 + 0.1
    np.testing.assert_allclose(s["velocity_m_s"].abs(), V_PEAK, rtol=0.01)


def test_one_cycle_has_no_standard_error():
    t, x, f = record(seconds=0.75)                  # one + peak at 0.5 s, - peaks at 0.25 and 0.75 (cut)
    s = summarise(settled(peak_points(t, x, f, 1.0 / FREQ))).set_index("direction")
    assert s.loc["+", "n_cycles"] == 1 and math.isnan(s.loc["+", "force_se_N"])
    assert s.loc["+", "force_N"] == pytest.approx(damper_force(V_PEAK), rel=1e-3)


def test_a_sine_is_periodic_and_a_two_tone_record_is_not():
    t, x, f = record(force_noise_N=2.0)
    assert periodicity(peak_points(t, x, f, 1.0 / FREQ)) == pytest.approx(1.0 / FREQ, rel=1e-3)
    t = np.arange(0.0, 8.0, 1e-3)
    x = 0.01 * np.sin(2 * math.pi * 1.3 * t) + 0.004 * np.sin(2 * math.pi * 3.1 * t + 0.4)
    assert periodicity(peak_points(t, x, damper_force(np.gradient(x, t)), 1.0 / 1.3)) is None


def test_the_speed_window_on_a_sine_spans_the_arccos_of_the_peak_fraction():
    # |cos(w tau)| >= 0.99 for |tau| <= arccos(0.99) / w: 2.25 % of the period either side
    t, x, f = record()
    p = peak_points(t, x, f, 1.0 / FREQ, spec=PeakSpec(peak_fraction=0.99))
    np.testing.assert_allclose(p["window_s"], 2.0 * math.acos(0.99) / W, rtol=2e-3)


def test_a_smooth_force_is_steady_and_the_window_gives_its_value_at_the_peak():
    # window mean of c2 v^2 lies (p/6) theta0^2 ~ 0.7 % below the peak; the quadratic's curvature corrects it
    t, x, f = record()
    s = summarise(peak_points(t, x, f, 1.0 / FREQ)).set_index("direction")
    assert s.loc["+", "force_N"] == pytest.approx(damper_force(V_PEAK), rel=2e-4)
    assert s.loc["-", "force_N"] == pytest.approx(-damper_force(V_PEAK), rel=2e-4)
    noisy = peak_points(*record(force_noise_N=2.0), 1.0 / FREQ)
    assert noisy["steady"].all() and (noisy["force_spread_N"] == 0).all()


def test_a_force_notch_at_the_peak_is_flagged_with_its_spread_and_the_window_mean():
    # a backlash-like notch: the force falls by 30 % over the middle third of the speed window
    t, x, f = record(force_noise_N=2.0)
    half = math.acos(0.99) / W
    phase = (t - 0.5 / FREQ) % (1.0 / FREQ)                  # 0 at each '-' peak (x falls through X0)
    near = np.minimum(phase, 1.0 / FREQ - phase) < half / 3.0
    f_notched = np.where(near, 0.7 * f, f)
    p = peak_points(t, x, f_notched, 1.0 / FREQ)
    minus, plus = p[p["direction"] == "-"], p[p["direction"] == "+"]
    assert plus["steady"].all() and not minus["steady"].any()
    # the mean of the noise-free notched force over the samples within the analytic window of each '-' peak
    peaks = 0.5 / FREQ + np.round((minus["time_s"].to_numpy() - 0.5 / FREQ) * FREQ) / FREQ
    clean = np.where(near, 0.7, 1.0) * damper_force(X * W * np.cos(W * t))
    expected = [clean[np.abs(t - tp) <= half].mean() for tp in peaks]
    n_window = int(np.sum(np.abs(t - peaks[0]) <= half))
    np.testing.assert_allclose(minus["force_N"], expected, atol=4.0 * 2.0 / math.sqrt(n_window))  # 4 SE of noise
    # the spread of a two-level force, 1/3 at 0.7 F and 2/3 at F: F 0.3 sqrt(2/9)
    np.testing.assert_allclose(minus["force_spread_N"], damper_force(V_PEAK) * 0.3 * math.sqrt(2 / 9), rtol=0.1)
    s = summarise(p).set_index("direction")
    assert s.loc["-", "n_unsteady"] == len(minus) and s.loc["+", "n_unsteady"] == 0


def test_settling_keeps_a_cycle_one_percent_slower_and_drops_a_ramp():
    # the last peak-speed scatter of real rigs is 0.2-1 %; a ramp's cycles differ by tens of %
    t, x, f = record(force_noise_N=1.0)
    envelope = np.clip(t / 1.5, 0.0, 1.0) * np.where((t > 2.5) & (t < 3.0), 0.99, 1.0)
    x2 = X0 + X * envelope * np.sin(W * t)
    f2 = damper_force(np.gradient(x2, t))
    p = peak_points(t, x2, f2, 1.0 / FREQ)
    kept = settled(p)
    assert kept["time_s"].min() > 1.4                            # the ramp's cycles are out
    assert ((kept["time_s"] > 2.5) & (kept["time_s"] < 3.0)).sum() >= 1     # the 1 % slower cycle is in


def test_a_spike_at_a_peak_gives_the_clean_twins_force_within_its_standard_error_counted():
    t, x, f = record(force_noise_N=5.0, seed=4)
    clean = peak_points(t, x, f, 1.0 / FREQ)
    at = int(np.argmin(np.abs(t - clean["time_s"].iloc[3])))      # the sample at one cycle's velocity peak
    spiked = f.copy()
    spiked[at] += 10_000.0
    p = peak_points(t, x, spiked, 1.0 / FREQ)
    assert p["spikes_excluded"].tolist() == [1 if k == 3 else 0 for k in range(len(p))]
    assert not p["spike_set_aside"].any() and p["steady"].all()
    same = [k for k in range(len(p)) if k != 3]
    assert p.iloc[same]["force_N"].tolist() == clean.iloc[same]["force_N"].tolist()
    n_window = int(clean["i_stop"].iloc[3] - clean["i_start"].iloc[3])
    assert abs(p["force_N"].iloc[3] - clean["force_N"].iloc[3]) < 3.0 * 5.0 * math.sqrt(3.0 / n_window)
    expected = [1, 0] if clean["direction"].iloc[3] == "+" else [0, 1]
    assert summarise(p)["spikes_excluded"].tolist() == expected


def test_a_cycle_with_too_many_spikes_in_its_speed_window_is_marked_set_aside():
    t, x, f = record(force_noise_N=5.0, seed=6)
    clean = peak_points(t, x, f, 1.0 / FREQ)
    i0, i1 = int(clean["i_start"].iloc[2]), int(clean["i_stop"].iloc[2])
    spiked = f.copy()
    spiked[[i0 + 5, i0 + 15, i1 - 10]] -= 6000.0
    p = peak_points(t, x, spiked, 1.0 / FREQ)
    assert p["spike_set_aside"].tolist() == [k == 2 for k in range(len(p))]
