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
    survey_folder,
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


def write_rows(path, columns, header: bool = True) -> None:
    """A whitespace-separated file of ``columns`` (12 significant digits), with or without a header row."""
    rows = [" ".join(f"{v:.12g}" for v in row) for row in zip(*columns.values())]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(([" ".join(columns)] if header else []) + rows) + "\n", encoding="utf-8")


def test_a_headerless_t_x_v_f_file_drafts_the_velocity_unused_and_the_force_from_its_own_column(tmp_path):
    from .test_channels import mr_like_record

    write_rows(tmp_path / "mr" / "2mm5Hz.txt", mr_like_record(), header=False)
    survey = survey_folder(tmp_path / "mr")
    f = survey.files[0]
    names = list(f.data)                         # positional columns: t, x, v, F
    assert f.ok and (f.roles["time"], f.roles["displacement"], f.roles["force"]) == (names[0], names[1], names[3])
    assert "a velocity, not a force" in f.unused[names[2]]
    assert "velocity" not in f.roles and names[2] not in f.roles.values()


def test_a_named_force_that_is_the_displacements_derivative_is_a_guess_with_a_check(tmp_path):
    from .test_channels import mr_like_record

    r = mr_like_record()
    write_rows(tmp_path / "mr" / "a.txt", {"time": r["t"], "x_mm": r["x"], "force_N": r["v"]})
    f = survey_folder(tmp_path / "mr").files[0]
    how, sure = f.role_how["force"]
    assert sure == "guess" and "CHECK" in how and "a velocity" in how


def test_a_switching_voltage_named_y_is_not_the_displacement_and_a_random_record_is_one_free_case(tmp_path):
    rng = np.random.default_rng(21)
    t = np.arange(12000) / 400.0
    kernel = np.exp(-np.arange(-40, 41) ** 2 / 200.0)
    x = np.convolve(rng.standard_normal(t.size), kernel / kernel.sum(), mode="same") * 20.0    # mm, random
    v = np.gradient(x, t) * 1e-3
    force = 1500.0 * v + 400.0 * np.tanh(v / 0.002) + rng.normal(0.0, 2.0, t.size)
    volts = np.repeat(rng.choice([0.0, 1.0, 2.0, 2.5], 50), 240) + 0.01 * rng.standard_normal(t.size)
    stamps = np.array([float(f"{s:.5g}") for s in t + 10.0])        # rounded to 5 significant digits
    write_rows(tmp_path / "rnd" / "random.txt", {"time": stamps, "Y": volts, "x": x, "F": force})
    survey = survey_folder(tmp_path / "rnd")
    f = survey.files[0]
    assert f.roles["displacement"] == "x" and f.roles["force"] == "F" and "switches between 4 levels" in f.unused["Y"]
    assert survey.case_kinds() == ["free"] and not f.steps
    assert survey.sample_rate_Hz == pytest.approx(400.0, rel=1e-3)


def test_a_single_sine_record_with_ramps_drafts_its_steady_part_as_a_sine(tmp_path):
    from .test_channels import mr_like_record

    r = mr_like_record()
    write_rows(tmp_path / "mr" / "ramped.txt", {"time_s": r["t"], "x_mm": r["x"], "force_N": r["F"]})
    f = survey_folder(tmp_path / "mr").files[0]
    assert f.waveform.kind == "free"                         # the whole record, ramps and all
    (case,) = f.steps
    assert case.case_id == f.case_id and case.waveform.kind == "sine"
    assert case.waveform.frequency_Hz.value == pytest.approx(5.0, rel=1e-3)
    assert case.start_s >= 0.4 and case.end_s <= r["t"][-1] - 0.4       # inside the steady part, ramps left out
    assert case.waveform.amplitude_m.value == pytest.approx(2e-3, rel=0.01)
