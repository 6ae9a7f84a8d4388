"""Physics any damper's record obeys: causality, dissipation, magnitudes, a temperature that follows the motion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.init_campaign import channels
from isokinetic.measurement import plausibility as pl
from isokinetic.physics.plan import triangle_displacement

RATE_HZ, PERIOD_S, AMPLITUDE_M = 500.0, 2.0, 1e-3


def _first_order(t, x, tau_s):
    """x through a first-order lag (exact for a piecewise-constant input between samples)."""
    if tau_s == 0:
        return x.copy()
    a = math.exp(-(t[1] - t[0]) / tau_s)
    y = np.empty_like(x)
    y[0] = x[0]
    for i in range(1, x.size):
        y[i] = a * y[i - 1] + (1 - a) * x[i]
    return y


def _record(tau_s=0.02, delay_s=0.0, noise_N=5.0, seed=1):
    """A triangle with a friction + viscous force through a first-order lag tau_s; the displacement measured
    delay_s late."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(2.5 * PERIOD_S * RATE_HZ)) / RATE_HZ
    x = triangle_displacement(t, AMPLITUDE_M, PERIOD_S)
    v = np.gradient(x, t)
    force = _first_order(t, np.sign(v) * (100.0 + 2e5 * np.abs(v)), tau_s) + rng.normal(0, noise_N, t.size)
    measured_x = triangle_displacement(t - delay_s, AMPLITUDE_M, PERIOD_S) + rng.normal(0, 1e-7, t.size)
    return t, measured_x, force


def test_a_first_order_lag_is_measured_as_its_median_delay():
    t, x, f = _record(tau_s=0.02)
    lags, errors, _ = pl.force_lags(t, x, f)
    assert lags.size >= 4
    # a velocity step through a first-order lag crosses its middle at tau ln 2
    assert np.allclose(lags, 0.02 * math.log(2), atol=3 * errors.max() + 1.0 / RATE_HZ)


def test_a_reversed_record_leads_by_the_lag_whatever_the_load_cells_sign():
    t, x, f = _record(tau_s=0.02)
    lead = pl.causality(t, x[::-1], -f[::-1], 1.0 / RATE_HZ)
    assert lead.leads_everywhere
    assert np.allclose(-lead.lags_s, 0.02 * math.log(2), atol=3 * lead.errors_s.max() + 1.0 / RATE_HZ)
    assert not pl.causality(t, x, f, 1.0 / RATE_HZ).leads_everywhere


def test_a_stronger_rebound_moves_the_two_directions_apart_and_their_pair_cancels_it():
    t = np.arange(int(6.0 * RATE_HZ)) / RATE_HZ
    x = AMPLITUDE_M * np.sin(2 * np.pi * t)
    v = np.gradient(x, t)
    force = np.where(v > 0, 3e5, 1e5) * v                # no lag, twice as strong one way: 0.1 rad apart
    lead = pl.causality(t, x, force, 1.0 / RATE_HZ)
    lags = lead.lags_s[2:-2]
    assert np.ptp(lags) > 0.01                           # the directions disagree by tens of ms...
    assert np.allclose(lead.pair_lags_s[0], 0.0, atol=1.0 / RATE_HZ)     # ...their pairs do not
    assert not lead.leads_everywhere and not pl.causality(t, x[::-1], -force[::-1], 1.0 / RATE_HZ).leads_everywhere


@pytest.mark.parametrize("tau_s, delay_s", [(0.0, 0.0), (0.0, 0.004), (0.05, 0.0), (0.0, 2.0 / RATE_HZ)],
                         ids=["no-lag", "lvdt-delay-4ms", "force-low-pass", "two-samples-skew"])
def test_no_lead_is_seen_within_what_real_rigs_make(tau_s, delay_s):
    t, x, f = _record(tau_s=tau_s, delay_s=delay_s)
    assert not pl.causality(t, x, f, 1.0 / RATE_HZ).leads_everywhere


def test_a_damper_absorbs_energy_and_an_inverted_or_reversed_record_gives_it_back():
    t, x, f = _record(tau_s=0.0)     # a lag takes about 2 tau / (T/2) of the work: none here
    net, absolute = pl.cycle_energies(t, x, f)
    # independent: the friction + viscous force's work over a cycle, 4 A (100 N + 2e5 N s/m x 4A/T)
    assert net.sum() / net.size == pytest.approx(4 * AMPLITUDE_M * (100.0 + 2e5 * 4 * AMPLITUDE_M / PERIOD_S),
                                                 rel=0.03)
    assert not pl.gives_energy_back(net, absolute)
    assert pl.gives_energy_back(*pl.cycle_energies(t, x, -f))
    assert pl.gives_energy_back(*pl.cycle_energies(t, x[::-1], f[::-1]))
    assert pl.gives_energy_back(*pl.cycle_energies(t, x + 0.3, f + 500.0)) is False     # offsets cancel


def test_kn_as_n_is_decided_as_init_campaign_decides_a_columns_unit():
    # independent: init-campaign's own choice between N and kN over a campaign's files (channels.choose_unit)
    rng = np.random.default_rng(5)
    decided = []
    for _ in range(400):
        peaks = 10.0 ** rng.uniform(-1.0, 2.0, size=int(rng.integers(1, 6)))
        choice = channels.choose_unit([channels.force_scores(np.array([p, -p])) for p in peaks])
        expected = choice.unit == "kN" and choice.sure == "sure"
        assert pl.kn_reading_sure(peaks) is expected, (peaks, choice)
        decided.append(expected)
    assert 0.1 < np.mean(decided) < 0.9          # both outcomes exercised
    assert pl.kn_reading_sure([pl.MIN_PEAK_FORCE_N * 0.99]) and not pl.kn_reading_sure([pl.MIN_PEAK_FORCE_N * 1.01])


@pytest.mark.parametrize("peak_N, full_scale_N, flagged", [
    (0.27, None, True), (1.6, None, True), (1.8, None, False), (270.0, None, False), (5000.0, None, False),
    (0.27, 10.0, False), (0.27, 1e4, True), (1.2, 1e4, True), (270.0, 1e4, False)])
def test_force_magnitude_against_full_scale_or_a_dampers_forces(peak_N, full_scale_N, flagged):
    f = peak_N * np.sin(np.linspace(0, 20, 2000))
    assert bool(pl.force_magnitude_problem(f, full_scale_N)) is flagged


def test_implied_damping_is_force_over_velocity():
    t = np.arange(2000) / RATE_HZ
    x = 1e-3 * np.sin(2 * np.pi * 1.0 * t)
    f = 3e4 * 2e-3 * np.pi * np.cos(2 * np.pi * t)
    assert pl.implied_damping_N_s_m(t, x, f) == pytest.approx(3e4, rel=1e-3)
    assert pl.plausible_damping(3e4) and not pl.plausible_damping(0.5) and not pl.plausible_damping(2e9)


def test_a_channel_that_repeats_the_motion_follows_it_a_drifting_temperature_does_not():
    t, x, _ = _record()
    assert pl.follows(40.0 + 1e3 * x, x) > pl.FOLLOW_CORRELATION
    drift = 40.0 + 2.0 * t / t[-1] + np.random.default_rng(2).normal(0, 0.05, t.size)
    assert pl.follows(drift, x) < pl.FOLLOW_CORRELATION
    assert pl.follows(np.full(t.size, 40.0), x) == 0.0


def test_an_elastic_force_seen_through_a_lagging_channel_gives_back_less_than_an_inverted_damper():
    """A passive element whose force is mostly elastic (k x) with a little damping, read through a first-order
    low-pass that lags it past a quarter period, gives some work back: less than ENERGY_FRACTION, so it is kept
    (flagged); the same damper with its force inverted gives back nearly all."""
    t = np.arange(0.0, 4.0, 1e-3)
    w = 2 * np.pi * 2.0
    x = 1e-4 * np.sin(w * t)
    v = 1e-4 * w * np.cos(w * t)
    # independent: the low-pass's steady response to F = k x + c v, phase lag atan(w tau), gain 1/sqrt(1 + (w tau)^2)
    k, c, tau = 1e6, 2e4, 1.0 / (2 * np.pi * 4.0)
    lag, gain = np.arctan(w * tau), 1.0 / np.hypot(1.0, w * tau)
    f = gain * 1e-4 * (k * np.sin(w * t - lag) + c * w * np.cos(w * t - lag))
    back = pl.energy_given_back(*pl.cycle_energies(t, x, f))
    assert pl.ENERGY_NOTE_FRACTION < back < pl.ENERGY_FRACTION
    assert not pl.gives_energy_back(*pl.cycle_energies(t, x, f))
    assert pl.energy_given_back(*pl.cycle_energies(t, x, -c * v)) > 0.9
