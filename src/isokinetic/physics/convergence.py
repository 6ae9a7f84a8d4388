"""Test design: how fast the pressure differential converges after a velocity step (Eq. 15-29).

Implements Sec. 3 of the paper "A method for the identification of hydraulic damper characteristics
from steady velocity inputs" (Titurus et al.); equation numbers are the paper's. SI units throughout.

Physics (nominal damper, Eq. 2, 3, 7, 12-29)
    After a velocity step from rest (Δp(0) = 0) to a constant piston speed W > 0, the pressure
    differential approaches the incompressible value Δp∞ = A_p W c1 + (A_p W)² c2 (Eq. 24) as
    the piston moves. The normalised stroke d = A_p s / V1,s (s the stroke in metres, V1,s the
    volume of the chamber being compressed at the start of the segment) needed to reach the
    fraction ϕ of Δp∞ is Eq. (28) for the mixed laminar-turbulent orifice, and the closed forms
    of Eq. (29) for purely laminar (c2 = 0) and purely turbulent (c1 = 0) flow. Convergence is
    governed by G1, G2, G3 (Eq. 19, 21, 22), with B_eff = 1/β_eff from Eq. (3), entrained air
    included (``Effects.air_volume_fraction``).

    The paper prints the turbulent form of Eq. (29) with the exponent 1/G1; setting c1 = 0 in
    Eq. (28) (and the text after Eq. 29) gives 1/G2, which is what is implemented.

Start position
    A triangle record with phase -π/2 starts at y = -Y and its first half-period moves up, so the
    chambers at the start of the segment are V1 = V0,1 + A_p Y (compressed) and V2 = V0,2 - A_p Y
    (Eq. 2); d is converted to metres with that V1 and the ratio V1/V2 replaces V0,1/V0,2 in
    Eq. (28)-(29). Segments moving down compress chamber 2 and swap the roles.

Reversal (an extension, not in the paper)
    Half-periods after the first start from the steady Δp of the opposite direction, not from
    rest: integrating Eq. (15) from -Δp∞ instead of 0 adds ln 2 / G1 + (1 - ln 2) / G2 to
    -ln R, i.e. R_rev = R · exp(-ln 2/G1 - (1 - ln 2)/G2) (symmetric damper).
"""

from __future__ import annotations

import math

import numpy as np

from isokinetic.physics.damper import (
    NOMINAL,
    Damper,
    Effects,
    effective_compressibility,
    laminar_coefficient,
    turbulent_coefficient,
)

FLOWS = ("laminar", "turbulent", "mixed")
LN2 = math.log(2.0)


# ----------------------------------------------------------------------------------------------
# coefficients (Eq. 3, 7, 19-25)
# ----------------------------------------------------------------------------------------------

def bulk_modulus(damper: Damper, effects: Effects = NOMINAL) -> float:
    """B_eff = 1/β_eff, β_eff = β_0,F + (V_G/V_C) β_G, Eq. (3) with entrained air [Pa]."""
    return 1.0 / float(effective_compressibility(damper, effects))


def _coefficients(damper: Damper, effects: Effects) -> tuple[float, float, float]:
    """(c1, c2, B_eff): Table 1 loss coefficients (Sec. 2.2) with the nominal C_D, and Eq. (3)."""
    return (float(laminar_coefficient(damper, effects)), float(turbulent_coefficient(damper, effects)),
            bulk_modulus(damper, effects))


def piston_flow(velocity_m_s, damper: Damper):
    """Q_p = A_p |W|, the piston-induced flow of Eq. (2) [m³/s] (the paper takes W > 0)."""
    return damper.piston_area_m2 * np.abs(np.asarray(velocity_m_s, dtype=float))


def _ratio(num, den):
    """num/den with num/0 = inf (a zero speed never leaves the incompressible state)."""
    num, den = np.broadcast_arrays(np.asarray(num, dtype=float), np.asarray(den, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), np.inf)


def g1(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Laminar convergence number G1 = B_eff / (A_p W c1) [-], Eq. (19); converges iff G1 > 1."""
    c1, _, bulk = _coefficients(damper, effects)
    return _ratio(bulk, piston_flow(velocity_m_s, damper) * c1)


def g2(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Turbulent convergence number G2 = B_eff / (2 (A_p W)² c2) [-], Eq. (21); converges iff G2 > 1."""
    _, c2, bulk = _coefficients(damper, effects)
    return _ratio(bulk, 2.0 * piston_flow(velocity_m_s, damper) ** 2 * c2)


def c3(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Mixed-flow loss coefficient c3 = 2 A_p W c2 + c1, Eq. (22)-(23) [Pa s/m³]."""
    c1, c2, _ = _coefficients(damper, effects)
    return 2.0 * piston_flow(velocity_m_s, damper) * c2 + c1


def g3(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Laminar-turbulent convergence number G3 = B_eff / (A_p W c3) [-], Eq. (22); converges iff G3 > 1."""
    _, _, bulk = _coefficients(damper, effects)
    return _ratio(bulk, piston_flow(velocity_m_s, damper) * c3(velocity_m_s, damper, effects))


def incompressible_pressure(velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Δp∞ = A_p W c1 + (A_p W)² c2 for W > 0, Eq. (24) [Pa] (magnitude for W < 0)."""
    c1, c2, _ = _coefficients(damper, effects)
    q = piston_flow(velocity_m_s, damper)
    return q * c1 + q * q * c2


def phi_tilde(phi, velocity_m_s, damper: Damper, effects: Effects = NOMINAL):
    """Adjusted pressure measure φ̃ = ((1 - ϕ) c1² + ϕ c3²)^½ at the fraction ϕ of Δp∞, Eq. (25).

    Equals (c1² + 4 c2 Δp)^½ (Eq. 23) at Δp = ϕ Δp∞ [Pa s/m³].
    """
    c1, _, _ = _coefficients(damper, effects)
    phi = np.asarray(phi, dtype=float)
    return np.sqrt((1.0 - phi) * c1**2 + phi * c3(velocity_m_s, damper, effects) ** 2)


# ----------------------------------------------------------------------------------------------
# normalised stroke to reach ϕ of the incompressible Δp (Eq. 28-29)
# ----------------------------------------------------------------------------------------------

def check_phi(phi) -> np.ndarray:
    """The fraction ϕ of Δp∞ (Eq. 25) as a float array [-]; ValueError unless every value lies in (0, 1)."""
    phi = np.asarray(phi, dtype=float)
    if not np.all((phi > 0) & (phi < 1)):
        raise ValueError(f"phi must lie in (0, 1), got {phi!r}")
    return phi


def _stroke_from_log_r(log_r, volume_ratio):
    """d = (1 - R)/(1 + (V1/V2) R) with R = exp(log_r), Eq. (15) inverted; exact for R -> 1."""
    log_r = np.asarray(log_r, dtype=float)
    return -np.expm1(log_r) / (1.0 + np.asarray(volume_ratio, dtype=float) * np.exp(log_r))


def normalised_stroke_laminar(phi, G1, volume_ratio=1.0):
    """d|c2=0 = (1 - (1-ϕ)^(1/G1)) / (1 + (V1/V2)(1-ϕ)^(1/G1)) [-], Eq. (29) left; ϕ, G1, V1/V2 [-]."""
    phi = check_phi(phi)
    with np.errstate(divide="ignore"):
        return _stroke_from_log_r(np.log1p(-phi) / np.asarray(G1, dtype=float), volume_ratio)


def normalised_stroke_turbulent(phi, G2, volume_ratio=1.0):
    """d|c1=0 = (1 - X^(1/G2)) / (1 + (V1/V2) X^(1/G2)) [-], X = (1 - √ϕ) e^√ϕ, Eq. (29) right; ϕ, G2, V1/V2 [-].

    The paper prints 1/G1 here; c1 = 0 in Eq. (28) gives G3 = G2 (see the module docstring).
    """
    phi = check_phi(phi)
    root = np.sqrt(phi)
    log_x = np.log1p(-root) + root
    with np.errstate(divide="ignore"):
        return _stroke_from_log_r(log_x / np.asarray(G2, dtype=float), volume_ratio)


def _log_x_mixed(phi, c1, c2, q, bulk):
    """(ln X, c3, G3) of Eq. (28): X = ((c3 - φ̃)/(2 A_p W c2)) e^((φ̃ - c1)/c3) = R^G3.

    Written without cancellation (c3² - c1² = 4 c2 Q (c1 + c2 Q)):
    (c3 - φ̃)/(2 Q c2) = 2 (1-ϕ)(c1 + c2 Q)/(c3 + φ̃) and (φ̃ - c1)/c3 = ϕ (c3² - c1²)/((φ̃ + c1) c3),
    so c2 = 0 or c1 = 0 are exact (the laminar and turbulent limits of Eq. 29).
    """
    phi = check_phi(phi)
    c1, c2, q, bulk = (np.asarray(x, dtype=float) for x in (c1, c2, q, bulk))
    c3_ = 2.0 * q * c2 + c1
    excess = 4.0 * c2 * q * (c1 + c2 * q)                      # c3² - c1²
    tilde = np.sqrt(c1 * c1 + phi * excess)                     # Eq. (25)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_x = np.log1p(-phi) + np.log(2.0 * (c1 + c2 * q) / (c3_ + tilde)) + phi * excess / ((tilde + c1) * c3_)
        g3_ = np.where(q > 0, bulk / (q * c3_), np.inf)
    return log_x, c3_, g3_


def normalised_stroke_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa, volume_ratio=1.0):
    """The normalised stroke d [-] to reach ϕ Δp∞ from rest, mixed laminar-turbulent flow, Eq. (28).

    d = (1 - X^(1/G3)) / (1 + (V1/V2) X^(1/G3)), X = ((c3 - φ̃)/(2 A_p W c2)) e^((φ̃ - c1)/c3),
    φ̃ from Eq. (25), G3 = B_eff/(A_p W c3) (Eq. 22). Coefficient-level (c1 or c2 may be 0).
    """
    log_x, _, g3_ = _log_x_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa)
    return _stroke_from_log_r(log_x / g3_, volume_ratio)


def normalised_stroke_reversal(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa, volume_ratio=1.0):
    """The normalised stroke d [-] to reach ϕ Δp∞ after a reversal from -Δp∞ (extension of Eq. 28).

    Integrating Eq. (15)-(16) from -Δp∞ adds Q_p (c1 ln 2 + 2 Q_p c2 (1 - ln 2)) / B_eff
    = ln 2/G1 + (1 - ln 2)/G2 to -ln R of Eq. (28) (symmetric damper, steady start).
    """
    log_x, _, g3_ = _log_x_mixed(phi, c1, c2, piston_flow_m3_s, bulk_modulus_Pa)
    q = np.asarray(piston_flow_m3_s, dtype=float)
    extra = q * (np.asarray(c1, dtype=float) * LN2 + 2.0 * q * np.asarray(c2, dtype=float) * (1.0 - LN2))
    return _stroke_from_log_r(log_x / g3_ - extra / np.asarray(bulk_modulus_Pa, dtype=float), volume_ratio)


# ----------------------------------------------------------------------------------------------
# strokes in metres and times (Eq. 2, 15)
# ----------------------------------------------------------------------------------------------

def segment_volumes(damper: Damper, start_position_m=0.0, direction=1.0):
    """(compressed, other) chamber volume at the start of a constant-velocity segment, Eq. (2) [m³].

    y0 = ``start_position_m``: V1 = V0,1 - A_p y0, V2 = V0,2 + A_p y0. Moving up (direction > 0)
    compresses chamber 1; moving down compresses chamber 2. A triangle record with phase -π/2
    starts at y0 = -Y moving up: (V0,1 + A_p Y, V0,2 - A_p Y).
    """
    y0 = np.asarray(start_position_m, dtype=float)
    v1 = damper.chamber_volume_1_m3 - damper.piston_area_m2 * y0
    v2 = damper.chamber_volume_2_m3 + damper.piston_area_m2 * y0
    up = np.asarray(direction, dtype=float) >= 0
    return np.where(up, v1, v2), np.where(up, v2, v1)


def stroke_to_converge(velocity_m_s, damper: Damper, *, phi: float, start_position_m=0.0,
                       effects: Effects = NOMINAL, flow: str = "mixed", reversal: bool = False):
    """Piston stroke s = d V1,s / A_p to reach ϕ of the incompressible Δp (Eq. 28-29, 24) [m].

    ``phi``: the fraction ϕ of the steady Δp to reach (the paper's 0.999; a build's is the config's
    ``design.convergence_fraction``, :class:`isokinetic.contracts.settings.DesignLimits`).
    ``flow``: 'mixed' (Eq. 28), 'laminar' or 'turbulent' (Eq. 29, the damper's c1 or c2 alone).
    The sign of ``velocity_m_s`` gives the direction (which chamber is compressed), with the
    volumes at ``start_position_m`` (:func:`segment_volumes`). ``reversal=True``: starting from the
    opposite steady Δp instead of rest (:func:`normalised_stroke_reversal`). Vectorised.
    """
    if flow not in FLOWS:
        raise ValueError(f"flow must be one of {FLOWS}, got {flow!r}")
    w = np.asarray(velocity_m_s, dtype=float)
    c1, c2, bulk = _coefficients(damper, effects)
    if flow == "laminar":
        c2 = 0.0
    elif flow == "turbulent":
        c1 = 0.0
    v_comp, v_other = segment_volumes(damper, start_position_m, np.sign(w) + (w == 0))
    ratio = v_comp / v_other
    q = piston_flow(w, damper)
    if reversal:
        d = normalised_stroke_reversal(phi, c1, c2, q, bulk, ratio)
    elif flow == "laminar":
        d = normalised_stroke_laminar(phi, _ratio(bulk, q * c1), ratio)
    elif flow == "turbulent":
        d = normalised_stroke_turbulent(phi, _ratio(bulk, 2.0 * q * q * c2), ratio)
    else:
        d = normalised_stroke_mixed(phi, c1, c2, q, bulk, ratio)
    return d * v_comp / damper.piston_area_m2


def strokes_to_converge_in_a_cycle(velocity_m_s: float, damper: Damper, *, phi: float, start_position_m: float,
                                   effects: Effects = NOMINAL) -> tuple[float, float, float]:
    """(from rest, after the first reversal, after the second) strokes to converge (Eq. 28, mixed flow) of a
    triangle case whose first half-period starts at ``start_position_m`` at ``velocity_m_s``: from rest there;
    from the opposite steady Δp at the other end (-start_position_m, moving back); and again at the start's end
    (moving on as first). Every window after the first follows one of the two reversals, and the chambers' volumes,
    hence the strokes, differ at the two ends."""
    kw = {"phi": phi, "effects": effects}
    y0, w = float(start_position_m), float(velocity_m_s)
    return (float(stroke_to_converge(w, damper, start_position_m=y0, **kw)),
            float(stroke_to_converge(-w, damper, start_position_m=-y0, reversal=True, **kw)),
            float(stroke_to_converge(w, damper, start_position_m=y0, reversal=True, **kw)))


def time_to_converge(velocity_m_s, damper: Damper, **kwargs):
    """Time after the velocity step to reach ϕ of Δp∞: stroke_to_converge / |W| [s]."""
    s = stroke_to_converge(velocity_m_s, damper, **kwargs)
    return _ratio(s, np.abs(np.asarray(velocity_m_s, dtype=float)))


# ----------------------------------------------------------------------------------------------
# A-T boundary of the quasi-steady constraint (Eq. 26-28)
# ----------------------------------------------------------------------------------------------

def quasi_steady_boundary(velocities_m_s, damper: Damper, *, phi: float, start_fraction: float,
                          effects: Effects = NOMINAL, iterations: int = 80):
    """(T, Y) on the minimum-time constraint of the A-T diagram, one point per velocity [s, m].

    The window of a triangle case starts after the stroke start_fraction (T/2) W = 2 start_fraction Y;
    on the boundary this equals the stroke to converge from -Y (Eq. 28, the start volumes depend
    on Y), solved for Y by bisection on [0, 0.95 V0/A_p]; T = 4Y/W (Eq. 26). NaN where G3 <= 1
    or no such amplitude fits in the cylinder. A case of velocity W with a longer period (larger
    Y) than the boundary point starts its window after convergence. ``phi`` as :func:`stroke_to_converge`;
    ``start_fraction``: the window's start as a fraction of T/2 (the config's ``windows.start_fraction``).
    """
    w = np.abs(np.asarray(velocities_m_s, dtype=float))
    limit = 0.95 * min(damper.chamber_volume_1_m3, damper.chamber_volume_2_m3) / damper.piston_area_m2

    def excess(y):  # window-start stroke minus stroke to converge, < 0 at y = 0
        return 2.0 * start_fraction * y - stroke_to_converge(w, damper, phi=phi, start_position_m=-y, effects=effects)

    lo, hi = np.zeros_like(w), np.full_like(w, limit)
    ok = (excess(hi) >= 0) & (w > 0) & (g3(w, damper, effects) > 1.0)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = excess(mid) < 0
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    y = np.where(ok, 0.5 * (lo + hi), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(ok, 4.0 * y / np.where(w > 0, w, 1.0), np.nan)
    return t, y
