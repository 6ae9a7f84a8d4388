"""The damper on the physics' grid (physics.sine_grid): against LSODA on every sample, an independent integrator."""

import math
import os

import numpy as np
import pytest

from isokinetic.physics.damper import NOMINAL, Damper, Effects
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.sine_drive import SineDrive, sine_drive_response
from isokinetic.physics.sine_grid import (
    CONVERGED,
    FIRST_SUBSTEP,
    NEWTON_ITERATIONS,
    NEWTON_TOL,
    POINTS_PER_CYCLE,
    RADAU_A,
    RADAU_C,
    SUBSTEPS,
    _sine_kernel,
    built_before_edit,
    grid_parameters,
    grid_response,
    mode_sweep,
    stage_motion,
)
from isokinetic.reference.rig import TABLE1

DAMPER = Damper.from_mapping({**TABLE1.to_dict(), "charge_pressure_Pa": 2.0e6})
FS = 2000.0


def hermite_at(resp, tau):
    """The grid response read at times ``tau`` by its cubic Hermite interpolant."""
    p, f = resp.unfolded(float(tau[-1]))
    x = np.clip(tau / resp.step_s, 0.0, p.size - 1 - 1e-9)
    j = np.floor(x).astype(int)
    s = x - j
    h = resp.step_s
    return (p[j] * (2 * s**3 - 3 * s**2 + 1) + h * f[j] * (s**3 - 2 * s**2 + s) + p[j + 1] * (3 * s**2 - 2 * s**3)
            + h * f[j + 1] * (s**3 - s**2))


@pytest.mark.parametrize("effects", [NOMINAL, Effects(leakage_conductance_m3_s_Pa=2e-12, asymmetry=0.1),
                                     Effects(air_volume_fraction=0.01)], ids=["nominal", "leakage", "air"])
@pytest.mark.parametrize("frequency_Hz, harmonics", [(0.5, ()), (5.0, ((2, 0.03, 0.4), (3, 0.01, -1.0)))],
                         ids=["slow", "fast-distorted"])
def test_the_grid_response_is_the_sampled_integration_after_the_first_cycle(effects, frequency_Hz, harmonics):
    hyd = Hydraulics.from_damper(DAMPER, effects)
    amplitude = 0.2e-3 / frequency_Hz
    harm = tuple((k, a * amplitude, th) for k, a, th in harmonics)
    cycles = 6
    n = int(cycles / frequency_Hz * FS)
    tau, dp, _vel = sine_drive_response(SineDrive(amplitude, frequency_Hz, 0.0, n, harm), FS, hyd)
    grid = grid_response(amplitude, frequency_Hz, harm, hyd, float(tau[-1]))
    later = tau >= 1.0 / frequency_Hz
    # read between grid points by a cubic: within O((2π/128)²) of the pressure scale where the orifice's q|q|
    # turns its curvature at each flow reversal (a bin's mean is closer: tests/diagnosis/test_sine_model.py)
    assert np.max(np.abs(hermite_at(grid, tau)[later] - dp[later])) < 5e-4 * np.max(np.abs(dp))


def test_a_response_that_settles_stops_integrating_and_repeats_its_last_cycle():
    hyd = Hydraulics.from_damper(DAMPER, NOMINAL)
    frequency = 0.2   # relaxation in milliseconds against a 5 s period: settled within the first cycles
    long_record = grid_response(0.5e-3, frequency, (), hyd, 100 / frequency)
    assert 0 <= long_record.periodic_from <= 4 * POINTS_PER_CYCLE   # its change from cycle to cycle settled
    assert long_record.dp_Pa.size <= 6 * POINTS_PER_CYCLE
    p, _f = long_record.unfolded(100 / frequency)
    assert p.size >= 100 * POINTS_PER_CYCLE
    tau = np.arange(int(8 / frequency * 200.0)) / 200.0
    _t, dp, _v = sine_drive_response(SineDrive(0.5e-3, frequency, 0.0, tau.size), 200.0, hyd)
    later = tau >= 1 / frequency
    assert np.max(np.abs(hermite_at(long_record, tau)[later] - dp[later])) < 5e-4 * np.max(np.abs(dp))


def test_the_gas_laws_drift_from_cycle_to_cycle_is_carried_on_after_the_integration_stops():
    # entrained air under the gas law: the chambers' mean pressure drifts by a constant step a cycle (the oil term),
    # so the response never repeats; once the step repeats, the later cycles carry it on
    hyd = Hydraulics.from_damper(DAMPER, Effects(air_volume_fraction=0.01))
    frequency, rate = 0.5, 250.0
    grid = grid_response(0.2e-3, frequency, (), hyd, 60 / frequency)
    assert grid.periodic_from >= 0 and grid.dp_Pa.size < 40 * POINTS_PER_CYCLE   # stopped well before the end
    tau = np.arange(int(60 / frequency * rate)) / rate
    _t, dp, _v = sine_drive_response(SineDrive(0.2e-3, frequency, 0.0, tau.size), rate, hyd)
    later = tau >= 1 / frequency
    assert np.max(np.abs(hermite_at(grid, tau)[later] - dp[later])) < 5e-4 * np.max(np.abs(dp))


def test_the_grid_does_not_depend_on_the_sampling_rate():
    # the grid is one cycle's POINTS_PER_CYCLE points whatever the record's rate: the motion tables are a cycle's
    y, v = stage_motion(1e-3, 2.0, (), POINTS_PER_CYCLE)
    assert y.shape == v.shape == (POINTS_PER_CYCLE, 4)
    u = 2 * math.pi * np.arange(POINTS_PER_CYCLE) / POINTS_PER_CYCLE
    np.testing.assert_allclose(y[:, 3], 1e-3 * np.sin(u), atol=1e-15)
    np.testing.assert_allclose(v[:, 3], 1e-3 * 2 * math.pi * 2.0 * np.cos(u), atol=1e-15)


@pytest.mark.parametrize("lam", [0j, -2.0 + 0j, -2.0 + 3.0j], ids=["integrator", "real-mode", "complex-mode"])
def test_the_mode_sweep_is_the_integrated_mode_equation(lam):
    from scipy.integrate import solve_ivp

    jumps, signs = np.array([0.5, 1.2, 2.0]), np.array([1.0, -1.0, 1.0])
    queries = np.array([0.0, 0.3, 0.5, 0.9, 1.2, 1.7, 2.6, 3.0])
    w, big = np.empty(queries.size, complex), np.empty(queries.size, complex)
    mode_sweep(jumps, signs, lam, queries, w, big)

    def rate(t, y):   # w' = λ w + σ(t), W' = w: real and imaginary parts
        sigma = signs[np.searchsorted(jumps, t, side="right") - 1] if t >= jumps[0] else 0.0
        dw = lam * (y[0] + 1j * y[1]) + sigma
        return [dw.real, dw.imag, y[0], y[1]]

    ref = solve_ivp(rate, (0.0, 3.0), [0.0] * 4, t_eval=queries, rtol=1e-11, atol=1e-13, max_step=0.01)
    assert np.allclose(w, ref.y[0] + 1j * ref.y[1], atol=1e-8)
    assert np.allclose(big, ref.y[2] + 1j * ref.y[3], atol=1e-8)


def test_the_kernel_refuses_an_array_of_the_wrong_type_or_size_naming_it():
    hyd = Hydraulics.from_damper(DAMPER, NOMINAL)
    par = grid_parameters(1e-4, 1.0, hyd, POINTS_PER_CYCLE)
    stage_y, stage_v = stage_motion(1e-4, 1.0, (), POINTS_PER_CYCLE)
    out = np.empty(11)
    args = [par, np.zeros(0), np.zeros(0), np.zeros(0), RADAU_A, RADAU_C, 10, POINTS_PER_CYCLE, SUBSTEPS,
            FIRST_SUBSTEP, CONVERGED, NEWTON_ITERATIONS, NEWTON_TOL, stage_y, stage_v, out, out.copy()]
    assert _sine_kernel.integrate(*args) == -1   # ten steps: no cycle repeats yet
    with pytest.raises(TypeError, match="par: items of format 'd' expected"):
        _sine_kernel.integrate(par.astype(np.float32), *args[1:])
    with pytest.raises(ValueError, match="out_p: 11 items expected, 12 given"):
        _sine_kernel.integrate(*args[:15], np.empty(12), out)
    with pytest.raises(TypeError, match="stage_y: a C-contiguous array"):
        _sine_kernel.integrate(*args[:13], np.asfortranarray(stage_y), *args[14:])


def test_a_kernel_built_before_its_source_was_edited_is_refused(tmp_path):
    source, built = tmp_path / "_sine_kernel.c", tmp_path / "_sine_kernel.so"
    built.write_bytes(b"")
    assert not built_before_edit(source, built)   # an installed package ships no source
    source.write_text("/* edited */")
    os.utime(built, (1.0e9, 1.0e9))
    assert built_before_edit(source, built)
    os.utime(built, None)
    os.utime(source, (1.0e9, 1.0e9))
    assert not built_before_edit(source, built)
