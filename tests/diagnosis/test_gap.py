"""Where the gap lies (isokinetic.diagnosis.gap)."""

import numpy as np
import pytest

from isokinetic.diagnosis.gap import gap_bands
from isokinetic.diagnosis.observations import Observations


def test_gap_bands_group_contiguous_points_of_equal_significance_and_sign():
    n = 6
    obs = Observations(
        campaign="c", plans=(), case=np.array([f"T{i}" for i in range(n)], dtype=object),
        case_index=np.arange(n), kind=np.array(["window"] * n, dtype=object), segment=np.ones(n, dtype=np.int64),
        period=np.ones(n, dtype=np.int64), sign=np.ones(n), speed_m_s=np.arange(1, n + 1) * 1e-4,
        start=np.zeros(n, dtype=np.int64), stop=np.ones(n, dtype=np.int64),
        force_N=np.full(n, 100.0), sigma_N=np.ones(n), rep_rel=0.0)
    model = np.array([100.0, 100.5, 110.0, 112.0, 100.0, 90.0])  # z = 0, -0.5, -10, -12, 0, +10
    bands = gap_bands(obs, model)
    got = [(b["v_min_m_s"], b["v_max_m_s"], b["significant"]) for b in bands]
    assert got == [(pytest.approx(1e-4), pytest.approx(2e-4), False), (pytest.approx(3e-4), pytest.approx(4e-4), True),
                   (pytest.approx(5e-4), pytest.approx(5e-4), False), (pytest.approx(6e-4), pytest.approx(6e-4), True)]
    assert bands[1]["mean_rel_error"] == pytest.approx(-0.11)  # damper 11 % weaker than the model
    assert bands[3]["mean_rel_error"] == pytest.approx(0.10)
