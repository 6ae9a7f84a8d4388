"""The audit command: every table kind traced back to its raw data and re-derived.

A small project is built in a temporary folder with the stage functions themselves: a simulated
campaign (``mini``), the same campaign exported as a raw campaign and ingested (``mini-raw``, one
CSV with comment lines before its header), a one-scenario blind suite and the all-campaigns plan
check. Tampering tests work on copies.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import pandas as pd
import pytest
import yaml

from isokinetic.audit import lineage, trace_core
from isokinetic.audit import trace as tr
from isokinetic.contracts.outputs import rule_of
from isokinetic.contracts.settings import SCHEMA_FILE, Settings, with_defaults
from isokinetic.io import lineage_context, write_json, write_parquet
from isokinetic.measurement.model_fit import fit_models
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages import blind_diagnose, blind_score
from isokinetic.stages.characteristic import assemble, paired_repeatability, records_stage, windows_stage
from isokinetic.stages.design import plan_check
from isokinetic.stages.diagnosis import diagnose
from isokinetic.stages.harmonic import harmonic_stage
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.nominal import nominal_stage
from isokinetic.stages.validate import write_validated
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign, write_campaign

#: builds and re-derives a whole project's tables (~20 s)
pytestmark = pytest.mark.slow

DAMPER = {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
          "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
          "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9}
SPEC = {"description": "trace test campaign", "seed": 7, "temperature_C": 40.0, "damper": DAMPER,
        "effects": {"friction": {"coulomb_force_N": 60.0}, "leakage": {"conductance_m3_s_Pa": 2.0e-12}},
        "measurement": {"force_noise_N": 5.0, "force_noise_rel": 0.01, "displacement_noise_m": 1.0e-6},
        "plan": {"triangle": {"velocities_mm_s": [0.02, 0.1, 0.4, 1.0], "periods_s": [40, 20, 20, 20],
                              "sample_rate_Hz": 20.0},
                 "sine": {"frequency_Hz": 1.75, "amplitudes_mm": [0.3], "periods": 4, "sample_rate_Hz": 200.0}}}
ROOT = Path(__file__).resolve().parents[2]
CONFIG = {"raw_dir": "data/raw", "windows": {"start_fraction": 0.45, "end_fraction": 0.95},
          "repeatability": {"tolerance": 0.05},
          "design": {"convergence_fraction": 0.999, "max_amplitude_mm": 10.0, "min_amplitude_mm": 0.1},
          "validation": {"sample_rate_tolerance": 0.05}, "virtual_campaigns": {"mini": SPEC}}
SPEC_W = WindowSpec(0.45, 0.95)
COMMENT = "# rig: bench 2\n# operator: trace fixture\n"


@contextmanager
def cwd(path: Path):
    old = Path.cwd()
    os.chdir(path)
    try:
        yield
    finally:
        os.chdir(old)


def process(root: Path, damper) -> None:
    """Every stage after ingest, as the rules run them, into ``root`` (results/<campaign>)."""
    write_validated(root, sample_rate_tolerance=0.05)
    win = windows_stage(root, SPEC_W)
    records, _energy = records_stage(root)
    rep = paired_repeatability(win, records, 0.05)
    write_parquet(win, root / "windows.parquet")
    write_parquet(rep, root / "repeatability.parquet")
    char = assemble(win, rep, records)
    write_parquet(char, root / "characteristic.parquet")
    write_parquet(nominal_stage(root, SPEC_W), root / "nominal_windows.parquet")
    name = json.loads((root / "ingest" / "campaign.json").read_text())["campaign"]
    write_parquet(plan_check(name, pd.read_parquet(root / "cases.parquet"), damper, phi=0.999, max_amplitude_m=0.01,
                             min_amplitude_m=1e-4, start_fraction=0.45), root / "design" / "plan_check.parquet")
    write_parquet(harmonic_stage(root)[0], root / "harmonic" / "harmonic.parquet")
    models, residuals = fit_models(char, damper)
    write_parquet(models, root / "models" / "models.parquet")
    write_parquet(residuals, root / "models" / "model_residuals.parquet")
    write_json(diagnose(root, SPEC_W)[0], root / "diagnosis.json")


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("trace") / "project"
    (base / "config").mkdir(parents=True)
    (base / "config" / "config.yaml").write_text(yaml.safe_dump(CONFIG, sort_keys=False), encoding="utf-8")
    (base / SCHEMA_FILE).parent.mkdir(parents=True)   # its defaults fill what the config leaves out, as a build's
    shutil.copy(ROOT / SCHEMA_FILE, base / SCHEMA_FILE)
    vc = VirtualCampaign.from_config("mini", SPEC)
    with cwd(base):  # relative paths, as the pipeline records them
        write_campaign(vc, Path("results/mini"))
        process(Path("results/mini"), vc.damper)
        raw = export_raw_campaign(vc, Path("data/raw/mini-raw"))
        csv = raw / "T02.csv"
        csv.write_text(COMMENT + csv.read_text(encoding="utf-8"), encoding="utf-8")
        ingest_campaign(raw, Path("results/mini-raw"))
        process(Path("results/mini-raw"), vc.damper)
        checks = [pd.read_parquet(f"results/{c}/design/plan_check.parquet") for c in ("mini", "mini-raw")]
        write_parquet(pd.concat(checks, ignore_index=True), Path("results/design/plan_check.parquet"))
        b = Path("results/blind")
        export_raw_campaign(vc, b / "raw" / "blind-000")
        write_json({"scenario": "blind-000", "truth": ["friction", "leakage"], "magnitude_x_detection": 3.0},
                   b / "truth" / "blind-000.json")
        blind_diagnose.diagnose_suite(b / "raw", ["blind-000"], b / "diagnosis" / "chunk0",
                                      Settings.from_config(with_defaults(CONFIG, yaml.safe_load(
                                          (ROOT / SCHEMA_FILE).read_text(encoding="utf-8")))))
        blind_score.write_scores(b / "truth", [b / "diagnosis" / "chunk0"], b / "scores.parquet",
                                 b / "summary.json", b / "fig17_blind_confusion.png")
    return base


def restamp(record: dict, *paths: Path) -> None:
    """Write the files again (a folder: every table and JSON inside) as a job with that lineage record would."""
    with lineage_context(record):
        for path in paths:
            for f in sorted(path.rglob("*")) if path.is_dir() else [path]:
                if f.suffix == ".parquet":
                    write_parquet(pd.read_parquet(f), f)
                elif f.suffix == ".json":
                    write_json(json.loads(f.read_text(encoding="utf-8")), f)


def copy_project(project: Path, dst: Path, *parts: str) -> Path:
    """A copy of the config, its schema and the named folders (e.g. 'results/mini', 'data/raw/mini-raw')."""
    shutil.copytree(project / "config", dst / "config")
    shutil.copytree(project / "workflow", dst / "workflow")
    for part in parts:
        shutil.copytree(project / part, dst / part)
    return dst


def run(table: Path, selector: str | None = None, **kwargs) -> tr.TraceResult:
    return tr.trace(table, selector, stream=None, **kwargs)


# --------------------------------------------------------------------------------------------
# matches
# --------------------------------------------------------------------------------------------

def test_cli_traces_a_raw_characteristic_point_down_to_its_csv_lines(project, tmp_path):
    table = project / "results/mini-raw/characteristic.parquet"
    proc = subprocess.run([sys.executable, "-m", "isokinetic", "trace", str(table), "case=T02,segment=3"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    out = proc.stdout
    assert out.rstrip().splitlines()[-1] == "MATCH"
    row = pd.read_parquet(table).query("case == 'T02' and segment == 3").iloc[0]
    lines = (project / "data/raw/mini-raw/T02.csv").read_text().splitlines()
    first = lines[2 + 1 + int(row["row_start"])]  # two comment lines and the header come first
    assert f"line {2 + 1 + int(row['row_start']) + 1}: {first}" in out
    assert "data/raw/mini-raw/T02.csv" in out and row["raw_sha256"][:12] in out
    assert "windows.window_ranges" in out and "least-squares slope" in out
    assert "force_N" in out and "identical" in out


CASES = [
    ("results/mini/cases.parquet", "case=T01"),
    ("results/mini/ingest/cases.parquet", "row=4"),
    ("results/mini/ingest/timeseries/T03.parquet", "row=7"),
    ("results/mini/windows.parquet", "row=5"),
    ("results/mini/characteristic.parquet", "case=T03,segment=2"),
    ("results/mini/repeatability.parquet", "case=T02,direction=-"),
    ("results/mini/nominal_windows.parquet", "case=T04,segment=3"),
    ("results/mini/design/plan_check.parquet", "case=T02"),
    ("results/mini/design/plan_check.parquet", "case=H01"),
    ("results/design/plan_check.parquet", "campaign=mini-raw,case=T03"),
    ("results/mini/harmonic/harmonic.parquet", "case=H01,direction=+"),
    ("results/mini/models/models.parquet", "model=surace,direction=-,parameter=D_Q"),
    ("results/mini/models/models.parquet", "model=wallaschek,parameter=c1"),
    ("results/mini/models/model_residuals.parquet", "model=wallaschek,case=T02,segment=1"),
    ("results/mini/diagnosis.json", "gap_before"),
    ("results/mini/diagnosis.json", None),
    ("results/mini-raw/cases.parquet", "case=T02"),
    ("results/mini-raw/ingest/timeseries/T02.parquet", "row=0"),
    ("results/mini-raw/repeatability.parquet", "case=T04,direction=+"),
    ("results/mini-raw/models/models.parquet", "model=surace,direction=+,parameter=F_C"),
    ("results/mini-raw/harmonic/harmonic.parquet", "row=0"),
    ("results/blind/scores.parquet", "scenario=blind-000"),
    ("results/blind/diagnosis/chunk0/blind-000/characteristic.parquet", "case=T01,segment=4"),
]


@pytest.mark.parametrize("table, selector", CASES)
def test_every_table_kind_is_rederived_to_a_match(project, table, selector):
    result = run(project / table, selector)
    assert result.status == tr.MATCH, result.text
    assert result.exit_code == 0
    assert result.comparisons and all(c.ok for c in result.comparisons)
    assert result.text.rstrip().splitlines()[-1] == "MATCH"


def test_timeseries_row_shows_the_raw_line_and_its_conversion(project):
    result = run(project / "results/mini-raw/ingest/timeseries/T02.parquet", "row=3")
    assert result.status == tr.MATCH, result.text
    line = (project / "data/raw/mini-raw/T02.csv").read_text().splitlines()[2 + 1 + 3]
    assert f"line 7: {line}" in result.text
    assert "force_kN [kN] x 1000 -> force_N" in result.text


def test_simulated_case_is_resimulated_and_its_csv_hash_checked(project):
    result = run(project / "results/mini/characteristic.parquet", "case=T04,segment=1")
    assert result.status == tr.MATCH
    assert "virtual_campaigns.mini" in result.text and "(re-simulated CSV)" in result.text
    sha = pd.read_parquet(project / "results/mini/cases.parquet").set_index("case").loc["T04", "raw_sha256"]
    assert f"sha256 {sha[:12]}.. = recorded" in result.text


def test_lineage_records_supply_the_spec_and_parameters_without_a_config(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "results/mini")
    with cwd(dst):
        root = Path("results/mini")
        restamp(lineage.stage_lineage("virtual_rig", {"spec": SPEC}, [], "mini"), root / "ingest")
        restamp(lineage.stage_lineage("validate", {"sample_rate_tolerance": 0.05, "max_missing_fraction": 0.05,
                                                   "max_gap_s": 0.1}, [root / "ingest"], "mini"),
                root / "cases.parquet")
        restamp(lineage.stage_lineage("windows", {"start_fraction": 0.45, "end_fraction": 0.95},
                                      [root / "cases.parquet", root / "ingest"], "mini"), root / "windows.parquet")
        restamp(lineage.stage_lineage("repeatability", {"tolerance": 0.05}, [root / "windows.parquet"], "mini"),
                root / "repeatability.parquet")
        restamp(lineage.stage_lineage("characteristic", {}, [root / "windows.parquet", root / "repeatability.parquet"],
                                      "mini"), root / "characteristic.parquet")
    shutil.rmtree(dst / "config")
    result = run(dst / "results/mini/characteristic.parquet", "case=T02,segment=2")
    assert result.status == tr.MATCH, result.text
    assert "lineage: rule characteristic, campaign mini" in result.text
    assert "input results/mini/windows.parquet" in result.text and "unchanged" in result.text
    assert "spec from lineage params of results/mini/ingest/cases.parquet" in result.text
    assert "from lineage params of results/mini/windows.parquet" in result.text


# --------------------------------------------------------------------------------------------
# changed raw data, missing files, tampered derived values
# --------------------------------------------------------------------------------------------

def flip_one_byte(path: Path) -> None:
    data = bytearray(path.read_bytes())
    i = data.rindex(b"\n", 0, len(data) - 1) - 1   # last character of the second-to-last line
    data[i] = ord("7") if data[i] != ord("7") else ord("3")
    path.write_bytes(bytes(data))


def test_one_byte_edit_of_a_raw_file_is_reported_and_exit_2(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "data/raw/mini-raw", "results/mini-raw")
    flip_one_byte(dst / "data/raw/mini-raw/T03.csv")
    table = dst / "results/mini-raw/characteristic.parquet"
    proc = subprocess.run([sys.executable, "-m", "isokinetic", "trace", str(table), "case=T03,segment=1"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    lines = proc.stdout.rstrip().splitlines()
    assert lines[-1] == "RAW FILE CHANGED"
    assert "T03.csv has sha256" in proc.stdout and "recorded in results/mini-raw/cases.parquet" in proc.stdout
    assert "Window statistics" not in proc.stdout  # nothing recomputed from the changed file
    # a fit over the whole campaign notices it as well; an untouched case still matches
    assert run(dst / "results/mini-raw/models/models.parquet", "row=0").status == tr.RAW_CHANGED
    assert run(dst / "results/mini-raw/characteristic.parquet", "case=T01,segment=1").status == tr.MATCH


def test_missing_raw_file_and_edited_manifest(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "data/raw/mini-raw", "results/mini-raw")
    (dst / "data/raw/mini-raw/T04.csv").unlink()
    result = run(dst / "results/mini-raw/repeatability.parquet", "case=T04,direction=+")
    assert result.status == tr.MISSING and result.exit_code == 2, result.text
    assert "T04.csv not found" in result.text
    manifest = dst / "data/raw/mini-raw/campaign.yaml"
    manifest.write_text(manifest.read_text().replace("disp_mm", "disp_um"), encoding="utf-8")
    result = run(dst / "results/mini-raw/characteristic.parquet", "case=T01,segment=1")
    assert result.status == tr.RAW_CHANGED and result.exit_code == 2
    assert "campaign.yaml" in result.text
    assert run(dst / "results/mini-raw/nominal.parquet", "row=0").status == tr.MISSING


def test_changed_virtual_spec_is_reported_as_changed_raw_data(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "results/mini")
    config = yaml.safe_load((dst / "config/config.yaml").read_text())
    config["virtual_campaigns"]["mini"]["seed"] = 8
    (dst / "config/config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    result = run(dst / "results/mini/windows.parquet", "case=T01,segment=1")
    assert result.status == tr.RAW_CHANGED and result.exit_code == 2, result.text
    assert "or the simulator changed after processing" in result.text


def test_tampered_derived_values_are_mismatches(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "results/mini")
    path = dst / "results/mini/characteristic.parquet"
    char = pd.read_parquet(path)
    i = char.index[(char["case"] == "T03") & (char["segment"] == 2)][0]
    char.loc[i, "force_N"] *= 1 + 1e-7
    write_parquet(char, path)
    result = run(path, "case=T03,segment=2")
    assert result.status == tr.MISMATCH and result.exit_code == 1, result.text
    assert [c.name for c in result.comparisons if not c.ok] == ["force_N"]
    assert "DIFFER" in result.text and result.text.rstrip().splitlines()[-1] == "MISMATCH"
    # the untouched neighbour still matches; a tampered fit and diagnosis value are caught too
    assert run(path, "case=T03,segment=4").status == tr.MATCH
    char["note"] = "added by a script"  # a column the stage functions do not make is listed, not compared
    write_parquet(char, path)
    result = run(path, "case=T03,segment=4")
    assert result.status == tr.MATCH and "not compared: note" in result.text
    models = pd.read_parquet(dst / "results/mini/models/models.parquet")
    models.loc[0, "estimate"] += 1.0
    write_parquet(models, dst / "results/mini/models/models.parquet")
    assert run(dst / "results/mini/models/models.parquet", "row=0").status == tr.MISMATCH
    diag = json.loads((dst / "results/mini/diagnosis.json").read_text())
    diag["gap_after"] *= 1.001
    write_json(diag, dst / "results/mini/diagnosis.json")
    result = run(dst / "results/mini/diagnosis.json", "gap_after")
    assert result.status == tr.MISMATCH and result.exit_code == 1


# --------------------------------------------------------------------------------------------
# selectors and refusals
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("table, selector, words", [
    ("results/mini/characteristic.parquet", "case=T03", "4 rows match case=T03; narrow it with one of segment"),
    ("results/mini/characteristic.parquet", "cas=T03", "no column 'cas'"),
    ("results/mini/characteristic.parquet", "case=T99", "no row matches case=T99"),
    ("results/mini/characteristic.parquet", "row=999", "row=999"),
    ("results/mini/characteristic.parquet", None, "give a selector"),
    ("results/mini/diagnosis.json", "seconds", "not re-derivable"),
    ("results/mini/diagnosis.json", "params.nothing", "no 'nothing'"),
    ("results/mini/quarantine.parquet", "row=0", "not a table trace knows"),
])
def test_bad_selectors_and_unknown_tables_cannot_be_traced(project, table, selector, words):
    result = run(project / table, selector)
    assert result.status == tr.CANNOT and result.exit_code == 2
    assert words in result.text, result.text


def test_simulated_campaign_without_spec_cannot_be_traced(project, tmp_path):
    result = run(project / "results/mini/characteristic.parquet", "row=0", config=tmp_path / "absent.yaml")
    assert result.status == tr.CANNOT and "nothing to re-simulate from" in result.text


def test_selector_parsing_and_value_comparison():
    core = trace_core
    assert core.parse_selector("case=T12, direction=-") == {"case": "T12", "direction": "-"}
    with pytest.raises(core.TraceStop):
        core.parse_selector("T12")
    assert core.compare_value("x", 1.0, 1.0 + 1e-12, rtol=1e-9)[0].ok
    assert not core.compare_value("x", 1.0, 1.0 + 1e-8, rtol=1e-9)[0].ok
    assert core.compare_value("x", float("nan"), float("nan"), rtol=1e-9)[0].ok
    assert core.compare_value("s", 1e-15, 0.0, rtol=1e-9, atol=1e-7)[0].ok  # a rounding-size spread
    nested = core.compare_value("", {"a": [1.0, {"b": 2.0}], "seconds": 3.0}, {"a": [1.0, {"b": 2.5}], "seconds": 9.0},
                                rtol=1e-9)
    assert [(c.name, c.ok) for c in nested] == [("a.0", True), ("a.1.b", False)]


def test_blind_score_is_rescored_from_the_truth_file_and_a_fresh_diagnosis(project):
    result = run(project / "results/blind/scores.parquet", "scenario=blind-000")
    assert result.status == tr.MATCH, result.text
    assert "results/blind/truth/blind-000.json" in result.text
    assert "results/blind/raw/blind-000/T01.csv" in result.text and "diagnosis.diagnose" in result.text
    scores = pd.read_parquet(project / "results/blind/scores.parquet")
    for col in ("raw_dir", "truth_file", "diagnosis_file"):  # provenance columns, when write_scores adds them
        if col in scores.columns:
            assert col in result.text.split("not compared:")[1].splitlines()[0]


def rebuild_mini_raw_windows(dst: Path) -> None:
    """Ingest, validate and windows of the copied project's mini-raw campaign, in-process."""
    with cwd(dst):
        root = Path("results/mini-raw")
        ingest_campaign(Path("data/raw/mini-raw"), root)
        write_validated(root, sample_rate_tolerance=0.05)
        write_parquet(windows_stage(root, SPEC_W), root / "windows.parquet")


# --------------------------------------------------------------------------------------------
# timing from the record: windows at the measured motion start
# --------------------------------------------------------------------------------------------

def test_windows_of_a_delayed_case_on_an_offset_time_axis_are_rederived(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "data/raw/mini-raw")
    csv = dst / "data/raw/mini-raw/T03.csv"
    table = pd.read_csv(csv, dtype=str)
    table["time_s"] = (table["time_s"].astype(float) + 7.3).map("{:.10g}".format)   # time axis offset
    for column in ("disp_mm", "force_kN"):                                          # 150 ms actuator delay
        values = table[column].tolist()
        table[column] = values[:1] * 3 + values[:-3]
    csv.write_text(table.to_csv(index=False), encoding="utf-8")
    rebuild_mini_raw_windows(dst)
    t03 = pd.read_parquet(dst / "results/mini-raw/cases.parquet").set_index("case").loc["T03"]
    assert t03["status"] == "ok" and t03["delay_s"] == pytest.approx(0.15, abs=0.005)
    assert t03["motion_start_s"] == pytest.approx(7.45, abs=0.005) and "time axis offset" in t03["quality"]
    result = run(dst / "results/mini-raw/windows.parquet", "case=T03,segment=2")
    assert result.status == tr.MATCH, result.text
    assert f"plan t = 0 at record t = {t03['motion_start_s']:.6g} s" in result.text
    assert f"delay {t03['delay_s'] * 1e3:.4g} ms after the first sample" in result.text
    result = run(dst / "results/mini-raw/cases.parquet", "case=T03")
    assert result.status == tr.MATCH, result.text
    assert "motion_start_s" in result.text and "delay_s" in result.text


def test_a_window_with_a_spike_left_out_is_rederived_to_a_match_that_says_so(project, tmp_path):
    dst = copy_project(project, tmp_path / "p", "data/raw/mini-raw")
    csv = dst / "data/raw/mini-raw/T03.csv"
    table = pd.read_csv(csv, dtype=str)
    window = pd.read_parquet(project / "results/mini-raw/windows.parquet").query("case == 'T03' and segment == 2")
    at = (int(window["row_start"].iloc[0]) + int(window["row_stop"].iloc[0])) // 2
    table.loc[at, "force_kN"] = f"{float(table.loc[at, 'force_kN']) + 10.0:.10g}"    # one 10 kN spike
    csv.write_text(table.to_csv(index=False), encoding="utf-8")
    rebuild_mini_raw_windows(dst)
    row = pd.read_parquet(dst / "results/mini-raw/windows.parquet").query("case == 'T03' and segment == 2").iloc[0]
    assert row["spikes_excluded"] == 1
    result = run(dst / "results/mini-raw/windows.parquet", "case=T03,segment=2")
    assert result.status == tr.MATCH, result.text
    assert "1 left out as spikes by measurement.spikes.spike_mask" in result.text


def test_every_table_kind_is_a_file_a_rule_writes():
    """Where each table lies comes from isokinetic.contracts.outputs, not from a map of trace's own."""
    for kind in tr.KINDS.values():
        assert rule_of(kind.path.replace("*", "T01")) is not None, kind.name
    assert tr.table_kind(Path("results/x/ingest/cases.parquet")).name == "ingest_cases"
    assert tr.table_kind(Path("results/x/cases.parquet")).name == "cases"
    assert tr.table_kind(Path("results/x/ingest/timeseries/T01.parquet")).name == "timeseries"
    assert tr.table_kind(Path("results/design/plan_check.parquet")).name == "plan_check"
    with pytest.raises(tr.TraceStop, match="not a table trace knows"):
        tr.table_kind(Path("results/x/quarantine.parquet"))


# --------------------------------------------------------------------------------------------
# the CSV exports (characteristic.csv, models/models.csv)
# --------------------------------------------------------------------------------------------

def _exported(project: Path, dst: Path) -> Path:
    from isokinetic.stages.exports import write_exports

    dst = copy_project(project, dst, "results/mini-raw", "data/raw/mini-raw")
    write_exports(dst / "results/mini-raw")
    return dst / "results/mini-raw"


def test_csv_exports_are_traced_through_their_parquet_rows(project, tmp_path):
    root = _exported(project, tmp_path / "p")
    char = pd.read_parquet(root / "characteristic.parquet")
    as_csv = run(root / "characteristic.csv", "row=5")
    as_parquet = run(root / "characteristic.parquet", "row=5")
    assert as_csv.status == tr.MATCH and as_csv.exit_code == 0, as_csv.text
    assert "line 8 of the file" in as_csv.text and "force_N [N]" in as_csv.text  # the names and units rows
    assert [(c.name, c.stored) for c in as_csv.comparisons] == [(c.name, c.stored) for c in as_parquet.comparisons]
    stored = {c.name: c.stored for c in as_csv.comparisons}
    assert stored["case"] == char.loc[5, "case"] and stored["force_N"] == char.loc[5, "force_N"]
    by_key = run(root / "characteristic.csv", f"case={char.loc[5, 'case']},segment={char.loc[5, 'segment']}")
    assert by_key.status == tr.MATCH and "line 8 of the file" in by_key.text
    models = run(root / "models/models.csv", "row=1")
    assert models.status == tr.MATCH, models.text


def test_an_edited_csv_export_is_a_mismatch_naming_line_and_field(project, tmp_path):
    root = _exported(project, tmp_path / "p")
    path = root / "characteristic.csv"
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    fields = lines[3].split(",")
    col = lines[0].split(",").index("force_N")
    fields[col] = repr(float(fields[col]) + 1.0)
    lines[3] = ",".join(fields)
    path.write_text("".join(lines), encoding="utf-8")
    result = run(path, "row=1")
    assert result.status == tr.MISMATCH and result.exit_code == 1, result.text
    assert "line 4 of" in result.text and "force_N: CSV" in result.text
    other = run(path, "row=0")  # an untouched line still matches; the edited one is pointed out
    assert other.status == tr.MATCH and "1 other line(s) of the file differ from their source rows (lines 4)" \
        in other.text, other.text


def test_a_directory_or_fifo_is_named_as_what_it_is_not_as_missing(tmp_path):
    from isokinetic.audit.trace import trace

    folder = tmp_path / "results" / "c" / "characteristic.parquet"
    folder.mkdir(parents=True)
    fifo = tmp_path / "results" / "c" / "windows.parquet"
    os.mkfifo(fifo)
    for path, said in ((folder, "a directory, not a table file"), (fifo, "a named pipe (FIFO)"),
                       (tmp_path / "results" / "c" / "none.parquet", "no such file")):
        result = trace(path, root=tmp_path, stream=None)
        assert result.status == "MISSING FILE" and said in result.text, result.text
