"""Entrained air under the isothermal gas law around the damper's charge pressure (Eq. 3 without its
approximation, in the two chambers of Eq. 2).

Chamber i holds a fixed amount of gas G_i = φ0 V0,i p0 and oil; its compliance is 𝒞_i = β_oil (V_i - G_i/p_i) +
G_i/p_i², and the chambers act in series on Δp (Eq. 1). How Δp splits into p1 and p2 is fixed by the stored volume
K = Σ ∫_{p0}^{p_i} 𝒞_i dp, the model's second state (:func:`stored_volume_rate`). :func:`compressibility_ratio`
gives r = 𝒞(Δp)/𝒞(0) for the segment tables of :mod:`isokinetic.physics.hydraulics`; a sine record integrates
the two chamber pressures themselves (:mod:`isokinetic.physics.sine_drive`).
"""

from __future__ import annotations

import numpy as np

#: Chamber pressures are held at this fraction of the charge pressure or above (the gas law has no cavitation).
PRESSURE_FLOOR = 0.05


def gas_amounts(gas_1_Pa: float, charge_pressure_Pa: float, volume_1_m3: float, volume_2_m3: float):
    """G_i = φ0 V0,i p0 = γ p0² V0,i of the two chambers [Pa m³], γ = ``gas_1_Pa`` the gas term of Eq. (3) at p0."""
    p0 = charge_pressure_Pa
    return gas_1_Pa * p0 * p0 * volume_1_m3, gas_1_Pa * p0 * p0 * volume_2_m3


def chamber_compliance(u, oil_volume_term, gas_amount: float, oil_1_Pa: float):
    """𝒞_i = β_oil (V_i - G_i/p) + G_i/p² [m³/Pa] at u = 1/p [1/Pa], ``oil_volume_term`` = β_oil V_i [m³/Pa]."""
    return oil_volume_term + gas_amount * u * (u - oil_1_Pa)


def chamber_compliance_slope(u, gas_amount: float, oil_1_Pa: float):
    """d𝒞_i/dp = G_i u² (β_oil - 2u) at u = 1/p [1/Pa] [m³/Pa²]."""
    return gas_amount * u * u * (oil_1_Pa - 2.0 * u)


def compressibility_ratio(dp_Pa, oil_1_Pa: float, gas_1_Pa: float, charge_pressure_Pa: float, volume_1_m3: float,
                          volume_2_m3: float, y_m=0.0, piston_area_m2: float = 0.0, stored_m3=0.0,
                          floor: float = PRESSURE_FLOOR):
    """r(Δp) = 𝒞(Δp)/𝒞(0) and dr/dΔp [1/Pa]: the two chambers' series compliance when the gas of Eq. (3)
    is isothermal around the charge pressure p0, at piston position ``y_m`` (chambers V0,i = ``volume_*_m3``
    at y = 0, Eq. 2).

    Chamber i holds gas of the fixed amount G_i = φ0 V0,i p0 (isothermal: volume G_i/p), with φ0/p0 = γ =
    ``gas_1_Pa``, the gas term of Eq. (3) at p0, and oil (β_oil = ``oil_1_Pa``) in the rest of V_i(y): the
    mixture of Eq. (3) without its approximation, 𝒞_i = β_oil (V_i - G_i/p_i) + G_i/p_i², and
    𝒞 = 𝒞_1 𝒞_2/(𝒞_1 + 𝒞_2). The chamber pressures p_1 = p0 + δ_1, p_2 = p_1 - Δp satisfy
    Σ ∫_{p0}^{p_i} 𝒞_i dp = K = ``stored_m3`` (Newton's method from the linear split): 𝒞_1 ṗ_1 = -𝒞_2 ṗ_2
    (Eq. 1 of each chamber) keeps K while the piston stands, and a moving piston changes it
    (:func:`stored_volume_rate`): K is the model's second state, which the chambers' mean pressure follows.
    Pressures are held at ``floor`` p0 or above (the gas law has no cavitation).
    """
    dp, y = np.asarray(dp_Pa, dtype=float), np.asarray(y_m, dtype=float)
    b, p0 = oil_1_Pa, charge_pressure_Pa
    g1, g2 = gas_amounts(gas_1_Pa, p0, volume_1_m3, volume_2_m3)
    bv1, bv2 = b * (volume_1_m3 - piston_area_m2 * y), b * (volume_2_m3 + piston_area_m2 * y)
    low = floor * p0

    def cap(u, bv, g):
        return chamber_compliance(u, bv, g, b)

    def held(d, p, u, bv, g):                       # ∫ 𝒞_i dp from p0 to p = p0 + d
        return bv * d - b * g * np.log(p / p0) + (g / p0) * d * u

    u0 = 1.0 / p0
    r1, r2 = cap(u0, bv1, g1), cap(u0, bv2, g2)
    d1 = (stored_m3 + r2 * dp) / (r1 + r2)          # the linear split: 𝒞_1 δ_1 + 𝒞_2 δ_2 = K at p0
    d2 = d1 - dp                                    # and its second-order correction, 𝒞_i' = G_i u0² (β_oil - 2 u0)
    d1 = d1 - 0.5 * u0 * u0 * (b - 2.0 * u0) * (g1 * d1 * d1 + g2 * d2 * d2) / (r1 + r2)
    for _ in range(30):
        p1, p2 = np.maximum(p0 + d1, low), np.maximum(p0 + d1 - dp, low)
        u1, u2 = 1.0 / p1, 1.0 / p2
        step = (held(d1, p1, u1, bv1, g1) + held(d1 - dp, p2, u2, bv2, g2) - stored_m3) / (
            cap(u1, bv1, g1) + cap(u2, bv2, g2))
        d1 = d1 - step
        if not np.abs(step).max(initial=0.0) > 1e-9 * p0:
            break
    p1, p2 = np.maximum(p0 + d1, low), np.maximum(p0 + d1 - dp, low)
    u1, u2 = 1.0 / p1, 1.0 / p2
    c1, c2 = cap(u1, bv1, g1), cap(u2, bv2, g2)
    total = c1 + c2
    c = c1 * c2 / total
    c_ref = r1 * r2 / (r1 + r2)
    # dδ_1/dΔp = 𝒞_2/(𝒞_1 + 𝒞_2), dδ_2/dΔp = -𝒞_1/(𝒞_1 + 𝒞_2)
    dc1 = chamber_compliance_slope(u1, g1, b) * (c2 / total)
    dc2 = -chamber_compliance_slope(u2, g2, b) * (c1 / total)
    dc = c * c * (dc1 / (c1 * c1) + dc2 / (c2 * c2))
    return c / c_ref, dc / c_ref


def stored_volume_rate(dp_Pa, velocity_m_s, oil_1_Pa: float, piston_area_m2: float):
    """dK/dt = -β_oil A_p Δp ẏ [m³/s] of K = Σ ∫_{p0}^{p_i} 𝒞_i dp (:func:`compressibility_ratio`).

    Each chamber's Eq. (1), 𝒞_i ṗ_i = ±(A_p ẏ - Q), gives Σ 𝒞_i ṗ_i = 0; K changes only through the oil
    volumes in 𝒞_i = β_oil (V_i(y) - G_i/p_i) + G_i/p_i², ∂𝒞_i/∂y = ∓β_oil A_p (Eq. 2).
    """
    return -oil_1_Pa * piston_area_m2 * np.asarray(dp_Pa, dtype=float) * velocity_m_s


def hermite(x, x0, x1, f0, f1, d0, d1):
    """The cubic Hermite interpolant of values f and slopes d at x0, x1, at x (f0 where x1 = x0)."""
    h = x1 - x0
    t = np.divide(x - x0, h, out=np.zeros(x.size), where=h != 0.0)
    t2 = t * t
    return (f0 * (2.0 * t2 * t - 3.0 * t2 + 1.0) + h * d0 * (t2 * t - 2.0 * t2 + t)
            + f1 * (3.0 * t2 - 2.0 * t2 * t) + h * d1 * (t2 * t - t2))
