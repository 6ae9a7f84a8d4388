"""The diagnosis section of a campaign page: which effects explain the sim-to-real gap, how far, where.

Read from ``results/<campaign>/diagnosis.json`` (:mod:`isokinetic.stages.diagnosis`): the
verdict and whether it explains the gap within noise, the gap before and after, the instrument
terms, the fitted effect parameters with their standard errors and correlations, the speed bands
where the nominal model misses, the residual-structure tests of the verdict on every axis (contract 1.3), the
top candidates, confounded effects with the next tests that would separate them (contract 1.5; the load-cell
calibration beside the cases, 1.6) and the observations
used. Every value's title names its JSON key path,
which ``python -m isokinetic trace`` audits.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import pandas as pd
from markupsafe import Markup

from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.diagnosis.plan_text import CALIBRATIONS, declaration
from isokinetic.physics.effects import REGISTRY
from isokinetic.physics.viscosity import ViscosityLaw, equivalent_temperature_offset_C
from isokinetic.report.cells import Cell, Col, Row, Table, json_table_view, kv_table, number_cell
from isokinetic.report.embed import FigureView
from isokinetic.report.numbers import esc, fmt, fmt_pct, fmt_text, formula, short, text, yes_no
from isokinetic.report.sources import Source, lineage_of

#: Unit and words of each effect parameter a verdict fits (its registry record's field).
EFFECT_PARAM_UNITS = {e.field: e.unit for e in REGISTRY if e.fit is not None}
EFFECT_PARAM_NAMES = {e.field: e.display_name for e in REGISTRY if e.fit is not None}
WHERE_COLS = [Col("direction", "dir", text, False), Col("v_min_m_s", "from [mm/s]", scale=1e3),
              Col("v_max_m_s", "to [mm/s]", scale=1e3), Col("n_cases", "cases"),
              Col("mean_rel_error", "mean signed rel. error", fmt_pct), Col("mean_z", "mean z", lambda x: fmt(x, 3)),
              Col("significant", "significant", yes_no, False)]
STRUCTURE_COLS = [Col("axis", "axis", text, False), Col("range_text", "range", text, False),
                  Col("mean_rel", "mean signed rel. error", fmt_pct), Col("z", "bin z", lambda x: fmt(x, 3)),
                  Col("p_adjusted", "Holm-adjusted p", lambda x: fmt(x, 2)),
                  Col("quantity", "value binned", text, False)]
TEST_COLS = [Col("axis", "axis", text, False), Col("n_units", "units"), Col("n_bins", "bins"),
             Col("bins_p", "binned-means p", lambda x: fmt(x, 2)), Col("trend_p", "trend p", lambda x: fmt(x, 2)),
             Col("p_adjusted", "Holm-adjusted p", lambda x: fmt(x, 2)),
             Col("significant", "structure", yes_no, False), Col("quantity", "what is tested", text, False)]
CANDIDATE_COLS = [Col("rank", "rank"), Col("effects", "effects", text, False),
                  Col("explained", "explains", yes_no, False), Col("gap_after", "gap after"),
                  Col("holdout_gap_after", "holdout gap"), Col("score", "score"),
                  Col("params", "fitted parameters", text, False)]
SHOWN_CANDIDATES = 8
PLAN_COLS = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
             Col("velocity_m_s", "speed [mm/s]", scale=1e3), Col("amplitude_m", "amplitude [mm]", scale=1e3),
             Col("period_s", "period [s]"), Col("rig_time_s", "rig time [s]", lambda x: fmt(x, 3)),
             Col("resolves_text", "resolves", text, False),
             Col("separation_se", "separation [SE]", lambda x: fmt(x, 3))]
CALIBRATION_COLS = [Col("check", "calibration", text, False),
                    Col("uncertainty_rel", "uncertainty (1 σ) [%]", lambda x: fmt(x, 2), scale=100.0),
                    Col("rig_time_s", "rig time [s]", lambda x: fmt(x, 3)),
                    Col("resolves_text", "resolves", text, False),
                    Col("separation_se", "separation [SE]", lambda x: fmt(x, 3))]


def _how_far(diag: Mapping, src: Source) -> Table:
    """The gap before and after the verdict's effects, on the fit and the holdout."""
    metric = esc(diag.get("metric", "gap"))
    items = [("verdict", esc(", ".join(diag.get("verdict") or []) or "[] (nominal)"), src.title("verdict", "verdict")),
             ("explained", yes_no(diag.get("explained", True)), src.title("explained", "explained")),
             (f"gap before ({metric})", fmt(diag.get("gap_before")), src.title("gap_before", "gap_before")),
             (f"gap after ({metric})", fmt(diag.get("gap_after")), src.title("gap_after", "gap_after")),
             (f"holdout gap after ({metric})", fmt(diag.get("holdout_gap_after")),
              src.title("holdout_gap_after", "holdout_gap_after")),
             ("shrink (before / after)", fmt(diag.get("shrink")), src.title("shrink", "shrink"))]
    if "rms_rel_before" in diag:
        items.append(("rms relative error before -> after",
                      f"{fmt_pct(diag.get('rms_rel_before'))} &rarr; {fmt_pct(diag.get('rms_rel_after'))}",
                      src.title("rms_rel_before", "rms_rel_before (rms_rel_after: key rms_rel_after)")))
    noise = diag.get("noise") or {}
    if noise:
        items.append(("data", f"{noise.get('n_windows', '-')} windows + {noise.get('n_transient_bins', '-')} "
                              f"transient bins; between-period scatter {fmt_pct(noise.get('repeatability_rel'))}",
                      src.title("noise", "noise")))
    check = diag.get("sine_check")
    if isinstance(check, Mapping):
        shown = (f"{'consistent' if check.get('consistent') else 'not consistent'}: rms z "
                 f"{fmt(check['verdict'].get('rms_z'), 3)} (nominal {fmt(check['nominal'].get('rms_z'), 3)}) "
                 f"over {check.get('dof', '-')} degrees of freedom") if "verdict" in check \
            else f"not checked: {esc(check.get('error', ''))}"
        items.append(("sine records (" + esc(check.get("cases", "")) + ") against the verdict", shown,
                      src.title("sine_check", "sine_check")))
    if "nominal_p_value" in diag:
        items.append(("nominal test p-value (chi-squared, instrument terms fitted)",
                      fmt(diag.get("nominal_p_value"), 3), src.title("nominal_p_value", "nominal_p_value")))
    return kv_table(items)


def _instrument(diag: Mapping, src: Source) -> Table | None:
    """The rig's own errors fitted with the effects: actuator delay, load-cell offset and gain."""
    inst = diag.get("instrument") or {}
    if not inst:
        return None

    def shown(key: str, scale: float = 1.0, unit: str = "") -> str:
        value = inst.get(key)
        return "not needed" if value is None else f"{fmt(value * scale)} {unit}".strip()

    chain = [(label, key, scale, unit) for label, key, scale, unit in (  # the sensor chain, contract 1.2
        ("force-channel lag (group delay)", "force_lag_s", 1e3, "ms"), ("LVDT scale", "displacement_scale", 1.0, ""),
        ("load-cell zero drift", "force_drift_N_s", 1e3, "mN/s")) if key in inst]
    return kv_table([
        ("actuator delay (median over cases)", shown("delay_s", 1e3, "ms"), src.title("instrument.delay_s", "delay_s")),
        ("load-cell zero offset", shown("force_offset_N", 1.0, "N"),
         src.title("instrument.force_offset_N", "force_offset_N")),
        ("load-cell gain", shown("force_gain"), src.title("instrument.force_gain", "force_gain")),
        *[(label, shown(key, scale, unit), src.title(f"instrument.{key}", key)) for label, key, scale, unit in chain]])


def _params(diag: Mapping, src: Source) -> Table | None:
    """The verdict's fitted effect parameters (each in its effect's words and unit, from the effect registry) with
    their standard errors."""
    params = diag.get("params") or {}
    if not params:
        return None
    ident = (diag.get("identifiability") or {}).get("parameters") or {}
    rows = [Row([Cell(f"{esc(EFFECT_PARAM_NAMES.get(k, ''))} <code>{esc(k)}</code>".lstrip()),
                 number_cell(fmt(v), src.title(f"params.{k}", k)),
                 number_cell(fmt((ident.get(k) or {}).get("std_error"), 3),
                             src.title(f"identifiability.parameters.{k}.std_error", "std_error")),
                 Cell(formula(EFFECT_PARAM_UNITS.get(k, "")))]) for k, v in params.items()]
    return Table(["parameter", "estimate", "std error", "unit"], rows, id="diagnosis-params")


def viscosity_as_temperature(diag: Mapping, law: ViscosityLaw | None, reference_C: float | None,
                             nominal_Pa_s: float | None) -> str | None:
    """The fitted viscosity deviation read as a temperature offset (:func:`equivalent_temperature_offset_C`)
    at the cases' median temperature, with the 95 % interval from its standard error; a hint to give a
    viscosity law when there is none. None when the verdict fits no viscosity."""
    mu = (diag.get("params") or {}).get("viscosity_Pa_s")
    if mu is None or not nominal_Pa_s:
        return None
    ratio = float(mu) / float(nominal_Pa_s)
    head = f"The fitted viscosity is {fmt(ratio, 3)} &times; the nominal"
    if law is None or reference_C is None or not math.isfinite(reference_C):
        return (head + ". With a viscosity-temperature law in the manifest (<code>damper.viscosity_law</code>) and "
                "case temperatures, this deviation would also be read as a temperature offset.")
    se = ((diag.get("identifiability") or {}).get("parameters") or {}).get("viscosity_Pa_s", {}).get("std_error")
    dt = equivalent_temperature_offset_C(law, reference_C, ratio)
    text_ = (f"{head} at each case's temperature: the oil behaves as if it were {fmt(abs(dt), 3)} K "
             f"{'colder' if dt < 0 else 'warmer'} than the temperature the models took (equivalent offset "
             f"&Delta;T = {fmt(dt, 3)} K at {fmt(reference_C, 4)} &deg;C, the cases' median; {law.kind} law)")
    if se is not None and math.isfinite(float(se)) and float(se) > 0:
        lo, hi = (ratio - 1.96 * float(se) / nominal_Pa_s, ratio + 1.96 * float(se) / nominal_Pa_s)
        if lo > 0:
            ends = sorted(equivalent_temperature_offset_C(law, reference_C, r) for r in (lo, hi))
            text_ += f"; 95 % interval {fmt(ends[0], 3)} to {fmt(ends[1], 3)} K"
    return text_ + ". A temperature sensor reading that far off, or oil that no longer follows its datasheet law."


def _correlation(diag: Mapping) -> dict | None:
    corr = (diag.get("identifiability") or {}).get("correlation") or {}
    if not corr:
        return None
    return {"text": Markup(", ".join(f"{esc(k)} {fmt(v, 2)}" for k, v in corr.items())),
            "strong": any(abs(v) >= 0.8 for v in corr.values())}


def _where(diag: Mapping, src: Source) -> Table | None:
    """The speed bands where the nominal model misses (|z| > 3): the ``where`` entries of axis speed (or none)."""
    where = diag.get("where") or []
    bands = [(i, b) for i, b in enumerate(where) if b.get("axis", "speed") == "speed"]
    if not bands:
        return None
    wdf = pd.DataFrame([b for _i, b in bands]).reset_index(drop=True)
    wdf["band"] = [f"where.{i}" for i, _b in bands]
    cols = [c for c in WHERE_COLS if c.key in wdf]
    return json_table_view(wdf, cols, src, "band", "where-bands", json_keys=set(wdf.columns) - {"band"})


def _range_text(entry: Mapping) -> str:
    """'2 to 5 m', '+' (a direction), or one value."""
    if entry.get("axis") == "direction":
        return str(entry.get("direction", ""))
    lo, hi = entry.get("range") or [None, None]
    unit = entry.get("unit", "")
    return f"{fmt(lo, 3)} {unit}".strip() if lo == hi else f"{fmt(lo, 3)} to {fmt(hi, 3)} {unit}".strip()


def _structure(diag: Mapping, src: Source) -> dict | None:
    """The residual-structure tests of the verdict (``structure``): a table of the tests on every axis, the
    ``where`` entries of the axes with structure, and the note; None for a diagnosis without them (before 1.3)."""
    structure = diag.get("structure")
    if not isinstance(structure, Mapping):
        return None
    tests = list(structure.get("tests") or [])
    tdf = pd.DataFrame(tests)
    if tests:
        tdf["key"] = [f"structure.tests.{i}" for i in range(len(tests))]
    test_table = json_table_view(tdf, TEST_COLS, src, "key", "structure-tests",
                                 json_keys={"n_units", "n_bins", "bins_p", "trend_p", "p_adjusted"}) if tests else None
    entries = [(i, e) for i, e in enumerate(diag.get("where") or []) if e.get("axis", "speed") != "speed"]
    where_table = None
    if entries:
        wdf = pd.DataFrame([e for _i, e in entries])
        wdf["key"] = [f"where.{i}" for i, _e in entries]
        wdf["range_text"] = [_range_text(e) for _i, e in entries]
        where_table = json_table_view(wdf, STRUCTURE_COLS, src, "key", "where-structure",
                                      json_keys={"mean_rel", "z", "p_adjusted"})
    return {"tests": test_table, "where": where_table, "note": diag.get("structure_note"),
            "alpha": structure.get("alpha"), "skipped": "; ".join(f"{k}: {v}" for k, v in
                                                                   (structure.get("skipped") or {}).items())}


def _candidates(diag: Mapping, src: Source) -> dict | None:
    """The best-scoring candidates, and the verdict's row wherever it ranks."""
    cands = diag.get("candidates") or []
    if not cands:
        return None
    verdict = set(diag.get("verdict") or [])
    shown = list(range(min(SHOWN_CANDIDATES, len(cands))))
    in_verdict = [i for i, c in enumerate(cands) if set(c.get("effects") or []) == verdict]
    shown += [i for i in in_verdict[:1] if i not in shown]
    top = [cands[i] for i in shown]
    cdf = pd.DataFrame({
        "rank": [i + 1 for i in shown],
        "key": [f"candidates.{i}" for i in shown],
        "effects": [", ".join(c.get("effects") or []) or "(nominal)" for c in top],
        "explained": [c.get("explained") for c in top],
        "gap_after": [c.get("gap_after") for c in top],
        "holdout_gap_after": [c.get("holdout_gap_after") for c in top],
        "score": [c.get("score") for c in top],
        "params": ["; ".join(f"{k} = {fmt_text(v)}" for k, v in (c.get("params") or {}).items()) for c in top],
    })
    table = json_table_view(cdf, CANDIDATE_COLS, src, "key", "candidates",
                            json_keys={"gap_after", "holdout_gap_after", "score"},
                            row_class=lambda r: "verdict" if set(r["effects"].split(", ")) == verdict else "")
    return {"n_shown": len(top), "n": len(cands), "table": table}


def _observations(diag: Mapping) -> dict | None:
    """The windows and time series the diagnosis used."""
    sources = diag.get("sources")
    if not isinstance(sources, Mapping) or not sources:
        return None
    series = sources.get("timeseries") or {}
    return {"windows": [k for k in str(sources.get("windows") or "").split(",") if k],
            "characteristic_file": sources.get("characteristic_file",
                                               STAGE_OUTPUTS["characteristic"]["characteristic"]),
            "n_series": len(series),
            "series": [{"case": c, "timeseries_file": v.get("timeseries_file", ""), "raw_file": v.get("raw_file", ""),
                        "raw_sha256": short(v.get("raw_sha256"))} for c, v in series.items() if isinstance(v, Mapping)]}


def _confounded(diag: Mapping) -> str | None:
    confounded = diag.get("confounded") or []
    if not confounded:
        return None
    return "; ".join(", ".join(g) if isinstance(g, (list, tuple)) else str(g) for g in confounded)


def _calibrations(entries: Sequence[Mapping], src: Source) -> dict | None:
    """The calibrations the plan proposes (contract 1.6, ``next_tests.calibrations``: the load cell's, the LVDT's):
    their table and, per entry, what it calibrates, how it is done and declared (:data:`plan_text.CALIBRATIONS`)."""
    if not entries:
        return None
    df = pd.DataFrame([{**e, "key": f"next_tests.calibrations.{i}", "resolves_text": ", ".join(e.get("resolves") or [])}
                       for i, e in enumerate(entries)])
    table = json_table_view(df, CALIBRATION_COLS, src, "key", "next-calibrations",
                            json_keys={"uncertainty_rel", "rig_time_s", "separation_se"})
    return {"table": table, "entries": [{"text": CALIBRATIONS[e["check"]], "how": str(e.get("how", "")),
                                         "declare": declaration(e), "lvdt": e["check"] == "lvdt_scale"}
                                        for e in entries]}


def _next_tests(diag: Mapping, src: Source) -> dict | None:
    """The next tests beside the confounding they resolve (contract 1.5, ``next_tests``): the note, each group's
    separation now and with the plan (and by the load-cell calibration alone, 1.6), the calibration and the plan's
    cases, what no case separates."""
    block = diag.get("next_tests")
    if not isinstance(block, Mapping):
        return None
    plan = block.get("plan") or []
    table = None
    if plan:
        df = pd.DataFrame([{**e, "key": f"next_tests.plan.{i}", "resolves_text": ", ".join(e.get("resolves") or [])
                            or "-"} for i, e in enumerate(plan)])
        table = json_table_view(df, PLAN_COLS, src, "key", "next-tests",
                                json_keys={"velocity_m_s", "amplitude_m", "period_s", "rig_time_s", "separation_se"})
    calibrations = block.get("calibrations") or []
    by_calibration = {g: (CALIBRATIONS[c["check"]].name, se)
                      for c in calibrations for g, se in (c.get("separation_se_by_group") or {}).items()}
    now = block.get("separation_se_now") or {}
    groups = [{"group": g, "now": fmt(now.get(g), 3), "planned": fmt(se, 3),
               "calibration": fmt(by_calibration[g][1], 3) if g in by_calibration else None,
               "calibration_name": by_calibration[g][0] if g in by_calibration else None}
              for g, se in (block.get("separation_se") or {}).items()]
    unresolvable = {g: why + (f"; the {by_calibration[g][0]} below resolves its listing" if g in by_calibration else "")
                    for g, why in (block.get("unresolvable") or {}).items()}
    return {"needed": bool(block.get("needed")), "note": block.get("note", ""), "table": table, "groups": groups,
            "calibrations": _calibrations(calibrations, src),
            "total_min": fmt((block.get("total_rig_time_s") or 0.0) / 60.0, 3),
            "unresolvable": unresolvable, "target_se": block.get("target_se")}


def diagnosis_section(diag: Mapping | None, src: Source, figures: Sequence[FigureView],
                      viscosity_note: str | None = None) -> dict:
    """The data of the diagnosis section (``state``: missing, not_diagnosed or ok); ``viscosity_note``:
    :func:`viscosity_as_temperature`."""
    if diag is None:
        return {"state": "missing", "lineage": lineage_of(src), "figures": figures}
    if diag.get("status", "ok") != "ok":
        return {"state": "not_diagnosed", "reason": diag.get("reason", diag.get("status")),
                "lineage": lineage_of(src), "figures": figures}
    return {"state": "ok", "verdict": ", ".join(diag.get("verdict") or []), "explained": diag.get("explained", True),
            "unexplained_note": diag.get("unexplained_note", ""), "how_far": _how_far(diag, src),
            "instrument": _instrument(diag, src), "instrument_note": diag.get("confounded_instrument_note"),
            "calibration_note": diag.get("calibration_note"),
            "params": _params(diag, src), "correlation": _correlation(diag), "where": _where(diag, src),
            "structure": _structure(diag, src),
            "viscosity_note": Markup(viscosity_note) if viscosity_note else None,
            "candidates": _candidates(diag, src), "confounded": _confounded(diag),
            "next_tests": _next_tests(diag, src),
            "lineage": lineage_of(src, "verdict"), "observations": _observations(diag), "figures": figures}
