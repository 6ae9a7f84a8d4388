"""Where the sim-to-real gap lies: runs of characteristic points, per direction and speed, alike in
significance and sign (the ``where`` key of diagnosis.json)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from isokinetic.diagnosis.observations import Observations

#: |z| of a characteristic point beyond which it is not explained by noise (for ``where``).
Z_SIGNIFICANT = 3.0


def gap_bands(obs: Observations, prediction: np.ndarray, z_significant: float = Z_SIGNIFICANT) -> list[dict]:
    """Contiguous runs of characteristic points (per direction, ordered by speed) alike in significance
    and, for significant points, in sign.

    A point is significant when |z| > z_significant; each band gives its speed range (positive,
    the direction names the quadrant), the mean signed relative error of the force magnitude,
    sign(v)(F_meas - F_model)/|F_meas| (negative: the damper is weaker than the model), and the
    mean z. Both periods' points are pooled per case.
    """
    win = obs.is_window
    df = pd.DataFrame({"case": obs.case[win], "sign": obs.sign[win], "speed": obs.speed_m_s[win],
                       "force": obs.force_N[win], "model": prediction[win], "sigma": obs.sigma_N[win]})
    df["z"] = (df["force"] - df["model"]) / df["sigma"]
    df["rel"] = df["sign"] * (df["force"] - df["model"]) / df["force"].abs()  # < 0: measured weaker
    per_case = df.groupby(["sign", "case"], as_index=False).agg(speed=("speed", "first"), z=("z", "mean"),
                                                               rel=("rel", "mean"))
    bands = []
    for sign, group in per_case.groupby("sign"):
        group = group.sort_values("speed")
        state = [(True, int(np.sign(zv))) if abs(zv) > z_significant else (False, 0) for zv in group["z"]]
        run_start = 0
        for i in range(1, len(group) + 1):
            if i == len(group) or state[i] != state[run_start]:
                part = group.iloc[run_start:i]
                bands.append({"direction": "+" if sign > 0 else "-", "v_min_m_s": float(part["speed"].min()),
                              "v_max_m_s": float(part["speed"].max()), "mean_rel_error": float(part["rel"].mean()),
                              "mean_z": float(part["z"].mean()), "n_cases": int(len(part)),
                              "significant": state[run_start][0]})
                run_start = i
    return bands
