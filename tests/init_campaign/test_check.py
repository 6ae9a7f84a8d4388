"""``init-campaign --check``: a folder against its manifest, case by case; exit status 1 on any disagreement."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.__main__ import main
from isokinetic.init_campaign.check import check_folder


def edit_manifest(folder: Path, edit) -> None:
    path = folder / "campaign.yaml"
    manifest = yaml.safe_load(path.read_text(encoding="utf-8"))
    edit(manifest)
    path.write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")


def case(manifest: dict, case_id: str) -> dict:
    return next(c for c in manifest["cases"] if c["id"] == case_id)


def findings(folder: Path) -> dict[str, list[str]]:
    checks, _ = check_folder(folder)
    return {c.case: [f.key for f in c.findings] for c in checks}


def test_check_agrees_with_the_exported_campaign(campaign_copy, capsys):
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 0
    out = capsys.readouterr().out
    assert "T16 (T16.csv): agrees: triangle, period 20 s, amplitude 1.22 mm, 100 Hz" in out
    assert "H01 (H01.csv): agrees: sine, 1.75 Hz, amplitude 0.23 mm, 1000 Hz" in out
    assert "3 of 3 cases agree" in out


def test_check_refuses_a_load_cell_calibration_outside_its_range_naming_campaign_and_key(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: m["columns"]["force"].update(calibration={"gain": 1.2,
                                                                                     "uncertainty_rel": 0.001}))
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    err = capsys.readouterr().err
    assert f"{campaign_copy / 'campaign.yaml'}: key 'columns.force.calibration.gain': " in err


def test_check_refuses_an_lvdt_calibration_outside_its_range_naming_campaign_and_key(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: m["columns"]["displacement"].update(calibration={"scale": 0.8,
                                                                                            "uncertainty_rel": 0.001}))
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    err = capsys.readouterr().err
    assert f"{campaign_copy / 'campaign.yaml'}: key 'columns.displacement.calibration.scale': " in err


def test_check_reports_a_wrong_period(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: case(m, "T16").update(period_s=20.1))
    assert findings(campaign_copy) == {"T16": ["period_s"], "T22": [], "H01": []}
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    assert "  period_s: planned 20.1, detected 20 ± " in capsys.readouterr().out


def test_check_reports_a_unit_the_magnitudes_contradict(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: m["columns"]["force"].update(unit="N"))
    assert findings(campaign_copy) == {"T16": ["columns.force"], "T22": ["columns.force"], "H01": ["columns.force"]}
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    assert "columns.force: declared 'force_kN' in N, detected magnitudes that look like kN" in capsys.readouterr().out


def test_check_reports_a_displacement_declared_in_m_that_looks_like_mm(campaign_copy):
    edit_manifest(campaign_copy, lambda m: m["columns"]["displacement"].update(unit="m"))
    assert all("columns.displacement" in keys for keys in findings(campaign_copy).values())


def test_check_reports_a_wrong_waveform_amplitude_and_sample_rate(campaign_copy):
    def edit(m):
        h01 = case(m, "H01")
        h01.update(waveform="triangle", period_s=0.5714)
        del h01["frequency_Hz"]
        case(m, "T22").update(amplitude_mm=6.0)
        m["sample_rate_Hz"] = 50.0
    edit_manifest(campaign_copy, edit)
    assert findings(campaign_copy) == {"T16": ["sample_rate_Hz"], "T22": ["sample_rate_Hz", "amplitude_mm"],
                                       "H01": ["waveform"]}


def test_check_reports_a_file_ingest_would_refuse(campaign_copy):
    (campaign_copy / "T22.csv").write_text("time_s;disp_mm\n0;1\n", encoding="utf-8")
    assert findings(campaign_copy)["T22"] == ["file"]


def test_check_piped_into_a_reader_that_stops_early_ends_quietly(campaign_copy):
    # `init-campaign FOLDER --check | head -1`: the read end is closed before the command prints
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run([sys.executable, "-m", "isokinetic", "init-campaign", str(campaign_copy), "--check"],
                              stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 1


def test_check_reports_columns_other_than_the_role_choice_takes(campaign_copy):
    def swap(m):
        m["columns"]["displacement"], m["columns"]["command"] = m["columns"]["command"], m["columns"]["displacement"]
    edit_manifest(campaign_copy, swap)
    for keys in findings(campaign_copy).values():
        assert {"columns.displacement", "columns.command"} <= set(keys)


# --- issue 34: what spreadsheets and loggers write -----------------------------------------------------------

def _rewritten(exported: Path, out: Path, layout, edit=None) -> Path:
    """The exported campaign's files in ``layout``, each file's bytes then passed through ``edit``."""
    from .layouts import rewrite_campaign

    folder = rewrite_campaign(exported, out, layout)
    for path in folder.glob("*.csv"):
        path.write_bytes(edit(path.read_bytes()) if edit is not None else path.read_bytes())
    return folder


def _draft_then_check(folder: Path, capsys) -> str:
    from isokinetic.init_campaign.draft import write_draft

    write_draft(folder)
    assert main(["init-campaign", "--check", str(folder)]) == 0, capsys.readouterr().out
    return capsys.readouterr().out


def test_check_of_its_own_decimal_comma_draft_agrees(exported, tmp_path, capsys):
    """Before: AttributeError "Can only use .str accessor with string values!" on every decimal-comma campaign."""
    from .layouts import LAYOUTS

    layout = next(x for x in LAYOUTS if x.decimal == ",")
    out = _draft_then_check(_rewritten(exported, tmp_path / "raw" / "lag", layout), capsys)
    assert "3 of 3 cases agree" in out


@pytest.mark.parametrize("edit", [lambda b: b.replace(b"\n", b"\r"),
                                  lambda b: b"sep=;\r\n" + b.replace(b"\n", b"\r\n")], ids=["lone-cr", "excel-sep"])
def test_draft_and_check_read_lone_cr_files_and_an_excel_sep_line(exported, tmp_path, capsys, edit):
    """Before: a _csv.Error traceback (lone CRs); a refusal citing a manifest that did not exist yet (sep=;)."""
    from .layouts import LAYOUTS

    layout = next(x for x in LAYOUTS if x.delimiter == ";")
    out = _draft_then_check(_rewritten(exported, tmp_path / "raw" / "lag", layout, edit), capsys)
    assert "3 of 3 cases agree" in out


def _with_time(folder: Path, cells) -> None:
    """Every case file's time column (the first) rewritten by ``cells(seconds) -> list of text``."""
    for path in folder.glob("*.csv"):
        lines = path.read_text(encoding="utf-8").split("\n")
        seconds = np.array([float(line.split(",")[0]) for line in lines[1:] if line])
        new = cells(seconds)
        path.write_text("\n".join([lines[0]] + [",".join([c] + line.split(",")[1:])
                                                for c, line in zip(new, lines[1:])]) + "\n", encoding="utf-8")


@pytest.mark.parametrize("cells, unit", [
    (lambda s: [(pd.Timestamp("2024-05-01T10:00:00") + pd.Timedelta(seconds=x)).strftime("%H:%M:%S.%f")
                for x in s], "hms"),
    (lambda s: [f"{45413.5 + x / 86400.0:.12f}" for x in s], "excel_serial"),
], ids=["hms", "excel-serial"])
def test_clock_times_and_excel_serial_dates_are_drafted_as_time(exported, tmp_path, capsys, cells, unit):
    """Before: "does not increase from row to row" (HH:MM:SS.fff) and "no plausible unit" (Excel serial dates)."""
    from isokinetic.contracts.manifest import load_manifest

    from .layouts import LAYOUTS

    folder = _rewritten(exported, tmp_path / "raw" / "lag", LAYOUTS[0])
    _with_time(folder, cells)
    out = _draft_then_check(folder, capsys)
    assert load_manifest(folder / "campaign.yaml").columns["time"].unit == unit
    assert "3 of 3 cases agree" in out


def test_local_stamps_across_a_fall_back_are_not_drafted_as_sure(exported, tmp_path):
    """Before: sample_rate_Hz: -1.1, "sure", every case free. Now the file is not a case, its reason names the
    jump and the key to set."""
    from isokinetic.init_campaign.draft import write_draft

    from .layouts import LAYOUTS

    folder = _rewritten(exported, tmp_path / "raw" / "lag", LAYOUTS[0])
    utc = pd.Timestamp("2024-10-27T00:59:58Z")        # every record crosses 03:00 CEST -> 02:00 CET
    _with_time(folder, lambda s: [(utc + pd.Timedelta(seconds=x)).tz_convert("Europe/Berlin").tz_localize(None)
                                  .isoformat(timespec="microseconds") for x in s])
    with pytest.raises(ValueError) as info:
        write_draft(folder)
    assert "a daylight-saving fall-back" in str(info.value) and "timezone: Europe/Berlin" in str(info.value)


def _force_in_grouped_N(data: bytes) -> bytes:
    """A ';' and ',' file's force column (the third, in kN) rewritten in N with '.' between thousands."""
    lines = data.decode("utf-8").split("\n")
    k = next(i for i, line in enumerate(lines) if line.startswith("Zeit"))
    lines[k] = lines[k].replace("Kraft [kN]", "Kraft [N]")
    for i in range(k + 1, len(lines)):
        if lines[i]:
            fields = lines[i].split(";")
            newton = float(fields[2].replace(",", ".")) * 1e3
            fields[2] = f"{newton:,.6f}".replace(",", "_").replace(".", ",").replace("_", ".")
            lines[i] = ";".join(fields)
    return "\n".join(lines).encode("utf-8")


def test_thousands_separators_are_drafted_and_checked(exported, tmp_path, capsys):
    """``1.234,567890`` N: before, "no force column found" (the grouped cells were no numbers)."""
    from isokinetic.contracts.manifest import load_manifest

    from .layouts import LAYOUTS

    layout = next(x for x in LAYOUTS if x.decimal == ",")
    folder = _rewritten(exported, tmp_path / "raw" / "lag", layout, _force_in_grouped_N)
    assert any("." in line.split(";")[2] for line in (folder / "T22.csv").read_text(encoding="utf-8").split("\n")[2:]
               if line)
    out = _draft_then_check(folder, capsys)
    assert load_manifest(folder / "campaign.yaml").columns["force"].unit == "N"
    assert "3 of 3 cases agree" in out


def _damaged(data: bytes) -> bytes:
    """A blank force cell (data row 499), a blank time cell (899), a row written twice (1199, 1200) and the last
    value cut short (no line end)."""
    lines = data.decode("utf-8").rstrip("\n").split("\n")
    for line_no, field_no in ((500, 2), (900, 0)):
        fields = lines[line_no].split(",")
        fields[field_no] = ""
        lines[line_no] = ",".join(fields)
    lines.insert(1200, lines[1200])
    text = "\n".join(lines)
    return text[:text.rfind(",") + 2].encode("utf-8")


def test_a_partial_record_is_drafted_and_checked_as_ingest_reads_it(exported, tmp_path, capsys):
    """Before: "no time column found (column 'time_s' ... does not increase from row to row)", nothing drafted,
    for files the build keeps."""
    from isokinetic.init_campaign.draft import write_draft

    from .layouts import LAYOUTS

    folder = _rewritten(exported, tmp_path / "raw" / "lag", LAYOUTS[0], _damaged)
    _, survey = write_draft(folder)
    assert all(f.ok for f in survey.files)
    assert all("3 row(s) with a missing or unreadable value or a repeated time stamp left out (data rows 499, 899, "
               "1200), as ingest does" in f.warnings for f in survey.files)
    assert main(["init-campaign", "--check", str(folder)]) == 0, capsys.readouterr().out


def test_a_velocity_declared_as_the_displacement_is_named_a_velocity_not_an_invert(campaign_copy, capsys):
    """Before: "a force opposing the velocity in all 9 cycles: `invert` is wrong" (the sine case)."""
    for path in campaign_copy.glob("*.csv"):
        table = pd.read_csv(path)
        table["disp_mm"] = np.gradient(table["cmd_mm"].to_numpy(), table["time_s"].to_numpy())
        table.to_csv(path, index=False)
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    out = capsys.readouterr().out
    assert out.count("detected a column that equals the derivative of the command") == 3
    assert out.count("a velocity, not a displacement (`invert` would not fix it)") == 3
    assert "`invert` is wrong" not in out
