"""Which files a draft reads: case files in subfolders (relative ``file:`` entries), every file passed over listed
with why, and files in another encoding than UTF-8 or with a units row read and declared in the csv block."""

from __future__ import annotations

import pandas as pd

from isokinetic.contracts.manifest import load_manifest
from isokinetic.init_campaign.draft import write_draft
from isokinetic.init_campaign.survey import MAX_DEPTH, walk_folder
from isokinetic.stages.ingest import ingest_campaign

from .records import sine_record, write_table


def write_case(path, frequency_Hz: float = 2.0, encoding: str = "utf-8", temperature: str | None = None,
               units: list[str] | None = None):
    rec = sine_record(frequency_Hz, 0.01, 6, 500.0)
    columns = {"time_s": rec["time_s"], "disp_mm": rec["displacement_m"] * 1e3, "force_N": rec["force_N"]}
    if temperature:
        columns[temperature] = [f"{40.0 + 0.01 * i:.2f}" for i in range(rec["time_s"].size)]
    return write_table(path, columns, encoding=encoding, units=units)


def test_case_files_in_subfolders_are_found_and_every_other_file_is_listed(tmp_path):
    folder = tmp_path / "raw" / "camp"
    write_case(folder / "T1.dat")
    write_case(folder / "run1" / "T2.csv", 3.0)
    write_case(folder / "run1" / "more" / "T3.txt", 4.0)
    write_case(folder / ".cache" / "T4.csv")
    deep = folder / "a" / "b" / "c" / "d"
    write_case(deep / "T5.csv")
    (folder / "notes.pdf").write_bytes(b"%PDF")
    files, skipped = walk_folder(folder)
    assert [p.relative_to(folder).as_posix() for p in files] == ["T1.dat", "run1/T2.csv", "run1/more/T3.txt"]
    assert dict(skipped) == {".cache": "hidden folder", "a/b/c/d": f"a folder more than {MAX_DEPTH} levels deep: "
                             "not searched", "notes.pdf": "not a case file (.csv, .tsv, .txt, .dat, .xlsx)"}
    path, survey = write_draft(folder)
    text = path.read_text(encoding="utf-8")
    for name, why in skipped:
        assert f"#   {name}: {why}" in text
    cases = load_manifest(path).cases
    assert [(c.id, c.file, c.plan.frequency_Hz) for c in cases] == [("T1", "T1.dat", 2.0), ("T2", "run1/T2.csv", 3.0),
                                                                    ("T3", "run1/more/T3.txt", 4.0)]
    ingest_campaign(folder, tmp_path / "out" / "camp")
    assert (pd.read_parquet(tmp_path / "out" / "camp" / "ingest" / "cases.parquet")["status"] == "ok").all()


def test_a_windows_1252_file_with_a_units_row_is_read_and_declared(tmp_path):
    folder = tmp_path / "raw" / "camp"
    write_case(folder / "T1.csv", encoding="cp1252", temperature="oil [°C]", units=["s", "mm", "N", "°C"])
    write_case(folder / "T2.csv", 3.0, encoding="cp1252", temperature="oil [°C]", units=["s", "mm", "N", "°C"])
    path, survey = write_draft(folder)
    manifest = load_manifest(path)
    assert (manifest.csv.encoding, manifest.csv.units_row) == ("cp1252", True)
    assert manifest.cases[0].columns["temperature"].name == "oil [°C]"
    ingest_campaign(folder, tmp_path / "out" / "camp")
    cases = pd.read_parquet(tmp_path / "out" / "camp" / "ingest" / "cases.parquet")
    assert (cases["status"] == "ok").all() and cases["temperature_C"].between(40.0, 50.0).all()


def test_a_units_row_naming_an_unknown_unit_sets_the_file_aside(tmp_path):
    folder = tmp_path / "camp"
    write_case(folder / "T1.csv", units=["s", "mm", "N"])
    write_case(folder / "T2.csv", units=["s", "mm", "kipp"])
    path, survey = write_draft(folder)
    problems = {f.file: f.problem for f in survey.files}
    assert problems["T1.csv"] is None
    assert problems["T2.csv"].startswith("column 'force_N': the units row says 'kipp': unknown unit 'kipp'; nearest "
                                         "known units: ")
    assert "kip" in problems["T2.csv"] and problems["T2.csv"].endswith("(ingest would set the case aside)")
    assert [c.id for c in load_manifest(path).cases] == ["T1"]
