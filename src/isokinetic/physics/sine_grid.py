"""The damper driven by a measured periodic motion, on a grid set by the physics, not by the sampling rate.

Eq. (1) with the composite volume of Eq. (2), the flow of Eq. (7) plus leakage (and, with entrained air under the
gas law, the two chambers of :mod:`isokinetic.physics.gas_law`) is integrated from rest by the 3-stage Radau IIA
method (order 5, L-stable: Hairer & Wanner, "Solving Ordinary Differential Equations II", IV.5) with a fixed step
of one ``points_per_cycle``-th of the drive's period, so that the result is a smooth function of the damper's
parameters (finite-difference Jacobians need that) and costs the same at any sampling rate. The first step is
cut into geometrically growing sub-steps: the pressure starts at 0 while the piston moves at its peak speed, a
transient as short as the relaxation time of Eq. (14).

The periodic steady state is reached after a number of cycles set by the physics (the relaxation against the
period); a cycle whose change from the one before repeats the change before it to within ``CONVERGED`` of the
pressure scale ends the integration, and every later cycle is that one plus as many of that change (none, or the
constant drift of the chambers' mean pressure the gas law's oil term makes: some 1e-7 of the pressure a cycle)
(:attr:`GridResponse.periodic_from`). A record of a hundred cycles costs as little as its first few. The kernel
(``_sine_kernel.c``: the Radau step, its simplified Newton iteration on the three stages with the Jacobian of Eq. (1)
and an LU factorisation, and the cycle test above) is C, compiled when the package is installed, so that a fresh
process loads it in a millisecond (each Snakemake job is one; a just-in-time compiler's start-up cost 0.3 s).

The piston motion is that of :class:`isokinetic.physics.sine_drive.SineDrive`: y = Y sin ωτ + Σ A_k (sin(kωτ +
θ_k) - sin θ_k) for τ >= 0, at rest at y = 0 before (the diagnosis' sine drive has no backlash).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from isokinetic.physics.gas_law import PRESSURE_FLOOR, gas_amounts
from isokinetic.physics.hydraulics import Hydraulics
from isokinetic.physics.sine_drive import SineDrive

#: How the compiled kernel is built (again): the README's set-up installs the package, which compiles it.
REBUILD = "pip install --no-deps --no-build-isolation -e . (README, set-up)"


def built_before_edit(source: Path, built: Path) -> bool:
    """Whether the compiled module ``built`` is older than its C ``source`` (none: an installed package, which
    ships no source)."""
    return source.exists() and source.stat().st_mtime > built.stat().st_mtime


def compiled_kernel():
    """The compiled kernel (``_sine_kernel.c``), refused where it is missing (a source tree on the path that was
    never installed) or older than its source (an editable install whose C was edited since: it would run the old
    code silently)."""
    source = Path(__file__).with_name("_sine_kernel.c")
    try:
        from isokinetic.physics import _sine_kernel
    except ImportError as exc:
        raise ImportError(f"the sine grid's compiled kernel is not built: {REBUILD} compiles {source}") from exc
    built = Path(_sine_kernel.__file__)
    if built_before_edit(source, built):
        raise ImportError(f"{source} was edited after {built.name} was built: the kernel would run the old code; "
                          f"{REBUILD} compiles it again")
    return _sine_kernel


_sine_kernel = compiled_kernel()

#: Grid points per cycle of the drive: Radau IIA's error on the pressure of a smooth periodic drive is about
#: (2π/points)^5 of its amplitude: within 1e-5 of the pressure scale at 128 (against LSODA at rtol 1e-10).
POINTS_PER_CYCLE = 128
#: Sub-steps of the first step, growing geometrically from FIRST_SUBSTEP of the period.
SUBSTEPS = 48
FIRST_SUBSTEP = 1e-9
#: A cycle whose pressure repeats the cycle before's to within this share of the largest |Δp| ends the integration.
CONVERGED = 1e-8
#: Newton iterations per step at most; the Newton iteration stops at this relative step.
NEWTON_ITERATIONS = 12
NEWTON_TOL = 1e-11

_S6 = math.sqrt(6.0)
#: Radau IIA, 3 stages: nodes and coefficients (the last row is the step's weights: stiffly accurate).
RADAU_C = np.array([(4.0 - _S6) / 10.0, (4.0 + _S6) / 10.0, 1.0])
RADAU_A = np.array([[(88.0 - 7.0 * _S6) / 360.0, (296.0 - 169.0 * _S6) / 1800.0, (-2.0 + 3.0 * _S6) / 225.0],
                    [(296.0 + 169.0 * _S6) / 1800.0, (88.0 + 7.0 * _S6) / 360.0, (-2.0 - 3.0 * _S6) / 225.0],
                    [(16.0 - _S6) / 36.0, (16.0 + _S6) / 36.0, 1.0 / 9.0]])


@dataclass(frozen=True)
class GridResponse:
    """Δp and dΔp/dτ of one drive at τ_j = j·``step_s``, j = 0 .. (from τ = 0, the motion's start, at rest before);
    ``periodic_from``: the index of the first grid point of the cycle from which on the response repeats, or
    changes from cycle to cycle by a constant drift (the arrays end with that cycle; :meth:`unfolded`), or -1 where
    the record ended before the response settled."""

    step_s: float
    points_per_cycle: int
    dp_Pa: np.ndarray
    slope_Pa_s: np.ndarray
    periodic_from: int

    def unfolded(self, end_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(Δp [Pa], dΔp/dτ [Pa/s]) on the grid from τ = 0 to at least ``end_s``: after the integrated cycles, the
        last one plus m times its change from the one before, m = 1, 2, ... (the change is none, or the drift of the
        chambers' mean pressure that the gas law's oil term makes each cycle: constant)."""
        need = int(math.ceil(end_s / self.step_s)) + 2
        p, f = self.dp_Pa, self.slope_Pa_s
        if self.periodic_from < 0 or need <= p.size:
            return p, f
        last = slice(self.periodic_from + 1, self.periodic_from + 1 + self.points_per_cycle)
        before = slice(self.periodic_from + 1 - self.points_per_cycle, self.periodic_from + 1)
        copies = np.arange(1, int(math.ceil((need - p.size) / self.points_per_cycle)) + 1)[:, None]

        def extend(x):   # the last cycle plus m times its change from the one before (the gas law's slow drift)
            return np.concatenate([x, (x[last] + copies * (x[last] - x[before])).ravel()])
        return extend(p), extend(f)


def _drive_terms(harmonics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, A_k, θ_k) of the drive's harmonics as three arrays (the kernel's form)."""
    ks = np.array([float(k) for k, _a, _t in harmonics])
    aks = np.array([float(a) for _k, a, _t in harmonics])
    ths = np.array([float(t) for _k, _a, t in harmonics])
    return ks, aks, ths


def mode_sweep(jumps: np.ndarray, signs: np.ndarray, lam: complex, queries: np.ndarray, w_out: np.ndarray,
               big_w_out: np.ndarray) -> None:
    """w and W = ∫_0 w of the mode w' = λ w + σ(t) (σ piecewise constant: ``signs`` from each of ``jumps``, 0
    before the first) at the sorted ``queries``, written into ``w_out`` and ``big_w_out`` (complex): exactly,
    segment by segment (w = -σ/λ + (w0 + σ/λ) e^{λΔ}); λ = 0: the integral of σ and its integral. The compiled
    kernel (``_sine_kernel.c``)."""
    _sine_kernel.mode_sweep(np.ascontiguousarray(jumps, dtype=float), np.ascontiguousarray(signs, dtype=float),
                            complex(lam), np.ascontiguousarray(queries, dtype=float), w_out, big_w_out)


@lru_cache(maxsize=256)
def stage_motion(amplitude_m: float, frequency_Hz: float, harmonics: tuple, points_per_cycle: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(y [m], dy/dτ [m/s]) of the drive at τ = (j + c_i) h, j = 0 .. points - 1, i the Radau stages, and (column 3) at
    τ = j h (h = 1/(f points)): the same every cycle, computed once per drive."""
    drive = SineDrive(amplitude_m, frequency_Hz, 0.0, 1, harmonics)
    u = 2.0 * math.pi * (np.arange(points_per_cycle)[:, None] + np.append(RADAU_C, 0.0)[None, :]) / points_per_cycle
    y = amplitude_m * np.sin(u)
    for k, a_k, theta in harmonics:
        y = y + a_k * (np.sin(k * u + theta) - math.sin(theta))
    return y, 2.0 * math.pi * frequency_Hz * drive.phase_velocity(u)


def grid_parameters(amplitude_m: float, frequency_Hz: float, hyd: Hydraulics, points_per_cycle: int) -> np.ndarray:
    """The kernel's parameter vector of a drive and its hydraulics (``_sine_kernel.integrate``): amp, omega, h, area,
    beta, v01, v02, c1p, c1n, c2p, c2n, leak, gas, b_oil, g1, g2, p0, low, scale."""
    gas = hyd.gas_law
    g1, g2 = gas_amounts(hyd.air_compressibility_1_Pa, hyd.charge_pressure_Pa, hyd.chamber_volume_1_m3,
                         hyd.chamber_volume_2_m3) if gas else (0.0, 0.0)
    p0 = hyd.charge_pressure_Pa if gas else 0.0
    omega = 2.0 * math.pi * frequency_Hz
    c1n = hyd.c1(-1.0)
    scale = max(abs(hyd.c2(1.0)), abs(hyd.c2(-1.0))) * (hyd.piston_area_m2 * amplitude_m * omega) ** 2 \
        + max(hyd.laminar_coefficient, c1n) * hyd.piston_area_m2 * amplitude_m * omega
    return np.array([amplitude_m, omega, 1.0 / (frequency_Hz * points_per_cycle), hyd.piston_area_m2,
                     hyd.compressibility_1_Pa, hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3,
                     hyd.laminar_coefficient, c1n, hyd.turbulent_coefficient_pos, hyd.turbulent_coefficient_neg,
                     hyd.leakage_conductance_m3_s_Pa, 1.0 if gas else 0.0, hyd.tau_compressibility_1_Pa, g1, g2, p0,
                     PRESSURE_FLOOR * p0, max(scale, 1.0)])


def grid_response(amplitude_m: float, frequency_Hz: float, harmonics, hyd: Hydraulics, end_s: float,
                  points_per_cycle: int = POINTS_PER_CYCLE) -> GridResponse:
    """The Δp of the damper driven from rest by the periodic motion (module docstring) on the grid of
    ``points_per_cycle`` points a cycle, up to ``end_s`` (or the cycle that repeats the one before)."""
    par = grid_parameters(amplitude_m, frequency_Hz, hyd, points_per_cycle)
    n_steps = max(int(math.ceil(end_s / par[2])) + 1, 2)
    out_p, out_f = np.empty(n_steps + 1), np.empty(n_steps + 1)
    ks, aks, ths = _drive_terms(harmonics)
    stage_y, stage_v = stage_motion(amplitude_m, frequency_Hz, tuple(harmonics), points_per_cycle)
    periodic = _sine_kernel.integrate(par, ks, aks, ths, RADAU_A, RADAU_C, n_steps, points_per_cycle, SUBSTEPS,
                                      FIRST_SUBSTEP, CONVERGED, NEWTON_ITERATIONS, NEWTON_TOL, stage_y, stage_v, out_p,
                                      out_f)
    last = n_steps + 1 if periodic < 0 else periodic + points_per_cycle + 1
    return GridResponse(float(par[2]), points_per_cycle, out_p[:last], out_f[:last], int(periodic))
