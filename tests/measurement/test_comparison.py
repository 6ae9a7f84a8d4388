"""Comparison of campaigns (isokinetic.measurement.comparison): the standard error of a point by hand, a known
offset found and equal data not, velocities matched within the tolerance and moved along the slope,
the model path where velocities differ (prediction SE, range, fallback, notes), the refusals. The stage's
files are tested in tests/stages/test_compare.py, the figures in tests/plots/test_compare.py, the page in
tests/report/test_compare_report.py.

The synthetic campaigns follow F = sign(v) (90 + 2e6 |v| + 1.5e9 v^2) N, the fitted models' own form,
plus white window noise (5 N over 400 samples), seeded."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from isokinetic.contracts import tables
from isokinetic.measurement.comparison import (
    MIN_DIFFERENCE_SE_N,
    CompareSpec,
    campaign_curves,
    campaign_points,
    compare_campaigns,
    local_slope,
    match_velocities,
    significance,
    z_test,
)
from isokinetic.measurement.model_fit import design_matrix, fit_models

SPEEDS_A = np.geomspace(1e-5, 1e-3, 9)
SPEEDS_B = np.geomspace(1.3e-5, 0.8e-3, 7)     # none within 1 % of SPEEDS_A


def damper_force(v, misfit_N: float = 0.0):
    """The synthetic damper; ``misfit_N`` adds a term the fitted models cannot follow."""
    a = np.abs(v)
    return np.sign(v) * (90.0 + 2.0e6 * a + 1.5e9 * a * a + misfit_N * np.tanh(a / 3e-5))


def characteristic(campaign: str, speeds, *, offset_N: float = 0.0, seed: int = 0, std_N: float = 5.0,
                   n: int = 400, speed_factor: float = 1.0, misfit_N: float = 0.0) -> pd.DataFrame:
    """Four windows per speed (two periods, both directions), CHARACTERISTIC columns."""
    rng = np.random.default_rng(seed)
    rows = []
    for i, w in enumerate(speeds, start=1):
        for segment, direction, period in ((1, "+", 1), (2, "-", 1), (3, "+", 2), (4, "-", 2)):
            v = (w if direction == "+" else -w) * speed_factor
            f = float(damper_force(v, misfit_N) + offset_N + rng.normal(0.0, std_N / math.sqrt(n)))
            rows.append({"campaign": campaign, "case": f"T{i:02d}", "segment": segment, "direction": direction,
                         "period": period, "planned_velocity_m_s": v, "velocity_m_s": v, "force_N": f,
                         "force_std_N": std_N, "n_samples": n, "window_start_s": 10.0 * segment,
                         "window_end_s": 10.0 * segment + 5, "row_start": 100 * segment,
                         "row_stop": 100 * segment + n, "raw_file": f"T{i:02d}.csv", "raw_sha256": "0" * 64,
                         "repeatability_flagged": False})
    return tables.validate_table(pd.DataFrame(rows), tables.CHARACTERISTIC)


def compare(spec: CompareSpec, chars: dict[str, pd.DataFrame], models: dict | None = None):
    models = models if models is not None else {c: fit_models(df)[0] for c, df in chars.items()}
    return compare_campaigns(spec, chars, models)


def test_point_standard_error_is_window_noise_and_repeatability_in_quadrature():
    char = characteristic("a", [1e-4])
    plus = char[char["direction"] == "+"].copy()
    plus["force_N"] = [300.0, 306.0]
    plus["force_std_N"] = [4.0, 8.0]
    plus["n_samples"] = [100, 400]
    point = campaign_points(plus).iloc[0]
    noise = math.sqrt(4.0**2 / 100 + 8.0**2 / 400) / 2          # 0.2828 N: SE of the mean of the two windows
    repeat = abs(306.0 - 300.0) / 2                              # 3 N: half the period difference
    assert point["force_N"] == pytest.approx(303.0)
    assert point["noise_se_N"] == pytest.approx(noise)
    assert point["repeatability_se_N"] == pytest.approx(repeat)
    assert point["se_N"] == pytest.approx(math.sqrt(noise**2 + repeat**2))
    assert point["n_windows"] == 2


def test_difference_se_is_the_two_ses_in_quadrature_and_p_two_sided_normal():
    table = pd.DataFrame({"reference_force_N": [100.0, 100.0], "campaign_force_N": [103.0, 100.5],
                          "reference_se_N": [1.2, 0.3], "campaign_se_N": [1.6, 0.4]})
    out = significance(table, 0.05)
    assert out["difference_se_N"].tolist() == pytest.approx([2.0, 0.5])
    assert out["z"].tolist() == pytest.approx([1.5, 1.0])
    assert out["p_value"].tolist() == pytest.approx([0.133614, 0.317311], abs=1e-6)   # tables of the normal
    assert out["significant"].tolist() == [False, False]
    assert significance(table.assign(campaign_force_N=[104.0, 101.0]), 0.05)["significant"].tolist() == [True, True]



def test_z_test_of_scalars_and_arrays_and_a_noise_free_difference():
    d, se, z, p = z_test(110.0, 3.0, 100.0, 4.0)
    assert (float(d), float(se), float(z)) == pytest.approx((10.0, 5.0, 2.0))
    assert float(p) == pytest.approx(0.0455003, abs=1e-7)           # tables of the normal: 2 (1 - Phi(2))
    d, se, z, p = z_test([100.0, 99.0], [0.0, 0.0], [100.0, 100.0], [0.0, 0.0])
    assert se.tolist() == [MIN_DIFFERENCE_SE_N] * 2 and z.tolist() == [0.0, -1.0 / MIN_DIFFERENCE_SE_N]
    assert p.tolist() == [1.0, 0.0]

def test_known_offset_at_matching_velocities_is_significant():
    spec = CompareSpec("offset", ("a", "b"))
    result = compare(spec, {"a": characteristic("a", SPEEDS_A, seed=1),
                            "b": characteristic("b", SPEEDS_A, seed=2, offset_N=3.0)})
    t = result.table
    assert len(t) == 2 * len(SPEEDS_A) and set(t["basis"]) == {"measured"}
    assert t["difference_N"].to_numpy() == pytest.approx(3.0, abs=0.5)
    assert t["significant"].all()
    assert result.summary["pairs"][0]["n_significant"] == len(t)


def test_equal_data_is_not_significant():
    char = characteristic("a", SPEEDS_A, seed=1)
    result = compare(CompareSpec("same", ("a", "b")), {"a": char, "b": char.assign(campaign="b")})
    t = result.table
    assert set(t["basis"]) == {"measured"}
    assert (t["difference_N"] == 0).all() and not t["significant"].any()
    assert (t["velocity_shift_N"] == 0).all()


def test_velocities_within_the_tolerance_match_and_are_moved_along_the_slope():
    a = characteristic("a", SPEEDS_A, seed=1, std_N=0.5)
    b = characteristic("b", SPEEDS_A, seed=2, std_N=0.5, speed_factor=1.005)
    t = compare(CompareSpec("speeds", ("a", "b")), {"a": a, "b": b}).table
    assert set(t["basis"]) == {"measured"}
    # unmoved, the 0.5 % faster campaign would differ by up to ~1 % of 7 kN: far beyond its SE
    raw = t["campaign_force_N"] - t["velocity_shift_N"] - t["reference_force_N"]
    assert raw.abs().max() > 20 * t["difference_se_N"].max()
    assert t["difference_N"].abs().max() < 0.05 * raw.abs().max()
    assert not t["significant"].any()
    far = compare(CompareSpec("far", ("a", "b"), velocity_tolerance=0.001), {"a": a, "b": b}).table
    assert not (far["basis"] == "measured").any()


def test_velocities_that_differ_are_compared_through_the_models():
    a = characteristic("a", SPEEDS_A, seed=1)
    same = compare(CompareSpec("model", ("a", "b")), {"a": a, "b": characteristic("b", SPEEDS_B, seed=2)})
    shifted = compare(CompareSpec("model", ("a", "b")), {"a": a, "b": characteristic("b", SPEEDS_B, seed=2,
                                                                                      offset_N=30.0)})
    for t in (same.table, shifted.table):
        assert set(t["basis"]) == {"model:surace"}
        assert (t["reference_noise_se_N"].isna() & t["campaign_noise_se_N"].isna()).all()
    assert not same.table["significant"].any()
    assert shifted.table["significant"].all()
    assert shifted.table["difference_N"].to_numpy() == pytest.approx(30.0, abs=1.0)


def test_model_rows_stay_within_both_campaigns_measured_speeds():
    result = compare(CompareSpec("range", ("a", "b")), {"a": characteristic("a", SPEEDS_A, seed=1),
                                                        "b": characteristic("b", SPEEDS_B, seed=2)})
    speeds = result.table["velocity_m_s"].abs()
    assert speeds.min() >= SPEEDS_B[0] * 0.99 and speeds.max() <= SPEEDS_B[-1] * 1.01
    excluded = result.summary["pairs"][0]["excluded"]
    assert sorted({round(abs(e["velocity_m_s"]), 9) for e in excluded}) == pytest.approx([SPEEDS_A[0], SPEEDS_A[-1]])
    assert all(e["campaign"] == "a" and "outside b's measured speeds" in e["reason"] for e in excluded)


def test_model_se_adds_the_scatter_about_the_model_to_the_parameter_covariance():
    char = characteristic("a", SPEEDS_A, seed=1, misfit_N=60.0)
    models = fit_models(char)[0]
    points = campaign_points(char)
    curve = campaign_curves(char, points, models, "a")[("surace", "+")]
    v = np.array([3e-5, 2e-4])
    x = design_matrix(v)
    band = np.sqrt(np.einsum("ij,jk,ik->i", x, curve.cov, x))
    sigma = 5.0 / math.sqrt(400)                                   # every window's noise SE
    assert curve.se(v) == pytest.approx(np.sqrt(band**2 + (curve.residual_scale * sigma) ** 2))
    assert curve.residual_scale > 10 and (curve.se(v) > 3 * band).all()


def test_refit_agrees_with_models_parquet_and_a_stale_one_is_refused():
    char = characteristic("a", SPEEDS_A, seed=1)
    models = fit_models(char)[0]
    curves = campaign_curves(char, campaign_points(char), models, "a")
    assert set(curves) == {("surace", "+"), ("surace", "-"), ("wallaschek", "+"), ("wallaschek", "-")}
    stale = models.copy()
    stale.loc[(stale["model"] == "surace") & (stale["parameter"] == "D_L"), "estimate"] *= 1.01
    with pytest.raises(ValueError, match="different runs"):
        campaign_curves(char, campaign_points(char), stale, "a")


def test_wallaschek_is_used_where_a_campaign_lacks_the_surace_fit_and_said():
    a, b = characteristic("a", SPEEDS_A, seed=1), characteristic("b", SPEEDS_B, seed=2)
    mb = fit_models(b)[0]
    result = compare(CompareSpec("fallback", ("a", "b")), {"a": a, "b": b},
                     {"a": fit_models(a)[0], "b": mb[mb["model"] != "surace"]})
    assert set(result.table["basis"]) == {"model:wallaschek"}
    assert any("wallaschek is used" in n for n in result.summary["pairs"][0]["notes"])


def test_a_model_fitted_to_as_many_speeds_as_parameters_is_said_to_hide_its_misfit():
    result = compare(CompareSpec("three", ("a", "b")), {"a": characteristic("a", SPEEDS_A, seed=1),
                                                        "b": characteristic("b", [1e-5, 1e-4, 5e-4], seed=2)})
    notes = result.summary["pairs"][0]["notes"]
    assert any(n.startswith("b: surace (+, -) is fitted to 3 speeds") for n in notes)
    assert not any(n.startswith("a:") for n in notes)


def test_every_campaign_is_compared_with_the_first():
    chars = {c: characteristic(c, SPEEDS_A, seed=k, offset_N=3.0 * k) for k, c in enumerate(("r", "x", "y"))}
    result = compare(CompareSpec("three", ("r", "x", "y")), chars)
    assert list(dict.fromkeys(result.table["campaign"])) == ["x", "y"]
    assert (result.table["reference"] == "r").all()
    by = result.table.groupby("campaign")["difference_N"].mean()
    assert by.to_dict() == pytest.approx({"x": 3.0, "y": 6.0}, abs=0.5)


@pytest.mark.parametrize("campaigns", [(), ("a",), ("a", "a")])
def test_fewer_than_two_distinct_campaigns_are_refused(campaigns):
    with pytest.raises(ValueError, match="comparison 'x'"):
        CompareSpec("x", campaigns)


def test_match_velocities_pairs_nearest_first_each_once():
    assert match_velocities([1.0, 2.0, -1.0], [2.01, 0.995, 1.004, 5.0], 0.01) == [(0, 2), (1, 0)]
    assert match_velocities([1.0], [1.02], 0.01) == []


def test_local_slope_is_exact_on_a_parabola_and_one_sided_at_the_ends():
    v = np.array([1e-4, 4e-4, 2e-4, 8e-4])
    f = 90.0 + 2.0e6 * v + 1.5e9 * v**2
    assert local_slope(v, f) == pytest.approx(2.0e6 + 3.0e9 * v, rel=1e-9)
    assert local_slope([1.0, 3.0], [2.0, 8.0]).tolist() == pytest.approx([3.0, 3.0])
    assert local_slope([1.0], [2.0]).tolist() == [0.0]

