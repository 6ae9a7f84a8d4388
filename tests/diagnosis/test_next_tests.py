"""The next test (isokinetic.diagnosis.next_tests, issue 37): the criterion against a brute-force refit, the
candidates and the plan within the rig's limits and the paper's design constraints, the note of a campaign
without confounding, the block valid against the schema; the load-cell calibration proposed for a gain group
(isokinetic.diagnosis.next_calibration) on the reference rig's campaign built for it (blind kind gain_discharge), and
the LVDT's calibration proposed for an LVDT-scale group without a command channel (blind kind scale_no_command)."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from isokinetic.blind import confounded as cf
from isokinetic.blind.next_tests import read_manifest, write_manifest
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.diagnosis import next_calibration as ncal
from isokinetic.diagnosis import next_cases as nc
from isokinetic.diagnosis import next_tests as nt
from isokinetic.diagnosis import verdict as vd
from isokinetic.diagnosis.candidate import Candidate
from isokinetic.diagnosis.model import Evaluator
from isokinetic.diagnosis.observations import Observations
from isokinetic.diagnosis.result import validate_diagnosis
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.physics.damper import NOMINAL, Effects
from isokinetic.stages.blind_diagnose import process_raw_campaign
from isokinetic.stages.diagnosis import diagnose, load_campaign

SPEC, N_BINS, DESIGN = DEFAULTS.window, 4, DEFAULTS.design
#: A command channel that measured the LVDT's scale as 1 (no displacement-scale confounding).
MEASURED_SCALE = {"estimate": 1.0, "std_error": 1e-3, "n_cases": 2, "applied": False, "source": "command"}


def stacked(a: Observations, b: Observations, force_N: np.ndarray) -> Observations:
    """One set of observations of ``a`` and ``b`` (every one in period 1: a fit sees them all)."""
    keys = ("case", "kind", "segment", "sign", "speed_m_s", "start", "stop", "sigma_N")
    return Observations(campaign=a.campaign, plans=a.plans + b.plans, drives=a.drives + b.drives, rep_rel=0.0,
                        case_index=np.concatenate([a.case_index, b.case_index + len(a.plans)]),
                        period=np.ones(len(a) + len(b), dtype=np.int64), force_N=force_N, holes=a.holes,
                        noise=a.noise, **{k: np.concatenate([getattr(a, k), getattr(b, k)]) for k in keys})


def test_the_linearised_separation_is_a_brute_force_refit_of_the_rival(campaign):
    obs, damper = campaign
    truth = Evaluator(obs, damper).predict(Effects(viscosity_Pa_s=1.06 * damper.viscosity_Pa_s))
    dg = Diagnoser(replace(obs, force_N=truth), damper)
    a, b = dg.refit(("viscosity",)), dg.refit(("discharge",))
    readings = [nt.Reading("viscosity", a), nt.Reading("discharge", b)]
    probe = nc.probe_observations(obs.campaign, [nc.Probe("P1", nc.triangle_plan("P1", 2e-3, 2e-3, 50.0), "", 1.0)],
                                  SPEC, N_BINS, 1.0)
    probe = replace(probe, sigma_N=np.full(len(probe), 2.0))
    group = nt.group_model("g", readings, nt.Channel(dg.evaluator, None, dg),
                           nt.Channel(Evaluator(probe, damper), None, dg))
    rows = np.arange(len(probe))
    states = nt.with_case(group, rows, np.zeros(rows.size), probe.sigma_N)
    linear = {(s.true, s.refit): nt.PairState.chi2(*new) for s, new in zip(group.pairs[0], states[0], strict=True)}
    # brute force: the rival refitted (nonlinear least squares, its gain and offset profiled) to the other's
    # noise-free means over the old observations and the new case's
    for true, refit in ((0, 1), (1, 0)):
        c = readings[true].candidate
        both = stacked(obs, probe, np.zeros(len(obs) + len(probe)))
        model = Diagnoser(both, damper).model(dg.param.effects(c.effects, c.x))
        brute = Diagnoser(replace(both, force_N=c.gain * model + c.offset_N), damper)
        refitted = brute.refit(readings[refit].candidate.effects, tol=1e-10)
        assert refitted.chi2_fit > 25.0    # the new case separates them: the comparison is not of two zeros
        assert linear[(true, refit)] == pytest.approx(refitted.chi2_fit, rel=0.03)


def test_a_nested_pair_counts_only_the_larger_reading_true(campaign):
    obs, damper = campaign
    dg = Diagnoser(obs, damper)
    small, large = dg.refit(("viscosity",)), dg.refit(("discharge", "viscosity"))
    other = dg.refit(("discharge",))
    pairs = nt.directed_pairs([nt.Reading("v", small), nt.Reading("dv", large), nt.Reading("d", other)])
    assert pairs == [[(1, 0)], [(0, 2), (2, 0)], [(1, 2)]]


@pytest.fixture(scope="module")
def confounded(campaign):
    """A diagnosis with a confounding (one slow case, a 1 % gain and a 30 ms lag in the force channel: air against
    the lag) and its fits."""
    obs, damper = campaign
    one = obs.subset(obs.case == "T01")
    force = 1.01 * Evaluator(one, damper).lagged(NOMINAL, [0.03])[0]
    force = force + np.random.default_rng(1).normal(0.0, 1.0, len(one)) * one.sigma_N
    t = np.linspace(0.0, 400.0, len(one))
    result, predictions = vd.diagnose_observations(replace(one, force_N=force), damper,
                                                   sensor={"obs_time_s": t, "time_ref_s": 200.0,
                                                           "displacement_scale": MEASURED_SCALE})
    return result, predictions, damper


def test_a_confounded_verdict_gets_a_plan_that_separates_its_rivals(confounded):
    result, predictions, damper = confounded
    assert result["confounded"]
    block = nt.next_tests(result, predictions["fits"], damper, SPEC, N_BINS, DESIGN)
    groups = ["+".join(g) for g in result["confounded"]]
    assert block["needed"] and block["plan"] and set(block["separation_se"]) == set(groups)
    assert max(block["separation_se"].values()) >= nt.TARGET_SE
    assert {r["group"] for r in block["rivals"]} == set(groups)
    assert all(p["resolves"] and set(p["resolves"]) <= set(groups) for p in block["plan"])


def test_the_plan_respects_the_rigs_limits_and_budget(confounded):
    result, predictions, damper = confounded
    block = nt.next_tests(result, predictions["fits"], damper, SPEC, N_BINS, DESIGN)
    limits = block["limits"]
    assert 1 <= len(block["plan"]) <= nt.MAX_CASES
    assert block["total_rig_time_s"] == pytest.approx(sum(p["rig_time_s"] for p in block["plan"]))
    assert block["total_rig_time_s"] <= nt.BUDGET_S
    for p in block["plan"]:
        if p["waveform"] == "triangle":
            assert p["velocity_m_s"] <= limits["max_speed_m_s"] * (1 + 1e-12)
            assert limits["min_amplitude_m"] * (1 - 1e-12) <= p["amplitude_m"]
            assert p["amplitude_m"] <= limits["max_amplitude_m"] * (1 + 1e-12)
            assert p["period_s"] == pytest.approx(4.0 * p["amplitude_m"] / p["velocity_m_s"])
            assert p["rig_time_s"] == pytest.approx(2.0 * p["period_s"] + nc.SETUP_S)


def test_the_block_is_valid_against_the_schema(confounded):
    result, predictions, damper = confounded
    block = nt.next_tests(result, predictions["fits"], damper, SPEC, N_BINS, DESIGN)
    validate_diagnosis({**result, "next_tests": vd.json_safe(block)})


def test_a_campaign_without_confounding_gets_the_one_line_note_and_costs_nothing(campaign):
    obs, damper = campaign
    force = Evaluator(obs, damper).predict(NOMINAL) + np.random.default_rng(2).normal(0.0, 1.0, len(obs)) * obs.sigma_N
    result, predictions = vd.diagnose_observations(replace(obs, force_N=force), damper,
                                                   sensor={"displacement_scale": MEASURED_SCALE})
    assert not result.get("confounded")
    calls = predictions["fits"]["dg"].calls
    block = nt.next_tests(result, predictions["fits"], damper, SPEC, N_BINS, DESIGN)
    assert block == {"needed": False, "note": "no confounding: no further test proposed", "plan": []}
    assert predictions["fits"]["dg"].calls == calls   # no model run
    validate_diagnosis({**result, "next_tests": block})


def test_an_lvdt_scale_the_verdicts_own_terms_equal_is_stated_unresolvable(campaign):
    obs, damper = campaign
    force = Evaluator(obs, damper).predict(Effects(discharge_coefficient=0.9 * damper.discharge_coefficient))
    dg = Diagnoser(replace(obs, force_N=force), damper)
    best = dg.refit(("discharge",))
    ctx = {"dg": dg, "bdg": dg, "best": best, "candidates": [best], "hyp": None, "verdict": ["discharge"],
           "margin": vd.SENSOR_MARGIN}
    assert nt.group_readings(["displacement_scale", "force_gain", "discharge"], ctx) == nt.SCALE_REASON


def test_an_lvdt_scale_reading_is_a_gain_tied_to_the_discharge_coefficient(campaign):
    obs, damper = campaign
    k = 1.02   # the LVDT reads 2 % long: the true speeds are the measured ones over k
    from isokinetic.diagnosis.instrument import rescaled_drives

    truth = Evaluator(rescaled_drives(obs, k), damper).predict(NOMINAL)
    dg = Diagnoser(replace(obs, force_N=truth), damper)
    scale = nt.fit_scale(dg, dg.refit(("viscosity",)))
    assert scale.gain == pytest.approx(1.0 / k, rel=2e-3)
    assert scale.params["discharge_coefficient"] == pytest.approx(damper.discharge_coefficient * math.sqrt(k),
                                                                   rel=2e-3)


def test_a_gain_confounding_sets_the_verdict_with_its_gain_against_discharge_and_viscosity_without(campaign):
    obs, damper = campaign
    truth = 1.015 * Evaluator(obs, damper).predict(Effects(discharge_coefficient=0.95 * damper.discharge_coefficient))
    dg = Diagnoser(replace(obs, force_N=truth), damper)
    best = dg.refit(("discharge",))
    ctx = {"dg": dg, "bdg": dg, "best": best, "candidates": [best], "hyp": None, "verdict": ["discharge"],
           "margin": vd.SENSOR_MARGIN, "gain_needed": True}
    verdict, alt = nt.group_readings(["force_gain", "discharge", "viscosity"], ctx)
    assert verdict.candidate is best and verdict.label == "discharge+force_gain"
    assert alt.candidate.effects == ("discharge", "viscosity") and "force_gain" not in alt.candidate.instrument
    assert alt.label == "discharge+viscosity" and alt.candidate.gain == 1.0


def test_a_group_the_plan_leaves_short_of_the_target_is_told_the_sensor_check_that_decides_it():
    block = {"target_se": 5.0, "plan": [{"case": "N01"}], "total_rig_time_s": 60.0,
             "separation_se": {"force_gain+discharge+viscosity": 2.4, "air+force_lag": 7.0},
             "separation_se_now": {"force_gain+discharge+viscosity": 1.5, "air+force_lag": 0.3}, "unresolvable": {}}
    note = nt.plan_note(block)
    assert "short of 5 SE: force_gain+discharge+viscosity" in note
    assert "force_gain+discharge+viscosity: calibrate the load cell against a reference force to decide" in note
    assert "air+force_lag: check" not in note


def test_no_case_is_proposed_that_cannot_separate_the_readings(campaign):
    obs, damper = campaign
    dg = Diagnoser(obs, damper)
    same = dg.refit(("viscosity",))
    probe = nc.probe_observations(obs.campaign, [nc.Probe("P1", nc.triangle_plan("P1", 2e-3, 2e-3, 50.0), "", 60.0)],
                                  SPEC, N_BINS, 1.0)
    group = nt.group_model("g", [nt.Reading("a", same), nt.Reading("b", replace(same, params=dict(same.params)))],
                           nt.Channel(dg.evaluator, None, dg), nt.Channel(Evaluator(probe, damper), None, dg))
    rows = nt.ProbeRows(probe.case_index, np.zeros(len(probe)), np.ones(len(probe)))
    assert nt.greedy_plan([group], [nc.Probe("P1", probe.plans[0], "", 60.0)], rows, 0.0) == []


def test_partial_explanations_fitted_twice_are_one_reading():
    def partial(effects, chi2_holdout, channel=None):
        return Candidate(effects=effects, x=np.zeros(len(effects)), params={}, prediction=np.zeros(1), chi2_fit=400.0,
                         chi2_holdout=chi2_holdout, n_fit=100, n_holdout=100, gap_after=2.0, holdout_gap_after=2.0,
                         score=chi2_holdout, explained=False, channel=channel)
    best = partial(("friction", "leakage"), 400.0, (0, 0.01))
    twice = partial(("friction", "leakage"), 401.0, (1, 0.012))
    other = partial(("leakage",), 402.0)
    readings = nt.partial_readings(best, [best, twice, other])
    assert sorted(r.label for r in readings) == ["friction+leakage+force_lag", "leakage"]


def test_the_fit_correlation_is_that_of_the_unscaled_fisher_information():
    rng = np.random.default_rng(4)
    base = rng.normal(size=(200, 1))
    jac = np.column_stack([base[:, 0] * 3e4 + rng.normal(size=200) * 2e3, base[:, 0] * 0.01, rng.normal(size=200)])
    cov = np.linalg.inv(jac.T @ jac)   # independent: no scaling, a plain inverse
    expected = abs(cov[0, 1]) / np.sqrt(cov[0, 0] * cov[1, 1])
    scale = np.sqrt(np.sum(jac * jac, axis=0))
    js = jac / scale
    corr = nt.Correlation(None, np.zeros((0, 3)), js.T @ js, scale, (0,), 1, False)
    assert corr.rho() == pytest.approx(expected, rel=1e-9) and expected > 0.9
    assert corr.chi2() < nt.TARGET_SE ** 2
    # a case whose rows move the two columns apart brings the correlation down, below the diagnosis' limit
    rows = np.column_stack([np.full(50, 3e4), np.full(50, -0.01), np.zeros(50)])
    group = nt.GroupModel("g", [], [], [], [], corr=replace(corr, probe_jac=rows))
    (fisher,) = nt.with_case(group, np.arange(50), np.zeros(50), np.ones(50))
    assert corr.rho(fisher) < nt.CORRELATION_LIMIT and corr.chi2(fisher) > nt.TARGET_SE ** 2


def test_a_group_no_case_separates_is_told_the_sensor_check_that_decides_it():
    block = {"target_se": 5.0, "plan": [], "total_rig_time_s": 0.0, "separation_se": {"air+force_lag": 0.8},
             "separation_se_now": {"air+force_lag": 0.8}, "unresolvable": {}}
    note = nt.plan_note(block)
    assert note.startswith("no candidate case within the rig's limits adds to the separation of air+force_lag")
    assert "air+force_lag: check the force channel's dynamics" in note



GAIN_GROUP = "force_gain+discharge+viscosity"


def diagnosed_gain_kind(tmp, calibration: dict | None = None) -> dict:
    """diagnosis.json's document of the blind kind gain_discharge (seed 777: a load cell reading 1.5 % high beside
    a discharge coefficient, on the reference rig), its force column declaring ``calibration`` where given."""
    kind = cf.BY_NAME["gain_discharge"]
    raw = cf.export_confounded(kind, cf.make_confounded(kind, 777, cf.KINDS.index(kind)), tmp / "raw", tmp / "truth")
    if calibration is not None:
        manifest = read_manifest(raw)
        manifest["columns"]["force"]["calibration"] = calibration
        write_manifest(raw, manifest)
    result, _obs, _predictions = diagnose(process_raw_campaign(raw, tmp / "work"))
    return result


@pytest.fixture(scope="module")
def gain_kind(tmp_path_factory):
    result = diagnosed_gain_kind(tmp_path_factory.mktemp("gain_kind"))
    assert GAIN_GROUP in ["+".join(g) for g in result["confounded"]]   # the kind lists the gain group
    return result


def test_a_gain_group_gets_a_calibration_separating_it_by_the_gains_difference_over_its_uncertainty(gain_kind):
    block = gain_kind["next_tests"]
    # each reading's load-cell gain: its fitted one where free, else held at 1 (no calibration declared)
    gains = [r["instrument"]["force_gain"] or 1.0 for r in block["rivals"] if r["group"] == GAIN_GROUP]
    assert len(gains) == 2
    expected = abs(gains[0] - gains[1]) / 0.001
    (entry,) = block["calibrations"]
    assert entry["check"] == "load_cell_gain" and entry["channel"] == "force" and entry["uncertainty_rel"] == 0.001
    assert entry["separation_se_by_group"][GAIN_GROUP] == pytest.approx(expected, rel=1e-9)
    assert expected > nt.TARGET_SE and entry["resolves"] == [GAIN_GROUP]   # a 1.5 % gain: far beyond 0.1 %
    assert entry["rig_time_s"] == 1800.0


def test_a_group_the_calibration_takes_beyond_the_target_gets_no_case_and_counts_its_rig_time(gain_kind):
    block = gain_kind["next_tests"]
    (entry,) = block["calibrations"]
    assert not [p for p in block["plan"] if GAIN_GROUP in p["resolves"]]
    # χ² of independent measurements add: the campaign's own separation and the calibration's
    now, cal = block["separation_se_now"][GAIN_GROUP], entry["separation_se_by_group"][GAIN_GROUP]
    assert block["separation_se"][GAIN_GROUP] == pytest.approx(math.hypot(now, cal), rel=1e-9)
    assert block["total_rig_time_s"] == pytest.approx(1800.0 + sum(p["rig_time_s"] for p in block["plan"]))


def test_the_note_of_a_calibrated_gain_group_names_the_calibration_not_a_check_in_words(gain_kind):
    note = gain_kind["next_tests"]["note"]
    assert "a load-cell calibration against a reference force (±0.1 %, 30 min of rig time) separates " \
           f"{GAIN_GROUP} by" in note
    assert "to decide" not in note and "no candidate case" not in note


def test_a_credit_beyond_the_target_leaves_the_group_no_case(campaign):
    obs, damper = campaign
    dg = Diagnoser(obs, damper)
    readings = [nt.Reading("viscosity", dg.refit(("viscosity",))), nt.Reading("discharge", dg.refit(("discharge",)))]
    plan = nc.triangle_plan("P1", 2e-3, 2e-3, 50.0)
    probe = nc.probe_observations(obs.campaign, [nc.Probe("P1", plan, "", 60.0)], SPEC, N_BINS, 1.0)
    rows = nt.ProbeRows(probe.case_index, np.zeros(len(probe)), np.full(len(probe), 2.0))

    def chosen(credit: float) -> list:
        group = nt.group_model("g", readings, nt.Channel(dg.evaluator, None, dg),
                               nt.Channel(Evaluator(probe, damper), None, dg), credit=credit)
        return nt.greedy_plan([group], [nc.Probe("P1", plan, "", 60.0)], rows, 0.0)

    assert len(chosen(0.0)) == 1                       # the case separates the two readings
    assert chosen(nt.TARGET_SE ** 2) == []             # a calibration that reaches the target leaves it none


def test_a_campaign_declaring_a_calibration_as_tight_gets_none(tmp_path):
    # the gain a calibration of the load cell reading 1.5 % high finds
    result = diagnosed_gain_kind(tmp_path, {"gain": 1.015, "uncertainty_rel": 0.001})
    block = result["next_tests"]
    assert block.get("calibrations", []) == []
    assert "separates force_gain" not in block.get("note", "")


def test_the_calibration_is_proposed_only_above_the_declared_uncertainty():
    gain = Candidate(effects=("discharge",), x=np.zeros(1), params={}, prediction=np.zeros(1), chi2_fit=1.0,
                     chi2_holdout=1.0, n_fit=10, n_holdout=10, gap_after=0.0, holdout_gap_after=0.0, score=0.0,
                     explained=True, gain=1.015, instrument=("force_gain", "force_offset"))
    held = replace(gain, effects=("discharge", "viscosity"), gain=1.0, instrument=("force_offset",))
    groups = [(GAIN_GROUP, [nt.Reading("a", gain), nt.Reading("b", held)])]
    assert ncal.calibration_proposal(groups, (1.0, 0.001))[0] == []
    (entry,), credit, _why = ncal.calibration_proposal(groups, (1.0, 0.01))
    assert entry["separation_se"] == pytest.approx(15.0) and credit[GAIN_GROUP] == pytest.approx(225.0)


def test_the_block_with_a_calibration_is_valid_against_the_schema_and_a_broken_entry_is_not(gain_kind):
    validate_diagnosis(gain_kind)
    broken = json.loads(json.dumps(gain_kind))
    del broken["next_tests"]["calibrations"][0]["how"]
    with pytest.raises(Exception, match="how"):
        validate_diagnosis(broken)


def test_an_lvdt_scale_group_gets_no_load_cell_calibration(campaign):
    obs, damper = campaign
    force = 1.012 * Evaluator(obs, damper).predict(Effects(discharge_coefficient=0.9 * damper.discharge_coefficient))
    dg = Diagnoser(replace(obs, force_N=force), damper)
    best = dg.refit(("discharge",))
    held = dg.refit(("discharge", "viscosity"), ("force_offset",))
    readings = [nt.Reading("verdict", best), nt.Reading("held", held)]
    entries, _credit, _why = ncal.calibration_proposal([("displacement_scale+force_gain+discharge", readings)], None)
    assert entries == []
    (entry,), _credit, _why = ncal.calibration_proposal([("force_gain+discharge+viscosity", readings)], None)
    assert entry["resolves"] == ["force_gain+discharge+viscosity"]


SCALE_GROUP = "displacement_scale+force_gain+discharge"


@pytest.fixture(scope="module")
def scale_kind(tmp_path_factory):
    """(diagnosis.json's document, the fits, the damper) of the blind kind scale_no_command (seed 777: an LVDT 1.2 %
    long without a command channel beside a discharge coefficient, on the reference rig)."""
    tmp = tmp_path_factory.mktemp("scale_kind")
    kind = cf.BY_NAME["scale_no_command"]
    raw = cf.export_confounded(kind, cf.make_confounded(kind, 777, cf.KINDS.index(kind)), tmp / "raw", tmp / "truth")
    root = process_raw_campaign(raw, tmp / "work")
    result, _obs, predictions = diagnose(root)
    assert SCALE_GROUP in ["+".join(g) for g in result["confounded"]]   # the kind lists the scale group
    return result, predictions["fits"], load_campaign(root)[1]


def lvdt_entry(block: dict) -> dict:
    (entry,) = [c for c in block["calibrations"] if c["check"] == "lvdt_scale"]
    return entry


def test_a_scale_group_gets_an_lvdt_calibration_separating_it_by_one_over_the_verdicts_gain(scale_kind):
    result, fits, _damper = scale_kind
    # the verdict's reading: the LVDT's scale 1; the scale's: 1/g, the verdict's fitted gain g being the LVDT's 1/k
    expected = abs(1.0 / fits["best"].gain - 1.0) / 0.001
    entry = lvdt_entry(result["next_tests"])
    assert entry["channel"] == "displacement" and entry["uncertainty_rel"] == 0.001 and entry["rig_time_s"] == 1800.0
    assert entry["separation_se_by_group"][SCALE_GROUP] == pytest.approx(expected, rel=1e-9)
    assert entry["separation_se"] == pytest.approx(expected, rel=1e-9)


def test_the_lvdt_calibration_counts_in_the_groups_separation_and_the_rig_time(scale_kind):
    block = scale_kind[0]["next_tests"]
    entry = lvdt_entry(block)
    assert block["separation_se"][SCALE_GROUP] == pytest.approx(entry["separation_se_by_group"][SCALE_GROUP])
    assert block["total_rig_time_s"] == pytest.approx(1800.0 + sum(p["rig_time_s"] for p in block["plan"]))


def test_the_lvdt_calibration_resolves_a_scale_group_whatever_its_separation():
    verdict = Candidate(effects=("discharge",), x=np.zeros(1), params={}, prediction=np.zeros(1), chi2_fit=1.0,
                        chi2_holdout=1.0, n_fit=10, n_holdout=10, gap_after=0.0, holdout_gap_after=0.0, score=0.0,
                        explained=True, gain=0.9999, instrument=("force_gain", "force_offset"))
    readings = [nt.Reading("verdict", verdict), nt.Reading("displacement_scale", verdict, scale=True)]
    (entry,), credit, _why = ncal.lvdt_proposal([(SCALE_GROUP, readings)], None)
    assert entry["separation_se"] < ncal.RESOLVES_MIN_SE   # a scale of 1.0001: 0.1 SE
    assert entry["resolves"] == [SCALE_GROUP] and credit[SCALE_GROUP] == pytest.approx(entry["separation_se"] ** 2)


def test_the_note_of_the_unresolvable_scale_group_names_the_lvdt_calibration_not_a_check_in_words(scale_kind):
    block = scale_kind[0]["next_tests"]
    assert SCALE_GROUP in block["unresolvable"]
    assert ("an LVDT calibration against a reference displacement (±0.1 %, 30 min of rig time) separates "
            f"{SCALE_GROUP} by {lvdt_entry(block)['separation_se']:.1f} SE and, declared, resolves its listing") \
        in block["note"]
    assert "record the command channel" not in block["note"] and "to decide" not in block["note"]


def test_a_campaign_declaring_an_lvdt_calibration_as_tight_gets_none(scale_kind):
    result, fits, damper = scale_kind
    # the diagnosis' report of a declared calibration (Interface 3), on the scale group as if still listed
    declared = {"estimate": 1.012, "std_error": None, "n_cases": 0, "applied": True, "source": "calibration",
                "uncertainty_rel": 0.001}
    tight = {**result, "instrument_tests": {**result["instrument_tests"], "displacement_scale": declared}}
    block = nt.next_tests(tight, fits, damper, SPEC, N_BINS, DESIGN)
    assert block["calibrations"] == []
    assert f"{SCALE_GROUP}: the campaign's declared LVDT calibration (±0.1 %) holds the scale" in block["note"]


def test_the_lvdt_calibration_is_proposed_only_above_the_declared_uncertainty(scale_kind):
    _result, fits, _damper = scale_kind
    family = nt.scale_family({SCALE_GROUP: nt.SCALE_REASON}, fits)
    assert ncal.lvdt_proposal(family, (1.0, 0.001))[0] == []
    (entry,), _credit, _why = ncal.lvdt_proposal(family, (1.0, 0.01))
    assert entry["separation_se"] == pytest.approx(abs(1.0 / fits["best"].gain - 1.0) / 0.001, rel=1e-9)


def test_the_load_cell_calibration_is_still_not_proposed_for_a_scale_group(scale_kind):
    assert [c["check"] for c in scale_kind[0]["next_tests"]["calibrations"]] == ["lvdt_scale"]


def test_the_block_with_an_lvdt_calibration_is_valid_against_the_schema_and_a_force_channel_is_not(scale_kind):
    validate_diagnosis(scale_kind[0])
    broken = json.loads(json.dumps(scale_kind[0]))
    lvdt_entry(broken["next_tests"])["channel"] = "force"
    with pytest.raises(Exception, match="displacement"):
        validate_diagnosis(broken)
