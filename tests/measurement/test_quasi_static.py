"""The quasi-static test (measurement.quasi_static): a memoryless damper's record passes however it is driven,
a force with a first-order lag fails; the branch difference is checked against the lag's closed form."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from isokinetic.measurement.loops import free_loop
from isokinetic.measurement.quasi_static import branch_bins, quasi_static

C1, C2 = 3000.0, 20000.0
X = 0.01


def series(t, x, f) -> pd.DataFrame:
    return pd.DataFrame({"time_s": t, "displacement_m": x, "force_N": f})


def lagged_sine(freq_Hz: float, tau_s: float, seconds: float, noise_N: float = 2.0, seed: int = 1):
    """x = X sin(wt) and the steady force of a linear damper c v behind a first-order lag tau:
    F = c X w / sqrt(1 + (w tau)^2) cos(wt - atan(w tau)) (closed form), plus white noise."""
    t = np.arange(0.0, seconds, 1e-3)
    w = 2 * math.pi * freq_Hz
    phi = math.atan(w * tau_s)
    amp = C1 * X * w / math.hypot(1.0, w * tau_s)
    f = amp * np.cos(w * t - phi) + noise_N * np.random.default_rng(seed).standard_normal(t.size)
    return t, X * np.sin(w * t), f, amp, phi


def test_a_slow_sine_on_a_memoryless_damper_is_quasi_static():
    t = np.arange(0.0, 20.0, 1e-3)
    w = 2 * math.pi * 0.2
    v = X * w * np.cos(w * t)
    f = C1 * v + C2 * v * np.abs(v) + 2.0 * np.random.default_rng(2).standard_normal(t.size)
    verdict = quasi_static(free_loop(series(t, X * np.sin(w * t), f)))
    assert verdict.passed and verdict.n_tested >= 30, verdict.reason
    assert verdict.reason.startswith("quasi-static")


def test_a_random_two_tone_record_on_a_memoryless_damper_is_quasi_static():
    t = np.arange(0.0, 8.0, 1e-3)
    x = 0.01 * np.sin(2 * math.pi * 1.3 * t) + 0.004 * np.sin(2 * math.pi * 3.1 * t + 0.4)
    v = np.gradient(x, t)
    f = C1 * v + C2 * v * np.abs(v) + 2.0 * np.random.default_rng(3).standard_normal(t.size)
    assert quasi_static(free_loop(series(t, x, f))).passed


def test_a_force_lagging_by_a_first_order_time_constant_fails():
    t, x, f, _amp, _phi = lagged_sine(2.0, 0.005, 5.0)          # w tau = 0.063
    verdict = quasi_static(free_loop(series(t, x, f)))
    assert not verdict.passed
    assert verdict.reason.startswith("not quasi-static") and "standard errors" in verdict.reason


def test_branch_difference_is_the_lags_closed_form():
    # v = V cos(th), F = A cos(th - phi): at speed u = V cos(th0) the accelerating branch (th = -th0) has
    # F = A cos(th0 + phi), the decelerating one (th = th0) A cos(th0 - phi): difference -2 A sin(th0) sin(phi)
    t, x, f, amp, phi = lagged_sine(2.0, 0.02, 5.0, noise_N=0.0)
    b = branch_bins(free_loop(series(t, x, f)))
    plus = b[(b["direction"] == "+") & (b["bin"].between(3, 17))]
    vmax = X * 2 * math.pi * 2.0
    th0 = np.arccos(np.clip(plus["velocity_m_s"].to_numpy() / vmax, -1.0, 1.0))
    np.testing.assert_allclose(plus["difference_N"], -2 * amp * np.sin(th0) * math.sin(phi), rtol=0.03)


def test_a_record_with_no_bin_on_both_branches_cannot_pass():
    t = np.arange(0.0, 1.0, 1e-3)
    x = 0.01 * t                                    # one constant speed: no branch
    verdict = quasi_static(free_loop(series(t, x, C1 * 0.01 + np.zeros(t.size))))
    assert not verdict.passed and verdict.n_tested == 0 and "cannot" in verdict.reason


@pytest.mark.parametrize("tau_s", [0.0, 0.02])
def test_the_verdict_names_the_worst_bin(tau_s):
    t, x, f, _amp, _phi = lagged_sine(1.0, tau_s, 6.0)
    verdict = quasi_static(free_loop(series(t, x, f)))
    assert verdict.passed == (tau_s == 0.0)
    assert math.isfinite(verdict.velocity_m_s) and abs(verdict.velocity_m_s) <= X * 2 * math.pi * 1.01
