"""provenance.json of a processed campaign, and the row-level sources of the aggregate tables."""

import hashlib
import json
import os
import shutil
from pathlib import Path

import pandas as pd
import pytest

import isokinetic.io
from campaign_meta_fixture import write_campaign_meta
from isokinetic.audit import lineage, provenance
from isokinetic.blind.score import SCORE_COLUMNS, SOURCE_COLUMNS
from isokinetic.contracts.row_keys import parse_row_keys
from isokinetic.io import canonical_json, hash_once, lineage_context, write_json
from isokinetic.stages import blind_score
from isokinetic.stages.analysis import write_analysis
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.diagnosis import write_diagnosis
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign, write_campaign

#: processes a whole raw campaign through every per-campaign stage once (~6 s)
pytestmark = pytest.mark.slow

#: A raw campaign exported by the virtual rig: three short triangle cases and one sine case.
CAMPAIGN = "tiny"
SPEC = {
    "description": "three short triangle cases and a sine", "seed": 7, "temperature_C": 40.0,
    "damper": {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
               "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
               "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9},
    "effects": {"friction": {"coulomb_force_N": 90.0}, "leakage": {"conductance_m3_s_Pa": 2.2e-12}},
    "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
    "plan": {"triangle": {"velocities_mm_s": [0.05, 0.5, 1.5], "periods_s": [8, 8, 8], "sample_rate_Hz": 20.0},
             "sine": {"frequency_Hz": 1.75, "amplitudes_mm": [0.3], "periods": 6, "sample_rate_Hz": 200.0}},
}
CASE_IDS = [c.case for c in VirtualCampaign.from_config(CAMPAIGN, SPEC).cases]
RAW = Path("data", "raw", CAMPAIGN)
ROOT = Path("results", CAMPAIGN)


def run_chain(root: Path = ROOT, raw: Path = RAW) -> None:
    """The per-campaign jobs on the fixture campaign, each output written with its job's record, as the scripts do."""
    def stage(rule, inputs, params=None):
        return lineage_context(lineage.stage_lineage(rule, params or {}, inputs, campaign=CAMPAIGN,
                                                     config_sha256="cfg"))

    raw_files = sorted(str(p) for p in raw.iterdir())
    with stage("ingest", raw_files, {"campaign_dir": str(raw)}):
        ingest_campaign(raw, root)
    with stage("characteristic", [root / "ingest"], {"repeatability_tolerance": 0.05}):
        write_characteristic(root)
    with stage("analysis", [root / "ingest", root / "cases.parquet", root / "windows.parquet",
                            root / "characteristic.parquet"]):
        write_analysis(root)
    with stage("diagnosis", [root / "cases.parquet", root / "ingest", root / "characteristic.parquet"]):
        write_diagnosis(root, root / "diagnosis.json", root / "diagnosis" / "fig16_gap.png")


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A project folder with the fixture raw campaign processed by every per-campaign stage."""
    work = tmp_path_factory.mktemp("prov")
    export_raw_campaign(VirtualCampaign.from_config(CAMPAIGN, SPEC), work / RAW)
    old = os.getcwd()
    os.chdir(work)
    try:
        run_chain()
    finally:
        os.chdir(old)
    return work


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_every_output_carries_lineage(project):
    assert provenance.files_without_lineage(project / ROOT) == []


def test_provenance_lists_every_raw_file_with_its_hash(project):
    prov = provenance.campaign_provenance(project / ROOT, base=project, config_sha256="cfg")
    raw = prov["raw"]
    assert raw["kind"] == "raw"
    files = {f["path"]: f for f in raw["files"]}
    on_disk = {(RAW / p.name).as_posix(): sha256(p) for p in (project / RAW).iterdir()}
    assert set(files) == set(on_disk)
    for path, f in files.items():
        assert f["sha256_recorded"] == f["sha256_now"] == on_disk[path] and f["unchanged"] is True
    assert {f["case"] for f in raw["files"] if f["role"] == "case"} == set(CASE_IDS)
    assert [f["role"] for f in raw["files"]].count("manifest") == 1
    checks = prov["checks"]
    assert checks["ok"] and checks["raw_unchanged"], checks
    env = prov["environment"]
    assert set(provenance.PACKAGES) <= set(env["packages"]) and all(env["packages"].values())
    stages = {s["rule"]: s for s in prov["stages"]}
    assert list(stages) == [r for r in provenance.STAGE_ORDER if r in stages]       # pipeline order
    assert set(stages) == {"ingest", "characteristic", "analysis", "diagnosis"}
    char = stages["characteristic"]
    params = {"repeatability_tolerance": 0.05}
    assert char["params"] == params and char["inputs_current"] and char["consistent"]
    assert char["params_sha256"] == lineage.sha256_text(canonical_json(params))
    made = ("cases.parquet", "quarantine.parquet", "windows.parquet", "repeatability.parquet", "characteristic.parquet",
            "energy.parquet")
    assert char["outputs"] == {(project / ROOT / f).as_posix(): sha256(project / ROOT / f) for f in made}
    assert char["last_run_utc"].endswith("Z")
    index = prov["outputs"]
    assert set(index) == {f for s in prov["stages"] for f in s["outputs"]}
    assert index[(project / ROOT / "characteristic.parquet").as_posix()]["rule"] == "characteristic"
    json.dumps(prov, allow_nan=False)


def test_the_provenance_job_reads_no_file_twice(project, monkeypatch):
    """Its own record hashed every output of the campaign; the provenance record reuses those hashes."""
    reads = []
    read = isokinetic.io._read_sha256
    monkeypatch.setattr(isokinetic.io, "_read_sha256", lambda p: reads.append(os.path.realpath(p)) or read(p))
    old = os.getcwd()
    os.chdir(project)
    try:
        fresh = provenance.campaign_provenance(ROOT)
        reads.clear()
        with hash_once():
            outputs = sorted(str(p) for p in ROOT.rglob("*") if p.suffix in (".parquet", ".json", ".png"))
            lineage.stage_lineage("provenance", {}, outputs, CAMPAIGN)
            again = provenance.campaign_provenance(ROOT)
    finally:
        os.chdir(old)
    assert reads and len(reads) == len(set(reads))
    assert {k: v for k, v in again.items() if k != "created_utc"} == {k: v for k, v in fresh.items()
                                                                       if k != "created_utc"}


def test_provenance_flags_a_changed_raw_file(project, tmp_path):
    work = tmp_path / "copy"
    shutil.copytree(project, work)
    case_file = work / RAW / f"{CASE_IDS[1]}.csv"
    case_file.write_text(case_file.read_text(encoding="utf-8").replace("0.", "1.", 1), encoding="utf-8")
    out = work / ROOT / provenance.FILE_NAME
    prov = provenance.write_provenance(work / ROOT, out, base=work)
    changed = (RAW / f"{CASE_IDS[1]}.csv").as_posix()
    entry = next(f for f in prov["raw"]["files"] if f["path"] == changed)
    assert entry["unchanged"] is False and entry["sha256_now"] == sha256(case_file) != entry["sha256_recorded"]
    checks = prov["checks"]
    assert checks["changed_raw_files"] == [changed] and not checks["raw_unchanged"] and not checks["ok"]
    assert checks["stale_stages"] == ["ingest"]      # ingest read the file; nothing else did directly
    assert any(changed in line for line in provenance.provenance_warnings(prov))
    assert json.loads(out.read_text())["checks"] == checks
    (work / RAW / f"{CASE_IDS[2]}.csv").unlink()
    again = provenance.campaign_provenance(work / ROOT, base=work)
    assert again["checks"]["missing_raw_files"] == [(RAW / f"{CASE_IDS[2]}.csv").as_posix()]


def test_provenance_reads_no_raw_file_leading_outside_the_campaign_folder(project, tmp_path):
    work = tmp_path / "copy"
    shutil.copytree(project, work)
    case_file = work / RAW / f"{CASE_IDS[1]}.csv"
    outside = tmp_path / "outside.csv"                 # the same bytes, so a hash would even match
    outside.write_bytes(case_file.read_bytes())
    case_file.unlink()
    case_file.symlink_to(outside)
    prov = provenance.campaign_provenance(work / ROOT, base=work)
    path = (RAW / f"{CASE_IDS[1]}.csv").as_posix()
    entry = next(f for f in prov["raw"]["files"] if f["path"] == path)
    assert entry["outside"] and entry["sha256_now"] is None and entry["unchanged"] is None
    assert prov["checks"]["raw_files_outside"] == [path] and not prov["checks"]["raw_unchanged"]
    assert not prov["checks"]["ok"] and any(path in line for line in provenance.provenance_warnings(prov))


def test_unused_raw_folder_entries_are_listed_by_name_never_hashed(project, tmp_path):
    work = tmp_path / "copy"
    shutil.copytree(project, work)
    secret = tmp_path / "secret.txt"
    secret.write_text("not campaign data\n", encoding="utf-8")
    (work / RAW / "passwd.csv").symlink_to(secret)
    (work / RAW / "notes {old}.txt").write_text("x", encoding="utf-8")
    (work / RAW / "run1").mkdir()
    (work / RAW / "run1" / "spare.csv").write_text("t,x\n", encoding="utf-8")
    prov = provenance.campaign_provenance(work / ROOT, base=work)
    unused = {u["path"]: u for u in prov["raw"]["unused_files"]}
    assert set(unused) == {(RAW / name).as_posix() for name in ("passwd.csv", "notes {old}.txt", "run1/spare.csv")}
    assert "outside the campaign folder" in unused[(RAW / "passwd.csv").as_posix()]["note"]
    named = {f["path"] for f in prov["raw"]["files"]}
    assert not named & set(unused)
    assert sha256(secret) not in json.dumps(prov)


def test_simulated_campaign_provenance_carries_the_rig_spec(tmp_path):
    root = tmp_path / "results" / CAMPAIGN
    with lineage_context(lineage.stage_lineage("virtual_rig", {"spec": SPEC}, [], CAMPAIGN)):
        write_campaign(VirtualCampaign.from_config(CAMPAIGN, SPEC), root)
    raw = provenance.campaign_provenance(root, base=tmp_path)["raw"]
    assert raw["kind"] == "simulation" and raw["virtual_rig"]["seed"] == 7 and raw["virtual_rig"]["spec"] == SPEC
    cases = pd.read_parquet(root / "ingest" / "cases.parquet")
    assert [(f["case"], f["sha256_recorded"]) for f in raw["files"]] == list(zip(cases["case"], cases["raw_sha256"]))


# ----------------------------------------------------------------------------------------------
# row-level sources
# ----------------------------------------------------------------------------------------------

def char_keys(project) -> set[tuple[str, int]]:
    char = pd.read_parquet(project / ROOT / "characteristic.parquet")
    return set(zip(char["case"], char["segment"].astype(int)))


def test_models_rows_name_the_characteristic_rows_they_were_fitted_to(project):
    models = pd.read_parquet(project / ROOT / "models" / "models.parquet")
    char = pd.read_parquet(project / ROOT / "characteristic.parquet").set_index(["case", "segment"])
    assert len(models) and (models["source_file"] == "characteristic.parquet").all()
    for r in models.itertuples():
        keys = parse_row_keys(r.source_rows)
        assert len(keys) == r.n_points and set(keys) <= char_keys(project)
        if r.direction in "+-":
            assert set(char.loc[keys, "direction"]) == {r.direction}
    comparison = pd.read_parquet(project / ROOT / "models" / "comparison.parquet")
    assert set(zip(comparison["case"], comparison["segment"])) == char_keys(project)
    assert not comparison.duplicated(["case", "segment"]).any()


def test_diagnosis_sources_point_to_real_rows(project):
    d = json.loads((project / ROOT / "diagnosis.json").read_text())
    src = d["sources"]
    windows = parse_row_keys(src["windows"])
    assert windows and set(windows) <= char_keys(project) and len(windows) == d["noise"]["n_windows"]
    bins = [k.rsplit(":", 1) for k in src["transient_bins"].split(",")]
    assert sum(int(n) for _, n in bins) == d["noise"]["n_transient_bins"]
    cases = pd.read_parquet(project / ROOT / "cases.parquet").set_index("case")
    for case, ts in src["timeseries"].items():
        assert (project / ROOT / ts["timeseries_file"]).is_file()
        assert ts["raw_sha256"] == cases.loc[case, "raw_sha256"]


def test_harmonic_rows_name_their_sample_range(project):
    table = pd.read_parquet(project / ROOT / "harmonic" / "harmonic.parquet")
    cases = pd.read_parquet(project / ROOT / "cases.parquet").set_index("case")
    assert len(table)
    for r in table.itertuples():
        series = pd.read_parquet(project / ROOT / cases.loc[r.case, "timeseries_file"]).set_index("row")
        assert 0 <= r.row_start < r.row_stop <= len(series)
        assert series.loc[r.row_start, "time_s"] == r.loop_start_s
        assert series.loc[r.row_stop - 1, "time_s"] == r.loop_end_s
        if r.kind == "peak_velocity":
            assert r.loop_start_s <= r.time_s <= r.loop_end_s
        assert (r.raw_file, r.raw_sha256) == (cases.loc[r.case, "raw_file"], cases.loc[r.case, "raw_sha256"])


def test_blind_scores_name_raw_folder_truth_and_diagnosis(tmp_path):
    truth_root, work = tmp_path / "blind" / "truth", tmp_path / "blind" / "diagnosis" / "chunk0"
    for name in ("blind-000", "blind-001"):
        write_json({"scenario": name, "truth": ["friction"], "magnitude_x_detection": 2.0}, truth_root / f"{name}.json")
        (tmp_path / "blind" / "raw" / name).mkdir(parents=True)
    write_campaign_meta(work / "blind-000", "blind-000", source="raw",
                        manifest_file="results/blind/raw/blind-000/campaign.yaml")
    # a record that does not read (a key missing) stops nothing: the raw folder beside the truth file is named
    write_json({"campaign": "blind-001", "manifest_file": "elsewhere/campaign.yaml"},
               work / "blind-001" / "ingest" / "campaign.json")
    write_json({"verdict": ["friction"], "gap_before": 9.0, "gap_after": 1.0, "shrink": 9.0},
               work / "blind-000" / "diagnosis.json")
    scores, _ = blind_score.write_scores(truth_root, [work], tmp_path / "scores.parquet",
                                         tmp_path / "summary.json", tmp_path / "fig.png")
    got = pd.read_parquet(tmp_path / "scores.parquet").set_index("scenario")
    assert list(got.reset_index().columns) == [*SCORE_COLUMNS, *SOURCE_COLUMNS]
    assert got.loc["blind-000", "raw_dir"] == "results/blind/raw/blind-000"          # as ingest recorded it
    assert got.loc["blind-001", "raw_dir"] == (tmp_path / "blind" / "raw" / "blind-001").as_posix()
    assert got.loc["blind-000", "truth_file"] == (truth_root / "blind-000.json").as_posix()
    assert got.loc["blind-000", "diagnosis_file"] == (work / "blind-000" / "diagnosis.json").as_posix()
    assert got.loc["blind-001", "diagnosis_file"] == "" and got.loc["blind-001", "verdict"] == "error"
