"""Static force at v -> 0: the mean of the + and - branches, extrapolated, with its interval; and its
agreement with the diagnosis' load-cell offset."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml

import isokinetic.reference.campaign as rrc
import isokinetic.reference.rig as rr
from campaign_meta_fixture import write_campaign_meta
from isokinetic.contracts import tables
from isokinetic.measurement.loops import binned_characteristic, free_loop
from isokinetic.measurement.static_force_fit import StaticForceSpec, estimate_static_force, intercept_fit, offset_check
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.static_force import static_force_stage, write_static_force

SPEEDS_M_S = np.geomspace(5e-6, 1.5e-3, 12)
WINDOW_SE_N = 0.05


def characteristic(speeds=SPEEDS_M_S, f0=0.0, friction=(90.0, 90.0), laminar=(4.0e5, 4.0e5), quadratic=1.0e9,
                   seed=1, directions=("+", "-")) -> pd.DataFrame:
    """Four windows per case (+ - + -, two periods): F = f0 + s (F_C,s + c1_s |v| + c2 v²) + noise, the
    noise of a window mean WINDOW_SE_N (force_std_N / sqrt(n_samples))."""
    rng = np.random.default_rng(seed)
    rows = []
    for k, v in enumerate(speeds):
        for segment, direction in enumerate(["+", "-", "+", "-"], start=1):
            if direction not in directions:
                continue
            s, i = (1.0, 0) if direction == "+" else (-1.0, 1)
            force = f0 + s * (friction[i] + laminar[i] * v + quadratic * v * v) + rng.normal(0.0, WINDOW_SE_N)
            rows.append({"campaign": "c", "case": f"T{k + 1:02d}", "segment": segment, "direction": direction,
                         "period": 1 + (segment > 2), "velocity_m_s": s * v, "force_N": force,
                         "force_std_N": WINDOW_SE_N * 40.0, "n_samples": 1600})
    return pd.DataFrame(rows)


def _covers(result, value) -> bool:
    return result.ci_low_N <= value <= result.ci_high_N


def test_static_offset_is_recovered_from_an_odd_characteristic():
    result = estimate_static_force("c", characteristic(f0=-25.0))
    assert (result.source, result.method) == ("characteristic", "linear_fit")
    assert _covers(result, -25.0) and result.significant
    assert result.static_force_N == pytest.approx(-25.0, abs=0.2)
    assert result.std_error_N < 0.5
    assert result.v_min_m_s == pytest.approx(5e-6) and result.n_speeds == StaticForceSpec().n_used(12)
    assert result.source_rows.startswith("T01/1,T01/3,T01/2,T01/4")


def test_symmetric_damper_without_offset_gives_no_significant_static_force():
    result = estimate_static_force("c", characteristic(f0=0.0))
    assert _covers(result, 0.0) and not result.significant


def test_laminar_direction_asymmetry_is_taken_out_by_the_extrapolation():
    # F+ - |F-| grows linearly with |v|: the branch mean is f0 + (c1+ - c1-)/2 |v|
    result = estimate_static_force("c", characteristic(f0=10.0, laminar=(5.0e5, 3.0e5)))
    assert _covers(result, 10.0)
    assert result.slope_N_s_m == pytest.approx(1.0e5, rel=0.05)


def test_a_friction_that_differs_by_direction_is_part_of_the_static_force():
    result = estimate_static_force("c", characteristic(friction=(100.0, 80.0)))
    assert result.static_force_N == pytest.approx(10.0, abs=0.2)


def test_a_curved_branch_mean_is_fitted_over_fewer_lowest_speeds():
    speeds = np.geomspace(5e-6, 1.5e-3, 24)
    curved = characteristic(speeds, laminar=(4.0e5, 4.0e5), quadratic=1.0e9, friction=(90.0, 90.0))
    curved["force_N"] += np.where(curved["direction"] == "+", 5.0e9 * curved["velocity_m_s"] ** 2, 0.0)
    result = estimate_static_force("c", curved)
    assert 3 <= result.n_speeds < StaticForceSpec().n_used(24)
    assert _covers(result, 0.0)


def test_one_direction_missing_is_not_estimated_and_says_why():
    result = estimate_static_force("c", characteristic(directions=("+",)))
    assert math.isnan(result.static_force_N) and (result.source, result.method, result.n_speeds) == ("none", "none", 0)
    assert "only + triangle windows: one direction missing" in result.note
    assert not result.significant


def test_nothing_to_estimate_from():
    result = estimate_static_force("c", None, None)
    assert result.note == "not estimated: no triangle windows; no binned free-record points"


@pytest.mark.parametrize("n, method", [(1, "lowest_speed"), (2, "two_speeds"), (3, "linear_fit")])
def test_few_speeds_give_a_weaker_estimate_that_says_so(n, method):
    result = estimate_static_force("c", characteristic(SPEEDS_M_S[:n], f0=-25.0))
    assert (result.method, result.n_speeds) == (method, n)
    assert result.static_force_N == pytest.approx(-25.0, abs=1.0)
    assert ("not extrapolated" in result.note) == (n == 1)
    assert ("no scatter check" in result.note) == (n == 2)
    assert math.isnan(result.extrapolation_N) == (n == 1)


def test_standard_error_is_the_larger_of_window_noise_and_scatter():
    x = np.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-5
    y = np.array([0.0, 0.3, -0.2, 0.4, 0.1])          # scatter ~0.25 N about any line
    small = intercept_fit(x, y, np.full(5, 0.01))
    smaller = intercept_fit(x, y, np.full(5, 0.001))
    assert small["residual_scale"] > 1
    assert small["statistical_error_N"] == pytest.approx(smaller["statistical_error_N"])   # scatter rules
    big = intercept_fit(x, y, np.full(5, 1.0))
    assert big["residual_scale"] < 1
    assert big["statistical_error_N"] > small["statistical_error_N"]                      # noise rules


def test_extrapolation_below_the_lowest_speed_is_a_systematic_error():
    x = np.array([1.0, 2.0, 4.0]) * 1e-5
    result = intercept_fit(x, 3.0 - 1.0e4 * x, np.full(3, 1e-3))
    assert result["static_force_N"] == pytest.approx(3.0)
    assert result["extrapolation_N"] == pytest.approx(0.1)          # |b| v_1: how far the line carries it
    assert result["std_error_N"] == pytest.approx(math.hypot(result["statistical_error_N"], 0.1))
    assert result["ci_high_N"] - result["ci_low_N"] == pytest.approx(2 * 1.959964 * result["std_error_N"], rel=1e-5)


def test_free_records_binned_points_serve_when_there_are_no_triangle_windows():
    speeds = np.linspace(1e-4, 2e-3, 10)
    rows = [{"campaign": "c", "case": "F01", "waveform": "free", "kind": "binned", "direction": d,
             "velocity_m_s": s * v * (1.0 + 0.01 * (d == "-")), "force_N": -25.0 + s * (90.0 + 4.0e5 * v),
             "force_std_N": 20.0, "n_points": 400}
            for v in speeds for d, s in (("+", 1.0), ("-", -1.0))]
    rows.append({**rows[0], "kind": "peak_velocity"})      # other kinds are not used
    result = estimate_static_force("c", characteristic()[:0], pd.DataFrame(rows))
    assert (result.source, result.source_file) == ("harmonic_binned", "harmonic/harmonic.parquet")
    assert _covers(result, -25.0)
    assert result.note.startswith("no triangle windows; from the free records' binned characteristic")
    assert result.source_rows.split(",")[:2] == ["F01/+/0", "F01/-/0"]


def _static(value=-25.0, se=1.0) -> dict:
    return {"static_force_N": value, "std_error_N": se, "note": ""}


def _diagnosis(offset, estimate=None, rise=None, bound=None, alpha=None, status="ok") -> dict:
    d = {"status": status, "instrument": {"delay_s": 0.0, "force_gain": None, "force_offset_N": offset}}
    if estimate is not None:
        d["instrument_tests"] = {"force_offset": {"estimate": estimate, "chi2_rise_if_fixed": rise}}
    if bound is not None:
        d.setdefault("instrument_tests", {})["bounds"] = {"force_offset_N": [-bound, bound]}
    if alpha is not None:
        d["noise"] = {"alpha": alpha}
    return d


def test_offset_agreeing_with_the_static_force_is_consistent():
    check = offset_check(_static(-25.0, 1.0), _diagnosis(-24.0))
    assert check.status == "consistent" and check.text.startswith("consistent (static force -25.0 ± 1.0 N")
    assert check.difference_N == pytest.approx(-1.0)


def test_offset_at_its_bound_disagrees_and_says_so():
    check = offset_check(_static(-25.0, 1.0), _diagnosis(-5.0, bound=5.0))
    assert check.status == "disagree"
    assert check.text.startswith("disagree by -20.0 N (20.0 sigma)")
    assert "the offset sits at its bound ±5.0 N" in check.text


def test_no_offset_fitted_against_a_static_force_near_zero():
    check = offset_check(_static(0.5, 1.0), _diagnosis(None))
    assert check.status == "no_offset_fitted" and check.text.startswith("no offset fitted")


def test_no_offset_fitted_against_a_clear_static_force_is_never_silent():
    check = offset_check(_static(-25.0, 1.0), _diagnosis(None))
    assert check.status == "disagree" and check.text.startswith("disagree by -25.0 N (25.0 sigma)")


def test_offset_standard_error_from_the_diagnosis_profile_test_counts():
    # the offset -4 N raised chi2 by 16 when fixed at 0: its standard error is about 1 N
    alone = offset_check(_static(0.0, 1.0), _diagnosis(-4.0))
    both = offset_check(_static(0.0, 1.0), _diagnosis(-4.0, estimate=-4.0, rise=16.0))
    assert alone.sigma == pytest.approx(4.0) and both.sigma == pytest.approx(4.0 / math.sqrt(2.0))
    assert (alone.status, both.status) == ("disagree", "consistent")


def test_disagreement_is_judged_at_the_diagnosis_own_level():
    assert offset_check(_static(2.5, 1.0), _diagnosis(None)).status == "no_offset_fitted"      # 2.5 sigma at 0.001
    assert offset_check(_static(2.5, 1.0), _diagnosis(None, alpha=0.05)).status == "disagree"


@pytest.mark.parametrize("diagnosis", [None, {"status": "not_diagnosed", "reason": "no damper data"}])
def test_without_a_diagnosis_there_is_nothing_to_compare(diagnosis):
    check = offset_check(_static(), diagnosis)
    assert check.status == "no_diagnosis" and "static force -25.0 ± 1.0 N" in check.text


def test_a_missing_static_force_is_reported_as_such():
    missing = {"static_force_N": float("nan"), "std_error_N": float("nan"), "note": "only +"}
    check = offset_check(missing, _diagnosis(1.0))
    assert (check.status, check.text) == ("not_estimated", "static force not estimated (only +)")


def test_written_table_meets_its_contract_and_carries_the_gas_force(tmp_path):
    root = tmp_path / "c"
    write_campaign_meta(root, "c", gas_force_N=25.0)
    characteristic(f0=-3.0).to_parquet(root / "characteristic.parquet")
    (path,) = write_static_force(root)
    table = pd.read_parquet(path)
    assert path == root / "static_force.parquet" and len(table) == 1
    assert tables.failure_cases(table, tables.STATIC_FORCE) is None
    assert (table["campaign"].iloc[0], table["gas_force_N"].iloc[0]) == ("c", 25.0)
    assert table["static_force_N"].iloc[0] == pytest.approx(-3.0, abs=0.2)
    assert offset_check(table.iloc[0].to_dict(), _diagnosis(-3.0)).status == "consistent"
    assert tables.failure_cases(pd.concat([table, table], ignore_index=True), tables.STATIC_FORCE) is not None


@pytest.mark.slow
def test_a_rig_load_cell_offset_is_found_and_a_declared_gas_force_takes_it_out(tmp_path):
    # the motivating case: a characteristic ~25 N below zero at v -> 0 (here a load-cell offset of the
    # independent reference rig, with coloured noise, friction and an asymmetric orifice)
    cases = [rr.TriangleCase(f"T{i + 1:02d}", float(v), 80.0 if v < 2e-4 else 20.0, 50.0)
             for i, v in enumerate(np.geomspace(1e-5, 1.5e-3, 8))]
    rig = rr.RigImperfections(force_noise_N=5.0, force_noise_rel=0.01, force_offset_N=-25.0,
                              displacement_noise_m=1e-6, delay_s=0.01, servo_lag_s=0.01)
    raw = tmp_path / "raw" / "offset"
    rrc.write_campaign(raw, cases, effects=rr.TrueEffects(coulomb_force_N=90.0, asymmetry=0.06), rig=rig, seed=3)
    found = {}
    for name, gas in (("plain", None), ("declared", -25.0)):
        if gas is not None:
            manifest = yaml.safe_load((raw / "campaign.yaml").read_text(encoding="utf-8"))
            (raw / "campaign.yaml").write_text(yaml.safe_dump({**manifest, "gas_force_N": gas}), encoding="utf-8")
        ingest_campaign(raw, tmp_path / name)
        write_characteristic(tmp_path / name)
        found[name] = static_force_stage(tmp_path / name)
    assert _covers(found["plain"], -25.0) and found["plain"].significant
    assert _covers(found["declared"], 0.0) and not found["declared"].significant
    assert found["declared"].gas_force_N == -25.0


def test_a_crank_dyno_record_25_N_low_is_found_through_its_binned_characteristic():
    # the motivating real campaign: a slider-crank (free) record whose curve sits 25 N below zero at v -> 0
    rng = np.random.default_rng(7)
    t = np.arange(6001) / 500.0
    dtheta = 2 * np.pi * (1.2 + 0.8 * t / t[-1])
    theta = np.cumsum(dtheta) / 500.0
    r, rod = 0.3e-3, 1.2e-3
    root = np.sqrt(rod ** 2 - (r * np.sin(theta)) ** 2)
    v = -r * np.sin(theta) * dtheta - r ** 2 * np.sin(theta) * np.cos(theta) * dtheta / root
    force = 150.0 * np.tanh(v / 2e-4) + 4e5 * v + 3e8 * v * np.abs(v) - 25.0 + rng.normal(0.0, 5.0, t.size)
    series = pd.DataFrame({"row": np.arange(t.size), "time_s": t, "force_N": force,
                           "displacement_m": r * np.cos(theta) + root - rod + rng.normal(0.0, 1e-6, t.size)})
    binned = binned_characteristic(free_loop(series)).assign(campaign="c", case="F01", waveform="free", kind="binned")
    result = estimate_static_force("c", None, binned)
    assert result.source == "harmonic_binned" and result.n_speeds >= 3
    assert _covers(result, -25.0) and result.significant


# --- standstill cases and the declared gas forces (manifest 1.2) ---------------------------------

def _standstill_campaign(tmp_path, declared: dict[str, float], true_gas_N: float = 120.0, moving: bool = False):
    """A record at rest under a gas force of ``true_gas_N`` (coloured noise, 2 N), cut into one standstill
    case per entry of ``declared`` (case -> its declared gas_force_N); ingested to tmp_path/results."""
    from stages.test_ingest_vendor import MM_N, write_campaign

    rng = np.random.default_rng(11)
    n = 4000
    t = np.arange(n) / 100.0
    noise = np.convolve(rng.normal(0.0, 2.0, n + 9), np.ones(10) / np.sqrt(10), mode="valid")
    table = pd.DataFrame({"time_s": t, "disp_mm": np.zeros(n), "force_N": true_gas_N + noise})
    cases = [{"id": case, "waveform": "standstill", "file": "rest.csv", "rows": [1000 * i, 1000 * i + 1000],
              "gas_force_N": gas} for i, (case, gas) in enumerate(declared.items())]
    if moving:
        cases.append({"id": "F01", "waveform": "free", "file": "rest.csv", "gas_force_N": true_gas_N})
    folder = write_campaign(tmp_path / "raw", "rest", MM_N, cases,
                            {"rest.csv": table.to_csv(index=False, float_format="%.17g").encode()})
    ingest_campaign(folder, tmp_path / "results")
    return tmp_path / "results", table


def test_standstill_cases_give_the_static_force_directly(tmp_path):
    root, table = _standstill_campaign(tmp_path, {"Z01": 100.0, "Z02": 100.0})
    result = static_force_stage(root)
    left = table["force_N"].to_numpy()[:2000] - 100.0
    assert (result.source, result.method, result.n_standstill) == ("standstill", "standstill_mean", 2)
    means, errors = [], []
    for stretch in (left[:1000], left[1000:]):      # each case: its mean, the scatter of 20 block means
        blocks = np.array([stretch[i:i + 50].mean() for i in range(0, 1000, 50)])
        means.append(stretch.mean())
        errors.append(blocks.std(ddof=1) / np.sqrt(20))
    weights = 1.0 / np.square(errors)
    assert result.static_force_N == pytest.approx(np.sum(weights * means) / np.sum(weights), abs=1e-9)
    assert result.std_error_N == pytest.approx(max(1.0 / np.sqrt(np.sum(weights)), np.std(means, ddof=1) / np.sqrt(2)))
    assert _covers(result, 20.0) and result.significant


def test_each_standstill_case_is_checked_against_its_declared_gas_force(tmp_path):
    root, _ = _standstill_campaign(tmp_path, {"Z01": 120.0, "Z02": 80.0, "Z03": 119.0})
    result = static_force_stage(root)
    assert result.gas_force_check == "disagrees"
    lines = result.gas_force_cases.split("; ")
    assert [line.split(":")[0] for line in lines] == ["Z01", "Z02", "Z03"]
    assert [line.rsplit(": ", 1)[1] for line in lines] == ["agrees", "disagrees", "agrees"]
    assert "N left of the declared 80 N" in lines[1]


def test_declared_gas_forces_that_hold_agree(tmp_path):
    root, _ = _standstill_campaign(tmp_path, {"Z01": 120.0, "Z02": 120.0})
    (path,) = write_static_force(root)
    table = pd.read_parquet(path)
    assert tables.failure_cases(table, tables.STATIC_FORCE) is None
    assert table["gas_force_check"].iloc[0] == "agrees" and not table["significant"].iloc[0]
    assert table["n_standstill"].iloc[0] == 2


def test_moving_cases_are_checked_together_and_say_when_they_cannot_be(tmp_path):
    root, _ = _standstill_campaign(tmp_path, {"Z01": 120.0}, moving=True)
    result = static_force_stage(root)               # no characteristic written: nothing to check F01 with
    assert result.gas_force_check == "agrees"
    assert result.gas_force_cases.split("; ")[1] == ("moving cases F01: not checked (no static force from the "
                                                     "characteristic)")


def test_without_declared_gas_forces_nothing_is_checked(tmp_path):
    root = tmp_path / "c"
    write_campaign_meta(root, "c", gas_force_N=None)
    characteristic(f0=-3.0).to_parquet(root / "characteristic.parquet")
    result = static_force_stage(root)
    assert (result.source, result.gas_force_check, result.gas_force_cases, result.n_standstill) == (
        "characteristic", "not_checked", "", 0)
