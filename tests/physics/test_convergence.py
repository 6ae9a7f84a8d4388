"""Convergence after a velocity step (physics.convergence, Sec. 3 and Eq. 15-29 of the paper):
G-numbers and strokes against hand values from Table 1, the laminar/turbulent limits of Eq. 28, and
the strokes the virtual rig's own responses take."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from isokinetic.physics import convergence as cv
from isokinetic.physics.damper import TABLE_1, Effects
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import true_responses

PHI = 0.999
MM = 1e3

# Hand arithmetic from Table 1 (not from the code under test):
#   c1 = 8π μ l_O / A_O² = 8π · 0.03 · 5e-4 / (6e-8)² = 3.76991e-4 / 3.6e-15 = 1.0471976e11 Pa s/m³
#   c2 = ρ / (2 C_D² A_O²) = 815 / (2 · 0.36 · 3.6e-15) = 815 / 2.592e-15 = 3.1442901e17 Pa s²/m⁶
#   B  = 1 / β_oil = 1 / 3.8e-9 = 2.6315789e8 Pa
# W [mm/s] -> Q = A_p W [m³/s], Q c1 [Pa], Q² c2 [Pa], G1 = B/(Q c1), G2 = B/(2 Q² c2), G3 = B/(2 Q² c2 + Q c1)
#   0.01: Q = 4e-8, Q c1 = 4188.790, Q² c2 = 1.6e-15 · 3.1442901e17 = 503.0864
#         G1 = 2.6315789e8/4188.790 = 62824.32; G2 = 2.6315789e8/1006.173 = 261543.4
#         G3 = 2.6315789e8/(1006.173 + 4188.790 = 5194.963) = 50656.36
#   0.1:  Q = 4e-7, Q c1 = 41887.90, Q² c2 = 1.6e-13 · 3.1442901e17 = 50308.64
#         G1 = 6282.432; G2 = 2.6315789e8/100617.28 = 2615.434; G3 = 2.6315789e8/142505.18 = 1846.655
#   1.0:  Q = 4e-6, Q c1 = 418879.0, Q² c2 = 1.6e-11 · 3.1442901e17 = 5.0308642e6
#         G1 = 628.2432; G2 = 2.6315789e8/1.0061728e7 = 26.15434; G3 = 2.6315789e8/1.0480607e7 = 25.10903
HAND_G = {  # W [m/s]: (G1, G2, G3)
    1.0e-5: (62824.32, 261543.4, 50656.36),
    1.0e-4: (6282.432, 2615.434, 1846.655),
    1.0e-3: (628.2432, 26.15434, 25.10903),
}
# Strokes at phi = 0.999 from a central start (V1 = V2 = 3e-4 m³, r = 1, V1/A_p = 75 mm); d = (1 - R)/(1 + R):
#   laminar (Eq. 29): ln R = ln(1e-3)/G1 = -6.907755/G1
#     0.01: ln R = -1.099535e-4, R = 0.99989005, d = 5.497676e-5, s = 0.004123257 mm
#     0.1:  ln R = -1.099535e-3, R = 0.99890107, d = 5.497676e-4, s = 0.04123257 mm
#     1.0:  ln R = -1.099535e-2, R = 0.98906488, d = 5.497621e-3, s = 0.4123216 mm
#   turbulent (Eq. 29 with G2): X = (1 - √0.999) e^√0.999 = 5.001251e-4 · 2.716923 = 1.358801e-3,
#   ln X = -6.601152, ln R = ln X / G2
#     0.01: ln R = -2.523922e-5, R = 0.99997476, s = 0.0009464708 mm
#     0.1:  ln R = -2.523922e-3, R = 0.99747926, s = 0.09464703 mm
#     1.0:  ln R = -0.2523922,   R = 0.77693995, s = 9.414783 mm
#   mixed (Eq. 28 as printed, with φ̃ of Eq. 25 and c3 = 2 Q c2 + c1): ln X -> ln R = ln X / G3
#     0.01: c3 = 1.2987408e11, φ̃ = 1.2985136e11, X = 1.0960777e-3, ln R = -1.345540e-4, s = 0.005045776 mm
#     0.1:  c3 = 3.5626296e11, φ̃ = 3.5610019e11, X = 1.3104575e-3, ln R = -3.594271e-3, s = 0.1347850 mm
#     1.0:  c3 = 2.6201519e12, φ̃ = 2.6188435e12, X = 1.3577449e-3, ln R = -0.2629305,   s = 9.803481 mm
HAND_STROKE_MM = {  # W [m/s]: (laminar, turbulent, mixed)
    1.0e-5: (0.004123257, 0.0009464708, 0.005045776),
    1.0e-4: (0.04123257, 0.09464703, 0.1347850),
    1.0e-3: (0.4123216, 9.414783, 9.803481),
}


def triangle(case, y_m, period_s, rate_Hz=100.0, periods=2.0):
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=y_m, period_s=period_s,
                    phase_rad=-math.pi / 2, duration_s=periods * period_s)


# ----------------------------------------------------------------------------------------------
# G-numbers and strokes against hand values
# ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("w", sorted(HAND_G))
def test_g_numbers_match_hand_values_from_table1(w):
    expected = HAND_G[w]
    got = (cv.g1(w, TABLE_1), cv.g2(w, TABLE_1), cv.g3(w, TABLE_1))
    assert got == pytest.approx(expected, rel=2e-6)


def test_air_contamination_lowers_the_bulk_modulus_and_g3():
    # β_eff = 3.8e-9 + 0.01 · 9.9e-6 = 1.028e-7 /Pa -> B = 9.727626e6 Pa (Eq. 3, Table 1 β_air)
    # at 1 mm/s: G3 = 9.727626e6 / 1.0480607e7 = 0.9281548 (< 1: no convergence)
    air = Effects(air_volume_fraction=0.01)
    assert cv.bulk_modulus(TABLE_1, air) == pytest.approx(9.727626e6, rel=1e-6)
    assert cv.g3(1e-3, TABLE_1, air) == pytest.approx(0.9281548, rel=1e-6)


def test_phi_tilde_and_incompressible_pressure_match_hand_values():
    # 0.1 mm/s: Δp∞ = Q c1 + Q² c2 = 41887.90 + 50308.64 = 92196.54 Pa (Eq. 24)
    # φ̃ = ((1 - 0.999) c1² + 0.999 c3²)^½ = (1e-3 · 1.0966e22 + 0.999 · 1.26923e23)^½ = 3.5610019e11 (Eq. 25)
    assert cv.incompressible_pressure(1e-4, TABLE_1) == pytest.approx(92196.54, rel=1e-6)
    assert cv.c3(1e-4, TABLE_1) == pytest.approx(3.5626296e11, rel=1e-7)
    assert cv.phi_tilde(PHI, 1e-4, TABLE_1) == pytest.approx(3.5610019e11, rel=1e-7)


@pytest.mark.parametrize("w", sorted(HAND_STROKE_MM))
def test_strokes_from_the_centre_match_hand_values(w):
    got = [float(cv.stroke_to_converge(w, TABLE_1, phi=PHI, flow=f)) * MM for f in ("laminar", "turbulent", "mixed")]
    assert got == pytest.approx(HAND_STROKE_MM[w], rel=2e-6)


def test_stroke_from_minus_y_uses_the_start_volumes():
    # 1.5 mm/s, Y = 7.5 mm: V1 = 3e-4 + 4e-3 · 7.5e-3 = 3.3e-4, V2 = 2.7e-4, r = 1.222222
    # Q = 6e-6: Q c1 = 628318.5, Q² c2 = 1.1319444e7, G3 = 2.6315789e8 / 2.3267207e7 = 11.31025
    # X = 1.3583148e-3 (Eq. 28), R = X^(1/G3) = 0.5578445, d = 0.4421555 / (1 + 1.222222 · 0.5578445) = 0.2629046
    # s = d V1 / A_p = 0.2629046 · 0.0825 m = 21.68963 mm, t = s / W = 14.45975 s
    s = cv.stroke_to_converge(1.5e-3, TABLE_1, phi=PHI, start_position_m=-7.5e-3)
    assert s * MM == pytest.approx(21.68963, rel=1e-6)
    assert cv.time_to_converge(1.5e-3, TABLE_1, phi=PHI, start_position_m=-7.5e-3) == pytest.approx(14.45975, rel=1e-6)
    # moving down from +Y compresses chamber 2: the same stroke for this symmetric damper
    assert cv.stroke_to_converge(-1.5e-3, TABLE_1, phi=PHI, start_position_m=7.5e-3) == pytest.approx(s, rel=1e-12)


# ----------------------------------------------------------------------------------------------
# Eq. 28 -> Eq. 29 in the limits
# ----------------------------------------------------------------------------------------------

def _coeffs(w):
    c1 = 8 * math.pi * 0.03 * 5e-4 / 6e-8**2
    c2 = 815.0 / (2 * 0.6**2 * 6e-8**2)
    return c1, c2, 4e-3 * w, 1 / 3.8e-9


@pytest.mark.parametrize("w", [1e-5, 1e-4, 1e-3])
def test_mixed_stroke_tends_to_laminar_closed_form_as_c2_vanishes(w):
    c1, c2, q, b = _coeffs(w)
    closed = cv.normalised_stroke_laminar(PHI, b / (q * c1), 1.2)
    errs = [abs(cv.normalised_stroke_mixed(PHI, c1, eps * c2, q, b, 1.2) / closed - 1) for eps in (1e-3, 1e-6, 1e-9)]
    assert errs[0] > errs[1] > errs[2]   # linear in c2: ~2e-8 at c2 = 1e-9 c2,nom for 1 mm/s
    assert errs[2] < 1e-6


@pytest.mark.parametrize("w", [1e-5, 1e-4, 1e-3])
def test_mixed_stroke_tends_to_turbulent_closed_form_as_c1_vanishes(w):
    c1, c2, q, b = _coeffs(w)
    closed = cv.normalised_stroke_turbulent(PHI, b / (2 * q * q * c2), 1.2)
    errs = [abs(cv.normalised_stroke_mixed(PHI, eps * c1, c2, q, b, 1.2) / closed - 1) for eps in (1e-3, 1e-6, 1e-9)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-6


# ----------------------------------------------------------------------------------------------
# against the virtual rig
# ----------------------------------------------------------------------------------------------

def _crossing(t, dp, target, t0, t1, sign):
    """Time after t0 where sign·Δp first reaches PHI·target: log-linear in 1 - sign·Δp/target."""
    m = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    t, gap = t[m], 1.0 - sign * dp[m] / target
    hit = np.flatnonzero(gap <= 1.0 - PHI)
    if hit.size == 0 or hit[0] == 0:
        return math.nan
    k = hit[0]
    a, b, level = math.log(gap[k - 1]), math.log(gap[k]), math.log(1.0 - PHI)
    return t[k - 1] + (t[k] - t[k - 1]) * (level - a) / (b - a) - t0


@pytest.fixture(scope="module")
def rig_strokes(default_plan):
    """Stroke to PHI from rest (first half-period from -Y) and after the first reversal, rig and analytic.

    One period of each of the default plan's triangle cases, nominal damper, no noise. A case whose
    first half-period does not reach PHI is simulated again at the same velocity with Y = 20 mm.
    """
    damper = default_plan.damper
    tri = [c for c in default_plan.cases if c.waveform == "triangle"]
    w = np.array([c.velocity_m_s for c in tri])

    def run(cases):
        out = []
        for c, r in zip(cases, true_responses(cases, damper)):
            t, dp = r["time_s"].to_numpy(), r["dp_Pa"].to_numpy()
            target = float(cv.incompressible_pressure(c.velocity_m_s, damper))
            half = c.period_s / 2
            out.append((c, c.velocity_m_s * _crossing(t, dp, target, 0.0, half, +1),
                        c.velocity_m_s * _crossing(t, dp, target, half, c.period_s, -1)))
        return out

    rows = run([dataclasses.replace(c, duration_s=c.period_s) for c in tri])
    redo = [i for i, (_, fwd, _) in enumerate(rows) if not math.isfinite(fwd)]
    longer = [triangle(rows[i][0].case, 20e-3, 4 * 20e-3 / w[i], periods=1.0) for i in redo]
    for i, row in zip(redo, run(longer)):
        rows[i] = row
    cases = [r[0] for r in rows]
    y0 = np.array([-c.amplitude_m for c in cases])
    return {"w": w, "extended": [cases[i].case for i in redo],
            "rig": np.array([r[1] for r in rows]), "rig_reversal": np.array([r[2] for r in rows]),
            "analytic": cv.stroke_to_converge(w, damper, phi=PHI, start_position_m=y0),
            "analytic_reversal": cv.stroke_to_converge(-w, damper, phi=PHI, start_position_m=-y0, reversal=True)}


def test_stroke_to_converge_agrees_with_the_virtual_rig_over_the_default_plan(rig_strokes):
    assert len(rig_strokes["w"]) == 23
    assert np.all(np.isfinite(rig_strokes["rig"])), rig_strokes["extended"]
    rel = np.abs(rig_strokes["analytic"] / rig_strokes["rig"] - 1)
    assert rel.max() < 0.02, rel


def test_reversal_stroke_agrees_with_the_virtual_rig(rig_strokes):
    assert np.all(np.isfinite(rig_strokes["rig_reversal"]))
    rel = np.abs(rig_strokes["analytic_reversal"] / rig_strokes["rig_reversal"] - 1)
    assert rel.max() < 0.02, rel
    assert np.all(rig_strokes["rig_reversal"] > rig_strokes["rig"])  # a reversal takes longer than a start


def test_both_reversals_of_an_asymmetric_damper_agree_with_the_virtual_rig():
    # chamber 2 twice chamber 1: the reversal at +Y (chamber 2 compressed, moving down) and the one back at -Y
    # (chamber 1 compressed, moving up) take different strokes; a window after either must wait for its own
    damper = dataclasses.replace(TABLE_1, chamber_volume_2_m3=2.0 * TABLE_1.chamber_volume_1_m3)
    y, w = 5.0e-3, 0.5e-3
    period = 4.0 * y / w
    case = triangle("A", y, period, rate_Hz=1000.0, periods=1.5)
    r = true_responses([case], damper)[0]
    t, dp = r["time_s"].to_numpy(), r["dp_Pa"].to_numpy()
    target = float(cv.incompressible_pressure(w, damper))
    rig = [w * _crossing(t, dp, target, 0.0, period / 2, +1),
           w * _crossing(t, dp, target, period / 2, period, -1),
           w * _crossing(t, dp, target, period, 1.5 * period, +1)]
    analytic = cv.strokes_to_converge_in_a_cycle(w, damper, phi=PHI, start_position_m=-y)
    assert np.all(np.isfinite(rig)), rig
    np.testing.assert_allclose(analytic, rig, rtol=0.005)
    assert abs(rig[1] / rig[2] - 1.0) > 0.03   # the two reversals differ, beyond the agreement
