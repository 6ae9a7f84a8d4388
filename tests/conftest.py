"""A small good raw campaign (data/raw/demo) in tmp_path, and helpers to damage it."""

from __future__ import annotations

import copy
import hashlib
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.physics.plan import sine_displacement, triangle_displacement
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.validate import write_validated
from isokinetic.stages.virtual_rig import VirtualCampaign
from testconfig import paper_campaign

CAMPAIGN = "demo"
FORCE_A_N = 150.0          # force = sign(v) (a + b|v|) + noise
FORCE_B_N_S_M = 4.0e5
COMMENTS = "# rig: bench 2\n# operator: synthetic fixture\n"

MANIFEST = {
    "format_version": 1,
    "campaign": CAMPAIGN,
    "description": "Synthetic fixture campaign",
    "source": "rig",
    "temperature_C": 40.0,
    "sample_rate_Hz": 50.0,
    "operator": "fixture",  # not in the spec: carried as metadata
    "columns": {
        "time": {"name": "time_s", "unit": "s"},
        "displacement": {"name": "disp_mm", "unit": "mm"},
        "force": {"name": "force_kN", "unit": "kN"},
        "command": {"name": "cmd_mm", "unit": "mm"},
    },
    "damper": {
        "piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
        "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
        "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9,
    },
    "cases": [
        {"id": "T01", "waveform": "triangle", "period_s": 4.0, "amplitude_mm": 0.3, "file": "T01.csv"},
        {"id": "T02", "waveform": "triangle", "period_s": 2.0, "amplitude_mm": 0.5, "sample_rate_Hz": 100.0,
         "file": "T02.csv"},
        {"id": "T03", "waveform": "triangle", "period_s": 4.0, "amplitude_mm": 0.2, "file": "T03.csv",
         "columns": {"force": {"name": "force_inv_kN", "invert": True}}, "note": "load cell mounted upside down"},
        {"id": "H01", "waveform": "sine", "frequency_Hz": 1.75, "amplitude_mm": 0.23, "sample_rate_Hz": 200.0,
         "file": "H01.csv"},
        {"id": "F01", "waveform": "free", "file": "F01.csv"},
    ],
}
CASE_IDS = [c["id"] for c in MANIFEST["cases"]]
#: Samples per case: 2 periods of each triangle, 2 s of sine, 6 s of free excitation.
N_SAMPLES = {"T01": 400, "T02": 400, "T03": 400, "H01": 400, "F01": 300}


def synthetic_case(case: dict, sample_rate_Hz: float, rng: np.random.Generator) -> pd.DataFrame:
    """One case in SI: time_s, command_m, displacement_m, force_N."""
    t = np.arange(N_SAMPLES[case["id"]]) / sample_rate_Hz
    if case["waveform"] == "triangle":
        command = triangle_displacement(t, case["amplitude_mm"] * 1e-3, case["period_s"])
    elif case["waveform"] == "sine":
        command = sine_displacement(t, case["amplitude_mm"] * 1e-3, case["frequency_Hz"])
    else:
        command = 2e-4 * np.sin(2 * np.pi * 0.7 * t) + 1e-4 * np.sin(2 * np.pi * 1.9 * t + 0.3)
    v = np.gradient(command, t)
    force = np.sign(v) * (FORCE_A_N + FORCE_B_N_S_M * np.abs(v)) + rng.normal(0.0, 5.0, t.size)
    return pd.DataFrame({"time_s": t, "command_m": command,
                         "displacement_m": command + rng.normal(0.0, 1e-6, t.size), "force_N": force})


def case_csv_table(case: dict, si: pd.DataFrame) -> pd.DataFrame:
    """The CSV columns of a fixture case (mm, kN, s), an extra column, varied column order."""
    force_name = case.get("columns", {}).get("force", {}).get("name", "force_kN")
    sign = -1.0 if case.get("columns", {}).get("force", {}).get("invert") else 1.0
    table = pd.DataFrame({"time_s": si["time_s"], "disp_mm": si["displacement_m"] * 1e3,
                          force_name: sign * si["force_N"] / 1e3, "cmd_mm": si["command_m"] * 1e3,
                          "temp_C": 40.0})
    return table[table.columns[::-1]] if case["id"] == "T02" else table


def write_csv(path: Path, table: pd.DataFrame, comments: str = COMMENTS) -> None:
    """A case CSV with comment lines before the header (cells written as given)."""
    path.write_text(comments + table.to_csv(index=False, float_format="%.10g"), encoding="utf-8")


def write_manifest(raw_dir: Path, manifest: dict) -> None:
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")


def build_campaign(raw_dir: Path, seed: int = 20240601) -> None:
    """Write the good fixture campaign into ``raw_dir``."""
    raw_dir.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    write_manifest(raw_dir, MANIFEST)
    for case in MANIFEST["cases"]:
        si = synthetic_case(case, case.get("sample_rate_Hz", MANIFEST["sample_rate_Hz"]), rng)
        write_csv(raw_dir / case["file"], case_csv_table(case, si))


def set_cell(row: int, column: str, value: str):
    """A table edit for :meth:`RawCampaign.edit_table`: one cell replaced."""
    def edit(table: pd.DataFrame) -> pd.DataFrame:
        table.loc[row, column] = value
        return table
    return edit


def tree_hashes(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder`` by relative path."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@dataclass
class RawCampaign:
    """A writable copy of the fixture campaign and its results folder."""

    raw_dir: Path    # data/raw/demo (relative to the test's working directory)
    root: Path       # results/demo
    campaign: str = CAMPAIGN

    def manifest(self) -> dict:
        return yaml.safe_load((self.raw_dir / "campaign.yaml").read_text(encoding="utf-8"))

    def edit_manifest(self, edit) -> None:
        """Apply ``edit(manifest_dict)`` (in place) and rewrite campaign.yaml."""
        manifest = copy.deepcopy(self.manifest())
        edit(manifest)
        write_manifest(self.raw_dir, manifest)

    def case_entry(self, manifest: dict, case: str) -> dict:
        return next(c for c in manifest["cases"] if c["id"] == case)

    def read_table(self, case: str) -> pd.DataFrame:
        """A case CSV as strings (comments skipped)."""
        return pd.read_csv(self.raw_dir / f"{case}.csv", skiprows=COMMENTS.count("\n"), dtype=str,
                           keep_default_na=False)

    def edit_table(self, case: str, edit) -> None:
        """Apply ``edit(table_of_strings) -> table`` and rewrite the case CSV."""
        write_csv(self.raw_dir / f"{case}.csv", edit(self.read_table(case)))

    def run(self) -> tuple[pd.DataFrame, pd.DataFrame]:
        """Ingest then validate; returns (cases, quarantine) as written."""
        ingest_campaign(self.raw_dir, self.root)
        return write_validated(self.root)


@pytest.fixture(scope="session")
def pristine_campaign(tmp_path_factory) -> Path:
    raw_dir = tmp_path_factory.mktemp("pristine") / CAMPAIGN
    build_campaign(raw_dir)
    return raw_dir


@pytest.fixture
def raw_campaign(pristine_campaign, tmp_path, monkeypatch) -> RawCampaign:
    """A fresh copy of the good campaign; the working directory is ``tmp_path``, so paths are
    relative as in the pipeline (``data/raw/demo``, ``results/demo``)."""
    monkeypatch.chdir(tmp_path)
    raw_dir = Path("data", "raw", CAMPAIGN)
    shutil.copytree(pristine_campaign, raw_dir)
    return RawCampaign(raw_dir=raw_dir, root=Path("results", CAMPAIGN))


def assert_quarantine(campaign: RawCampaign, cases: pd.DataFrame, quarantine: pd.DataFrame,
                      expected: list[tuple]) -> None:
    """Quarantine holds exactly ``expected`` (campaign, case, stage, column, row) rows, and every
    other case is ok with its time series written."""
    got = [(r.campaign, r.case, r.stage, r.column, None if pd.isna(r.row) else int(r.row))
           for r in quarantine.itertuples()]
    assert got == expected, quarantine["reason"].tolist()
    bad = {e[1] for e in expected}
    status = cases.set_index("case")["status"]
    assert set(status[status == "quarantined"].index) == bad
    for case in set(CASE_IDS) - bad:
        row = cases.set_index("case").loc[case]
        assert row["status"] == "ok"
        series = pd.read_parquet(campaign.root / row["timeseries_file"])
        assert len(series) == N_SAMPLES[case] == row["n_samples"]
    for r in quarantine.itertuples():  # the reason names campaign, case, column and row
        assert r.reason.startswith(f"campaign {r.campaign}, case {r.case}, ")
        assert repr(r.column) in r.reason
        assert pd.isna(r.row) or f"row {r.row}:" in r.reason


# --- helpers for damaged copies (tests/test_damage.py) -------------------------------------------

@pytest.fixture(scope="session")
def baseline(pristine_campaign, tmp_path_factory) -> dict[str, pd.DataFrame]:
    """Canonical series of every case of the undamaged campaign (ingest + validate run once)."""
    root = tmp_path_factory.mktemp("baseline") / CAMPAIGN
    ingest_campaign(pristine_campaign, root)
    cases, quarantine = write_validated(root)
    assert quarantine.empty and (cases["quality"] == "ok").all()
    return {row.case: pd.read_parquet(root / row.timeseries_file) for row in cases.itertuples()}


def assert_rest_unchanged(campaign: RawCampaign, cases: pd.DataFrame, baseline: dict[str, pd.DataFrame],
                          damaged: set[str]) -> None:
    """Every case not in ``damaged`` is ok, quality 'ok', with a series identical to the undamaged run."""
    table = cases.set_index("case")
    for case in set(CASE_IDS) - set(damaged):
        assert (table.loc[case, "status"], table.loc[case, "quality"]) == ("ok", "ok"), case
        pd.testing.assert_frame_equal(pd.read_parquet(campaign.root / table.loc[case, "timeseries_file"]),
                                      baseline[case])


def csv_path(campaign: RawCampaign, case: str) -> Path:
    return campaign.raw_dir / f"{case}.csv"


def edit_bytes(campaign: RawCampaign, case: str, edit) -> None:
    """Apply ``edit(bytes) -> bytes`` to a case CSV as stored."""
    path = csv_path(campaign, case)
    path.write_bytes(edit(path.read_bytes()))


def data_line(case_bytes: bytes, row: int) -> int:
    """Index (in ``bytes.split(b'\\n')``) of data row ``row`` of a fixture CSV (comments, header first)."""
    return COMMENTS.count("\n") + 1 + row


def drop_rows(start: int, stop: int):
    """A table edit: data rows [start, stop) removed (samples missing)."""
    return lambda t: t.drop(index=range(start, stop)).reset_index(drop=True)


def scale_column(column: str, factor: float):
    """A table edit: every value of ``column`` multiplied (a wrong declared unit)."""
    def edit(t: pd.DataFrame) -> pd.DataFrame:
        t[column] = (t[column].astype(float) * factor).map("{:.10g}".format)
        return t
    return edit


# --- shared fixtures -----------------------------------------------------------------------------

@pytest.fixture(scope="session")
def default_plan():
    """The virtual campaign paper-lag-damper of the test configuration (.test/config/config.yaml)."""
    return VirtualCampaign.from_config("paper-lag-damper", paper_campaign())
