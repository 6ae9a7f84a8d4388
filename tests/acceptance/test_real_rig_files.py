"""Acceptance tests of issue 19 ("Done means"): files written in the vendors' formats by ``tests/rigfiles.py``
(never by the package's own writers) go through ``init-campaign`` and the pipeline as a user runs them, and the
results are checked against the virtual rig's noise-free truth or against a twin campaign.

The MTS 793 sweep and the crank dyno's folder are drafted by ``init-campaign`` and built by ``snakemake --cores 2``
in one scratch project (marked slow and workflow; built once per module); the CSV campaigns (dropouts,
Windows-1252, gas force) run ingest and the characteristic in-process.
"""

from __future__ import annotations

import csv
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import rigfiles as rf
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.ingest import ingest_campaign
from scratch_project import SNAKEMAKE, TINY, make_project

#: end-to-end runs on simulated vendor files (the sweep and the crank folders take seconds each)
pytestmark = pytest.mark.slow

#: A scratch project of raw campaigns only (no virtual campaign, no blind test, no comparison).
RAW_ONLY = {key: TINY[key] for key in ("raw_dir", "windows", "repeatability", "validation", "design")}
SWEEP = "mts-sweep"
#: A result against the rig's noise-free value (force at peak velocity, energy per cycle): issue 19's 1 %.
RIG_TOLERANCE = 0.01


def cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """The ``isokinetic`` command line as a user runs it."""
    return subprocess.run([sys.executable, "-m", "isokinetic", *args], cwd=cwd, capture_output=True, text=True)


def snakemake(work: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([SNAKEMAKE, "--cores", "2", *args], cwd=work, capture_output=True, text=True)


def stage_characteristic(folder: Path, root: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Ingest and characteristic of a raw campaign folder, in-process: (characteristic, cases)."""
    ingest_campaign(folder, root)
    char = write_characteristic(root)
    return char, pd.read_parquet(root / "cases.parquet")


def standard_error_N(char: pd.DataFrame) -> np.ndarray:
    """Standard error of each window's mean force: its scatter over sqrt(samples)."""
    return char["force_std_N"].to_numpy() / np.sqrt(char["n_samples"].to_numpy())


def by_window(char: pd.DataFrame) -> pd.DataFrame:
    return char.sort_values(["case", "segment"]).reset_index(drop=True)


# --------------------------------------------------------------------------------------------
# MTS 793 stepped sine sweep: init-campaign (no hand edit), snakemake, peak-velocity characteristic
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def sweep():
    """The virtual rig's stepped sine sweep (record, steps): 8 s at rest, 0.2 .. 10 Hz at +-12.7 mm, 1024 Hz."""
    return rf.stepped_sine_sweep()


CRANK = "crank-dyno"


@pytest.fixture(scope="module")
def rig_project(tmp_path_factory, sweep):
    """One scratch project holding the MTS 793 export and a crank dyno's folder, each with the draft written by
    init-campaign, untouched, then one full build. Returns (project, {campaign: init-campaign's process},
    snakemake's process or None when a draft failed, the crank runs)."""
    record, _ = sweep
    work = make_project(tmp_path_factory.mktemp("rigs"), RAW_ONLY)
    folder = work / "data" / "raw" / SWEEP
    folder.mkdir(parents=True)
    rf.write_mts793(folder / "sweep.txt", record["time_s"], record["displacement_m"], record["force_N"])
    runs = rf.write_crank_folder(work / "data" / "raw" / CRANK)
    drafts = {c: cli("init-campaign", f"data/raw/{c}", cwd=work) for c in (SWEEP, CRANK)}
    build = snakemake(work) if all(p.returncode == 0 for p in drafts.values()) else None
    return work, drafts, build, runs


@pytest.fixture(scope="module")
def sweep_build(rig_project):
    """(project, the sweep's init-campaign process, snakemake's process)."""
    work, drafts, build, _ = rig_project
    return work, drafts[SWEEP], build


def built(sweep_build) -> Path:
    work, draft, build = sweep_build
    assert draft.returncode == 0, f"init-campaign failed:\n{draft.stdout[-2000:]}\n{draft.stderr[-2000:]}"
    assert build is not None, "not built: a draft failed"
    assert build.returncode == 0, f"snakemake failed:\n{build.stdout[-3000:]}\n{build.stderr[-3000:]}"
    return work


def test_mts793_export_is_written_as_the_vendor_writes_it(tmp_path, sweep):
    record, steps = sweep
    path = rf.write_mts793(tmp_path / "sweep.txt", record["time_s"], record["displacement_m"], record["force_N"])
    raw = path.read_bytes()
    lines = raw.split(b"\r\n")
    assert lines[0] == b"MTS793|MPT|ENU|1|2|.|/|:|1|0|0|A" and b"\n" not in raw.replace(b"\r\n", b"")
    blocks = [i for i, line in enumerate(lines) if line.startswith(b"Data Acquisition:")]
    assert len(blocks) == -(-len(record) // 1024)
    assert lines[blocks[0] + 2:blocks[0] + 4] == [b"Time\tAxial Displacement\tAxial Force", b"Sec\tin\tlbf"]
    first = lines[blocks[0] + 4].split(b"\t")
    assert float(first[1]) * rf.INCH_M == pytest.approx(record["displacement_m"].iloc[0], rel=1e-5)
    assert float(first[2]) * rf.LBF_N == pytest.approx(record["force_N"].iloc[0], rel=1e-5, abs=1e-6)
    assert len(record) > 60_000 and [s.frequency_Hz for s in steps] == [0.2, 0.5, 1.0, 2.0, 5.0, 10.0]


def drafted(sweep_build) -> dict:
    work, draft, _ = sweep_build
    assert draft.returncode == 0, f"init-campaign failed:\n{draft.stdout[-2000:]}\n{draft.stderr[-2000:]}"
    return yaml.safe_load((work / "data" / "raw" / SWEEP / "campaign.yaml").read_text(encoding="utf-8"))


@pytest.mark.slow
@pytest.mark.workflow
def test_mts793_sweep_draft_has_one_sine_case_per_step(sweep_build, sweep):
    _, steps = sweep
    sines = [c for c in drafted(sweep_build)["cases"] if c.get("waveform") == "sine"]
    assert sorted(c["frequency_Hz"] for c in sines) == pytest.approx([s.frequency_Hz for s in steps], rel=0.01)
    assert all(c["amplitude_mm"] == pytest.approx(12.7, rel=0.02) for c in sines)
    assert all(c["file"] == "sweep.txt" and ("time_range_s" in c or "rows" in c) for c in sines)


@pytest.mark.slow
@pytest.mark.workflow
def test_mts793_sweep_draft_has_a_standstill_case(sweep_build):
    standstill = [c for c in drafted(sweep_build)["cases"] if c.get("waveform") == "standstill"]
    assert standstill
    # the record opens with 8 s at rest (and rests 1 s after each step): the first stretch lies in the first 8 s
    spans = [c.get("time_range_s") or list(np.asarray(c["rows"]) / 1024.0) for c in standstill]
    start, stop = min(spans)
    assert 0.0 <= start < stop <= 8.0 + 1e-3


@pytest.mark.slow
@pytest.mark.workflow
def test_mts793_sweep_peak_velocity_characteristic_matches_the_rigs_noise_free_force(sweep_build, sweep):
    work = built(sweep_build)
    record, steps = sweep
    char = pd.read_parquet(work / "results" / SWEEP / "characteristic.parquet")
    peaks = char[char["method"] == "sine_peak"]
    for step in steps:
        for sign, instants in ((1.0, step.positive_peaks_s), (-1.0, step.negative_peaks_s)):
            truth = rf.force_at_peaks(record, instants[1:])    # the first cycle settles
            assert np.ptp(truth) < 1e-3 * np.abs(truth).mean()  # the reference itself is steady
            v = sign * step.peak_velocity_m_s
            rows = peaks[np.abs(peaks["velocity_m_s"] - v) < 0.05 * abs(v)]
            where = f"{step.frequency_Hz} Hz, direction {'+' if sign > 0 else '-'}"
            assert len(rows), f"{where}: no sine_peak point near {v:.4g} m/s in\n{peaks.to_string()}"
            assert rows["force_N"].to_numpy() == pytest.approx(truth.mean(), rel=RIG_TOLERANCE), where


@pytest.mark.slow
@pytest.mark.workflow
def test_mts793_sweep_energy_per_cycle_matches_the_rigs_noise_free_loops(sweep_build, sweep):
    work = built(sweep_build)
    record, steps = sweep
    energy = pd.read_parquet(work / "results" / SWEEP / "energy.parquet")
    for step in steps:
        first, last = step.positive_peaks_s[1], step.positive_peaks_s[-1]     # the first cycle settles
        truth = rf.energy_per_cycle_J(record, first, last, len(step.positive_peaks_s) - 2)
        rows = energy[np.isclose(energy["frequency_Hz"], step.frequency_Hz, rtol=0.01)]
        assert len(rows) == 1, f"{step.frequency_Hz} Hz:\n{energy.to_string()}"
        assert rows["energy_J"].iloc[0] == pytest.approx(truth, rel=RIG_TOLERANCE), f"{step.frequency_Hz} Hz"


@pytest.mark.slow
@pytest.mark.workflow
def test_mts793_sweep_csv_export_carries_the_peak_velocity_points(sweep_build):
    work = built(sweep_build)
    char = pd.read_parquet(work / "results" / SWEEP / "characteristic.parquet")
    with (work / "results" / SWEEP / "characteristic.csv").open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    body = [dict(zip(header, r)) for r in rows[1:] if r and r[0] == SWEEP]   # a units row, if any, is skipped
    peaks = [r for r in body if r["method"] == "sine_peak"]
    assert len(peaks) == (char["method"] == "sine_peak").sum() >= 12
    exported = sorted(float(r["force_N"]) for r in peaks)
    assert exported == pytest.approx(sorted(char.loc[char["method"] == "sine_peak", "force_N"]), rel=1e-9)


#: Figures that show triangle records or their windows: on a campaign without a triangle case they could only be
#: placeholders ("no status-ok triangle case to show"), so its page leaves them out.
TRIANGLE_ONLY_FIGURES = ("Fig. 7 ", "Fig. 8 ", "Fig. 12 ")


def text_of(html: str) -> str:
    return re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", html)).strip()


@pytest.mark.slow
@pytest.mark.workflow
def test_sine_only_campaign_page_shows_its_characteristic_and_no_placeholder_figure(sweep_build):
    work = built(sweep_build)
    page = (work / "results" / SWEEP / "report.html").read_text(encoding="utf-8")
    captions = [text_of(c) for c in re.findall(r"<figcaption[^>]*>(.*?)</figcaption>", page, re.S)]
    assert any(c.startswith("Fig. 9 ") for c in captions), captions
    shown = [c for c in captions if c.startswith(TRIANGLE_ONLY_FIGURES)]
    assert not shown, shown
    # each left out with a line naming it (and why)
    assert all(name.strip() in text_of(page) for name in TRIANGLE_ONLY_FIGURES)
    assert "no status-ok triangle case to show" not in page
    assert "no temperature known" not in "".join(captions)          # Fig. 20 left out too: the sweep has none
    energy = pd.read_parquet(work / "results" / SWEEP / "energy.parquet")
    table = next(t for t in re.findall(r"<table.*?</table>", page, re.S) if 'id="energy-per-cycle"' in t)
    assert all(case in table for case in energy["case"])             # energy per cycle shown, every step


@pytest.mark.slow
@pytest.mark.workflow
def test_sine_only_campaign_index_counts_its_characteristic_points(sweep_build):
    work = built(sweep_build)
    char = pd.read_parquet(work / "results" / SWEEP / "characteristic.parquet")
    index = (work / "results" / "index.html").read_text(encoding="utf-8")
    table = next(t for t in re.findall(r"<table.*?</table>", index, re.S) if SWEEP in t)
    headers = [text_of(h) for h in re.findall(r"<th[^>]*>(.*?)</th>", table, re.S)]
    row = next(r for r in re.findall(r"<tr.*?</tr>", table, re.S) if SWEEP in r and "<td" in r)
    cells = [text_of(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", row, re.S)]
    assert len(char) >= 12 and cells[headers.index("points")] == str(len(char)), dict(zip(headers, cells))


# --------------------------------------------------------------------------------------------
# Crank (Scotch-yoke) dyno folder: voltage and scaled twins of every channel
# --------------------------------------------------------------------------------------------

CRANK_SCALED = {"force": "Force (N)", "displacement": "Displacement (mm)", "temperature": "Temperature (C)"}
CRANK_VOLTS = {"force": "Force (V)", "displacement": "Displacement (V)", "temperature": "Temperature (V)"}


@pytest.fixture(scope="module")
def crank(tmp_path_factory):
    """The crank dyno's folder with init-campaign's draft: (folder, init-campaign's process)."""
    folder = tmp_path_factory.mktemp("crank") / "crank-dyno"
    rf.write_crank_folder(folder)
    return folder, cli("init-campaign", str(folder))


def test_crank_dyno_draft_takes_the_scaled_columns(crank):
    folder, draft = crank
    assert draft.returncode == 0, draft.stderr[-2000:]
    columns = yaml.safe_load((folder / "campaign.yaml").read_text(encoding="utf-8"))["columns"]
    assert {role: columns.get(role, {}).get("name") for role in CRANK_SCALED} == CRANK_SCALED
    assert columns["displacement"]["unit"] == "mm" and columns["force"]["unit"] == "N"
    assert columns["temperature"]["unit"] == "degC" and not columns["force"].get("invert", False)


def test_crank_dyno_check_agrees_with_its_own_draft(crank, tmp_path):
    folder, draft = crank
    assert draft.returncode == 0, draft.stderr[-2000:]
    check = cli("init-campaign", str(folder), "--check")
    assert check.returncode == 0, check.stdout[-2000:] + check.stderr[-2000:]


def test_crank_dyno_check_fails_on_a_manifest_naming_the_voltage_columns(crank, tmp_path):
    folder, draft = crank
    assert draft.returncode == 0, draft.stderr[-2000:]
    volts = tmp_path / folder.name
    shutil.copytree(folder, volts)
    text = (volts / "campaign.yaml").read_text(encoding="utf-8")
    for role, name in CRANK_SCALED.items():
        assert text.count(f"name: {name}") == 1, (role, text)
        text = text.replace(f"name: {name}", f"name: {CRANK_VOLTS[role]}")
    (volts / "campaign.yaml").write_text(text, encoding="utf-8")
    check = cli("init-campaign", str(volts), "--check")
    assert check.returncode == 1, check.stdout[-2000:] + check.stderr[-2000:]
    assert "Force (V)" in check.stdout + check.stderr


@pytest.mark.slow
@pytest.mark.workflow
def test_crank_dyno_folder_builds_to_the_rigs_force_at_peak_velocity(rig_project):
    work, drafts, build, runs = rig_project
    assert drafts[CRANK].returncode == 0, drafts[CRANK].stderr[-2000:]
    work = built((work, drafts[SWEEP], build))
    char = pd.read_parquet(work / "results" / CRANK / "characteristic.parquet")
    peaks = char[char["method"] == "sine_peak"]
    for run in runs:
        for sign in (1.0, -1.0):
            v = sign * 2.0 * np.pi * run.frequency_Hz * run.amplitude_m
            rows = peaks[np.abs(peaks["velocity_m_s"] - v) < 0.05 * abs(v)]
            where = f"{run.path.name}, {run.frequency_Hz} Hz, direction {'+' if sign > 0 else '-'}"
            assert len(rows), f"{where}: no sine_peak point near {v:.4g} m/s in\n{peaks.to_string()}"
            truth = run.force_at_peak_velocity_N(sign)
            assert rows["force_N"].to_numpy() == pytest.approx(truth, rel=RIG_TOLERANCE), where


# --------------------------------------------------------------------------------------------
# CSV campaigns and their twins: dropped samples, Windows-1252, per-case gas force
# --------------------------------------------------------------------------------------------

OIL = "oil [°C]"
GAS_FORCE_N = {"T01": 40.0, "T02": 80.0, "T03": 120.0}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The UTF-8 triangle campaign every twin is compared with: (folder, characteristic, cases)."""
    base = tmp_path_factory.mktemp("reference")
    folder = base / "raw" / "ref"
    rf.triangle_campaign(folder, temperature_header=OIL)
    return (folder, *stage_characteristic(folder, base / "results" / "ref"))


def renamed_copy(folder: Path, dst: Path) -> Path:
    """``folder`` copied to ``dst`` with the manifest's campaign id set to the new folder's name."""
    shutil.copytree(folder, dst)
    manifest = yaml.safe_load((dst / "campaign.yaml").read_text(encoding="utf-8"))
    manifest["campaign"] = dst.name
    rf.write_manifest(dst, manifest)
    return dst


@pytest.fixture(scope="module")
def dropped(reference, tmp_path_factory):
    """The reference campaign less 1 % of each file's rows (singles and bursts of 5-40): (dropped data-row
    indices per case, characteristic, cases)."""
    folder, ref, _ = reference
    base = tmp_path_factory.mktemp("dropped")
    twin = renamed_copy(folder, base / "raw" / "dropped")
    lost = {case: rf.drop_rows(folder / f"{case}.csv", twin / f"{case}.csv", fraction=0.01, seed=100 + i)
            for i, case in enumerate(sorted(ref["case"].unique()))}
    return (lost, *stage_characteristic(twin, base / "results" / "dropped"))


def test_dropped_samples_give_the_same_characteristic_within_standard_errors(reference, dropped):
    _, ref, _ = reference
    lost, char, cases = dropped
    assert (cases["status"] == "ok").all(), cases[["case", "status", "quality"]].to_string()
    # the test bites: dropouts lie inside the analysed windows, not only between them
    inside = sum(((lost[c] >= a) & (lost[c] < b)).sum()
                 for c, a, b in ref[["case", "row_start", "row_stop"]].itertuples(index=False))
    assert inside >= 20
    a, b = by_window(ref), by_window(char)
    assert list(zip(a["case"], a["segment"])) == list(zip(b["case"], b["segment"]))
    assert (np.abs(b["force_N"] - a["force_N"]).to_numpy() <= 2.0 * standard_error_N(a)).all()
    assert b["velocity_m_s"].to_numpy() == pytest.approx(a["velocity_m_s"].to_numpy(), rel=2e-3)


def test_dropped_samples_are_counted_per_case(dropped):
    lost, _, cases = dropped
    counted = dict(zip(cases["case"], cases["missing_samples"].astype(int)))
    assert counted == {case: rows.size for case, rows in lost.items()}
    assert all(rows.size == 160 for rows in lost.values())      # 1 % of 16 001 rows


def test_cp1252_campaign_gives_the_characteristic_of_its_utf8_twin(reference, tmp_path):
    folder, ref, ref_cases = reference
    twin = tmp_path / "raw" / "cp1252"
    rf.triangle_campaign(twin, temperature_header=OIL, encoding="cp1252")
    header = (twin / "T01.csv").read_bytes().splitlines()[0]
    assert b"oil [\xb0C]" in header       # a Windows-1252 degree sign: not UTF-8
    char, cases = stage_characteristic(twin, tmp_path / "results" / "cp1252")
    assert (cases["status"] == "ok").all(), cases[["case", "status", "quality"]].to_string()
    a, b = by_window(ref), by_window(char)
    for column in ("velocity_m_s", "force_N", "force_std_N", "n_samples", "row_start", "row_stop"):
        assert b[column].to_numpy() == pytest.approx(a[column].to_numpy(), rel=1e-12), column
    assert cases["temperature_C"].to_numpy() == pytest.approx(ref_cases["temperature_C"].to_numpy(), rel=1e-12)
    assert (cases["temperature_source"] == ref_cases["temperature_source"]).all()


def test_cp1252_campaign_without_the_encoding_key_is_set_aside_naming_the_key(tmp_path):
    twin = tmp_path / "raw" / "cp1252-undeclared"
    rf.triangle_campaign(twin, temperature_header=OIL, encoding="cp1252")
    manifest = yaml.safe_load((twin / "campaign.yaml").read_text(encoding="utf-8"))
    del manifest["csv"]
    rf.write_manifest(twin, manifest)
    ingest_campaign(twin, tmp_path / "results")
    cases = pd.read_parquet(tmp_path / "results" / "ingest" / "cases.parquet")
    quarantine = pd.read_parquet(tmp_path / "results" / "ingest" / "quarantine.parquet")
    assert (cases["status"] == "quarantined").all()
    assert sorted(quarantine["case"]) == ["T01", "T02", "T03"]
    assert all("encoding" in r and "cp1252" in r for r in quarantine["reason"]), quarantine["reason"].tolist()


def test_per_case_gas_force_is_subtracted(reference, tmp_path):
    folder, ref, _ = reference
    twin = tmp_path / "raw" / "gas"
    rf.triangle_campaign(twin, temperature_header=OIL, gas_force_N=GAS_FORCE_N)
    offsets = np.array([GAS_FORCE_N[c] for c in by_window(ref)["case"]])
    se = standard_error_N(by_window(ref))
    assert (offsets > 10.0 * se).all()    # left in, the gas force would be seen
    char, cases = stage_characteristic(twin, tmp_path / "results" / "gas")
    assert (cases["status"] == "ok").all(), cases[["case", "status", "quality"]].to_string()
    a, b = by_window(ref), by_window(char)
    assert (np.abs(b["force_N"] - a["force_N"]).to_numpy() <= 2.0 * se).all()


def test_cp1252_folder_with_a_subfolder_drafts_to_the_same_characteristic(reference, tmp_path):
    _, ref, _ = reference
    folder = tmp_path / "raw" / "bench-pc"
    rf.triangle_campaign(folder, temperature_header=OIL, encoding="cp1252")
    (folder / "campaign.yaml").unlink()
    (folder / "day2").mkdir()
    (folder / "T03.csv").rename(folder / "day2" / "T03.csv")
    draft = cli("init-campaign", str(folder))
    assert draft.returncode == 0, draft.stdout[-2000:] + draft.stderr[-2000:]
    manifest = yaml.safe_load((folder / "campaign.yaml").read_text(encoding="utf-8"))
    assert manifest["csv"]["encoding"].lower().replace("-", "") in ("cp1252", "windows1252")
    assert manifest["columns"]["temperature"]["name"] == OIL
    assert sorted(c["file"] for c in manifest["cases"]) == ["T01.csv", "T02.csv", "day2/T03.csv"]
    char, cases = stage_characteristic(folder, tmp_path / "results" / "bench-pc")
    assert (cases["status"] == "ok").all(), cases[["case", "status", "quality"]].to_string()
    a, b = by_window(ref), by_window(char)
    for column in ("velocity_m_s", "force_N", "row_start", "row_stop"):
        assert b[column].to_numpy() == pytest.approx(a[column].to_numpy(), rel=1e-9), column
