"""A synthetic triangle campaign (tables and time series) for the figure tests.

Used by tests/plots/test_figures.py (drawing of Fig. 7-12) and tests/stages/test_figures.py (the
rule ``figures``): a friction + laminar + turbulent damper, 6 % stronger in compression.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from isokinetic.physics.plan import triangle_displacement


def _force_model(v):
    a = np.abs(v)
    f = 90.0 + 2.0e6 * a + 1.5e9 * a ** 2
    return np.sign(v) * f * np.where(v < 0, 1.06, 1.0)


def _triangle(case, v, period, campaign="synthetic-damper", n_per_period=200, seed=0):
    """Time series and the four windows ([0.45, 0.95] x T/2) of one triangle case."""
    rng = np.random.default_rng(seed)
    amp = v * period / 4.0
    t = np.arange(2 * n_per_period) * (period / n_per_period)
    y = triangle_displacement(t, amp, period)
    vel = np.gradient(y, t)
    force = _force_model(vel) * (1 + 0.01 * rng.standard_normal(t.size)) + 5.0 * rng.standard_normal(t.size)
    ts = pd.DataFrame({"row": np.arange(t.size, dtype="int64"), "time_s": t, "displacement_m": y,
                       "force_N": force})
    wins = []
    for k in range(4):
        t0 = k * period / 2
        m = (t >= t0 + 0.45 * period / 2) & (t <= t0 + 0.95 * period / 2)
        idx = np.flatnonzero(m)
        direction = "+" if k % 2 == 0 else "-"
        wins.append({"campaign": campaign, "case": case, "segment": k + 1, "direction": direction,
                     "period": 1 if k < 2 else 2, "planned_velocity_m_s": v if direction == "+" else -v,
                     "velocity_m_s": float(np.polyfit(t[m], y[m], 1)[0]), "force_N": float(force[m].mean()),
                     "force_std_N": float(force[m].std(ddof=1)), "n_samples": int(m.sum()),
                     "window_start_s": float(t[idx[0]]), "window_end_s": float(t[idx[-1]]),
                     "row_start": int(idx[0]), "row_stop": int(idx[-1] + 1),
                     "raw_file": f"{case}.csv", "raw_sha256": "0" * 64})
    return ts, pd.DataFrame(wins)


def synthetic_campaign(n=9, quarantined=(), sine=0, campaign="synthetic-damper"):
    """(cases, {case: series}, windows, characteristic) of a campaign with n log-spaced speeds."""
    speeds = np.geomspace(5e-6, 1.5e-3, n)
    rows, series, wins = [], {}, []
    for i, v in enumerate(speeds, start=1):
        case = f"T{i:02d}"
        period = 240.0 if v < 2e-5 else 80.0 if v < 2e-4 else 20.0
        status = "quarantined" if case in quarantined else "ok"
        rows.append({"campaign": campaign, "case": case, "waveform": "triangle", "sample_rate_Hz": 200.0 / period,
                     "amplitude_m": v * period / 4, "period_s": period, "frequency_Hz": math.nan,
                     "phase_rad": -math.pi / 2, "duration_s": 2 * period, "raw_file": f"{case}.csv",
                     "raw_sha256": "0" * 64, "timeseries_file": f"ingest/timeseries/{case}.parquet",
                     "n_samples": 400, "status": status})
        if status == "ok":
            series[case], w = _triangle(case, v, period, campaign, seed=i)
            wins.append(w)
    for j in range(1, sine + 1):
        rows.append({"campaign": campaign, "case": f"H{j:02d}", "waveform": "sine", "sample_rate_Hz": 1000.0,
                     "amplitude_m": 2e-4, "period_s": math.nan, "frequency_Hz": 1.75, "phase_rad": 0.0,
                     "duration_s": 1.0, "raw_file": f"H{j:02d}.csv", "raw_sha256": "0" * 64,
                     "timeseries_file": f"ingest/timeseries/H{j:02d}.parquet", "n_samples": 0, "status": "ok"})
    windows = pd.concat(wins, ignore_index=True) if wins else pd.DataFrame()
    char = windows.assign(repeatability_flagged=False)
    return pd.DataFrame(rows), series, windows, char


def write_campaign(root, cases, series, windows, char, cases_at_root=False):
    (root / "ingest" / "timeseries").mkdir(parents=True)
    for case, ts in series.items():
        ts.to_parquet(root / "ingest" / "timeseries" / f"{case}.parquet", index=False)
    cases.to_parquet(root / ("cases.parquet" if cases_at_root else "ingest/cases.parquet"), index=False)
    windows.to_parquet(root / "windows.parquet", index=False)
    char.to_parquet(root / "characteristic.parquet", index=False)
