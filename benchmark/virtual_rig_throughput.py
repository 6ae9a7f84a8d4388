"""Throughput of the virtual rig's triangle quadrature against plain solve_ivp at equal accuracy.

Run: .venv/bin/python benchmark/virtual_rig_throughput.py [--config config/config.yaml]

For the 23 triangle cases of the default config (truth effects, noise free Δp):
  1. reference: solve_ivp DOP853 at rtol 1e-13, split at every velocity reversal;
  2. the quadrature (responses.triangle_responses, all cases in one call): error, samples/s;
  3. plain solve_ivp (LSODA, analytic Jacobian, split at reversals, t_eval = samples), with the
     loosest rtol in 1e-6, 1e-7, ... whose max error is no larger than the quadrature's;
     samples/s at that tolerance, and the speed ratio.
Errors are max |Δp - Δp_ref| / max |Δp_ref| over each case, maximum over the cases.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import yaml
from scipy.integrate import solve_ivp

from isokinetic.physics.excitation import piston_segments, sample_times
from isokinetic.physics.hydraulics import Hydraulics, steady_pressure
from isokinetic.physics.plan import triangle_displacement
from isokinetic.physics.responses import triangle_responses
from isokinetic.stages.virtual_rig import VirtualCampaign

ROOT = Path(__file__).resolve().parents[1]


def ivp_triangle(case, hyd: Hydraulics, method: str, rtol: float):
    """Δp at the samples by solve_ivp on each constant-velocity segment (Eq. 1)."""
    t = sample_times(case)
    a, beta = hyd.piston_area_m2, hyd.compressibility_1_Pa
    v01, v02 = hyd.chamber_volume_1_m3, hyd.chamber_volume_2_m3
    w = case.velocity_m_s
    atol = rtol * abs(steady_pressure(-a * w, hyd))

    q_n, dq_n = hyd.flow, hyd.flow_derivative
    out = np.empty(t.size)
    p = 0.0
    segs = piston_segments(case)
    for k, seg in enumerate(segs):
        ta, tb = seg.t_start_s, seg.t_end_s
        qp = a * seg.direction * w

        def vol(tt):
            y = float(triangle_displacement(tt, case.amplitude_m, case.period_s, case.phase_rad))
            return (v01 - a * y) * (v02 + a * y) / (v01 + v02)

        def rhs(tt, z, qp=qp):
            return [(qp - q_n(z[0])) / (beta * vol(tt))]

        def jac(tt, z):
            return [[-dq_n(z[0]) / (beta * vol(tt))]]

        last = k == len(segs) - 1
        sel = (t >= ta) & ((t <= tb) if last else (t < tb))
        te = t[sel] if (sel.any() and t[sel][-1] == tb) else np.append(t[sel], tb)
        kw = {} if method == "DOP853" else {"jac": jac}
        sol = solve_ivp(rhs, (ta, tb), [p], method=method, rtol=rtol, atol=atol, t_eval=te, **kw)
        if not sol.success:
            raise RuntimeError(sol.message)
        out[sel] = sol.y[0, :sel.sum()]
        p = float(sol.y[0, -1])
    return out


def max_error(results, refs) -> float:
    return max(float(np.abs(r - ref).max() / np.abs(ref).max()) for r, ref in zip(results, refs))


def best_time(fn, repeats: int) -> tuple[float, list]:
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "config" / "config.yaml"))
    ap.add_argument("--campaign", default="paper-lag-damper")
    args = ap.parse_args(argv)
    cfg = yaml.safe_load(Path(args.config).read_text(encoding="utf-8"))
    vc = VirtualCampaign.from_config(args.campaign, cfg["virtual_campaigns"][args.campaign])
    hyd = Hydraulics.from_damper(vc.damper, vc.effects)
    cases = [c for c in vc.cases if c.waveform == "triangle"]
    n = sum(sample_times(c).size for c in cases)
    print(f"campaign {vc.name}: {len(cases)} triangle cases, {n} samples, effects {vc.effects.active()}")

    t0 = time.perf_counter()
    refs = [ivp_triangle(c, hyd, "DOP853", 1e-13) for c in cases]
    print(f"reference: solve_ivp DOP853 rtol 1e-13 in {time.perf_counter() - t0:.1f} s")

    t_quad, quad = best_time(lambda: [r[1] for r in triangle_responses(cases, hyd)], 7)
    err_quad = max_error(quad, refs)

    chosen = None
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13):
        t_try, res = best_time(lambda rtol=rtol: [ivp_triangle(c, hyd, "LSODA", rtol) for c in cases], 1)
        err = max_error(res, refs)
        print(f"  LSODA rtol {rtol:.0e}: max error {err:.2e}, {t_try:.2f} s")
        if err <= err_quad:
            chosen = (rtol, err)
            break
    if chosen is None:
        print("solve_ivp LSODA never reached the quadrature's accuracy down to rtol 1e-13")
        return 1
    rtol, err_ivp = chosen
    t_ivp, _ = best_time(lambda: [ivp_triangle(c, hyd, "LSODA", rtol) for c in cases], 2)

    print()
    print(f"{'method':<40}{'max rel. error':>16}{'time [s]':>12}{'samples/s':>14}")
    print(f"{'quadrature (virtual_rig)':<40}{err_quad:>16.2e}{t_quad:>12.3f}{n / t_quad:>14.3e}")
    print(f"{f'solve_ivp LSODA rtol {rtol:.0e}':<40}{err_ivp:>16.2e}{t_ivp:>12.3f}{n / t_ivp:>14.3e}")
    print(f"speed ratio: {t_ivp / t_quad:.1f}x (target >= 20x)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
