"""The drafted manifest: it reproduces the original characteristic on every layout a rig might write, comments
every guessed value, leaves the damper block to fill in, and writes nothing but ``campaign.yaml``."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from isokinetic.__main__ import main
from isokinetic.contracts.manifest import CsvDialect, load_manifest
from isokinetic.init_campaign.draft import write_draft
from isokinetic.physics.damper import Damper

from .conftest import CAMPAIGN, CASES, characteristic
from .layouts import LAYOUTS, Layout, rewrite_campaign

#: Characteristic columns that must be identical: the same windows on the same samples.
EXACT = ["case", "segment", "direction", "period", "n_samples", "row_start", "row_stop", "window_start_s",
         "window_end_s", "planned_velocity_m_s", "repeatability_flagged"]
#: Columns computed from the rewritten values: equal to float rounding. A value written in m and read x 1 and
#: the same value written in mm and read x 1e-3 differ in the last bit (seen: 5e-16 relative), so 1e-12.
ROUNDED = ["velocity_m_s", "force_N", "force_std_N"]
RTOL = 1e-12
#: Lines of the draft that carry a guessed value, by key.
GUESSED = ("sample_rate_Hz:", "csv:", "time:", "displacement:", "force:", "command:", "temperature:", "waveform:",
           "period_s:", "amplitude_mm:", "phase_rad:", "frequency_Hz:")


def assert_same_characteristic(got: pd.DataFrame, reference: pd.DataFrame) -> None:
    """The same windows on the same samples (a triangle window's columns exactly; the time stamps of other
    methods' points, computed from the rewritten time column, to float rounding) and the same values."""
    assert len(got) == len(reference) and (reference["method"] == "triangle_window").sum() == 8
    tri = (reference["method"] == "triangle_window").to_numpy()
    pd.testing.assert_frame_equal(got[EXACT][tri], reference[EXACT][tri], check_exact=True)
    times = ["window_start_s", "window_end_s"]
    exact = [c for c in EXACT if c not in times]
    pd.testing.assert_frame_equal(got[exact], reference[exact], check_exact=True)
    pd.testing.assert_frame_equal(got[times], reference[times], check_exact=False, rtol=RTOL, atol=0.0)
    pd.testing.assert_frame_equal(got[ROUNDED][tri], reference[ROUNDED][tri], check_exact=False, rtol=RTOL, atol=0.0)
    # a sine's cycle-to-cycle scatter is a difference of nearly equal values: float rounding grows to ~1e-11
    pd.testing.assert_frame_equal(got[ROUNDED][~tri], reference[ROUNDED][~tri], check_exact=False, rtol=1e-9,
                                  atol=0.0)


def assert_guesses_commented(text: str) -> int:
    """Every line of a draft that holds a guessed value ends in a comment saying how sure; returns their count."""
    guessed = [line for line in text.splitlines() if line.strip().startswith(GUESSED)]
    for line in guessed:
        assert re.search(r" # .+\b(sure|likely|guess)$", line), line
    return len(guessed)


def tree(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (symlinks not followed) and its bytes."""
    return {p.relative_to(folder).as_posix(): (p.read_bytes() if p.is_file() and not p.is_symlink() else b"")
            for p in sorted(folder.rglob("*"))}


@pytest.mark.parametrize("layout", LAYOUTS, ids=[layout.name for layout in LAYOUTS])
def test_drafted_manifest_reproduces_the_characteristic(exported, reference, tmp_path, layout: Layout):
    folder = rewrite_campaign(exported, tmp_path / "raw" / CAMPAIGN, layout)
    path, _ = write_draft(folder)
    manifest = load_manifest(path)
    assert [c.id for c in manifest.cases] == sorted(CASES)
    dialect = CsvDialect(delimiter=layout.delimiter, decimal=layout.decimal)
    assert manifest.csv == (None if dialect == CsvDialect() else dialect)
    assert_same_characteristic(characteristic(folder, tmp_path / "results" / CAMPAIGN), reference)


def test_files_of_mixed_layouts_get_their_own_columns(exported, reference, tmp_path):
    layouts = {"T16": LAYOUTS[0], "T22": LAYOUTS[1], "H01": LAYOUTS[2]}   # the campaign's columns are T16's
    folder = rewrite_campaign(exported, tmp_path / "raw" / CAMPAIGN, layouts)
    path, _ = write_draft(folder)
    assert_guesses_commented(path.read_text(encoding="utf-8"))
    cases = {c.id: c for c in load_manifest(path).cases}
    assert set(cases["T22"].columns) == {"time", "displacement", "force"}           # no command: `command: null`
    assert (cases["T22"].columns["force"].name, cases["T22"].columns["force"].unit) == ("F[N]", "N")
    assert cases["H01"].columns["command"].unit == "um"
    assert_same_characteristic(characteristic(folder, tmp_path / "results" / CAMPAIGN), reference)


def test_draft_reads_the_plan_of_every_case(exported, tmp_path):
    folder = rewrite_campaign(exported, tmp_path / CAMPAIGN, LAYOUTS[0])
    drafted = {c.id: c.plan for c in load_manifest(write_draft(folder)[0]).cases}
    for case in load_manifest(exported / "campaign.yaml").cases:
        plan = drafted[case.id]
        assert (plan.waveform, plan.sample_rate_Hz, plan.amplitude_m) == (case.waveform, case.plan.sample_rate_Hz,
                                                                          case.plan.amplitude_m)
        np.testing.assert_equal([plan.period_s, plan.frequency_Hz, plan.phase_rad],
                                [case.plan.period_s, case.plan.frequency_Hz, case.plan.phase_rad])


@pytest.mark.parametrize("layout, how", [(LAYOUTS[1], "# from header 'x_m'"),
                                         (LAYOUTS[-1], "# column 'ch2' from magnitudes")], ids=["named", "unnamed"])
def test_draft_comments_every_guessed_value_with_how_sure(exported, tmp_path, layout, how):
    folder = rewrite_campaign(exported, tmp_path / CAMPAIGN, layout)
    text = write_draft(folder)[0].read_text(encoding="utf-8")
    assert assert_guesses_commented(text) >= 1 + len(layout.columns) + 3 * 3
    assert how in text


def test_damper_block_is_left_commented_out_with_every_key(exported, tmp_path):
    folder = rewrite_campaign(exported, tmp_path / CAMPAIGN, LAYOUTS[0])
    path = write_draft(folder)[0]
    text = path.read_text(encoding="utf-8")
    assert "\ndamper:" not in text and "# damper:" in text
    for key in Damper.__dataclass_fields__:
        assert f"#   {key}:" in text
    assert load_manifest(path).damper is None


def test_existing_manifest_is_not_overwritten_without_force(campaign_copy, capsys):
    before = (campaign_copy / "campaign.yaml").read_bytes()
    with pytest.raises(FileExistsError, match="--force"):
        write_draft(campaign_copy)
    assert main(["init-campaign", str(campaign_copy)]) == 1
    assert "exists: not overwritten (--force replaces it)" in capsys.readouterr().err
    assert (campaign_copy / "campaign.yaml").read_bytes() == before
    assert main(["init-campaign", str(campaign_copy), "--force"]) == 0
    assert (campaign_copy / "campaign.yaml").read_bytes() != before
    assert len(load_manifest(campaign_copy / "campaign.yaml").cases) == len(CASES)


def test_symlinked_manifest_is_not_written_through(campaign_copy, tmp_path):
    target = tmp_path / "elsewhere.yaml"
    target.write_text("kept\n", encoding="utf-8")
    (campaign_copy / "campaign.yaml").unlink()
    (campaign_copy / "campaign.yaml").symlink_to(target)
    with pytest.raises(FileExistsError, match="symlink"):
        write_draft(campaign_copy, force=True)
    assert target.read_text(encoding="utf-8") == "kept\n"


def test_unusable_files_are_listed_commented_out_with_their_reason(exported, tmp_path):
    root = tmp_path / "root"
    folder = root / CAMPAIGN
    folder.mkdir(parents=True)
    (folder / "T16.csv").write_bytes((exported / "T16.csv").read_bytes())
    (folder / "empty.csv").write_bytes(b"")
    (folder / "utf16.csv").write_bytes("time_s,disp_mm\n0,1\n".encode("utf-16"))
    (folder / "dup.csv").write_text("time_s,time_s,force_kN\n0,0,1\n", encoding="utf-8")
    (folder / "nodisp.csv").write_text("time_s,force_kN\n" + "".join(f"{i / 100},1\n" for i in range(50)),
                                       encoding="utf-8")
    (folder / "outside.csv").symlink_to(exported / "T22.csv")
    (root / "sibling.txt").write_text("untouched\n", encoding="utf-8")
    before = tree(root)
    path, survey = write_draft(folder)
    after = tree(root)
    assert set(after) - set(before) == {f"{CAMPAIGN}/campaign.yaml"}
    assert all(after[k] == v for k, v in before.items())
    reasons = {f.file: f.problem for f in survey.files if not f.ok}
    assert set(reasons) == {"empty.csv", "utf16.csv", "dup.csv", "nodisp.csv", "outside.csv"}
    assert "empty file" in reasons["empty.csv"]
    assert "only 1 samples" in reasons["utf16.csv"]          # read (its byte-order mark says UTF-16), too short
    assert "column name appears twice" in reasons["dup.csv"]
    assert "no displacement column" in reasons["nodisp.csv"]
    assert "outside the campaign folder" in reasons["outside.csv"]
    text = path.read_text(encoding="utf-8")
    for file, reason in reasons.items():
        assert f"#   file: {file}" in text and f"NOT A CASE: {reason}" in text
    assert [c.id for c in load_manifest(path).cases] == ["T16"]


def test_folder_without_a_usable_file_is_an_error_and_nothing_is_written(tmp_path, capsys):
    folder = tmp_path / CAMPAIGN
    folder.mkdir()
    (folder / "empty.csv").write_bytes(b"")
    assert main(["init-campaign", str(folder)]) == 1
    assert "no usable case file" in capsys.readouterr().err
    assert os.listdir(folder) == ["empty.csv"]


def test_a_folder_name_that_is_not_a_campaign_id_is_said_clearly(exported, tmp_path, capsys):
    folder = tmp_path / "Bench 2 #May"
    folder.mkdir()
    (folder / "T16.csv").write_bytes((exported / "T16.csv").read_bytes())
    assert main(["init-campaign", str(folder)]) == 0
    err = capsys.readouterr().err
    assert "'Bench 2 #May' is not a valid campaign id" in err and "rename the folder to 'bench-2-may'" in err
    text = (folder / "campaign.yaml").read_text(encoding="utf-8")
    assert "campaign: bench-2-may" in text and "# WARNING: the folder name 'Bench 2 #May'" in text


def test_a_temperature_column_is_drafted_as_the_temperature_channel(exported, tmp_path):
    folder = rewrite_campaign(exported, tmp_path / CAMPAIGN, LAYOUTS[2])
    text = write_draft(folder)[0].read_text(encoding="utf-8")
    assert re.search(r"^  temperature: \{name: oil_C, unit: degC\} +# from header 'oil_C'", text, flags=re.M)
    assert "# temperature_C: 40.0" in text


def test_help_explains_the_command_with_examples(capsys):
    with pytest.raises(SystemExit):
        main(["init-campaign", "--help"])
    out = capsys.readouterr().out
    assert "--force" in out and "--check" in out and "examples:" in out
    assert "init-campaign data/raw/bench2 --check" in out
