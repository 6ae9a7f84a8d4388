"""Partial records keep what is good (issue 34): a last row cut off, a blank or unreadable cell, a repeated time
stamp, a repeated header and units row inside the data: the rows are left out, noted, and left as a gap in time
for validate's gap rule; the case is kept. More damage than MAX_DAMAGED_FRACTION of the rows is refused as
before, naming the first."""

from __future__ import annotations

import numpy as np
import pandas as pd

from conftest import CAMPAIGN, N_SAMPLES, assert_quarantine, edit_bytes, set_cell
from isokinetic.stages.ingest import MAX_DAMAGED_FRACTION


def _case(cases: pd.DataFrame, case: str) -> pd.Series:
    return cases.set_index("case").loc[case]


def _series(raw_campaign, cases, case: str) -> pd.DataFrame:
    return pd.read_parquet(raw_campaign.root / _case(cases, case)["timeseries_file"])


def _cut_mid_row(data: bytes) -> bytes:
    """The file cut off in the third field of its last row (no line end): a rig that stopped while writing."""
    body, last = data.rstrip(b"\n").rsplit(b"\n", 1)
    return body + b"\n" + b",".join(last.split(b",")[:2]) + b"," + last.split(b",")[2][:3]


def test_a_file_cut_off_mid_row_keeps_its_case_without_the_row(raw_campaign, baseline):
    edit_bytes(raw_campaign, "H01", _cut_mid_row)
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    row = _case(cases, "H01")
    assert (row["status"], row["n_samples"]) == ("ok", N_SAMPLES["H01"] - 1)
    assert "the last row (399) ends after 3 of 5 fields without a line end: the file is cut off" in row["quality"]
    pd.testing.assert_frame_equal(_series(raw_campaign, cases, "H01"), baseline["H01"].iloc[:-1])


def test_a_last_number_cut_short_is_cut_off_not_a_value(raw_campaign, baseline):
    """``0.`` for ``0.2732...`` in the last row (no line end) was read as 0 N; now the row is left out."""
    raw_campaign.edit_table("H01", lambda t: t[["time_s", "disp_mm", "cmd_mm", "temp_C", "force_kN"]])
    edit_bytes(raw_campaign, "H01", lambda data: data.rstrip(b"\n").rsplit(b".", 1)[0] + b".")
    cases, quarantine = raw_campaign.run()
    row = _case(cases, "H01")
    assert (row["status"], row["n_samples"]) == ("ok", N_SAMPLES["H01"] - 1)
    assert "without a line end: cut off in its last value, the row left out" in row["quality"]
    series = _series(raw_campaign, cases, "H01")
    pd.testing.assert_frame_equal(series, baseline["H01"].iloc[:-1])


def test_a_blank_cell_drops_its_row_as_a_gap_and_keeps_the_case(raw_campaign, baseline):
    raw_campaign.edit_table("T01", set_cell(100, "force_kN", ""))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    row = _case(cases, "T01")
    assert row["status"] == "ok" and row["n_samples"] == N_SAMPLES["T01"] - 1
    assert "1 row(s) with a blank or unreadable cell left out (data rows 100): a gap in the record" in row["quality"]
    assert row["missing_samples"] == 1                      # validate's gap rule counts it as a dropped sample
    expected = baseline["T01"].drop(index=100).reset_index(drop=True)
    pd.testing.assert_frame_equal(_series(raw_campaign, cases, "T01"), expected)


def test_a_non_numeric_cell_drops_its_row(raw_campaign):
    raw_campaign.edit_table("T02", set_cell(17, "force_kN", "abc"))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    row = _case(cases, "T02")
    assert "1 row(s) with a blank or unreadable cell left out (data rows 17)" in row["quality"]


def test_a_repeated_time_stamp_row_is_dropped_and_counted(raw_campaign, baseline):
    raw_campaign.edit_table("T01", lambda t: pd.concat([t.iloc[:51], t.iloc[50:51], t.iloc[51:]],
                                                       ignore_index=True))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    row = _case(cases, "T01")
    assert row["n_samples"] == N_SAMPLES["T01"] and row["missing_samples"] == 0
    assert "1 row(s) repeating the time stamp of the row before left out (data rows 51)" in row["quality"]
    series = _series(raw_campaign, cases, "T01")
    pd.testing.assert_frame_equal(series.drop(columns="row"), baseline["T01"].drop(columns="row"))


def test_a_repeated_header_and_units_row_inside_the_data_keep_the_case(raw_campaign):
    """A logger that restarts writes its header and units row again: the header is a marker row, the units row an
    unreadable row left out."""
    raw_campaign.edit_manifest(lambda m: m.update(csv={"units_row": True}))
    units = {"time_s": "s", "disp_mm": "mm", "force_kN": "kN", "force_inv_kN": "kN", "cmd_mm": "mm", "temp_C": "C"}
    for case in ("T01", "T02", "T03", "H01", "F01"):
        raw_campaign.edit_table(case, lambda t: pd.concat([pd.DataFrame([{c: units[c] for c in t.columns}]), t],
                                                          ignore_index=True))
    header = list(raw_campaign.read_table("H01").columns)
    raw_campaign.edit_table("H01", lambda t: pd.concat([t.iloc[:201], pd.DataFrame([dict(zip(header, header)),
                                                                                    t.iloc[0].to_dict()]),
                                                        t.iloc[201:]], ignore_index=True))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    row = _case(cases, "H01")
    assert row["n_samples"] == N_SAMPLES["H01"]
    assert "skipped 1 marker row(s)" in row["quality"] and "1 row(s) with a blank or unreadable cell" in row["quality"]


def test_more_damage_than_a_partial_record_is_refused_naming_the_first_row(raw_campaign):
    n = int(MAX_DAMAGED_FRACTION * N_SAMPLES["T02"]) + 1

    def damage(t):
        t.loc[17:16 + n, "force_kN"] = "abc"
        return t
    raw_campaign.edit_table("T02", damage)
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T02", "ingest", "force_kN", 17)])
    assert quarantine["reason"].iloc[0].endswith("row 17: non-numeric value 'abc'")


def test_a_velocity_declared_as_the_displacement_is_named_a_velocity(raw_campaign):
    """Before: validate's sign check asked for `invert: true`, which cannot fix it."""
    def velocity(t):
        time, cmd = t["time_s"].astype(float), t["cmd_mm"].astype(float)
        t["disp_mm"] = (cmd.diff() / time.diff()).bfill().map("{:.10g}".format)
        return t
    raw_campaign.edit_table("T01", velocity)
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "ingest", "disp_mm", None)])
    reason = quarantine["reason"].iloc[0]
    assert "looks like a velocity, not a displacement" in reason and "`invert` would not fix this" in reason



def test_a_displacement_lagging_a_fast_sine_command_is_no_velocity():
    # a servo above its bandwidth lags a 10 Hz command by 80 degrees: the shape of the derivative, the amplitude of
    # the command (a velocity would be 2 pi 10 = 63 times larger per metre)
    from isokinetic.stages.ingest import velocity_problem

    t = np.arange(0, 2.0, 1e-3)
    command = 20e-6 * np.sin(2 * np.pi * 10 * t)
    lagged = 18e-6 * np.sin(2 * np.pi * 10 * t - np.radians(80))
    df = pd.DataFrame({"time_s": t, "displacement_m": lagged, "command_m": command})
    assert velocity_problem(df, {}) is None
    velocity = pd.DataFrame({"time_s": t, "displacement_m": np.gradient(command, t), "command_m": command})
    assert velocity_problem(velocity, {"displacement": type("C", (), {"name": "v"})()}) is not None
