"""Columns are never silently wrong: volts give way to their scaled twins (and `--check` fails on a manifest that
names them), competing columns are only a guess, a force opposing the velocity in every cycle is drafted
inverted, an implausible temperature is not used."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.__main__ import main
from isokinetic.contracts.manifest import load_manifest
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign.check import check_folder
from isokinetic.init_campaign.draft import write_draft
from isokinetic.stages.ingest import ingest_campaign

from .records import sine_record, write_table

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rigfiles import CRANK_VOLTS, write_crank_folder  # noqa: E402

SCALED = {"displacement": "Displacement (mm)", "force": "Force (N)", "temperature": "Temperature (C)"}


@pytest.mark.parametrize("name, unit_text, volts", [
    ("Force (V)", None, True), ("disp_V", None, True), ("Load [mV]", None, True), ("LVDT volts", None, True),
    ("Axial Force", "V", True), ("Force (N)", None, False), ("x_mm", None, False), ("Velocity", None, False),
    ("Axial Force", "lbf", False)])
def test_a_name_or_units_row_saying_volts_is_recognised(name, unit_text, volts):
    assert ch.says_volts(name, unit_text) is volts


@pytest.fixture(scope="module")
def crank(tmp_path_factory) -> Path:
    """A crank dyno's folder of 300 Hz CSVs, each channel in volts and scaled (tests/rigfiles.py)."""
    folder = tmp_path_factory.mktemp("crank") / "crank"
    write_crank_folder(folder, frequencies_Hz=(1.0, 2.0), cycles=4)
    return folder


def campaign_copy(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    for p in src.glob("*.csv"):
        (dst / p.name).write_bytes(p.read_bytes())
    return dst


def test_scaled_twins_are_taken_and_volts_left_out(crank, tmp_path):
    folder = campaign_copy(crank, tmp_path / "crank")
    path, survey = write_draft(folder)
    manifest = load_manifest(path)
    for case in manifest.cases:
        assert {c: case.columns[c].name for c in SCALED} == SCALED
        assert "command" not in case.columns
        assert not case.columns["force"].invert
    text = path.read_text(encoding="utf-8")
    for channel, name in SCALED.items():
        volts = name.split(" (")[0] + " (V)"
        assert re.search(rf"^  {channel}: \{{name: {re.escape(name)},.*'{re.escape(volts)}' in volts, not taken, sure$",
                         text, flags=re.M)
    assert main(["init-campaign", "--check", str(folder)]) == 0


def test_check_fails_on_a_manifest_naming_the_volts_columns(crank, tmp_path, capsys):
    folder = campaign_copy(crank, tmp_path / "crank")
    path, _ = write_draft(folder)
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    doc["columns"].update(force={"name": "Force (V)", "unit": "kN"}, displacement={"name": "Displacement (V)",
                          "unit": "mm"}, temperature={"name": "Temperature (V)", "unit": "C"})
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    checks, _ = check_folder(folder)
    for c in checks:
        keys = [f.key for f in c.findings]
        assert {"columns.force", "columns.displacement", "columns.temperature"} <= set(keys)
    assert main(["init-campaign", "--check", str(folder)]) == 1
    out = capsys.readouterr().out
    assert "declared 'Force (V)' in kN, detected a column in volts, not in kN (its scaled twin 'Force (N)'" in out


def test_a_volts_column_without_a_scaled_twin_takes_no_role(tmp_path):
    rec = sine_record(2.0, 0.01, 6, 500.0)
    gain, offset = CRANK_VOLTS["Force"][1], CRANK_VOLTS["Force"][0]
    write_table(tmp_path / "c" / "run.csv", {"time_s": rec["time_s"], "disp_mm": rec["displacement_m"] * 1e3,
                                            "Force (V)": offset + rec["force_N"] / gain})
    with pytest.raises(ValueError, match=r"'Force \(V\)' is in volts and has no scaled twin: not taken as the force"):
        write_draft(tmp_path / "c")


def test_competing_columns_make_the_role_a_guess_naming_them(tmp_path):
    rec = sine_record(2.0, 0.01, 6, 500.0)
    write_table(tmp_path / "c" / "run.csv", {"time_s": rec["time_s"], "disp_mm": rec["displacement_m"] * 1e3,
                                            "force_N": rec["force_N"], "load_kN": rec["force_N"] * 1e-3})
    path, survey = write_draft(tmp_path / "c")
    assert survey.columns["force"].sure == "guess" and survey.columns["displacement"].sure == "sure"
    assert re.search(r"^  force: \{name: force_N, unit: N\} .*CHECK: 'load_kN' also named like a force.*, guess$",
                     path.read_text(encoding="utf-8"), flags=re.M)


def test_a_force_opposing_the_velocity_in_every_cycle_is_drafted_inverted(tmp_path):
    rec = sine_record(1.5, 0.02, 6, 400.0)
    folder = tmp_path / "raw" / "c"
    write_table(folder / "run.csv", {"time_s": rec["time_s"], "disp_mm": rec["displacement_m"] * 1e3,
                                     "force_N": -rec["force_N"]})
    path, _ = write_draft(folder)
    text = path.read_text(encoding="utf-8")
    assert re.search(r"^  # force inverted: the force opposes the displacement's velocity in all \d+ cycles", text,
                     flags=re.M)
    assert re.search(r"^  force: \{name: force_N, unit: N, invert: true\}", text, flags=re.M)
    ingest_campaign(folder, tmp_path / "out" / "c")
    series = pd.read_parquet(tmp_path / "out" / "c" / "ingest" / "timeseries" / "run.parquet")
    truth = np.interp(series["time_s"], rec["time_s"], rec["force_N"])
    np.testing.assert_allclose(series["force_N"], truth, atol=1e-6)           # the rig's sign, not flipped
    assert main(["init-campaign", "--check", str(folder)]) == 0
    path.write_text(text.replace(", invert: true}", "}"), encoding="utf-8")
    checks, _ = check_folder(folder)
    assert [f.key for f in checks[0].findings] == ["columns.force"]
    assert "opposing the velocity in all" in checks[0].findings[0].detected


def test_a_temperature_implausible_for_oil_is_not_used(tmp_path):
    rec = sine_record(2.0, 0.01, 6, 500.0)
    write_table(tmp_path / "c" / "run.csv", {"time_s": rec["time_s"], "disp_mm": rec["displacement_m"] * 1e3,
                                            "force_N": rec["force_N"], "oil_C": np.full(rec["time_s"].size, 480.0)})
    path, survey = write_draft(tmp_path / "c")
    assert "temperature" not in survey.columns
    assert "temperature" not in load_manifest(path).cases[0].columns
    assert "REFUSED: column 'oil_C' read as a temperature gives a median of 480 C, not plausible for oil" in \
        path.read_text(encoding="utf-8")
