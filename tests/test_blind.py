"""Blind test of the diagnosis: scenario generation, truth-free export, scoring, and a small end-to-end suite."""

import hashlib
import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from isokinetic import blind
from isokinetic import reference_rig as rr
from isokinetic.blind import (BOUNDS, EFFECTS, effect_fields, generate_scenarios, magnitude_bin, score,
                              summarize, summary_text, write_suite)
from isokinetic.damper import Effects
from isokinetic.virtual_rig import Measurement, simulate_cases
from isokinetic.windows import case_windows

ROOT = Path(__file__).resolve().parents[1]
SEED = 11
SUITE = dict(n_per_effect=1, n_pairs=2, n_none=1, n_out=3)
# small plans (8 speeds, no 240 s periods) keep the end-to-end suite fast
SMALL = dict(multiple=3.0, n_velocities=(8, 8), low_end_mm_s=(0.015, 0.05))


@pytest.fixture(scope="module")
def suite():
    return generate_scenarios(SEED, **SUITE)


def tree_hashes(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------------------------
# generation
# --------------------------------------------------------------------------------------------

def test_generation_is_deterministic_and_composed_as_asked(suite):
    assert generate_scenarios(SEED, **SUITE) == suite
    assert generate_scenarios(SEED + 1, **SUITE) != suite
    assert [s.name for s in suite] == [f"blind-{k:03d}" for k in range(12)]
    sizes = sorted(len(s.truth) for s in suite)
    assert sizes == [0] * 4 + [1] * 6 + [2] * 2
    assert sorted(s.out_of_catalogue for s in suite if s.out_of_catalogue) == sorted(blind.OUT_OF_CATALOGUE)
    assert all(not s.truth for s in suite if s.out_of_catalogue)
    assert sorted(s.truth[0] for s in suite if len(s.truth) == 1) == sorted(EFFECTS)
    assert len({s.truth for s in suite if len(s.truth) == 2}) == 2  # distinct pairs
    for s in suite:
        assert s.truth == tuple(e for e in EFFECTS if e in s.truth)
        for name in blind.GEOMETRY_FIELDS:
            assert 0.7 <= getattr(s.damper, name) / getattr(blind.TABLE1, name) <= 1.3
        speeds = [c.velocity_m_s * 1e3 for c in s.cases]
        assert 8 <= len(speeds) <= 12 and 0.005 <= min(speeds) and max(speeds) <= 1.5
        assert speeds != sorted(speeds)  # tested in a random order, not by speed
        for c in s.cases:
            assert 0.3e-3 * (1 - 1e-9) <= c.amplitude_m <= 8e-3 and c.period_s in (20.0, 80.0, 240.0)
            shorter = [t for t in (20.0, 80.0, 240.0) if t < c.period_s]
            assert all(c.velocity_m_s * t / 4 < 0.3e-3 for t in shorter)  # shortest period above the floor
            assert c.sample_rate_Hz == 50.0 and c.duration_s == 2 * c.period_s
        r, ranges = s.rig, blind.RIG_RANGES  # nuisances in every scenario
        assert ranges["delay_s"][0] <= r.delay_s <= ranges["delay_s"][1] and r.servo_lag_s > 0
        assert 2 <= r.force_noise_N <= 10 and 0.005 <= r.force_noise_rel <= 0.015
        assert 0.1 <= r.noise_corner_Hz <= 5.0 and abs(r.force_gain - 1) <= 0.01 and r.force_offset_N != 0
        assert abs(r.force_offset_N) <= 0.02 * blind.full_scale_N(s.damper, s.cases)


def test_magnitudes_lie_between_1_and_5_detection_levels(suite):
    for s in suite:
        assert set(s.multiple) == set(s.detection_level) == set(s.magnitude) == set(s.truth)
        for e in s.truth:
            assert 1.0 <= s.multiple[e] <= 5.0
            assert s.magnitude[e] == pytest.approx(s.multiple[e] * s.detection_level[e], rel=1e-12)
            assert 5.0 * s.detection_level[e] <= BOUNDS[e]
        if s.truth:
            assert s.magnitude_x_detection == min(s.multiple.values())
        else:
            assert math.isnan(s.magnitude_x_detection)


def test_physical_effects_have_the_drawn_catalogue_magnitudes(suite):
    for s in suite:
        params = s.truth_params()
        for e in s.truth:
            key = blind.PARAM_KEYS[e]
            want = effect_fields(e, s.magnitude[e], s.sign[e], s.damper)
            expected = next(iter(want.values()))
            assert params[key] == pytest.approx(expected, rel=1e-6), (s.name, e)


def _independent_rms_z(scenario, effects: Effects) -> float:
    """rms_z of the noise-free effect against the nominal, from the virtual rig's time series, the
    window extraction and the rig's exact noise of a window mean."""
    ideal = Measurement.ideal()
    with_effect = simulate_cases(scenario.cases, scenario.damper, effects, ideal, 0)
    nominal = simulate_cases(scenario.cases, scenario.damper, Effects(), ideal, 0)
    z = []
    for c in scenario.cases:
        for we, w0 in zip(case_windows(c, with_effect[c.case]), case_windows(c, nominal[c.case])):
            f = we["force_N"]
            se = math.sqrt(rr.mean_noise_variance(we["n_samples"], f, scenario.rig, c.sample_rate_Hz))
            z.append((f - w0["force_N"]) / se)
    return float(np.sqrt(np.mean(np.square(z))))


def test_detection_level_gives_rms_z_3_checked_independently(suite):
    seen = set()
    for s in suite:
        for e in s.truth:
            if e in seen:
                continue
            seen.add(e)
            def at(k):
                return Effects(**effect_fields(e, k * s.detection_level[e], s.sign[e], s.damper))
            assert _independent_rms_z(s, at(1.0)) == pytest.approx(3.0, rel=1e-4), (s.name, e)
            assert _independent_rms_z(s, at(0.5)) < 3.0  # the smallest magnitude reaching 3
    assert seen == set(EFFECTS)


def test_undetectable_effect_gives_no_detection_level(suite):
    s = next(s for s in suite if not s.truth)
    problem = blind.DetectionProblem.of(s.name, s.cases, s.damper, s.rig)
    assert blind.detection_level(problem, "friction", bound=1e-3) is None
    assert blind.detection_level(problem, "friction") == pytest.approx(
        blind.detection_level(problem, "friction", bound=10 * BOUNDS["friction"]), rel=1e-5)


# --------------------------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------------------------

def test_export_holds_no_truth_and_is_byte_reproducible(suite, tmp_path):
    write_suite(suite, tmp_path / "a" / "raw", tmp_path / "a" / "truth")
    write_suite(generate_scenarios(SEED, **SUITE), tmp_path / "b" / "raw", tmp_path / "b" / "truth")
    assert tree_hashes(tmp_path / "a") == tree_hashes(tmp_path / "b")
    raw = tmp_path / "a" / "raw"
    assert sorted(p.name for p in raw.iterdir()) == [s.name for s in suite]
    for s in suite:
        folder = raw / s.name
        assert sorted(p.name for p in folder.iterdir()) == sorted(["campaign.yaml"] + [f"{c.case}.csv"
                                                                                      for c in s.cases])
        text = (folder / "campaign.yaml").read_text(encoding="utf-8")
        manifest = yaml.safe_load(text)
        # the damper block is the nominal design data (checked below); everything else names no effect
        lowered = yaml.safe_dump({k: v for k, v in manifest.items() if k != "damper"}).lower()
        for word in EFFECTS + blind.OUT_OF_CATALOGUE + ("effects:", "seed", "truth", "coulomb", "conductance",
                                                         "volume_fraction", "multiple", "detection", "offset", "gain"):
            assert word not in lowered, (s.name, word)
        for value in s.magnitude.values():
            assert repr(value) not in text and f"{value:.6g}" not in text
        assert manifest["source"] == "simulation" and manifest["campaign"] == s.name
        assert manifest["description"] == blind.DESCRIPTION
        assert manifest["damper"] == s.damper.to_dict()  # nominal: no off-nominal C_D or viscosity
        truth = json.loads((tmp_path / "a" / "truth" / f"{s.name}.json").read_text(encoding="utf-8"))
        assert truth["truth"] == list(s.truth) and truth["multiple"] == s.multiple
        assert truth["out_of_catalogue"] == s.out_of_catalogue
        assert truth["magnitude_bin"] == magnitude_bin(s.magnitude_x_detection)


# --------------------------------------------------------------------------------------------
# scoring
# --------------------------------------------------------------------------------------------

def _truth(name, effects, multiple, out=""):
    return {"scenario": name, "truth": list(effects), "magnitude_x_detection": multiple, "out_of_catalogue": out}


def _diag(verdict, gap_before=10.0, gap_after=1.0, confounded=None, explained=True):
    d = {"status": "ok", "verdict": list(verdict), "gap_before": gap_before, "gap_after": gap_after,
         "shrink": None if gap_after is None else gap_before / gap_after, "explained": explained}
    if confounded:
        d["confounded"] = confounded
    return d


HAND = [
    (_truth("s00", ["friction"], 1.5), _diag(["friction"])),                       # 1-2x, exact
    (_truth("s01", ["leakage"], 2.0), _diag(["discharge"], confounded=[["leakage", "discharge"]])),  # 2-3x miss
    (_truth("s02", ["air"], 2.5), _diag(["air"], 8.0, 2.0)),                        # 2-3x exact, shrink 4
    (_truth("s03", ["viscosity"], 4.9), _diag(["viscosity"], 30.0, 1.0)),           # 3-5x exact
    (_truth("s04", ["air", "leakage"], 1.2), _diag(["leakage"], 20.0, 2.0)),        # pair, 1-2x, miss
    (_truth("s05", [], None), _diag([], 1.0, 1.0)),                                 # none, clean
    (_truth("s06", [], None), _diag(["friction"], 1.1, 1.0)),                       # none, claimed
    (_truth("s07", ["asymmetry"], 3.0), None),                                      # diagnosis failed
    (_truth("s08", [], None, "backlash"), _diag(["air"], 9.0, 3.0, explained=False)),  # out of catalogue, flagged
    (_truth("s09", [], None, "relief"), _diag(["discharge"], 9.0, 1.0)),            # out of catalogue, missed
]


def test_score_rows_bins_and_exactness():
    truths = [t for t, _ in HAND]
    diagnoses = {t["scenario"]: d for t, d in HAND if d is not None}
    scores = score(reversed(truths), diagnoses)
    assert list(scores.columns) == list(blind.SCORE_COLUMNS)
    assert scores["scenario"].tolist() == [f"s{k:02d}" for k in range(10)]
    s = scores.set_index("scenario")
    assert s["truth"].tolist() == ["friction", "leakage", "air", "viscosity", "leakage+air", "", "", "asymmetry",
                                   "", ""]
    assert s["verdict"].tolist() == ["friction", "discharge", "air", "viscosity", "leakage", "", "friction", "error",
                                     "air", "discharge"]
    assert s["exact"].tolist() == [True, False, True, True, False, True, False, False, False, False]
    assert s.loc["s01", "exact_up_to_confounding"] and not s.loc["s04", "exact_up_to_confounding"]
    assert s.loc["s01", "confounded"] == "leakage+discharge"
    assert s["magnitude_bin"].tolist() == ["1-2x", "2-3x", "2-3x", "3-5x", "1-2x", "", "", "3-5x", "", ""]
    assert np.isnan(s.loc["s05", "magnitude_x_detection"]) and np.isnan(s.loc["s07", "shrink"])
    assert s["error"].tolist() == [False] * 7 + [True, False, False]
    assert s.loc["s03", "shrink"] == 30.0 and s.loc["s02", "gap_after"] == 2.0

    summary = summarize(scores)
    json.dumps(summary, allow_nan=False)
    assert summary["bins"]["1-2x"] == {"n": 2, "exact": 1, "rate": 0.5, "n_single": 1, "exact_single": 1,
                                       "rate_single": 1.0}
    assert summary["bins"]["2-3x"]["n"] == 2 and summary["bins"]["2-3x"]["exact"] == 1
    assert summary["bins"]["3-5x"]["n"] == 2 and summary["bins"]["3-5x"]["exact"] == 1
    a, b, c, d = (summary["targets"][k] for k in ("a_single_at_2x", "b_none_clean", "c_out_of_catalogue",
                                                  "d_median_shrink"))
    assert (a["n"], a["exact"], a["pass"], a["misses"]) == (4, 2, False, ["s01", "s07"])
    assert (b["n"], b["claimed"], b["pass"], b["misses"]) == (2, 1, False, ["s06"])
    assert (c["n"], c["flagged"], c["rate"], c["pass"], c["misses"]) == (2, 1, 0.5, False, ["s09"])
    # shrink over s00-s04 (s07 failed): 10, 10, 4, 30, 10 -> median 10
    assert (d["n"], d["median"], d["pass"]) == (5, 10.0, True)
    assert summary["n_errors"] == 1 and summary["all_pass"] is False
    text = summary_text(summary)
    assert "(a) FAIL" in text and "(b) FAIL" in text and "(c) FAIL" in text and "(d) PASS" in text
    assert "1-2x" in text


def test_targets_pass_and_not_applicable():
    clean = [(_truth("s00", ["friction"], 2.0), _diag(["friction"], 10.0, 1.0)),
             (_truth("s01", [], None), _diag([], 1.0, 1.0))]
    summary = summarize(score([t for t, _ in clean], {t["scenario"]: d for t, d in clean}))
    assert [summary["targets"][k]["pass"] for k in ("a_single_at_2x", "b_none_clean", "d_median_shrink")] == [True] * 3
    assert summary["targets"]["c_out_of_catalogue"]["pass"] is None  # no scenario to judge
    assert summary["all_pass"] is True
    empty = summarize(score([_truth("s00", ["friction"], 1.5)], {"s00": _diag(["friction"])}))
    assert empty["targets"]["a_single_at_2x"]["pass"] is None and empty["targets"]["b_none_clean"]["pass"] is None
    assert "(a) N/A" in summary_text(empty)


def test_confusion_counts_and_figure(tmp_path):
    scores = score([t for t, _ in HAND], {t["scenario"]: d for t, d in HAND if d is not None})
    table = blind.confusion_counts(scores)
    assert table.index.tolist() == ["none", "(backlash)", "(relief)", "friction", "leakage", "asymmetry", "viscosity",
                                    "air", "leakage+air"]
    assert table.to_numpy().sum() == len(HAND)
    assert table.loc["none", "none"] == 1 and table.loc["none", "friction"] == 1
    assert table.loc["leakage", "discharge"] == 1 and table.loc["asymmetry", "error"] == 1
    path = blind.save_figure(blind.confusion_figure(scores, summarize(scores)), tmp_path / "fig.png")
    assert path.stat().st_size > 0


# --------------------------------------------------------------------------------------------
# end to end: one scenario per effect plus one without, each at 3x detection
# --------------------------------------------------------------------------------------------

def test_small_blind_suite_attributes_every_effect(tmp_path):
    pytest.importorskip("isokinetic.diagnosis")
    scenarios = generate_scenarios(5, 1, 0, 1, **SMALL)
    assert sorted(s.truth for s in scenarios) == sorted([()] + [(e,) for e in EFFECTS])
    write_suite(scenarios, tmp_path / "raw", tmp_path / "truth")
    shutil.copytree(tmp_path / "raw", tmp_path / "raw-before")
    diagnoses = blind.diagnose_suite(tmp_path / "raw", [s.name for s in scenarios], tmp_path / "work")
    assert tree_hashes(tmp_path / "raw") == tree_hashes(tmp_path / "raw-before")  # raw data untouched
    for s in scenarios:
        folder = tmp_path / "work" / s.name
        for name in ("cases.parquet", "characteristic.parquet", "diagnosis.json", blind.DIAGNOSIS_FIGURE):
            assert (folder / name).is_file(), (s.name, name)
    scores = score(blind.read_truths(tmp_path / "truth"), diagnoses)
    assert scores["verdict"].tolist() == scores["truth"].tolist(), scores[["scenario", "truth", "verdict"]]
    summary = summarize(scores)
    assert summary["all_pass"], summary_text(summary)


# --------------------------------------------------------------------------------------------
# workflow wiring
# --------------------------------------------------------------------------------------------

def test_workflow_runs_blind_test_in_four_jobs(tmp_path):
    work = tmp_path / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow", ignore=shutil.ignore_patterns("__pycache__"))
    (work / "config").mkdir()
    (work / "data" / "raw").mkdir(parents=True)
    config = yaml.safe_load((ROOT / "config" / "config.yaml").read_text(encoding="utf-8"))
    config["virtual_campaigns"] = {}
    config["blind"] = {"seed": 1, "n_per_effect": 1, "n_pairs": 1, "n_none": 2, "chunks": 2}
    (work / "config" / "config.yaml").write_text(yaml.safe_dump(config), encoding="utf-8")
    proc = subprocess.run([str(Path(sys.executable).parent / "snakemake"), "-n", "--cores", "2"], cwd=work,
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout + proc.stderr
    stats = {w[0]: w[1] for w in map(str.split, out.splitlines())
             if len(w) == 2 and w[0].startswith("blind_") and w[1].isdigit()}
    assert stats == {"blind_generate": "1", "blind_diagnose": "2", "blind_score": "1"}
    assert "results/blind/diagnosis/chunk1" in out
