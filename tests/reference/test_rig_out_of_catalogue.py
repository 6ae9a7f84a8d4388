"""The reference rig's effects outside the catalogue that hide from the steady characteristic (issue 35): a groove
open near mid-stroke, a worn bore, a gas spring, an orifice's wear and the oil's warm-up over the campaign. Each
is checked against the steady state of its physics written out here by hand (Eq. 7 per flow path, the annular
gap's laminar law, Vogel's law), never against the rig's own functions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from isokinetic.reference import campaign as rrc
from isokinetic.reference import rig as rr

D = rr.TABLE1
#: A slow stroke: W = 0.05 mm/s, T = 240 s, Y = 3 mm; the pressures settle within ~0.1 s (5 um of travel).
SLOW = rr.TriangleCase("T01", 5.0e-5, 240.0, 10.0)


def path_flow(dp: float, area_m2: float, mu: float = D.viscosity_Pa_s, cd: float = D.discharge_coefficient) -> float:
    """Flow of one sharp path of Eq. 7 at dp > 0: dp = c1 q + c2 q^2, c1 = 8 pi mu l / a^2, c2 = rho/(2 Cd^2 a^2)."""
    c1 = 8.0 * math.pi * mu * D.orifice_length_m / area_m2**2
    c2 = D.density_kg_m3 / (2.0 * cd**2 * area_m2**2)
    return (-c1 + math.sqrt(c1 * c1 + 4.0 * c2 * dp)) / (2.0 * c2)


def steady_force(flow, velocity_m_s: float = SLOW.velocity_m_s) -> float:
    """A dp with flow(dp) = A W: the incompressible steady force of a ramp at W > 0."""
    qp = D.piston_area_m2 * velocity_m_s
    return D.piston_area_m2 * brentq(lambda dp: flow(dp) - qp, 1.0, 1e9, xtol=1e-9, rtol=1e-14)


def rising(series, lo_m: float, hi_m: float):
    """(piston position, force) of the first upward stroke's samples with lo <= y <= hi, 2 s after the start."""
    s = series[(series.time_s > 2.0) & (series.time_s < SLOW.period_s / 2)]
    s = s[(s.piston_m >= lo_m) & (s.piston_m <= hi_m)]
    return s.piston_m.to_numpy(), s.force_N.to_numpy()


@pytest.fixture(scope="module")
def nominal():
    return rr.true_series(SLOW, D)


def test_bypass_groove_lowers_the_force_within_1_mm_of_mid_stroke_only(nominal):
    """Inside the groove (|y| <= 0.9 mm, after its taper) the steady force is that of the orifice and the groove in
    parallel (A_g = 0.3 A_O, the orifice's length and C_D); beyond 1.05 mm (and the settling after the taper) the
    nominal force, sample for sample."""
    area = 0.3 * D.orifice_area_m2
    s = rr.true_series(SLOW, D, rr.TrueEffects(bypass_area_m2=area))
    inside = steady_force(lambda dp: path_flow(dp, D.orifice_area_m2) + path_flow(dp, area))
    outside = steady_force(lambda dp: path_flow(dp, D.orifice_area_m2))
    y, f = rising(s, -0.85e-3, 0.85e-3)
    assert y.size > 100 and np.allclose(f, inside, rtol=2e-4)
    assert inside < 0.9 * outside                                      # the groove is there
    for lo, hi in ((-2.8e-3, -1.15e-3), (1.15e-3, 2.8e-3)):
        y, f = rising(s, lo, hi)
        _, f_nom = rising(nominal, lo, hi)
        assert y.size > 100 and np.allclose(f, outside, rtol=2e-4) and np.allclose(f, f_nom, rtol=1e-6)
    y, f = rising(s, 0.96e-3, 1.04e-3)                                # the taper: in between
    assert np.all((f > inside * (1 - 1e-4)) & (f < outside * (1 + 1e-4)))


def test_worn_bore_leaks_through_the_gap_at_the_piston(nominal):
    """Leakage gap h(y) = h0 + h_w (1 - (y/L)^2) within L of mid-stroke, h0 beyond: the steady force at each
    position is the orifice's and the annulus' pi D h(y)^3 / (12 mu L_s) in parallel."""
    h0, hw, half = 2e-6, 40e-6, 1.5e-3
    s = rr.true_series(SLOW, D, rr.TrueEffects(leakage_gap_m=h0, bore_wear_gap_m=hw, bore_wear_half_length_m=half))
    diameter = math.sqrt(4.0 * D.piston_area_m2 / math.pi)

    def by_hand(y: float) -> float:
        h = h0 + hw * max(0.0, 1.0 - (y / half) ** 2)
        g = math.pi * diameter * h**3 / (12.0 * D.viscosity_Pa_s * 0.02)
        return steady_force(lambda dp: path_flow(dp, D.orifice_area_m2) + g * dp)

    y, f = rising(s, -2.5e-3, 2.5e-3)
    error = f / np.array([by_hand(v) for v in y]) - 1.0
    # the force follows the gap with the chambers' compressible lag (~0.2 s; 0.23 % where it changes fastest),
    # which is odd in y on a stroke across the symmetric wear: it averages out over the stroke
    assert np.max(np.abs(error)) < 3e-3 and abs(np.mean(error)) < 1e-4
    assert by_hand(0.0) < 0.9 * by_hand(2e-3)                          # the wear is there
    y, f = rising(s, 1.7e-3, 2.8e-3)
    assert np.allclose(f, by_hand(2.0e-3), rtol=2e-4)


def test_gas_spring_adds_k_times_the_piston_position(nominal):
    """The load cell reads k y more, y = -Y + W t on the first upward stroke of an ideal rig."""
    k = 3.0e4
    s = rr.true_series(SLOW, D, rr.TrueEffects(gas_spring_N_m=k))
    t = s.time_s.to_numpy()
    up = t <= SLOW.period_s / 2
    y = -SLOW.amplitude_m + SLOW.velocity_m_s * t[up]
    assert np.allclose((s.force_N - nominal.force_N).to_numpy()[up], k * y, rtol=0, atol=1e-6 * k * SLOW.amplitude_m)


def test_wear_and_warmup_follow_each_cases_place_in_campaign_time(tmp_path):
    """Case i's middle lies at f_i = (its start + T_i) / total of the campaign's time (cases back to back, each
    2 T_i + 1/fs long): its viscosity is Vogel's at 40 + dT (f_i - 1/2) degC, its orifice's area A_O (1 + w (f_i -
    1/2)); the windows' steady force is the orifice's at both."""
    w, warm = 0.2, 8.0
    cases = [rr.TriangleCase(f"T{i}", v, period, 10.0) for i, (v, period) in
             enumerate(((4e-5, 60.0), (1e-4, 20.0), (6e-5, 40.0)), start=1)]
    series = rrc.write_campaign(tmp_path / "worn", cases, effects=rr.TrueEffects(orifice_wear_rel=w, warmup_K=warm))
    spans = [2 * c.period_s + 0.1 for c in cases]
    starts = np.cumsum([0.0] + spans[:-1])
    for case, start in zip(cases, starts, strict=True):
        f = (start + case.period_s) / sum(spans)
        kelvin = 40.0 + 273.15
        mu = D.viscosity_Pa_s * math.exp(977.0 / (kelvin + warm * (f - 0.5) - 150.0) - 977.0 / (kelvin - 150.0))
        s = series[case.case_id]
        assert np.allclose(s.viscosity_Pa_s, mu, rtol=1e-12)
        expected = steady_force(lambda dp, mu=mu, f=f: path_flow(dp, D.orifice_area_m2 * (1 + w * (f - 0.5)), mu),
                                case.velocity_m_s)
        t = s.time_s.to_numpy()
        window = (t >= 0.45 * case.period_s / 2) & (t <= 0.95 * case.period_s / 2)
        assert np.allclose(s.force_N.to_numpy()[window], expected, rtol=1e-6)
    first, last = series["T1"].viscosity_Pa_s.iloc[0], series["T3"].viscosity_Pa_s.iloc[0]
    assert last < D.viscosity_Pa_s < first                           # the oil thins as it warms


def test_hidden_effects_are_named_out_of_the_catalogue():
    effects = rr.TrueEffects(bypass_area_m2=1e-8, bore_wear_gap_m=1e-6, gas_spring_N_m=1.0, orifice_wear_rel=0.1,
                             warmup_K=1.0)
    assert rrc.out_of_catalogue_effects(effects) == ("bypass", "worn_bore", "gas_spring", "wear", "warmup")
    assert rrc.out_of_catalogue_effects(rr.TrueEffects()) == ()
    with pytest.raises(ValueError, match="orifice_wear_rel"):
        rr.TrueEffects(orifice_wear_rel=1.5)
    with pytest.raises(ValueError, match="bypass_taper_m"):
        rr.TrueEffects(bypass_half_width_m=1e-4, bypass_taper_m=3e-4)
