"""Surveying a folder: ids from the folder and file names, the campaign's dialect, roles from magnitudes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isokinetic.contracts.manifest import CASE_ID_PATTERN, CsvDialect
from isokinetic.init_campaign.sniff import ColumnData
from isokinetic.init_campaign.survey import (
    FileSurvey,
    assign_by_magnitude,
    assign_by_name,
    campaign_id,
    case_ids,
    choose_dialect,
)
from isokinetic.physics.plan import triangle_displacement


@pytest.mark.parametrize("folder, campaign, said", [("lag-damper", "lag-damper", False), ("Bench 2", "bench-2", True),
                                                    ("_x_Rig.May", "x_rig-may", True)])
def test_campaign_id_is_the_folder_name_or_says_why_not(tmp_path, folder, campaign, said):
    got, note = campaign_id(tmp_path / folder)
    assert got == campaign
    assert bool(note) == said and (not said or f"rename the folder to {campaign!r}" in note)


def test_case_ids_follow_the_case_id_rule_and_stay_unique():
    stems = ["T01", "run 1", "run_1", "-x", "é", "a" * 80, "a" * 80]
    ids = [case for case, _ in case_ids(stems)]
    assert ids[:5] == ["T01", "run_1", "run_1_2", "x", "case"]
    assert len(set(ids)) == len(ids) and all(CASE_ID_PATTERN.fullmatch(i) and len(i) <= 64 for i in ids)
    assert [bool(note) for _, note in case_ids(stems)][:3] == [False, True, True]


def test_files_in_another_dialect_than_most_are_set_aside():
    files = [FileSurvey(f"{i}.csv", str(i), dialect=CsvDialect(delimiter=";", decimal=",")) for i in range(2)]
    files.append(FileSurvey("odd.csv", "odd", dialect=CsvDialect()))
    dialect, how = choose_dialect(files)
    assert dialect == CsvDialect(delimiter=";", decimal=",") and "2 of 3 files" in how
    assert files[2].problem.startswith("written as ',' between fields") and files[0].ok


def survey_of(columns: dict[str, np.ndarray]) -> FileSurvey:
    survey = FileSurvey("a.csv", "a", data={n: ColumnData(n, v, None, 1.0) for n, v in columns.items()})
    assign_by_name(survey)
    assign_by_magnitude(survey)
    return survey


def test_unnamed_columns_get_their_roles_from_magnitudes():
    rng = np.random.default_rng(11)
    t = np.arange(4000) / 100.0
    command = triangle_displacement(t, 1.22, 20.0)
    force = np.sign(np.gradient(command, t)) * (0.09 + 0.3 * np.abs(np.gradient(command, t))) \
        + rng.normal(0, 0.005, t.size)
    survey = survey_of({"c1": force, "c2": command, "c3": t, "c4": command + rng.normal(0, 0.001, t.size)})
    assert survey.roles == {"time": "c3", "displacement": "c4", "force": "c1", "command": "c2"}
    assert all("from magnitudes" in how for how, _ in survey.role_how.values())


def test_names_win_over_magnitudes():
    t = np.arange(400) / 100.0
    y = triangle_displacement(t, 1.0, 2.0)
    survey = survey_of({"time_s": t, "F[N]": np.sign(np.gradient(y, t)) * 100.0, "x_mm": y})
    assert survey.roles == {"time": "time_s", "force": "F[N]", "displacement": "x_mm"}
    assert {sure for _, sure in survey.role_how.values()} == {"sure"}


def test_a_folder_with_no_case_file_is_an_error(tmp_path: Path):
    from isokinetic.init_campaign.survey import survey_folder

    (tmp_path / "notes.md").write_text("x", encoding="utf-8")
    with pytest.raises(FileNotFoundError, match="no case files"):
        survey_folder(tmp_path)


def test_a_volts_column_takes_no_role_from_magnitudes_either():
    t = np.arange(400) / 100.0
    y = triangle_displacement(t, 1.0, 2.0)
    survey = survey_of({"time_s": t, "x_mm": y, "ai1_V": np.sign(np.gradient(y, t)) * 2.5})
    assert "force" not in survey.roles and survey.volts == {"ai1_V": None}
