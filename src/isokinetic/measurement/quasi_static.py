"""Is a record quasi-static? Only then may its force, binned by velocity, stand for the characteristic.

Binning a record's force by velocity (:func:`isokinetic.measurement.loops.binned_characteristic`) averages
every sample at a speed, whichever way the speed was changing. On a dynamic record the force at a speed
depends on the history: a compressible damper's force lags its velocity (paper Sec. 4), so the branch on
which |v| grows (accelerating) and the branch on which it falls (decelerating) form a loop, and their mean is
no point of the steady characteristic (on a real 5-10 Hz sweep, bins 10-109 % off the force at peak velocity).

The test (:func:`quasi_static`), per direction and velocity bin (the bins of ``binned_characteristic``:
``N_BINS`` equal bins of |v| up to its 99.5th percentile):

- the samples of the bin are split by the sign of s a (a from the same Savitzky-Golay derivative applied to
  the velocity): accelerating (s a > 0) and decelerating (s a < 0); samples where |a| < 1e-3 V 2 pi f (V the
  99th percentile of |v|, f the dominant frequency) belong to neither;
- the branch difference at equal speed is dF = (F_acc - F_dec) - k (V_acc - V_dec): the branches' mean forces
  less the part their mean speeds explain along the binned curve's local slope k (central differences of
  the bins' mean force against mean speed);
- its standard error is SE = sigma_F sqrt(1/n_acc + 1/n_dec), sigma_F the force's white noise estimated on
  the record (third differences, :func:`isokinetic.measurement.loops.noise_sigma`); coloured noise makes this
  SE too small, so the test then errs towards refusing the bins, never towards accepting a loop;
- a bin is tested when each branch holds at least ``MIN_BRANCH_SAMPLES`` samples; it agrees when
  |dF| <= z_c SE (z_c: the two-sided normal quantile at ``ALPHA`` / m, Bonferroni over the m tested bins,
  ALPHA = 1e-3 as the diagnosis' tests) or |dF| <= ``REL_TOLERANCE`` (2 %) of the bin's mean |force| (then
  the bin's mean lies within 1 % of either branch: below what a characteristic point claims to resolve).

A record is quasi-static when at least one bin is tested and every tested bin agrees. A slow sine on a
damper whose pressure relaxes in milliseconds passes; a loop whose force lags by a first-order time constant
of a few hundredths of the period fails (tests/measurement/test_quasi_static.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.measurement.loops import N_BINS, noise_sigma, smooth_velocity
from isokinetic.stats import ALPHA, chi2_isf

#: Fewest samples each branch of a bin needs for the bin to be tested.
MIN_BRANCH_SAMPLES = 5
#: A branch difference below this fraction of the bin's mean |force| agrees whatever the noise.
REL_TOLERANCE = 0.02

#: Columns of :func:`branch_bins`.
BRANCH_COLUMNS = ["direction", "bin", "velocity_m_s", "force_N", "velocity_acc_m_s", "force_acc_N", "n_acc",
                  "velocity_dec_m_s", "force_dec_N", "n_dec", "difference_N", "se_N"]


@dataclass(frozen=True)
class QuasiStatic:
    """The verdict of :func:`quasi_static`: passed, bins tested, the critical z and the worst bin (the largest
    |dF| over its allowance max(z_c SE, REL_TOLERANCE |F|)): its signed speed, difference, SE and mean force."""

    passed: bool
    n_tested: int
    z_critical: float
    velocity_m_s: float = math.nan
    difference_N: float = math.nan
    se_N: float = math.nan
    force_N: float = math.nan

    @property
    def reason(self) -> str:
        """One sentence for a page: why the record's bins are, or are not, a characteristic."""
        if self.n_tested == 0:
            return ("not quasi-static: no velocity bin is crossed both accelerating and decelerating, "
                    "so the test cannot be made")
        what = "quasi-static" if self.passed else "not quasi-static"
        return (f"{what}: at {self.velocity_m_s * 1e3:.4g} mm/s the accelerating and decelerating branches "
                f"differ by {self.difference_N:.4g} N ({abs(self.difference_N) / max(self.se_N, 1e-300):.3g} "
                f"standard errors, {100 * abs(self.difference_N) / max(abs(self.force_N), 1e-300):.3g} % of "
                f"{abs(self.force_N):.4g} N; allowed {self.z_critical:.3g} SE or {100 * REL_TOLERANCE:g} %), "
                f"worst of {self.n_tested} bins")


def _slope(v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """dF/dv at each bin from its neighbours (one-sided at the ends; 0 for a lone bin)."""
    return np.gradient(f, v) if v.size >= 2 and np.all(np.diff(v) > 0) else np.zeros(v.size)


def branch_bins(lp: pd.DataFrame, n_bins: int = N_BINS) -> pd.DataFrame:
    """One row per direction and velocity bin: the mean speed and force of all its samples and of each branch, the
    branch difference at equal speed and its standard error (module doc). ``lp``: a loop (time_s,
    velocity_m_s, force_N; ``attrs['window_s']`` the smoothing window; loops.free_loop)."""
    t = lp["time_s"].to_numpy(float)
    v = lp["velocity_m_s"].to_numpy(float)
    f = lp["force_N"].to_numpy(float)
    if t.size < 8:
        return pd.DataFrame(columns=BRANCH_COLUMNS)
    a = smooth_velocity(t, v, lp.attrs.get("window_s"))
    # no branch where the speed hardly changes: |a| below 1e-3 of V 2 pi f (f the dominant frequency)
    still = 1e-3 * float(np.percentile(np.abs(v), 99)) * 2.0 * math.pi * float(lp.attrs.get("frequency_Hz", 0.0))
    sigma = noise_sigma(f)
    rows = []
    for s, label in ((1.0, "+"), (-1.0, "-")):
        sel = s * v > 0
        if sel.sum() < 2 * MIN_BRANCH_SAMPLES:
            continue
        av, fv, acc, dec = s * v[sel], f[sel], s * a[sel] > still, s * a[sel] < -still
        top = float(np.percentile(av, 99.5))
        edges = np.linspace(0.0, top, n_bins + 1)
        k = np.searchsorted(edges, av, side="right") - 1
        part = []
        for j in range(n_bins):
            m = k == j
            up, down = m & acc, m & dec
            if up.sum() < MIN_BRANCH_SAMPLES or down.sum() < MIN_BRANCH_SAMPLES:
                continue
            part.append({"direction": label, "bin": j + 1, "velocity_m_s": float(av[m].mean()),
                         "force_N": float(fv[m].mean()), "velocity_acc_m_s": float(av[up].mean()),
                         "force_acc_N": float(fv[up].mean()), "n_acc": int(up.sum()),
                         "velocity_dec_m_s": float(av[down].mean()), "force_dec_N": float(fv[down].mean()),
                         "n_dec": int(down.sum()), "se_N": sigma * math.sqrt(1.0 / up.sum() + 1.0 / down.sum())})
        if not part:
            continue
        d = pd.DataFrame(part)
        slope = _slope(d["velocity_m_s"].to_numpy(float), d["force_N"].to_numpy(float))
        d["difference_N"] = (d["force_acc_N"] - d["force_dec_N"]) - slope * (d["velocity_acc_m_s"]
                                                                             - d["velocity_dec_m_s"])
        d["velocity_m_s"] *= s
        d[["velocity_acc_m_s", "velocity_dec_m_s"]] *= s
        rows.append(d)
    out = pd.concat(rows, ignore_index=True) if rows else pd.DataFrame(columns=BRANCH_COLUMNS)
    return out[BRANCH_COLUMNS]


def quasi_static(lp: pd.DataFrame, n_bins: int = N_BINS) -> QuasiStatic:
    """The quasi-static test of a loop (module doc)."""
    b = branch_bins(lp, n_bins)
    m = len(b)
    if m == 0:
        return QuasiStatic(False, 0, math.nan)
    z_c = float(math.sqrt(chi2_isf(ALPHA / m, 1)))
    diff = b["difference_N"].to_numpy(float)
    allowed = np.maximum(z_c * b["se_N"].to_numpy(float), REL_TOLERANCE * b["force_N"].abs().to_numpy(float))
    ratio = np.abs(diff) / np.maximum(allowed, 1e-300)
    w = int(np.argmax(ratio))
    return QuasiStatic(bool(np.all(ratio <= 1.0)), m, z_c, float(b["velocity_m_s"].iloc[w]), float(diff[w]),
                       float(b["se_N"].iloc[w]), float(b["force_N"].iloc[w]))
