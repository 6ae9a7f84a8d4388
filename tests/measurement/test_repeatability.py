import pandas as pd
import pytest

from isokinetic.measurement.repeatability import relative_difference, repeatability
from isokinetic.stages.characteristic import assemble


def windows_table():
    rows = []
    forces = {"T01": (100.0, -80.0, 102.0, -80.4), "T02": (200.0, -190.0, 230.0, -190.0)}
    for case, (fp1, fm1, fp2, fm2) in forces.items():
        v = 1e-4 if case == "T01" else 2e-4
        for seg, (d, f) in enumerate([("+", fp1), ("-", fm1), ("+", fp2), ("-", fm2)], start=1):
            rows.append({"campaign": "c", "case": case, "segment": seg, "direction": d, "period": (seg + 1) // 2,
                         "planned_velocity_m_s": v if d == "+" else -v, "velocity_m_s": v if d == "+" else -v,
                         "force_N": f, "force_std_N": 1.0, "n_samples": 10, "window_start_s": 0.0,
                         "window_end_s": 1.0, "row_start": 0, "row_stop": 10, "raw_file": "f", "raw_sha256": "h"})
    return pd.DataFrame(rows)


def test_relative_difference_is_signed_and_normalised_by_mean_magnitude():
    assert relative_difference(100.0, 102.0) == pytest.approx(2.0 / 101.0)
    assert relative_difference(-80.0, -80.4) == pytest.approx(-0.4 / 80.2)


def test_repeatability_flags_only_pairs_beyond_tolerance():
    rep = repeatability(windows_table(), tolerance=0.05).set_index(["case", "direction"])
    assert rep.loc[("T02", "+"), "rel_diff"] == pytest.approx(30.0 / 215.0)
    assert bool(rep.loc[("T02", "+"), "flagged"]) is True
    assert not rep.drop(index=[("T02", "+")])["flagged"].any()
    assert rep.loc[("T01", "-"), "force_period2_N"] == -80.4


def test_repeatability_rejects_non_positive_tolerance():
    with pytest.raises(ValueError, match="tolerance"):
        repeatability(windows_table(), tolerance=0.0)


def test_characteristic_carries_flag_to_every_window_of_the_pair():
    win = windows_table()
    char = assemble(win, repeatability(win, tolerance=0.05))
    flagged = char[char["repeatability_flagged"]]
    assert sorted(flagged["segment"]) == [1, 3] and set(flagged["case"]) == {"T02"}
    assert len(char) == len(win)
    assert char["velocity_m_s"].is_monotonic_increasing


def test_a_case_and_direction_with_one_period_has_no_row():
    # a sine case of 2-3 steady cycles a direction gives period 1 only (stages.characteristic)
    win = windows_table()
    one = win[~((win["case"] == "T02") & (win["direction"] == "-") & (win["period"] == 2))]
    rep = repeatability(one, tolerance=0.05)
    assert set(zip(rep["case"], rep["direction"], strict=True)) == {("T01", "+"), ("T01", "-"), ("T02", "+")}
    full = repeatability(win, tolerance=0.05)
    pd.testing.assert_frame_equal(rep, full[~((full["case"] == "T02") & (full["direction"] == "-"))]
                                  .reset_index(drop=True))


def test_no_second_period_anywhere_gives_an_empty_table():
    win = windows_table()
    assert repeatability(win[win["period"] == 1], tolerance=0.05).empty
