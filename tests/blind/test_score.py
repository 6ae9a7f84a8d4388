"""The blind suite scored (isokinetic.blind.score): verdicts against the withheld truth, the targets, Fig. 17's
counts."""

import json

import numpy as np

from isokinetic.blind.score import (
    SCORE_COLUMNS,
    confusion_counts,
    confusion_title,
    named_axes,
    read_truths,
    score,
    score_sources,
    summarize,
    summary_text,
)
from isokinetic.io import write_json
from isokinetic.plots.blind_score import confusion_figure
from isokinetic.plots.style import save_figure


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
    assert list(scores.columns) == list(SCORE_COLUMNS)
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
    table = confusion_counts(scores)
    assert table.index.tolist() == ["none", "(backlash)", "(relief)", "friction", "leakage", "asymmetry", "viscosity",
                                    "air", "leakage+air"]
    assert table.to_numpy().sum() == len(HAND)
    assert table.loc["none", "none"] == 1 and table.loc["none", "friction"] == 1
    assert table.loc["leakage", "discharge"] == 1 and table.loc["asymmetry", "error"] == 1
    title = confusion_title(scores, summarize(scores))
    assert title.startswith("Blind test: 10 scenarios, 4 attributed exactly\n(a) FAIL")
    path = save_figure(confusion_figure(table, title), tmp_path / "fig.png")
    assert path.stat().st_size > 0


def _sensor_truth(name, lag_s, scale, effects=()):
    t = _truth(name, effects, 2.0 if effects else None)
    t["instrument"] = {"delay_s": 0.01, "force_offset_N": 1.0, "force_gain": 1.0, "force_lag_s": lag_s,
                       "displacement_scale": scale, "force_drift_N_s": 0.001}
    return t


def _sensor_diag(verdict, lag_s=None, lag_test=None, scale=None, scale_test=1.0, drift=None):
    d = _diag(verdict)
    d["instrument"] = {"delay_s": 0.01, "force_offset_N": 1.0, "force_gain": None, "force_lag_s": lag_s,
                       "displacement_scale": scale, "force_drift_N_s": drift}
    d["instrument_tests"] = {"force_lag": None if lag_test is None else {"estimate_s": lag_test},
                             "displacement_scale": {"estimate": scale_test},
                             "force_drift": {"estimate": 0.0015}}
    return d


def test_sensor_chain_errors_and_target_e():
    cases = [(_sensor_truth("s00", 0.045, 1.012), _sensor_diag([], lag_s=0.041, scale=1.0135)),  # both within
             (_sensor_truth("s01", 0.0225, 0.99), _sensor_diag([], lag_test=0.015, scale_test=0.9875)),  # lag off
             (_sensor_truth("s02", 0.0, 1.004), _sensor_diag([], lag_test=0.03, scale_test=None)),  # scale off
             (_sensor_truth("s03", 0.02, 1.001), _sensor_diag([])),  # no lag looked for: counts as 0
             (_sensor_truth("s04", 0.0, 1.0), _sensor_diag([]))]  # neither nuisance: not judged
    scores = score([t for t, _ in cases], {t["scenario"]: d for t, d in cases}).set_index("scenario")
    assert np.allclose(scores["lag_error_s"], [0.004, 0.0075, 0.03, 0.02, 0.0])
    assert np.allclose(scores["scale_error"], [0.0015, 0.0025, 0.004, 0.001, 0.0])
    assert np.allclose(scores["drift_error_N_s"], 0.0005)  # the test's estimate where none is reported
    e = summarize(scores.reset_index())["targets"]["e_parameters"]
    assert (e["n_lag"], e["lag_misses"], e["lag_error_max_s"]) == (3, ["s01", "s03"], 0.02)
    assert (e["n_scale"], e["scale_misses"]) == (4, ["s02"]) and e["pass"] is False
    assert "lag misses s01, s03" in summary_text(summarize(scores.reset_index()))


def test_target_e_judges_the_lag_where_the_verdict_names_its_effects_and_lists_the_others():
    # a verdict that misses the truth's effect fits the lag with it: listed beside, not judged, as the sizes
    cases = [(_sensor_truth("s00", 0.03, 1.0, ["viscosity"]), _sensor_diag(["viscosity"], lag_s=0.032)),
             (_sensor_truth("s01", 0.03, 1.0, ["viscosity"]), _sensor_diag(["friction"], lag_s=0.045))]
    scores = score([t for t, _ in cases], {t["scenario"]: d for t, d in cases})
    e = summarize(scores)["targets"]["e_parameters"]
    assert (e["n_lag"], e["lag_misses"]) == (1, [])
    assert e["lag_off_beside_missed_effects"] == ["s01 (15.0 ms)"]


def _sized(name, true_cd, got_cd, se):
    """A discharge scenario (manifest C_D 0.6) and its exact verdict with a reported standard error."""
    t = dict(_truth(name, ["discharge"], 3.0), params={"discharge_coefficient": true_cd},
             damper={"discharge_coefficient": 0.6})
    d = dict(_diag(["discharge"]), params={"discharge_coefficient": got_cd})
    if se is not None:
        d["identifiability"] = {"parameters": {"discharge_coefficient": {"std_error": se}}}
    return t, d


def test_target_e_takes_a_size_beyond_15_percent_only_within_3_of_its_standard_errors():
    cases = [_sized("s00", 0.606, 0.6058, 1e-3),    # size 0.006, 3 % off: within 15 %
             _sized("s01", 0.606, 0.6073, 6e-4),    # 22 % off, 2.2 SE: the data cannot pin it closer
             _sized("s02", 0.606, 0.6075, 4e-4),    # 25 % off, 3.75 SE: a miss
             _sized("s03", 0.606, 0.6075, 3e-3),    # 25 % off, SE half the size: not determined, a miss
             _sized("s04", 0.606, 0.6073, None)]    # 22 % off, no standard error reported: a miss
    scores = score([t for t, _ in cases], {t["scenario"]: d for t, d in cases}).set_index("scenario")
    assert np.allclose(scores["param_error_max"], [0.2 / 6, 1.3 / 6, 1.5 / 6, 1.5 / 6, 1.3 / 6])
    assert np.allclose(scores["param_z_max"][:3], [0.2, 1.3 / 0.6, 1.5 / 0.4])
    assert np.isinf(scores["param_z_max"][3:]).all()
    e = summarize(scores.reset_index())["targets"]["e_parameters"]
    assert e["param_misses"] == ["s02", "s03", "s04"] and e["param_z_over_3"] == 3
    assert [m.split()[0] for m in e["param_beyond_15pct"]] == ["s01", "s02", "s03", "s04"]


def test_target_f_counts_only_explained_claims_on_scenarios_without_effects():
    cases = [(_truth("s00", [], None), _diag([], 1.0, 1.0)),
             (_truth("s01", [], None), _diag(["viscosity", "air"], 5.0, 3.0, explained=False)),  # not explained
             (_truth("s02", ["air"], 3.0), _diag(["air"])),
             (_truth("s03", [], None, "relief"), _diag(["discharge"]))]  # out of catalogue: not judged by (f)
    f = summarize(score([t for t, _ in cases], {t["scenario"]: d for t, d in cases}))["targets"]["f_none_explained"]
    assert (f["n"], f["claimed"], f["pass"]) == (2, 0, True)
    cases.append((_truth("s04", [], None), _diag(["discharge"], 5.0, 1.0)))
    summary = summarize(score([t for t, _ in cases], {t["scenario"]: d for t, d in cases}))
    f = summary["targets"]["f_none_explained"]
    assert (f["n"], f["claimed"], f["pass"], f["misses"]) == (3, 1, False, ["s04"])
    assert "(f) FAIL" in summary_text(summary) and summary["all_pass"] is False


def test_sine_campaigns_are_scored_alike_and_counted_apart():
    sine = [(dict(_truth("s10", ["friction"], 3.0), waveform="sine"), _diag(["friction"])),
            (dict(_truth("s11", [], None), waveform="sine"), _diag(["discharge"])),
            (dict(_truth("s12", ["air"], 3.0), waveform="sine"), _diag(["viscosity"]))]
    cases = HAND + sine
    scores = score([t for t, _ in cases], {t["scenario"]: d for t, d in cases if d is not None})
    assert scores.set_index("scenario")["waveform"].tolist() == ["triangle"] * 10 + ["sine"] * 3
    summary = summarize(scores)
    assert summary["n_sine"] == 3 and summary["targets"]["f_none_explained"]["misses"] == ["s06", "s11"]
    assert summary["by_waveform"]["sine"] == {"n": 3, "n_effects": 2, "exact": 1, "n_none": 1, "none_claimed": 1,
                                              "errors": 0}
    assert summary["by_waveform"]["triangle"]["n"] == 8  # in-catalogue only
    assert "sine campaigns: with effects 1/2 exact; effects claimed on 1/1 without" in summary_text(summary)


def test_truth_of_several_chunks_is_read_and_traced_to_its_raw_folder(tmp_path):
    blind = tmp_path / "blind"
    for chunk, name in (("chunk0", "s01"), ("chunk1", "s00")):
        write_json(_truth(name, ["friction"], 2.0), blind / "truth" / chunk / f"{name}.json")
        (blind / "raw" / chunk / name).mkdir(parents=True)
    roots = [blind / "truth" / "chunk0", blind / "truth" / "chunk1"]
    assert [t["scenario"] for t in read_truths(roots)] == ["s00", "s01"]
    sources = score_sources(roots, [], ["s00", "s01"]).set_index("scenario")
    assert sources.loc["s00", "raw_dir"] == (blind / "raw" / "chunk1" / "s00").as_posix()
    assert sources.loc["s01", "truth_file"] == (blind / "truth" / "chunk0" / "s01.json").as_posix()


# --------------------------------------------------------------------------------------------
# (g): hidden out-of-catalogue effects (issue 35)
# --------------------------------------------------------------------------------------------

def _hidden(name, kind, axis, rms_z, truth=()):
    visible = rms_z >= 3.0
    expected = ({"explained": False, "where_axis": axis, "verdict": None} if visible else
                {"explained": None, "where_axis": None, "verdict": list(truth)})
    return {**_truth(name, truth, None, kind), "expected": expected,
            "hidden": {"kind": kind, "axis": axis, "rms_z": rms_z, "visible": visible}}


def _where(*axes, significant=True):
    return [{"axis": a, "range": [0.0, 1.0], "unit": "", "mean_rel": 0.01, "z": 4.0, "p_adjusted": 1e-4,
             "significant": significant} for a in axes]


HIDDEN = [
    (_hidden("h00", "bypass", "position", 9.0), {**_diag(["discharge"], explained=False), "where": _where("position")}),
    (_hidden("h01", "wear", "time", 7.0), {**_diag(["discharge"], explained=True), "where": _where("time")}),
    (_hidden("h02", "warmup", "time", 5.0), {**_diag(["viscosity"], explained=False), "where": _where("speed")}),
    (_hidden("h03", "worn_bore", "position", 2.0), _diag([], explained=True)),      # within the noise: not judged
    (_hidden("h04", "gas_spring", "position", 4.0), None),                           # failed diagnosis
    (_truth("h05", [], None, "backlash"), _diag(["air"], explained=False)),          # an old kind: (c) only
]


def test_g_counts_explained_verdicts_and_missed_axes_of_hidden_effects_beyond_the_noise():
    scores = score([t for t, _ in HIDDEN], {t["scenario"]: d for t, d in HIDDEN if d is not None})
    s = scores.set_index("scenario")
    assert s["expected_axis"].tolist() == ["position", "time", "time", "", "position", ""]
    assert s["axis_named"].tolist() == [True, True, False, False, False, False]
    assert s.loc["h02", "where_axes"] == "speed" and s.loc["h04", "where_axes"] == ""
    assert s["hidden_visible"].tolist() == [True, True, True, False, True, False]
    assert np.isnan(s.loc["h05", "hidden_rms_z"]) and s.loc["h00", "hidden_rms_z"] == 9.0
    summary = summarize(scores)
    json.dumps(summary, allow_nan=False)
    g = summary["targets"]["g_hidden_structure"]
    assert (g["n"], g["claimed"], g["axis_named"], g["errors"]) == (4, 1, 2, 1)
    assert g["explained_misses"] == ["h01"] and g["axis_misses"] == ["h02", "h04"] and g["pass"] is False
    assert g["misses"] == ["h01", "h02", "h04"]
    assert (g["n_within_noise"], g["within_noise_verdict_right"]) == (1, 1)
    # (c) leaves out the hidden effect within the noise (h03, rightly explained by its catalogue truth)
    c = summary["targets"]["c_out_of_catalogue"]
    assert (c["n"], c["flagged"]) == (5, 3) and "h03" not in c["misses"]
    text = summary_text(summary)
    assert "(g) FAIL" in text and "explained: h01" in text and "axis missed: h02, h04" in text
    assert confusion_title(scores, summary).endswith("(g) FAIL")


def test_g_passes_when_every_hidden_effect_beyond_the_noise_is_unexplained_on_its_axis():
    right = [(_hidden("h00", "bypass", "position", 9.0),
              {**_diag(["discharge"], explained=False), "where": _where("speed", "position")}),
             (_hidden("h01", "wear", "time", 7.0), {**_diag([], explained=False), "where": _where("time")})]
    g = summarize(score([t for t, _ in right], {t["scenario"]: d for t, d in right}))["targets"]["g_hidden_structure"]
    assert g["pass"] is True and g["misses"] == [] and g["axis_misses"] == []
    none = summarize(score([t for t, _ in HAND], {t["scenario"]: d for t, d in HAND if d is not None}))
    assert none["targets"]["g_hidden_structure"]["pass"] is None      # no hidden scenario to judge


def test_named_axes_read_where_and_structure_and_skip_insignificant_entries():
    d = {"where": [{"direction": "+", "v_min_m_s": 1e-5, "significant": True}, *_where("phase"),
                   *_where("time", significant=False)],
         "structure": {"where": _where("position")}}
    assert named_axes(d) == ["phase", "position"]
    assert named_axes({"where": [], "structure": _where("frequency")}) == ["frequency"]
    assert named_axes({}) == []
