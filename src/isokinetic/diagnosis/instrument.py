"""Instrument terms: load-cell gain and offset (and Coulomb friction) profiled in closed form; the delay.

The load cell reads F_meas = g·F + F_0: a gain g (|g - 1| <= GAIN_BOUND) and a zero offset F_0
(|F_0| <= OFFSET_BOUND_REL of the largest window force) are profiled out of every fit in closed
form (bounded weighted least squares, :class:`LinearTerms`). Coulomb friction, sign(v)·F_C over a
constant-velocity segment (Eq. 8's F_f in "A method for the identification of hydraulic damper
characteristics from steady velocity inputs", Titurus et al.), is linear in the means too and is
profiled alongside. The actuator delay is measured, not fitted: the median over cases of
``delay_s`` (motion start minus the record's first time stamp, :func:`case_delays`). They are
reported under ``instrument`` and never count as damper effects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

#: Instrument terms profiled out of every fit (load cell): F_meas = gain·F + offset.
INSTRUMENT = ("force_offset", "force_gain")
#: Largest load-cell gain error |g - 1| a calibrated load cell is allowed.
GAIN_BOUND = 0.02
#: Largest load-cell zero offset, as a fraction of the largest window force |F|.
OFFSET_BOUND_REL = 0.05


@dataclass(frozen=True)
class LinearTerms:
    """Terms linear in the measured means, profiled out of every fit in closed form.

    F_meas = g·(m + F_C·s) + F_0 with m the hydraulic model (Eq. 8 without friction), s = ±1 the
    observation's direction (Coulomb friction, Eq. 8's F_f, is sign(v)·F_C over a constant-velocity
    segment), g the load-cell gain, F_0 its zero offset. Solved as bounded weighted linear least
    squares in (g, g·F_C, F_0) (scipy ``lsq_linear``). ``free`` names the instrument terms fitted
    (others fixed at g = 1, F_0 = 0).
    """

    free: tuple[str, ...] = INSTRUMENT
    offset_bound_N: float = 0.0
    gain_bound: float = GAIN_BOUND
    friction_bound_N: float = math.inf

    def solve(self, force_N: np.ndarray, model_N: np.ndarray, sign: np.ndarray, weight: np.ndarray,
              friction: bool) -> tuple[float, float, float]:
        """(gain, coulomb_force_N, offset_N) minimising Σ w (F - g (m + F_C s) - F_0)² within the bounds."""
        root_w = np.sqrt(weight)
        y = force_N.copy()
        cols, lo, hi, names = [], [], [], []
        if "force_gain" in self.free:
            cols.append(model_N), lo.append(1.0 - self.gain_bound), hi.append(1.0 + self.gain_bound), names.append("g")
        else:
            y = y - model_N
        if friction:
            cols.append(sign), lo.append(0.0), hi.append((1.0 + self.gain_bound) * self.friction_bound_N)
            names.append("c")
        if "force_offset" in self.free and self.offset_bound_N > 0:
            cols.append(np.ones_like(y)), lo.append(-self.offset_bound_N), hi.append(self.offset_bound_N)
            names.append("o")
        if not cols:
            return 1.0, 0.0, 0.0
        a = np.column_stack(cols) * root_w[:, None]
        from scipy.optimize import lsq_linear  # scipy.optimize: only where the instrument is fitted

        sol = lsq_linear(a, y * root_w, bounds=(lo, hi), method="bvls").x
        v = dict(zip(names, sol, strict=True))
        g = float(v.get("g", 1.0))
        return g, float(v.get("c", 0.0)) / g, float(v.get("o", 0.0))


def case_delays(cases: pd.DataFrame) -> dict:
    """Measured actuator delay over the status-ok triangle cases (``delay_s`` of cases.parquet)."""
    if "delay_s" not in cases:
        return {"delay_s": None}
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    d = ok["delay_s"].to_numpy(dtype=float)
    d = d[np.isfinite(d)]
    if not d.size:
        return {"delay_s": None}
    return {"delay_s": float(np.median(d)), "delay_min_s": float(d.min()), "delay_max_s": float(d.max()),
            "n_cases": int(d.size)}
