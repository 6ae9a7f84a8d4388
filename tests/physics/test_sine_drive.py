"""The model driven by a measured sine (isokinetic.physics.sine_drive) against the virtual rig's own sine
integration (physics.responses.sine_response) on the plan grid and between its samples."""

import math

import numpy as np
import pytest

from isokinetic.physics.damper import TABLE_1, Effects
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import sine_response
from isokinetic.physics.sine_drive import SineDrive, sine_drive_response

HYD = Hydraulics.from_damper(TABLE_1, Effects(air_volume_fraction=0.01))


def plan(frequency_Hz: float, amplitude_m: float, fs: float, cycles: float = 3.0) -> CasePlan:
    return CasePlan("H01", "sine", fs, amplitude_m=amplitude_m, frequency_Hz=frequency_Hz, phase_rad=0.0,
                    duration_s=cycles / frequency_Hz)


@pytest.mark.parametrize("backlash_m", [0.0, 2e-6])
def test_on_the_plan_grid_the_sine_drive_is_the_virtual_rigs_sine(backlash_m):
    p = plan(2.0, 2e-5, 400.0)
    t, dp, vel = sine_response(p, HYD, backlash_m)
    tau, dp2, vel2 = sine_drive_response(SineDrive(p.amplitude_m, 2.0, 0.0, t.size), 400.0, HYD, backlash_m)
    assert np.allclose(tau, t, rtol=0, atol=1e-12)
    assert np.max(np.abs(dp2 - dp)) < 1e-6 * np.max(np.abs(dp))
    assert np.allclose(vel2[1:], vel[1:], rtol=0, atol=1e-12) and vel2[0] == 0.0   # at rest up to τ = 0


def test_an_offset_grid_samples_between_the_plan_grids_samples():
    # the plan grid at 2 fs holds the offset grid (start half a sample late) as its odd samples
    fine = plan(5.0, 1e-5, 1000.0)
    t, dp, _ = sine_response(fine, HYD)
    drive = SineDrive(fine.amplitude_m, 5.0, 0.5 / 500.0, (t.size - 1) // 2)
    tau, dp2, _ = sine_drive_response(drive, 500.0, HYD)
    assert np.allclose(tau, t[1::2][:tau.size], rtol=0, atol=1e-12)
    assert np.max(np.abs(dp2 - dp[1::2][:tau.size])) < 1e-6 * np.max(np.abs(dp))


def test_before_the_motion_starts_the_model_is_at_rest():
    drive = SineDrive(1e-5, 1.0, -0.05, 200)
    tau, dp, vel = sine_drive_response(drive, 100.0, HYD)
    before = tau <= 0.0
    assert before.sum() == 6 and np.all(dp[before] == 0.0) and np.all(vel[before] == 0.0)
    assert vel[~before][0] == pytest.approx(1e-5 * 2 * math.pi * math.cos(2 * math.pi * tau[~before][0]))


def test_without_backlash_the_pushed_pieces_are_integrated_as_one_and_gaps_stay_apart():
    from isokinetic.physics.excitation import piston_segments
    from isokinetic.physics.sine_drive import merged_contacts

    p = plan(2.0, 2e-5, 400.0)
    assert len(merged_contacts(piston_segments(p, 0.0))) == 1
    with_gap = piston_segments(p, 2e-6)
    merged = merged_contacts(with_gap)
    assert sum(not s.contact for s in merged) == sum(not s.contact for s in with_gap) > 0
    assert merged[0].t_start_s == with_gap[0].t_start_s and merged[-1].t_end_s == with_gap[-1].t_end_s


def sine_segment_system(seg, hyd: Hydraulics, amp: float, omega: float):
    """rhs and Jacobian of Eq. (1) on one piece of a sine case written with the Hydraulics methods themselves
    (composite_volume, flow, flow_derivative): the reference of the fused system."""
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    q_n, dq_n = hyd.flow, hyd.flow_derivative
    if seg.contact:
        off = seg.offset_m

        def kin(tt):
            y = amp * math.sin(omega * tt) + off
            return a * amp * omega * math.cos(omega * tt), hyd.composite_volume(y)
    else:
        vol0 = hyd.composite_volume(seg.piston_start_m)

        def kin(tt):
            return 0.0, vol0

    def rhs(tt, z):
        qp, vol = kin(tt)
        return [(qp - q_n(z[0])) / (beta * vol)]

    def jac(tt, z):
        return [[-dq_n(z[0]) / (beta * kin(tt)[1])]]

    return rhs, jac


@pytest.mark.parametrize("contact", [True, False])
def test_the_fused_system_is_the_hydraulics_arithmetic_bit_for_bit(contact):
    """fused_segment_system's rhs and Jacobian equal those written with Hydraulics.flow, flow_derivative and
    composite_volume (sine_segment_system above) exactly, both flow directions, with leakage and a one-sided
    path."""
    from isokinetic.physics.excitation import Segment
    from isokinetic.physics.sine_drive import fused_segment_system

    hyd = Hydraulics.from_damper(TABLE_1, Effects(leakage_conductance_m3_s_Pa=3e-13, asymmetry=0.05,
                                                  path_asymmetry=0.12, air_volume_fraction=0.01))
    seg = Segment(0.01, 0.4, contact, 3e-6, -1e-6, 1.0)
    ref_rhs, ref_jac = sine_segment_system(seg, hyd, 2e-5, 2.0 * math.pi * 3.0)
    rhs, jac = fused_segment_system(seg, hyd, 2e-5, 2.0 * math.pi * 3.0)
    rng = np.random.default_rng(5)
    for t, p in zip(rng.uniform(0.01, 0.4, 200), np.concatenate([[0.0], rng.normal(0.0, 2e5, 199)]), strict=True):
        z = np.array([p])   # as the integrator passes the state
        assert rhs(t, z) == ref_rhs(t, z) and jac(t, z) == ref_jac(t, z)


def test_a_harmonic_step_moves_one_component_of_the_motion():
    # the sensitivity steps of the drive's harmonics (diagnosis.model.harmonic_input_variance): ε cos 2u added to a
    # harmonic the drive holds, ε sin 3u to one it does not
    drive = SineDrive(1e-4, 2.0, 0.0, 10, ((2, 3e-6, 0.5),))
    w, eps = 2 * math.pi * 2.0, 1e-7
    tau = np.linspace(0.01, 0.5, 40)
    moved = drive.with_harmonic_step(2, True, eps).velocity(tau) - drive.velocity(tau)
    assert np.allclose(moved, -2 * w * eps * np.sin(2 * w * tau), rtol=1e-6, atol=1e-18)
    added = drive.with_harmonic_step(3, False, eps)
    assert [k for k, _a, _th in added.harmonics] == [2, 3]
    assert np.allclose(added.velocity(tau) - drive.velocity(tau), 3 * w * eps * np.cos(3 * w * tau), rtol=1e-6,
                       atol=1e-18)
    assert drive.scaled(2.0).velocity(tau) == pytest.approx(2.0 * drive.velocity(tau), rel=1e-12)
