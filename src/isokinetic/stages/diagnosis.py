"""Rule diagnosis: the sim-to-real gap of a processed campaign -> diagnosis.json and the gap figure.

The gap is the difference between the steady characteristic identified by the method of "A method for
the identification of hydraulic damper characteristics from steady velocity inputs" (Titurus et al.)
and the nominal damper model of the campaign's manifest.

Reads ``results/<campaign>/`` (ingest/campaign.json for the nominal damper, cases.parquet,
characteristic.parquet and the case time series), builds the observations twice (:func:`prepare`),
diagnoses them (the method: :mod:`isokinetic.diagnosis`), validates the result against the
diagnosis.json schema and writes it with Fig. 16 (:mod:`isokinetic.plots.diagnosis`). A campaign
that cannot be diagnosed gets a diagnosis.json with ``status: not_diagnosed`` and the reason; one
whose diagnosis fails, ``status: failed``.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign import case_plan, viscosity_scales
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS, figure
from isokinetic.contracts.settings import DEFAULTS, DesignLimits, Settings
from isokinetic.diagnosis.candidate import ALPHA
from isokinetic.diagnosis.instrument import (
    INSTRUMENT,
    calibrated_scale,
    case_delays,
    case_sine_response,
    case_speed_ratio,
    displacement_scale,
    rescaled_drives,
    sine_servo_terms,
)
from isokinetic.diagnosis.joint import joint_search, judged_on_all_records
from isokinetic.diagnosis.model import drive_input_variance, unsteady_windows
from isokinetic.diagnosis.next_tests import next_tests
from isokinetic.diagnosis.observations import Observations, build_observations, has_four_windows
from isokinetic.diagnosis.plan_text import plan_yaml
from isokinetic.diagnosis.result import (
    json_safe,
    no_model,
    observation_sources,
    validate_diagnosis,
)
from isokinetic.diagnosis.search import Diagnoser
from isokinetic.diagnosis.sine_check import channel_of, sine_check
from isokinetic.diagnosis.sine_observations import PERIODIC_RESIDUAL, periodic_motion
from isokinetic.diagnosis.structure import case_temperatures
from isokinetic.diagnosis.verdict import diagnose_observations, structure_keys
from isokinetic.io import write_json, write_text
from isokinetic.measurement.windows import WindowSpec, motion_start
from isokinetic.physics.damper import NOMINAL, Damper

log = logging.getLogger(__name__)

#: Why a campaign's sine cases are not diagnosed beside its triangle windows (``sources.not_used``). A short sine
#: record carries one slow-noise error common to all its phase bins, which the bins' independent standard errors
#: do not describe: beside triangle windows this produced damper effects the truth did not have (the reference
#: rig's mixed campaign with coloured noise). And each model run integrates the sine records (Eq. 1), which made
#: the 27-case paper campaign's diagnosis about seven times slower. The triangles' transient bins already carry
#: the compressibility and sensor lag that the sine bins would add.
SINES_BESIDE_TRIANGLES = ("sine cases beside triangle windows are not diagnosed: their phase bins share a slow-noise "
                          "error per record that the bins' standard errors do not describe; the triangles decide, "
                          "and the sine cases check their verdict (sine_check); where they fail it, the search is "
                          "repeated on both, each sine record's even error profiled out (joint)")
#: Why no joint search is made on a mixed campaign whose triangles no catalogue set explains (``joint.skipped``).
JOINT_SKIPPED = ("no candidate of the catalogue explains the triangle records alone (unexplained_note), so none "
                 "explains them beside the sine records: the joint search is not made")
#: What a periodic free record is diagnosed as (``sources.periodic``), and why one that is not periodic is not.
PERIODIC_FREE = (f"free records whose motion a sine and its second and third harmonics explain to within "
                 f"{100 * PERIODIC_RESIDUAL:g} % beyond the noise (a crank's) are diagnosed as sine records of their "
                 "measured fundamental")
NOT_PERIODIC = ("a free record that is not periodic (a road profile, a random input) is not diagnosed: the model has "
                "no drive for it")
#: Why a campaign's triangle cases are not diagnosed where its sine cases are (``sources.not_used``).
TRIANGLES_WITHOUT_FOUR_WINDOWS = ("no triangle case has its four windows (two periods, both directions), which "
                                  "the model's drive needs: the sine cases are diagnosed instead")


def load_campaign(campaign_root: Path) -> tuple[str, Damper | None, pd.DataFrame, pd.DataFrame, dict[str, float]]:
    """(campaign, nominal damper or None, cases, characteristic, case -> viscosity scale) of a processed
    campaign folder; the scales put each case at its temperature's viscosity (format 1.1 viscosity law,
    :func:`isokinetic.contracts.campaign.viscosity_scales`; empty without one)."""
    folder = CampaignFolder.at(campaign_root)
    meta = folder.meta
    damper = meta.damper
    cases = folder.validated_cases()
    char = folder.characteristic()
    if "method" in char:  # the triangle windows only: a sine is diagnosed from its record (phase bins)
        char = char[char["method"] == "triangle_window"].reset_index(drop=True)
    return meta.campaign, damper, cases, char, viscosity_scales(meta, cases)


def prepare(campaign_root: Path, spec: WindowSpec = DEFAULTS.window, n_bins: int = 4,
            alpha: float = ALPHA) -> tuple[str, Damper | None, pd.DataFrame, Observations | None, str]:
    """(campaign, damper, cases, observations, reason) of a processed campaign folder (:func:`prepare_sensor`
    without the sensor chain's measurements)."""
    return prepare_sensor(campaign_root, spec, n_bins, alpha)[:5]


def prepare_sensor(campaign_root: Path, spec: WindowSpec = DEFAULTS.window, n_bins: int = 4, alpha: float = ALPHA
                   ) -> tuple[str, Damper | None, pd.DataFrame, Observations | None, str, dict]:
    """(campaign, damper, cases, observations, reason, sensor) of a processed campaign folder.

    The LVDT's scale is measured first (or declared: :func:`motion_terms`), from its speed against the command's
    (:func:`isokinetic.diagnosis.instrument.displacement_scale`); where it departs from 1, the model is
    driven at the measured speeds divided by it. A sine-only campaign's scale and actuator delay come from its
    cases' amplitude and phase against the command (:func:`isokinetic.diagnosis.instrument.sine_servo_terms`;
    ``sensor['delays']``, else None: the triangles' ``delay_s`` of cases.parquet). ``sensor`` holds that scale
    and each observation's campaign time (``obs_time_s``: the cases back to back in the order of cases.parquet)
    and the campaign's middle (``time_ref_s``, where the load-cell offset is reported), for the load-cell zero
    drift.

    Sine cases are diagnosed where a campaign has no triangle window (a sine-only campaign); beside
    triangle windows they are left out of the search (SINES_BESIDE_TRIANGLES says why), ``sources`` names them,
    and their observations (``sensor['sine_obs']``, with ``sine_time_s``) check the triangles' verdict
    (:func:`isokinetic.diagnosis.sine_check.sine_check`) and, where they fail it, enter a joint search
    (:func:`judge_on_all_records`).

    Observations are built twice: first to profile the load-cell offset against the nominal model,
    then with the noise model fitted to offset-free samples (the proportional noise scales with the
    true force) and, for sine cases, with the nominal model's bin means (its cycle-to-cycle convergence
    is no noise). Sine cases (status ok) give phase bins (:mod:`isokinetic.diagnosis.sine_observations`).
    With a viscosity law and case temperatures, each case is modelled at its temperature.
    Observations is None, with the reason, when the campaign cannot be diagnosed.
    """
    root = Path(campaign_root)
    campaign, damper, cases, char, scales = load_campaign(root)
    if damper is None:
        return campaign, None, cases, None, "campaign.yaml has no damper block: there is no nominal model", {}
    cache: dict[str, pd.DataFrame] = {}

    def load(row):
        key = str(row["timeseries_file"])
        if key not in cache:
            cache[key] = pd.read_parquet(root / key)
        return cache[key]

    sines = cases[(cases["status"] == "ok") & (cases["waveform"] == "sine")]
    if not char.empty and not sines.empty and not any_four_windows(char):   # TRIANGLES_WITHOUT_FOUR_WINDOWS
        log.info("%s: no triangle case has its four windows: its sine cases are diagnosed", campaign)
        char = char.iloc[0:0]
    set_aside = sines.iloc[0:0]
    if not char.empty and not sines.empty:  # the triangles' windows and bins decide (SINES_BESIDE_TRIANGLES)
        log.info("%s: sine cases %s not diagnosed beside the triangle windows", campaign, ",".join(sines["case"]))
        set_aside, sines = sines, sines.iloc[0:0]
    periodic: dict[str, float] = {}
    refused = ""
    if char.empty and sines.empty:   # free records, where they are periodic (PERIODIC_FREE)
        cases, periodic, refused, reason = periodic_free_cases(cases, load)
        if reason:
            return campaign, damper, cases, None, reason, {}
        sines = cases[cases["case"].isin(list(periodic))]
    modelled = cases[(cases["waveform"] != "sine") | cases["case"].isin(sines["case"])]

    ok = cases[(cases["status"] == "ok") & (cases["waveform"] == "triangle")]
    meta = CampaignFolder.at(root).meta   # the declared calibrations: (gain or scale, uncertainty_rel), or None
    scale, delays = motion_terms(ok if not char.empty else ok.iloc[0:0], sines, load, meta.lvdt_calibration)
    lvdt = scale["estimate"] if scale["applied"] else 1.0

    def scaled(o: Observations) -> Observations:   # every build of the campaign's observations carries it
        o = replace(o, force_calibration=meta.calibration)   # the load cell's
        return rescaled_drives(o, scale["estimate"]) if scale["applied"] and len(o) else o

    def observations(of: pd.DataFrame, windows: pd.DataFrame) -> Observations:
        return two_pass_observations(campaign, damper, of, windows, load, scaled, spec, n_bins, scales, lvdt, alpha)

    obs = observations(modelled, char)
    if len(obs) == 0:
        return campaign, damper, cases, None, ("no triangle case with four windows and no sine case of two "
                                               "cycles: nothing to compare"), {}
    spans = {row["case"]: record_span(load(row)) for _, row in pd.concat([ok, sines, set_aside]).iterrows()}
    sensor = {"displacement_scale": scale, "delays": delays, "obs_time_s": campaign_times(obs, cases, spans),
              "time_ref_s": 0.5 * float(np.sum(case_lengths_s(cases, spans))), "periodic": periodic,
              "not_periodic": refused, "case_temperature_C": case_temperatures(cases)}
    if not set_aside.empty:
        sine_obs = observations(set_aside, char.iloc[0:0])
        if len(sine_obs):
            sensor.update(sine_obs=sine_obs, sine_time_s=campaign_times(sine_obs, cases, spans))
    return campaign, damper, cases, obs, "", sensor


def periodic_free_cases(cases: pd.DataFrame, load) -> tuple[pd.DataFrame, dict[str, float], str, str]:
    """(``cases`` with each periodic status-ok free record as a sine case of its measured fundamental, {case: the
    share of its amplitude its periodic fit leaves unexplained beyond noise}, the others as 'case: why', the
    reason there is nothing to diagnose or ''): a free record whose motion a sine and its harmonics explain to
    within PERIODIC_RESIDUAL (a crank's) is diagnosed as a sine record
    (:func:`isokinetic.diagnosis.sine_observations.periodic_motion`); one they do not (a road profile, a random
    input) is not, for the model has no drive for it."""
    free = cases[(cases["status"] == "ok") & (cases["waveform"] == "free")]
    if free.empty:
        return cases, {}, "", "no status-ok triangle or sine case: nothing to compare"
    periodic, refused, out = {}, [], cases.copy()
    for idx, row in free.iterrows():
        series = load(row)
        fit, unexplained = periodic_motion(series["time_s"].to_numpy(float), series["displacement_m"].to_numpy(float))
        if fit is None or not unexplained <= PERIODIC_RESIDUAL:
            why = "not three cycles of motion" if fit is None else f"{100 * unexplained:.2g} % of it not periodic"
            refused.append(f"{row['case']}: {why}")
            continue
        periodic[str(row["case"])] = unexplained
        out.loc[idx, ["waveform", "frequency_Hz", "amplitude_m", "phase_rad", "period_s"]] = [
            "sine", fit.frequency_Hz, fit.amplitude_m, 0.0, 1.0 / fit.frequency_Hz]
    if not periodic:
        return out, {}, ", ".join(refused), (f"no triangle or sine case, and no free record is periodic "
                                             f"({', '.join(refused)}): {NOT_PERIODIC}")
    log.info("free records %s diagnosed as periodic motions", ",".join(periodic))
    return out, periodic, ", ".join(refused), ""


def two_pass_observations(campaign: str, damper: Damper, modelled: pd.DataFrame, char: pd.DataFrame, load, scaled,
                          spec: WindowSpec, n_bins: int, scales: dict, lvdt: float, alpha: float) -> Observations:
    """The observations of the cases ``modelled`` (and the triangle windows ``char``), built twice
    (:func:`prepare_sensor`): first to profile the load-cell offset against the nominal model, then with the
    noise model fitted to offset-free samples, the unsteady windows left out of it and, for sine cases, the
    nominal model's bin means (its cycle-to-cycle convergence is no noise); ``scaled`` applies the LVDT scale."""
    masks: dict = {}   # each window's spike mask, for both builds
    obs = scaled(build_observations(campaign, modelled, char, load, spec, n_bins, viscosity_scales=scales,
                                    displacement_scale=lvdt, spike_masks=masks, parts=False))
    if not len(obs):
        return obs
    dg0 = Diagnoser(obs, damper, alpha)
    first = dg0.refit((), INSTRUMENT)
    offset = 0.0 if first is None else first.offset_N
    sine = np.array([obs.plans[i].waveform == "sine" for i in obs.case_index], dtype=bool)
    sine_means = {(str(c), int(k)): float(f) for c, k, f in zip(obs.case[sine], obs.start[sine], dg0.nominal[sine],
                                                               strict=True)}
    return scaled(build_observations(campaign, modelled, char, load, spec, n_bins, offset,
                                     unsteady_windows(obs, dg0.evaluator.spread(NOMINAL)),
                                     drive_input_variance(obs, damper, dg0.nominal), scales,
                                     displacement_scale=lvdt, sine_model_means=sine_means, spike_masks=masks))


def any_four_windows(char: pd.DataFrame) -> bool:
    """Whether any case of a characteristic's triangle windows has all four
    (:func:`isokinetic.diagnosis.observations.has_four_windows`)."""
    return any(has_four_windows(seg) for seg in char.groupby("case")["segment"].agg(list))


def motion_terms(triangles: pd.DataFrame, sines: pd.DataFrame, load,
                 lvdt_calibration: tuple[float, float] | None = None) -> tuple[dict, dict | None]:
    """(the LVDT's displacement scale, the actuator delays or None) of a campaign's status-ok triangle cases
    (their speed against the command's, :func:`isokinetic.diagnosis.instrument.displacement_scale`; delays: None,
    cases.parquet's ``delay_s`` serve) or, without any, of its sine cases (amplitude and phase against the
    command's, :func:`isokinetic.diagnosis.instrument.sine_servo_terms`); ``load``: row -> its time series.
    ``lvdt_calibration``: the LVDT's declared (scale, uncertainty_rel), the scale where no command channel
    measures it (:func:`isokinetic.diagnosis.instrument.calibrated_scale`)."""
    scale = displacement_scale(np.array([case_speed_ratio(load(row), float(row["period_s"]), motion_start(row))
                                         for _, row in triangles.iterrows()]))
    delays = None
    if triangles.empty and not sines.empty:   # a sine-only campaign: the servo's gain and phase beside the LVDT's
        scale, delays = sine_servo_terms(*zip(*(case_sine_response(load(row), case_plan(row).frequency_Hz)
                                                for _, row in sines.iterrows()), strict=True))
    elif triangles.empty:
        scale["source"] = "no triangle case"
    scale = calibrated_scale(scale, lvdt_calibration)
    if "velocity_ratio" in triangles:  # the evidence against the plan (not applied: a real stroke error reads the same)
        ratios = triangles["velocity_ratio"].to_numpy(dtype=float)
        scale["velocity_ratio_to_plan"] = float(np.median(ratios[np.isfinite(ratios)])) if np.isfinite(ratios).any() \
            else None
    return scale, delays


def record_span(series: pd.DataFrame) -> tuple[float, float]:
    """(first time stamp, length) of a case's record [s]."""
    t = series["time_s"].to_numpy(dtype=float)
    return (float(t[0]), float(t[-1] - t[0])) if t.size else (0.0, 0.0)


def case_lengths_s(cases: pd.DataFrame, spans: dict[str, tuple[float, float]]) -> np.ndarray:
    """Each case's length in the campaign [s], in the order of cases.parquet: its record's length (``spans``;
    else ``duration_s``, else two periods) plus one sample (their sum is the campaign's length)."""
    def length(row: dict) -> float:
        span = spans.get(row["case"])
        recorded = None if span is None else span[1]
        for value in (recorded, row.get("duration_s"), 2.0 * float(row.get("period_s") or 0.0)):
            if value is not None and np.isfinite(float(value)):
                return float(value)
        return 0.0

    return np.nan_to_num([length(r) + 1.0 / float(r["sample_rate_Hz"]) for r in cases.to_dict("records")])


def campaign_times(obs: Observations, cases: pd.DataFrame, spans: dict[str, tuple[float, float]]) -> np.ndarray:
    """Each observation's time in the campaign [s]: its case's start (the cases back to back, each its
    record's length (``spans``: first time stamp and length; else ``duration_s``, else two periods) plus
    one sample, in the order of cases.parquet) plus its motion start after the record's first time
    stamp and the middle of its samples."""
    rows = cases.to_dict("records")
    durations = case_lengths_s(cases, spans)
    starts = dict(zip(cases["case"], np.concatenate([[0.0], np.cumsum(np.nan_to_num(durations))[:-1]]), strict=True))
    # a triangle's model samples count from its motion start, a sine's from its record's first sample
    begin = {c: starts[c] + (0.0 if row.get("waveform") == "sine" else motion_start(row) - spans.get(c, (0.0, 0.0))[0])
             for c, row in zip(cases["case"], rows, strict=True)}
    fs = np.array([obs.plans[i].sample_rate_Hz for i in obs.case_index])
    return np.array([begin[c] for c in obs.case]) + 0.5 * (obs.start + obs.stop) / fs


def diagnose(campaign_root: Path, spec: WindowSpec = DEFAULTS.window, n_bins: int = 4,
             alpha: float = ALPHA, design: DesignLimits = DEFAULTS.design) -> tuple[dict, Observations | None, dict]:
    """Diagnose a processed campaign folder ``results/<campaign>/``.

    Returns (diagnosis dict, observations, predictions); observations is None when the campaign
    cannot be diagnosed (no damper block, no triangle or sine case). The dict's ``sources`` key lists the
    observations used (:func:`isokinetic.diagnosis.result.observation_sources`); ``next_tests`` the plan of
    extra cases that would separate what the verdict cannot tell apart (:func:`planned_tests`, within the
    ``design`` limits).
    """
    campaign, damper, cases, obs, reason, sensor = prepare_sensor(campaign_root, spec, n_bins, alpha)
    if obs is None:
        return {**no_model(campaign, reason), "sources": observation_sources(None, cases)}, None, {}
    delays = sensor.get("delays") or case_delays(cases)   # a sine-only campaign's: from its command channel
    result, predictions = diagnose_observations(obs, damper, alpha, delays, sensor)
    result["sources"] = observation_sources(obs, cases)
    result["sources"].update(not_used(cases, obs))
    if sensor.get("periodic"):
        result["sources"]["periodic"] = f"{','.join(sensor['periodic'])}: {PERIODIC_FREE}"
    if sensor.get("not_periodic"):
        note, prior = f"{sensor['not_periodic']}: {NOT_PERIODIC}", result["sources"].get("not_used")
        result["sources"]["not_used"] = f"{prior}; {note}" if prior else note
    if "sine_obs" in sensor:   # the sine cases set aside beside the triangles check their verdict
        check_verdict_on_sines(result, sensor, damper, alpha)
        if (result.get("sine_check") or {}).get("consistent") is False:   # and where they fail it, judge on both
            result = judge_on_all_records(result, predictions, obs, sensor, damper, alpha)
    result["next_tests"] = planned_tests(result, predictions, damper, spec, n_bins, design)
    return result, obs, predictions


def planned_tests(result: dict, predictions: dict, damper: Damper, spec: WindowSpec, n_bins: int,
                  design: DesignLimits) -> dict:
    """The ``next_tests`` block (:func:`isokinetic.diagnosis.next_tests.next_tests`; computed only where the
    verdict has a confounding or rival partial explanations). A plan that cannot be computed (a rival's model run
    that fails, or any other error) says so, with the reason, and proposes nothing: the diagnosis stands."""
    try:
        return json_safe(next_tests(result, predictions.get("fits"), damper, spec, n_bins, design))
    except Exception as exc:  # noqa: BLE001 - the verdict is written whatever becomes of its plan
        log.exception("%s: the next-test plan failed", result.get("campaign"))
        return {"needed": True, "note": f"the plan could not be computed: {type(exc).__name__}: {exc}", "plan": []}


def judge_on_all_records(result: dict, predictions: dict, obs: Observations, sensor: dict, damper: Damper,
                         alpha: float) -> dict:
    """A mixed campaign whose sine records fail the triangles' verdict, judged on all its records
    (:mod:`isokinetic.diagnosis.joint`): the search repeated on the triangles and the sine records together, each
    record with its own errors (a sine record's block noise profiled out), with and without the verdict's force
    channel; the joint verdict replaces the triangles' where it explains both (``predictions['verdict']`` then its
    triangles' prediction, whose residuals are tested for structure again: the triangles' verdict's structure keys
    move into ``triangles_verdict``), else the triangles' verdict stands, not explained. A joint search that cannot
    be made is reported with its reason, the verdict not explained; none is made where no candidate explained the
    triangles alone (JOINT_SKIPPED)."""
    if "unexplained_note" in result:   # no catalogue set explains the triangles: none explains them and the sines
        return json_safe(judged_on_all_records(result, {"skipped": JOINT_SKIPPED}, None, None))
    dg = Diagnoser(obs, damper, alpha, sensor.get("obs_time_s"), sensor.get("time_ref_s"))
    try:
        joint, best = joint_search(dg, sensor["sine_obs"], damper, tuple(result.get("verdict") or ()),
                                   channel_of(result))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        log.warning("%s: the joint search failed: %s", result.get("campaign"), exc)
        joint, best = {"error": f"{type(exc).__name__}: {exc}"}, None
    out = judged_on_all_records(result, joint, best, dg)
    if best is not None and best.explained:   # the joint verdict's residuals tested for structure in turn
        for key in ("structure", "structure_note"):
            if key in out:
                out["triangles_verdict"][key] = out.pop(key)
        out["where"] = [w for w in out.get("where", []) if w.get("axis") == "speed"]   # the nominal model's gap
        predictions.update(verdict=best.triangles.measured_prediction,
                           structure=structure_keys(out, obs, best.triangles, alpha, sensor, damper, dg))
    return json_safe(out)


def check_verdict_on_sines(result: dict, sensor: dict, damper: Damper, alpha: float) -> None:
    """``result['sine_check']`` (:func:`isokinetic.diagnosis.sine_check.sine_check`) of the sine observations set
    aside beside the triangles (where it fails, :func:`judge_on_all_records` follows). A check that cannot be
    made (a model run that fails) is reported with its reason, the verdict left as it is."""
    sine_obs = sensor["sine_obs"]
    try:
        check = sine_check(sine_obs, damper, result, sensor["sine_time_s"], sensor["time_ref_s"], alpha)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        log.warning("%s: the sine check failed: %s", result.get("campaign"), exc)
        check = {"cases": ",".join(dict.fromkeys(sine_obs.case.tolist())), "error": f"{type(exc).__name__}: {exc}"}
    result["sine_check"] = check


def not_used(cases: pd.DataFrame, obs: Observations) -> dict[str, str]:
    """``sources.not_used`` where status-ok cases of one waveform were set aside for the other's: sine cases beside
    triangle windows (SINES_BESIDE_TRIANGLES), or triangle cases none of which has its four windows, beside sine
    cases (TRIANGLES_WITHOUT_FOUR_WINDOWS)."""
    ok = cases[(cases["status"] == "ok") & ~cases["case"].isin(obs.case)]
    waves = {obs.plans[i].waveform for i in obs.case_index}
    for left, used, why in (("sine", "triangle", SINES_BESIDE_TRIANGLES),
                            ("triangle", "sine", TRIANGLES_WITHOUT_FOUR_WINDOWS)):
        names = ok.loc[ok["waveform"] == left, "case"]
        if len(names) and used in waves:
            return {"not_used": f"{','.join(names)}: {why}"}
    return {}


def write_diagnosis(campaign_root: Path, json_path: Path, figure_path: Path | None, spec: WindowSpec = DEFAULTS.window,
                    n_bins: int = 4, design: DesignLimits = DEFAULTS.design, plan_figure_path: Path | None = None
                    ) -> dict:
    """Diagnose, validate against the schema, write diagnosis.json, next_tests.yaml beside it (the plan as a
    manifest fragment, :func:`isokinetic.diagnosis.plan_text.plan_yaml`), the gap figure (none without
    ``figure_path``: the blind suite draws none, and then needs no plotting library) and, at ``plan_figure_path``,
    the next tests on the A-T diagram (Fig. 21, :func:`isokinetic.plots.next_tests.next_tests_figure`)."""
    try:
        result, obs, predictions = diagnose(Path(campaign_root), spec, n_bins, design=design)
    except Exception as exc:  # noqa: BLE001 - an accepted campaign always gets its diagnosis.json
        log.exception("diagnosis of %s failed", campaign_root)
        name = Path(campaign_root).name
        with contextlib.suppress(Exception):  # noqa: BLE001 - the folder's name serves
            name = load_campaign(Path(campaign_root))[0]
        result, obs, predictions = no_model(name, f"diagnosis failed: {type(exc).__name__}: {exc}", "failed"), None, {}
    validate_diagnosis(result)
    write_json(result, json_path)
    write_text(plan_yaml(result.get("next_tests"), result["campaign"]),
               Path(json_path).parent / STAGE_OUTPUTS["diagnosis"]["next_tests"])
    if figure_path is not None:
        from isokinetic.plots.diagnosis import gap_figure  # matplotlib only where a figure is drawn
        from isokinetic.plots.style import save_figure

        save_figure(gap_figure(result, obs, predictions), figure_path)
    if plan_figure_path is not None:
        from isokinetic.plots.next_tests import next_tests_figure
        from isokinetic.plots.style import save_figure

        fits = predictions.get("fits")
        damper = fits["dg"].evaluator.damper if fits else None   # the damper the diagnosis ran
        save_figure(next_tests_figure(result["campaign"], result.get("next_tests"), obs.plans if obs else (), damper,
                                      design, spec), plan_figure_path)
    return result


def run_diagnosis(campaign_root: str | Path, settings: Settings, figures: bool = True) -> dict:
    """The chain's diagnosis step (:mod:`isokinetic.stages.chain`): :func:`write_diagnosis` into the campaign
    folder's diagnosis.json and, with ``figures``, Fig. 16, at the places the output registry names."""
    root = Path(campaign_root)
    gap, plan = (root / figure(name).path if figures else None for name in ("fig16_gap", "fig21_next_tests"))
    return write_diagnosis(root, root / STAGE_OUTPUTS["diagnosis"]["json"], gap, settings.window,
                           design=settings.design, plan_figure_path=plan)
