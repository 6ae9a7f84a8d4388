"""Every kind of damaged case is set aside with an exact reason (campaign, case, column, first bad
row), or flagged but kept with a ``quality`` warning (a partial record, issue 34: its damaged rows left out);
every other case is processed exactly as in
the undamaged run (same canonical series, status ok, quality 'ok')."""

from __future__ import annotations

import codecs

import pandas as pd
import pytest

from conftest import (
    CAMPAIGN,
    assert_quarantine,
    assert_rest_unchanged,
    data_line,
    drop_rows,
    edit_bytes,
    scale_column,
    set_cell,
)

W = "campaign demo, case"


def check(campaign, baseline, cases, quarantine, stage, case, column, row, reason):
    """Exactly one quarantine row with this reason; the rest unchanged."""
    assert_quarantine(campaign, cases, quarantine, [(CAMPAIGN, case, stage, column, row)])
    assert quarantine["reason"].tolist() == [reason]
    assert cases.set_index("case").loc[case, "quality"] == "quarantined"
    assert_rest_unchanged(campaign, cases, baseline, {case})


def test_zero_byte_file(raw_campaign, baseline):
    (raw_campaign.raw_dir / "T01.csv").write_bytes(b"")
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "T01", "file", None,
          f"{W} T01, key 'file': empty file (0 bytes)")


def test_comments_only_file(raw_campaign, baseline):
    (raw_campaign.raw_dir / "F01.csv").write_text("# rig: bench 2\n\n", encoding="utf-8")
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "F01", "file", None,
          f"{W} F01, key 'file': no header row")


def _cut_last_line(data: bytes) -> bytes:
    """The file cut off in the third field of its last row (no line end)."""
    body, last = data.rstrip(b"\n").rsplit(b"\n", 1)
    fields = last.split(b",")
    return body + b"\n" + b",".join(fields[:2]) + b"," + fields[2][:3]


def test_file_cut_off_mid_row(raw_campaign, baseline):
    """The cut row is left out (issue 34); T02's record, one sample short of its plan, still holds its four windows."""
    edit_bytes(raw_campaign, "T02", _cut_last_line)          # T02: temp_C,cmd_mm,force_kN,disp_mm,time_s
    cases, quarantine = raw_campaign.run()
    kept(raw_campaign, baseline, cases, quarantine, "T02", [399],
         "the last row (399) ends after 3 of 5 fields without a line end")
    assert "missing" not in cases.set_index("case").loc["T02", "quality"]


def kept(campaign, baseline, cases, quarantine, case, dropped: list[int], note: str) -> None:
    """A partial record (issue 34): no quarantine, the case's series is the undamaged one without ``dropped``, its
    quality holds ``note``; the rest unchanged."""
    assert quarantine.empty, quarantine["reason"].tolist()
    assert note in cases.set_index("case").loc[case, "quality"]
    series = pd.read_parquet(campaign.root / cases.set_index("case").loc[case, "timeseries_file"])
    expected = baseline[case].drop(index=dropped).reset_index(drop=True)
    if case == "H01" and 0 in dropped:              # the record starts at its first kept row: time from there
        expected = expected.assign(time_s=expected["time_s"] - expected["time_s"].iloc[0])
    pd.testing.assert_frame_equal(series.drop(columns="time_s"), expected.drop(columns="time_s"))
    assert_rest_unchanged(campaign, cases, baseline, {case})


def test_missing_final_line_end_is_flagged_not_quarantined(raw_campaign, baseline):
    edit_bytes(raw_campaign, "T01", lambda b: b.rstrip(b"\n"))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    assert cases.set_index("case").loc["T01", "quality"] == (
        "no line end after the last row (399): it may be cut off in its last value")
    pd.testing.assert_frame_equal(pd.read_parquet(raw_campaign.root / "ingest/timeseries/T01.parquet"),
                                  baseline["T01"])
    assert_rest_unchanged(raw_campaign, cases, baseline, {"T01"})


@pytest.mark.parametrize("case, edit, column, row, message", [
    ("T03", set_cell(40, "force_inv_kN", "-inf"), "force_inv_kN", 40, "non-finite value inf"),
], ids=["inf"])
def test_nan_inf_non_numeric(raw_campaign, baseline, case, edit, column, row, message):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", case, column, row,
          f"{W} {case}, column {column!r}, row {row}: {message}")


@pytest.mark.parametrize("case, edit, row", [
    ("T02", set_cell(23, "force_kN", "NaN"), 23),
    ("T02", set_cell(23, "force_kN", ""), 23),
    ("T01", set_cell(17, "disp_mm", "1.2.3"), 17),
], ids=["nan", "empty-cell", "non-numeric"])
def test_a_missing_or_unreadable_cell_leaves_out_its_row(raw_campaign, baseline, case, edit, row):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    kept(raw_campaign, baseline, cases, quarantine, case, [row],
         f"1 row(s) with a blank or unreadable cell left out (data rows {row}): a gap in the record")


def _backward(t):
    t.loc[120, "time_s"] = "1.1"
    return t


def test_a_repeated_time_stamp_leaves_out_its_row(raw_campaign, baseline):
    raw_campaign.edit_table("H01", set_cell(9, "time_s", "0.04"))
    cases, quarantine = raw_campaign.run()
    kept(raw_campaign, baseline, cases, quarantine, "H01", [9],
         "1 row(s) repeating the time stamp of the row before left out (data rows 9)")


@pytest.mark.parametrize("case, edit, row, message", [
    ("T02", _backward, 120, "time 1.1 s is not above the previous row's 1.19 s"),
], ids=["backward"])
def test_duplicate_or_backward_time(raw_campaign, baseline, case, edit, row, message):
    raw_campaign.edit_table(case, edit)
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", case, "time_s", row,
          f"{W} {case}, column 'time_s', row {row}: {message}")


def test_gap_inside_a_window(raw_campaign, baseline):
    raw_campaign.edit_table("T01", drop_rows(50, 53))       # t = 1.00 .. 1.04 s, window 1 is 0.9 .. 1.9 s
    cases, quarantine = raw_campaign.run()                  # 3 of its 51 samples: over the 5 % tolerated
    check(raw_campaign, baseline, cases, quarantine, "validate", "T01", "time_s", 50,
          f"{W} T01, column 'time_s', row 50: 3 of the 51 samples (5.9%) missing inside the window of segment 1 "
          "(t = 0.9 .. 1.9 s), more than the 5.0% tolerated (validation.max_missing_fraction)")


def test_long_gap_outside_the_windows_breaks_the_motion_fit(raw_campaign, baseline):
    raw_campaign.edit_table("T01", drop_rows(100, 116))     # 16 samples at t = 2.0 .. 2.3 s, between windows
    cases, quarantine = raw_campaign.run()                  # 6 of them in the line fit of half-period 2
    check(raw_campaign, baseline, cases, quarantine, "validate", "T01", "time_s", 100,
          f"{W} T01, column 'time_s', row 100: 6 of the 81 samples (7.4%) missing inside the motion fit of "
          "half-period 2 (t = 2.2 .. 3.8 s), more than the 5.0% tolerated (validation.max_missing_fraction)")


def test_few_samples_missing_outside_the_windows_is_flagged(raw_campaign, baseline):
    raw_campaign.edit_table("T01", drop_rows(100, 103))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    t01 = cases.set_index("case").loc["T01"]
    assert (t01["status"], t01["quality"]) == ("ok", "3 sample(s) missing in 1 gap(s), 0.75% of the record; longest "
                                                     "gap 0.08 s at t = 1.98 s; at most 0.0% of an analysed span "
                                                     "(tolerance 5.0%)")
    assert (t01["missing_samples"], t01["missing_fraction"], t01["longest_gap_s"]) == (3, 0.0075, pytest.approx(0.08))
    series = pd.read_parquet(raw_campaign.root / t01["timeseries_file"])
    expected = baseline["T01"].drop(index=range(100, 103)).reset_index(drop=True)
    expected["row"] = range(len(expected))
    pd.testing.assert_frame_equal(series, expected)
    assert_rest_unchanged(raw_campaign, cases, baseline, {"T01"})


def test_semicolon_delimiter_with_decimal_commas(raw_campaign, baseline):
    def to_semicolons(data: bytes) -> bytes:
        lines = data.split(b"\n")
        body = [line.replace(b",", b";").replace(b".", b",") if not line.startswith(b"#") else line
                for line in lines]
        return b"\n".join(body)
    edit_bytes(raw_campaign, "T03", to_semicolons)
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "T03", "file", None,
          f"{W} T03, key 'file': fields are separated by ';', not ',' (header "
          "'time_s;disp_mm;force_inv_kN;cmd_mm;temp_C'): the format needs ',' between fields and '.' "
          "as the decimal mark")


def test_unquoted_decimal_comma(raw_campaign, baseline):
    def comma(data: bytes) -> bytes:
        lines = data.split(b"\n")
        i = data_line(data, 5)
        fields = lines[i].split(b",")                       # time_s,disp_mm,force_kN,cmd_mm,temp_C
        fields[2] = fields[2].replace(b".", b",")
        lines[i] = b",".join(fields)
        return b"\n".join(lines)
    raw = (raw_campaign.raw_dir / "H01.csv").read_bytes().split(b"\n")[data_line(b"", 5)].split(b",")[2]
    edit_bytes(raw_campaign, "H01", comma)
    cases, quarantine = raw_campaign.run()
    shown = raw.decode().replace(".", ",")
    check(raw_campaign, baseline, cases, quarantine, "ingest", "H01", "force_kN", 5,
          f"{W} H01, column 'force_kN', row 5: decimal comma in '{shown}' (row has 6 fields, the header 5): "
          "the format needs ',' between fields and '.' as the decimal mark")


def test_quoted_decimal_comma(raw_campaign, baseline):
    raw_campaign.edit_table("H01", set_cell(0, "time_s", "0,0"))    # written quoted: one field
    cases, quarantine = raw_campaign.run()
    kept(raw_campaign, baseline, cases, quarantine, "H01", [0], "1 row(s) with a blank or unreadable cell left out "
                                                                 "(data rows 0)")


def test_utf8_byte_order_mark_is_stripped(raw_campaign, baseline):
    edit_bytes(raw_campaign, "F01", lambda b: codecs.BOM_UTF8 + b)
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    assert_rest_unchanged(raw_campaign, cases, baseline, set())     # F01 too


def test_non_utf8_bytes(raw_campaign, baseline):
    def latin1(data: bytes) -> bytes:
        lines = data.split(b"\n")
        i = data_line(data, 30)
        fields = lines[i].split(b",")                       # T02: temp_C,cmd_mm,force_kN,disp_mm,time_s
        fields[2] += b"\xb5"
        lines[i] = b",".join(fields)
        return b"\n".join(lines)
    field = (raw_campaign.raw_dir / "T02.csv").read_bytes().split(b"\n")[data_line(b"", 30)].split(b",")[2]
    field += b"\xb5"
    edit_bytes(raw_campaign, "T02", latin1)
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "T02", "force_kN", 30,
          f"{W} T02, column 'force_kN', row 30: not UTF-8: byte 0xb5 in {field!r}: set `encoding:` in the "
          "manifest's csv block (for example cp1252)")


def test_utf16_file(raw_campaign, baseline):
    edit_bytes(raw_campaign, "F01", lambda b: b.decode().encode("utf-16"))
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "F01", "file", None,
          f"{W} F01, key 'file': UTF-16 byte-order mark: the file is UTF-16, the format needs UTF-8 "
          "(or set `encoding: utf-16` in the manifest's csv block)")


@pytest.mark.parametrize("edit, column, header", [
    (lambda t: t.drop(columns="disp_mm"), "disp_mm", "time_s, force_kN, cmd_mm, temp_C"),
    (lambda t: t.rename(columns={"force_kN": "Force_kN"}), "force_kN", "time_s, disp_mm, Force_kN, cmd_mm, temp_C"),
], ids=["missing", "renamed"])
def test_missing_or_renamed_channel(raw_campaign, baseline, edit, column, header):
    raw_campaign.edit_table("T01", edit)
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "ingest", "T01", column, None,
          f"{W} T01, column {column!r}: column not in the file (header: {header})")


def test_force_in_newton_declared_as_kilonewton(raw_campaign, baseline):
    raw_campaign.edit_table("T01", scale_column("force_kN", 1000.0))
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, "T01", "validate", "force_N", 0)])
    check(raw_campaign, baseline, cases, quarantine, "validate", "T01", "force_N", 0,
          f"{W} T01, column 'force_N', row 0: median |force| 2.699e+05 N is 117 x the nominal model's 2314 N "
          "at the planned 0.3 mm/s (Eq. 31) and above the physical limit 2e+05 N (piston area x 50 MPa): "
          "implausibly large, a unit mix-up (e.g. values in N declared as kN)?")


def test_displacement_in_micrometre_declared_as_millimetre(raw_campaign, baseline):
    raw_campaign.edit_table("T03", scale_column("disp_mm", 1000.0))
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T03", "displacement_m", 0,
          f"{W} T03, column 'displacement_m', row 0: amplitude 200.7 mm is 1003 x the planned 0.2 mm: implausibly "
          "large, a unit mix-up (e.g. values in um declared as mm, or in mm declared as m)?")


def _clip(rows, value):
    def edit(t):
        t.loc[list(rows), "force_kN"] = value
        return t
    return edit


def test_saturated_load_cell_inside_a_window(raw_campaign, baseline):
    raw_campaign.edit_table("T02", _clip(range(60, 75), "0.6"))     # window 1: t = 0.45 .. 0.95 s
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T02", "force_N", 60,
          f"{W} T02, column 'force_N', row 60: saturated: 15 consecutive samples at the maximum 600 N "
          "(t = 0.6 .. 0.74 s), inside the window of segment 1 (t = 0.45 .. 0.95 s)")


def test_saturated_lvdt_inside_a_window(raw_campaign, baseline):
    def clip(t):                                                    # LVDT range ends at +0.15 mm
        t["disp_mm"] = t["disp_mm"].astype(float).clip(upper=0.15).map("{:.10g}".format)
        return t
    raw_campaign.edit_table("T03", clip)                            # window 1: t = 0.9 .. 1.9 s, 50 Hz
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T03", "displacement_m", 88,
          f"{W} T03, column 'displacement_m', row 88: saturated: 25 consecutive samples at the maximum "
          "0.00015 m (t = 1.76 .. 2.24 s), inside the window of segment 1 (t = 0.9 .. 1.9 s)")


def test_flat_top_outside_the_windows_is_flagged(raw_campaign, baseline):
    raw_campaign.edit_table("T02", _clip(range(100, 112), "-0.6"))  # t = 1.00 .. 1.11 s, before window 3
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    assert cases.set_index("case").loc["T02", "quality"] == (
        "force_N saturated: 12 consecutive samples at the minimum -600 N (t = 1 .. 1.11 s), outside windows")
    assert_rest_unchanged(raw_campaign, cases, baseline, {"T02"})


def test_record_shorter_than_the_plan_keeps_its_complete_windows(raw_campaign, baseline):
    raw_campaign.edit_table("T02", lambda t: t.iloc[:300])
    cases, quarantine = raw_campaign.run()
    kept(raw_campaign, baseline, cases, quarantine, "T02", list(range(300, 400)),
         "record ends at 2.99 s, before the plan's 4 s: window 4 missing")


def test_record_that_ends_before_its_second_half_periods_middle_is_set_aside(raw_campaign, baseline):
    raw_campaign.edit_table("T02", lambda t: t.iloc[:130])       # window 1 complete, the motion start uncertain
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T02", "time_s", None,
          f"{W} T02, column 'time_s': record ends at 1.29 s, before the middle of its second half-period (1.5 s "
          "after the motion start in the plan): the motion start, on which the windows are placed, needs the line "
          "of a rising and of a falling half-period (at least the first window and the middle of the second "
          "half-period)")


def test_sample_rate_far_from_the_manifest(raw_campaign, baseline):
    raw_campaign.edit_manifest(lambda m: raw_campaign.case_entry(m, "H01").update(sample_rate_Hz=250.0))
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "H01", "time_s", None,
          f"{W} H01, column 'time_s': sample interval 0.005 s is +25.0% off 1/sample_rate_Hz = "
          "0.004 s (tolerance 5.0%)")


# --- timing from the record: the measured motion against the plan ---------------------------------

def delay_rows(rows: int):
    """A table edit: displacement and force ``rows`` samples later on the same time axis (the piston
    held at its start before), as an actuator delay gives them; the command stays as it was."""
    def edit(t: pd.DataFrame) -> pd.DataFrame:
        for column in ("disp_mm", "force_kN"):
            values = t[column].tolist()
            t[column] = values[:1] * rows + values[:-rows]
        return t
    return edit


def test_force_with_the_opposite_sign_convention(raw_campaign, baseline):
    raw_campaign.edit_table("T02", scale_column("force_kN", -1.0))     # a forgotten `invert: true`
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T02", "force_N", 45,
          f"{W} T02, column 'force_N', row 45: the mean force opposes the measured velocity in all four windows "
          "(-550.6 N at +1 mm/s, +551.3 N at -0.9995 mm/s, -549.6 N at +1.002 mm/s, +549.7 N at -0.9993 mm/s): "
          "the rig's sign convention looks opposite: add `invert: true` to the manifest's `force` column")


def test_displacement_with_the_opposite_sign_convention(raw_campaign, baseline):
    raw_campaign.edit_table("T01", scale_column("disp_mm", -1.0))
    cases, quarantine = raw_campaign.run()
    # the force is right: it is not blamed for the inverted velocity
    check(raw_campaign, baseline, cases, quarantine, "validate", "T01", "displacement_m", None,
          f"{W} T01, column 'displacement_m': the displacement moves against the plan in every half-period "
          "(measured -0.3002, +0.3, -0.3, +0.3001 mm/s, planned +0.3, -0.3, +0.3, -0.3 mm/s): the rig's sign "
          "convention looks opposite: add `invert: true` to the manifest's `displacement` column")


def test_piston_speed_20_percent_off_the_plan(raw_campaign, baseline):
    raw_campaign.edit_table("T01", scale_column("disp_mm", 1.2))
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "validate", "T01", "displacement_m", None,
          f"{W} T01, column 'displacement_m': measured piston speed 0.3601 mm/s (mean |v| of the half-periods: "
          "+0.3603, -0.36, +0.3601, -0.3601 mm/s) is +20.0% off the planned 4Y/T = 0.3 mm/s (Eq. 26; tolerance "
          "5%): a wrong period_s or amplitude in the manifest, or a wrong LVDT scale?")


def test_delay_too_large_for_the_last_window_keeps_the_first_three(raw_campaign, baseline):
    raw_campaign.edit_table("T01", delay_rows(10))          # 0.2 s at 50 Hz; window 4 would end at 8.1 s
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    assert "record ends at 7.98 s, before the plan's 8.19995 s: window 4 missing" in \
        cases.set_index("case").loc["T01", "quality"]
    assert_rest_unchanged(raw_campaign, cases, baseline, {"T01"})
