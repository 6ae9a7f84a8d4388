"""Rule ``campaign_report``: ``results/<campaign>/report.html``, one self-contained page per campaign.

The page shows what the method of "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.) yields for one campaign: the plan
check, the cases and their measured motion, the steady characteristic, its repeatability, the
fitted models, the harmonic records, the test design, the sim-to-real gap diagnosis and the
quarantined cases, with every figure embedded. Each table is followed by a lineage line and
every number cell's title names its file, row, rule, commit, parameters and audit command
(:mod:`isokinetic.report.sources`); numbers the report computes itself (counts, rms of a
column) say so. The data of each section is built here; ``templates/campaign_report.html.j2``
lays it out.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from markupsafe import Markup

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.campaign_meta import CampaignMeta
from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_in, ingest_path
from isokinetic.io import write_text
from isokinetic.measurement.static_force_fit import offset_check
from isokinetic.physics.viscosity import ViscosityLaw
from isokinetic.plots.figures import applies as figure_applies
from isokinetic.report.cells import Col, Table, badge, kv_table, table_view
from isokinetic.report.diagnosis_section import diagnosis_section, viscosity_as_temperature
from isokinetic.report.embed import FigureView, LeftOut, figure_views, read_captions
from isokinetic.report.layout import footer, render
from isokinetic.report.numbers import esc, fmt, fmt_pct, fmt_text, formula, missing, short, text, yes_no
from isokinetic.report.sources import Source, Sources, lineage_of, lineage_rows, read_json, read_parquet, selector_of

DAMPER_LABELS = {
    "piston_area_m2": ("piston area A_p", "m^2"), "chamber_volume_1_m3": ("chamber volume V_1", "m^3"),
    "chamber_volume_2_m3": ("chamber volume V_2", "m^3"), "orifice_area_m2": ("orifice area A_O", "m^2"),
    "orifice_length_m": ("orifice length l_O", "m"), "discharge_coefficient": ("discharge coefficient C_D", "-"),
    "density_kg_m3": ("oil density rho", "kg/m^3"), "viscosity_Pa_s": ("oil viscosity mu", "Pa s"),
    "oil_compressibility_1_Pa": ("oil compressibility beta", "1/Pa"),
    "charge_pressure_Pa": ("charge pressure p_0", "Pa"),
}
MODEL_NAMES = {"wallaschek": "Wallaschek (symmetric: F = sign(v) F_C + D_L v + D_Q v|v|)",
               "surace": "Surace (one parameter set per direction)"}
CAMPAIGN_NAV = [("header", "Campaign"), ("plan", "Plan check"), ("cases", "Cases"),
                ("characteristic", "Characteristic"),
                ("repeatability", "Repeatability"), ("models", "Models"), ("harmonic", "Harmonic"),
                ("design", "Design"), ("diagnosis", "Diagnosis"), ("quarantine", "Quarantine"),
                ("lineage", "Lineage")]
COUNTED = ["counted by the report"]


@dataclass
class CampaignData:
    """Everything a campaign page reads from ``results/<campaign>/`` (None: not produced), read once through
    :class:`~isokinetic.contracts.campaign_folder.CampaignFolder` (paths from the registry, the typed meta)."""

    folder: CampaignFolder
    name: str
    meta: CampaignMeta | None
    cases: pd.DataFrame | None
    quarantine: pd.DataFrame | None
    characteristic: pd.DataFrame | None
    repeatability: pd.DataFrame | None
    plan_check: pd.DataFrame | None
    models: pd.DataFrame | None
    comparison: pd.DataFrame | None
    harmonic: pd.DataFrame | None
    energy: pd.DataFrame | None
    static_force: pd.DataFrame | None
    diagnosis: dict | None
    provenance: dict | None
    sources: Sources

    @classmethod
    def read(cls, root: str | os.PathLike) -> CampaignData:
        folder = CampaignFolder.at(root)
        provenance = read_json(folder.path("provenance", "provenance"))

        def table(stage: str, name: str) -> pd.DataFrame | None:
            return read_parquet(folder.path(stage, name))
        return cls(folder=folder, name=folder.campaign, meta=folder.meta if folder.has_meta() else None,
                   cases=table("validate", "cases"), quarantine=table("validate", "quarantine"),
                   characteristic=table("characteristic", "characteristic"),
                   repeatability=table("repeatability", "repeatability"), plan_check=table("design", "plan_check"),
                   models=table("models", "models"), comparison=table("models", "comparison"),
                   harmonic=table("harmonic", "table"), energy=table("characteristic", "energy"),
                   static_force=table("static_force", "static_force"),
                   diagnosis=read_json(folder.path("diagnosis", "json")), provenance=provenance,
                   sources=Sources(folder.root, provenance))

    @property
    def root(self) -> Path:
        return self.folder.root

    def source(self, stage: str, name: str) -> Source:
        """The lineage of a registered output of a stage (``source("validate", "cases")``)."""
        return self.sources(STAGE_OUTPUTS[stage][name])

    def meta_source(self) -> Source:
        """The lineage of ``ingest/campaign.json``."""
        return self.sources(ingest_path("meta"))

    def viscosity_law(self) -> ViscosityLaw | None:
        return None if self.meta is None else self.meta.viscosity_law()

    def figures(self, section: str, captions: Mapping[str, str]) -> list[FigureView | LeftOut]:
        """The figures of a report section, embedded; one that does not apply to the campaign's cases
        (:func:`isokinetic.plots.figures.applies`) is left out with its reason."""
        return figure_views(self.sources, figures_in(section), captions,
                            applies=lambda name: figure_applies(name, self.cases))

    def has_ok(self, waveform: str) -> bool:
        """The campaign has a status-ok case of that waveform (cases.parquet)."""
        c = self.cases
        return c is not None and {"waveform", "status"} <= set(c.columns) and bool(
            ((c["waveform"] == waveform) & (c["status"] == "ok")).any())


# ----------------------------------------------------------------------------------------------
# header: the campaign, its damper data, its provenance checks, summary cards
# ----------------------------------------------------------------------------------------------

def _campaign_items(d: CampaignData) -> list[tuple[str, str, str]]:
    meta = d.meta
    src = d.meta_source()
    items = [("campaign", esc(d.name), src.title("campaign", "campaign")),
             ("source", text(meta and meta.source), src.title("source", "source")),
             ("description", text(meta and meta.description), src.title("description", "description")),
             ("temperature", f"{fmt(meta and meta.temperature_C)} &deg;C", src.title("temperature_C", "temperature_C"))]
    if meta is not None and meta.manifest_file:
        items.append(("manifest", f"<code>{esc(meta.manifest_file)}</code> (sha256 "
                                  f"<code>{esc(short(meta.manifest_sha256, 16))}</code>)",
                      src.title("manifest_file", "manifest_file")))
    gen = None if meta is None else meta.generated_by
    if isinstance(gen, Mapping):
        items.append(("generated by", esc(f"{gen.get('generator', '?')} (config campaign "
                                          f"{gen.get('config_campaign', '?')}, seed {gen.get('seed', '?')})"),
                      src.title("metadata.generated_by", "generated_by")))
    return items


def _damper_table(d: CampaignData) -> Table | None:
    if d.meta is None or d.meta.damper is None:
        return None
    src = d.meta_source()
    rows = []
    for key, value in sorted(d.meta.damper.to_dict().items()):     # the file's order (keys sorted)
        label, unit = DAMPER_LABELS.get(key, (key, ""))
        unit_html = "" if unit in ("", "-") else formula(unit)
        rows.append((formula(label), f"{fmt(value)} {unit_html}", src.title(f"damper.{key}", key)))
    return kv_table(rows)


PROVENANCE_PROBLEMS = (("changed_raw_files", "raw files changed since ingest"),
                       ("missing_raw_files", "raw files missing"),
                       ("raw_files_outside", "raw files leading outside the campaign folder (not read)"),
                       ("stale_stages", "stages whose inputs changed since they ran"),
                       ("inconsistent_stages", "stages whose outputs come from different runs"),
                       ("files_without_lineage", "files without lineage"))


def _provenance(prov: Mapping | None) -> dict | None:
    """What the campaign's provenance.json checks say: raw files unchanged, stages current."""
    if prov is None:
        return None
    checks = prov.get("checks")
    if not isinstance(checks, Mapping):
        return {"checked": False}
    git = prov.get("git") or {}
    problems = [{"label": label, "files": (checks.get(key) or [])[:12], "more": max(len(checks.get(key) or []) - 12, 0)}
                for key, label in PROVENANCE_PROBLEMS if checks.get(key)]
    unused = [u for u in ((prov.get("raw") or {}).get("unused_files") or []) if isinstance(u, Mapping)]
    return {"checked": True, "ok": bool(checks.get("ok")), "made": prov.get("created_utc", "?"),
            "commit": short(git.get("commit"), 12) if git.get("commit") else None, "problems": problems,
            "unused": [u.get("path") or u.get("note") for u in unused[:12]], "unused_more": max(len(unused) - 12, 0)}


def _summary_cards(d: CampaignData) -> list[dict]:
    cards = []

    def card(k: str, v: str, title: str) -> None:
        cards.append({"k": k, "v": Markup(v), "title": title})

    if d.cases is not None:
        card("cases ok / planned", f"{int((d.cases['status'] == 'ok').sum())} / {len(d.cases)}",
             d.source("validate", "cases").title("", "count of rows with status ok", COUNTED))
    if d.characteristic is not None:
        card("characteristic points", str(len(d.characteristic)),
             d.source("characteristic", "characteristic").title("", "count of rows", COUNTED))
    if d.plan_check is not None:
        card("plan cases flagged", str(int(d.plan_check["flagged"].sum())),
             d.source("design", "plan_check").title("", "count of rows with flagged true", COUNTED))
    if d.repeatability is not None:
        card("repeatability pairs flagged", f"{int(d.repeatability['flagged'].sum())} / {len(d.repeatability)}",
             d.source("repeatability", "repeatability").title("", "count of rows with flagged true", COUNTED))
    implausible = _implausible(d.models)
    if implausible is not None:
        card("readings outside their physical range", str(len(implausible)) + (
             " " + badge("implausible", "bad") if len(implausible) else ""),
             d.source("models", "models").title("", "count of rows with plausible false", COUNTED))
    diag = d.diagnosis
    if diag and diag.get("status", "ok") == "ok":
        src = d.source("diagnosis", "json")
        verdict = ", ".join(diag.get("verdict") or []) or "none (nominal model explains)"
        explained = diag.get("explained", True)
        card("diagnosis verdict", esc(verdict) + ("" if explained else " " + badge("not explained", "bad")),
             src.title("verdict", "verdict"))
        card(f"gap {diag.get('metric', '')} before -> after",
             f"{fmt(diag.get('gap_before'), 3)} &rarr; {fmt(diag.get('gap_after'), 3)}",
             src.title("gap_before", "gap_before (gap_after: key gap_after)"))
        card("shrink", fmt(diag.get("shrink"), 3), src.title("shrink", "shrink"))
    if d.quarantine is not None:
        card("quarantined cases", str(d.quarantine["case"].nunique() if len(d.quarantine) else 0),
             d.source("validate", "quarantine").title("", "count of distinct cases", COUNTED))
    return cards


def _header_section(d: CampaignData) -> dict:
    campaign = kv_table(_campaign_items(d))
    damper = _damper_table(d)
    return {"campaign": campaign, "damper": damper, "lineage": lineage_of(d.meta_source(), "damper"),
            "provenance": _provenance(d.provenance), "cards": _summary_cards(d)}


# ----------------------------------------------------------------------------------------------
# plan check and cases
# ----------------------------------------------------------------------------------------------

PLAN_COLS = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
             Col("status", "status", text, False),
             Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("period_s", "T [s]"),
             Col("frequency_Hz", "f [Hz]"), Col("amplitude_m", "amplitude [mm]", scale=1e3),
             Col("G3", "G3", lambda x: fmt(x, 3)),
             Col("stroke_to_converge_m", "stroke to converge [mm]", lambda x: fmt(x, 3), scale=1e3),
             Col("window_start_stroke_m", "window start stroke [mm]", lambda x: fmt(x, 3), scale=1e3),
             Col("flagged", "flagged", yes_no, False), Col("reasons", "reasons", text, False)]
CASE_COLS = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
             Col("status", "status", text, False), Col("n_samples", "samples"),
             Col("motion_start_s", "motion start [s]", lambda x: fmt(x, 5)),
             Col("delay_s", "delay [ms]", lambda x: fmt(x, 3), scale=1e3),
             Col("velocity_ratio", "speed / planned", lambda x: fmt(x, 4)),
             Col("motion_rms_m", "motion rms [&micro;m]", lambda x: fmt(x, 3), scale=1e6),
             Col("temperature_C", "temperature [&deg;C]", lambda x: fmt(x, 4)),
             Col("temperature_span_C", "T span [K]", lambda x: fmt(x, 3)),
             Col("temperature_source", "T from", text, False),
             Col("quality", "quality", text, False)]
#: Dropped samples of each case (validate, measurement.sampling), shown when cases.parquet has them.
GAP_COLS = [Col("missing_samples", "missing samples"), Col("missing_fraction", "missing", fmt_pct),
            Col("longest_gap_s", "longest gap [ms]", lambda x: fmt(x, 3), scale=1e3)]


def _plan_section(d: CampaignData) -> dict:
    pc = d.plan_check
    src = d.source("design", "plan_check")
    if pc is None:
        return {"table": None, "lineage": lineage_of(src)}
    flagged = [{"case": r["case"], "reasons": r["reasons"], "title": src.title(selector_of(r, ["case"]), "reasons")}
               for r in pc[pc["flagged"].astype(bool)].to_dict("records")]
    return {"n": len(pc), "flagged": flagged,
            "table": table_view(pc, PLAN_COLS, src, ["case"], row_class=lambda r: "flagged" if r["flagged"] else "",
                                 table_id="plan-check")}


def _case_row_class(r: Mapping) -> str:
    if r["status"] != "ok":
        return "flagged"
    return "warned" if isinstance(r.get("quality"), str) and r["quality"] != "ok" else ""


def temperature_summary(law: ViscosityLaw | None, cases: pd.DataFrame | None) -> str:
    """What the report says about the cases' temperatures and their use by the models (format 1.1), with the
    campaign's viscosity law (:meth:`CampaignMeta.viscosity_law`, None without one)."""
    known = pd.Series(dtype=float) if cases is None or "temperature_C" not in cases else \
        pd.to_numeric(cases["temperature_C"], errors="coerce").dropna()
    if known.empty:
        return "No temperature is known (no temperature channel, no <code>temperature_C</code>)."
    sources = sorted(set(cases["temperature_source"].fillna("").astype(str)) - {""}) \
        if "temperature_source" in cases else []
    text_ = (f"Case temperatures {fmt(known.min(), 4)} to {fmt(known.max(), 4)} &deg;C (from "
             f"{', '.join(sources) or '?'}).")
    if law is None:
        return text_ + (" The manifest gives no viscosity law (<code>damper.viscosity_law</code>): the nominal model "
                        "and the diagnosis take the damper block's viscosity for every case.")
    mu = law.viscosity_Pa_s(known.to_numpy(float))
    return text_ + (f" With the manifest's {law.kind} law the nominal model and the diagnosis take each case's "
                    f"viscosity at its temperature: {fmt(1e3 * mu.min(), 3)} to {fmt(1e3 * mu.max(), 3)} mPa s.")


def _cases_section(d: CampaignData, captions: Mapping[str, str] | None = None) -> dict:
    """The cases table: status, quality, the measured motion (validate) and the temperature of each case."""
    src = d.source("validate", "cases")
    if d.cases is None:
        return {"table": None, "lineage": lineage_of(src)}
    cases = d.cases.copy()
    for column in ("motion_start_s", "delay_s", "velocity_ratio", "motion_rms_m", "temperature_C",
                   "temperature_span_C"):
        if column not in cases:
            cases[column] = np.nan      # a cases table written before the motion or temperature was recorded
    if "quality" not in cases:
        cases["quality"] = np.where(cases["status"] == "ok", "ok", "quarantined")
    cols = CASE_COLS[:-1] + [c for c in GAP_COLS if c.key in cases] + CASE_COLS[-1:]
    return {"table": table_view(cases, cols, src, ["case"], row_class=_case_row_class, table_id="cases-table"),
            "temperature": Markup(temperature_summary(d.viscosity_law(), d.cases)),
            "figures": d.figures("cases", captions or {})}


# ----------------------------------------------------------------------------------------------
# characteristic and repeatability
# ----------------------------------------------------------------------------------------------

#: How each characteristic point was found (stages.characteristic; the table's ``method`` column).
METHOD_LABELS = {"triangle_window": "triangle window", "sine_peak": "sine peak", "free_bin": "free bin"}
CHARACTERISTIC_COLS = [
    Col("case", "case", text, False), Col("method", "method", lambda x: text(METHOD_LABELS.get(x, x)), False),
    Col("direction", "dir", text, False),
    Col("period", "period"), Col("segment", "segment"),
    Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_N", "force [N]"),
    Col("force_std_N", "force std [N]", lambda x: fmt(x, 3)), Col("n_samples", "samples"),
    Col("raw_file", "raw file", lambda x: f"<code>{text(x)}</code>", False),
    Col("row_start", "rows from"), Col("row_stop", "rows to (excl.)"),
    Col("window_start_s", "window from [s]"), Col("window_end_s", "window to [s]"),
    Col("repeatability_flagged", "rep. flagged", yes_no, False)]
REPEATABILITY_COLS = [Col("case", "case", text, False), Col("direction", "dir", text, False),
                      Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_period1_N", "F period 1 [N]"),
                      Col("force_period2_N", "F period 2 [N]"), Col("rel_diff", "(F2-F1)/mean", fmt_pct),
                      Col("tolerance", "tolerance", fmt_pct), Col("flagged", "flagged", yes_no, False)]


def _point_origin(r: Mapping) -> list[str]:
    """Row-level lineage of a characteristic point: its raw file, rows and window."""
    return [f"raw {r.get('raw_file')} rows {r.get('row_start')}-{r.get('row_stop')} "
            f"(window {fmt_text(r.get('window_start_s'))}-{fmt_text(r.get('window_end_s'))} s, "
            f"raw sha256 {short(r.get('raw_sha256'))})"]


def _export_link(d: CampaignData, name: str) -> str | None:
    """The page-relative link of a CSV export (stages.exports) when the campaign has it, else None."""
    rel = STAGE_OUTPUTS["exports"][name]
    return rel if (d.root / rel).is_file() else None


def _cases_without_points(cases: pd.DataFrame | None, char: pd.DataFrame) -> list[str]:
    """The status-ok cases that gave no characteristic point (a sine step with fewer than two steady cycles a
    direction, a free record with no full velocity bin, a triangle case whose windows left the record)."""
    if cases is None or not {"case", "status", "waveform"} <= set(cases.columns):
        return []
    ok = cases[(cases["status"] == "ok") & (cases["waveform"] != "standstill")]
    return sorted(set(ok["case"].astype(str)) - set(char["case"].astype(str)))


def _characteristic_section(d: CampaignData, captions: Mapping[str, str]) -> dict:
    src = d.source("characteristic", "characteristic")
    figures = d.figures("characteristic", captions)
    char = d.characteristic
    if char is None:
        return {"figures": figures, "table": None, "lineage": lineage_of(src)}
    speed = char["velocity_m_s"].abs()
    char = char.assign(_speed=speed).sort_values(["direction", "_speed", "case", "period"]).reset_index(drop=True)
    cols = [c for c in CHARACTERISTIC_COLS if c.key != "method" or "method" in char]
    methods = char["method"].map(lambda x: METHOD_LABELS.get(x, x)).value_counts() if "method" in char else None
    by_method = None if methods is None else ", ".join(f"{n} {m}" for m, n in methods.items())
    return {"figures": figures, "n": len(char), "csv": _export_link(d, "characteristic_csv"), "by_method": by_method,
            "without_points": _cases_without_points(d.cases, char),
            "table": table_view(char, cols, src, ["case", "segment"], row_extra=_point_origin,
                                row_class=lambda r: "flagged" if r.get("repeatability_flagged") else "",
                                table_id="characteristic-points")}


def _repeatability_section(d: CampaignData) -> dict:
    rep = d.repeatability
    src = d.source("repeatability", "repeatability")
    if (rep is None or not len(rep)) and not d.has_ok("triangle"):
        return {"all": None, "left_out": "no status-ok triangle case: the check compares the two periods of a "
                                         "triangle case", "lineage": lineage_of(src)}
    if rep is None:
        return {"all": None, "lineage": lineage_of(src)}
    flagged = rep[rep["flagged"].astype(bool)]
    worst = rep.loc[rep["rel_diff"].abs().idxmax()] if len(rep) else None
    keys = ["case", "direction"]
    return {"n": len(rep), "n_flagged": len(flagged),
            "tolerance": fmt_pct(rep["tolerance"].iloc[0] if len(rep) else float("nan")),
            "worst": None if worst is None else {"rel_diff": fmt_pct(worst["rel_diff"]), "case": worst["case"],
                                                 "direction": worst["direction"]},
            "flagged": table_view(flagged, REPEATABILITY_COLS, src, keys, row_class=lambda r: "flagged",
                                  table_id="repeatability-flagged") if len(flagged) else None,
            "all": table_view(rep, REPEATABILITY_COLS, src, keys, row_class=lambda r: "flagged" if r["flagged"] else "",
                              table_id="repeatability-all")}


# ----------------------------------------------------------------------------------------------
# models and harmonic records
# ----------------------------------------------------------------------------------------------

MODEL_COLS = [Col("direction", "dir", text, False), Col("parameter", "parameter", text, False),
              Col("estimate", "estimate"), Col("ci_low", "95 % low"), Col("ci_high", "95 % high"),
              Col("std_error", "std error", lambda x: fmt(x, 3)), Col("unit", "unit", formula, False),
              Col("description", "meaning", formula, False), Col("assumption", "assuming", formula, False)]
#: The plausibility check of each reading (stages.models), shown beside its unit when the table has it.
PLAUSIBILITY_COLS = [Col("physical_range", "physical range", text, False),
                     Col("plausibility_shown", "plausible?", str, False)]
MODEL_KEYS = ["model", "direction", "parameter"]
NOT_EXCLUDED = "not excluded: "
COMPARISON_ERRORS = (("rel_err_nominal_plan", "nominal model through the plan"),
                     ("rel_err_nominal_eq31", "incompressible nominal (Eq. 31)"),
                     ("rel_err_wallaschek", "Wallaschek fit"), ("rel_err_surace", "Surace fit"))


def _fit_rows(row: Mapping) -> list[str]:
    """Row-level lineage of a fitted parameter: the characteristic rows the fit used."""
    rows = row.get("source_rows")
    if not isinstance(rows, str) or not rows:
        return []
    shown = rows if len(rows) <= 400 else rows[:400] + "..."
    table = row.get("source_file") or STAGE_OUTPUTS["characteristic"]["characteristic"]
    return [f"fitted on {row.get('n_points')} rows (case/segment) of {table}: {shown}"]


def _has_plausibility(models: pd.DataFrame | None) -> bool:
    """The models table carries the plausibility check (tables written before it was added do not)."""
    return models is not None and {"physical_range", "plausible", "plausibility"} <= set(models.columns)


def _plausibility_html(row: Mapping) -> str:
    """A reading's plausibility as HTML: a badge and the reason when outside or not excluded."""
    reason = row.get("plausibility")
    reason = reason if isinstance(reason, str) else ""
    if not missing(row.get("plausible")) and not bool(row.get("plausible")):
        return f"{badge('outside its range', 'bad')} {esc(reason)}"
    if reason.startswith(NOT_EXCLUDED):
        return f"{badge('not excluded', 'warn')} {esc(reason[len(NOT_EXCLUDED):])}"
    return "in range" if row.get("physical_range") else "-"


def _plausibility_class(row: Mapping) -> str:
    """Row class: flagged when the reading lies outside its physical range, warned when only not excluded."""
    if not missing(row.get("plausible")) and not bool(row.get("plausible")):
        return "flagged"
    reason = row.get("plausibility")
    return "warned" if isinstance(reason, str) and reason.startswith(NOT_EXCLUDED) else ""


def _implausible(models: pd.DataFrame | None) -> pd.DataFrame | None:
    """The rows of readings wholly outside their physical range (None: the table has no check)."""
    if not _has_plausibility(models):
        return None
    return models[~models["plausible"].astype(bool)]


def _model_view(d: CampaignData, model: str, group: pd.DataFrame) -> dict:
    """One fitted model: its fit quality, fitted parameters and physical readings with their plausibility."""
    src = d.source("models", "models")
    first = group.iloc[0]
    scale = first.get("residual_scale")
    fit_sel = selector_of(first, MODEL_KEYS)
    cols, row_class = MODEL_COLS, None
    if _has_plausibility(group):
        group = group.assign(plausibility_shown=[_plausibility_html(r) for r in group.to_dict("records")])
        cols, row_class = MODEL_COLS[:7] + PLAUSIBILITY_COLS + MODEL_COLS[7:], _plausibility_class
    fitted = group[group["kind"] == "fitted"]
    derived = group[group["kind"] != "fitted"]
    return {"name": MODEL_NAMES.get(model, model), "n_points": int(first["n_points"]), "dof": int(first["dof"]),
            "rms": Markup(fmt(first["rms_residual_N"])), "scale": Markup(fmt(scale, 3)),
            "kind": "warn" if not missing(scale) and float(scale) > 3 else "info",
            "title": src.title(fit_sel, "n_points,dof,rms_residual_N,residual_scale"),
            "fitted": table_view(fitted, cols, src, MODEL_KEYS, caption="Fitted parameters, 95 % intervals",
                                 row_class=row_class, row_extra=_fit_rows, table_id=f"models-{model}-fitted"),
            "derived": table_view(derived, cols, src, MODEL_KEYS, row_class=row_class, row_extra=_fit_rows,
                                  caption="Physical readings (equivalent values with the nominal geometry)",
                                  table_id=f"models-{model}-derived") if len(derived) else None}


def _implausible_note(models: pd.DataFrame | None) -> list[Markup] | None:
    """One line per reading wholly outside its physical range: model, direction and reason."""
    bad = _implausible(models)
    if bad is None or not len(bad):
        return None
    return [Markup(f"{esc(r['model'])} ({esc(r['direction'])}): {esc(r['plausibility'])}")
            for r in bad.to_dict("records")]


def _comparison(d: CampaignData) -> dict | None:
    """rms relative error of each model against the measured characteristic (computed here)."""
    comp = d.comparison
    csrc = d.source("models", "comparison")
    if comp is None or not len(comp):
        return None
    items = []
    for col, label in COMPARISON_ERRORS:
        if col in comp:
            v = comp[col].to_numpy(dtype=float)
            v = v[np.isfinite(v)]
            if v.size:
                items.append((esc(label), fmt_pct(math.sqrt(float(np.mean(v ** 2)))), csrc.title(
                    "", col, [f"computed by the report: rms over {v.size} points of {col}"])))
    return {"table": kv_table(items), "lineage": lineage_of(csrc)} if items else None


def _static_force(d: CampaignData) -> dict | None:
    """The static force at v -> 0 (gas force, load-cell zero; stages.static_force) and whether the
    diagnosis' load-cell offset agrees with it (offset_check: a disagreement is never silent)."""
    sf = d.static_force
    if sf is None or sf.empty:
        return None
    row = sf.iloc[0].to_dict()
    src = d.source("static_force", "static_force")
    sel = f"campaign={row['campaign']}"
    standstill = row.get("method") == "standstill_mean"
    if missing(row["static_force_N"]):
        value = esc(row["note"])
    else:
        basis = (f"mean of {int(row.get('n_standstill') or 0)} standstill case(s)" if standstill else
                 f"{int(row['n_speeds'])} lowest speeds, {fmt(row['v_min_m_s'] * 1e3, 3)}&ndash;"
                 f"{fmt(row['v_max_m_s'] * 1e3, 3)} mm/s")
        value = (f"{fmt(row['static_force_N'], 3)} N &plusmn; {fmt(row['std_error_N'], 2)} N "
                 f"(95 %: {fmt(row['ci_low_N'], 3)} to {fmt(row['ci_high_N'], 3)} N; {basis})")
    gas = "none declared" if missing(row["gas_force_N"]) else f"{fmt(row['gas_force_N'])} N, subtracted at ingest"
    gas_check = row.get("gas_force_check") or "not_checked"
    if row.get("gas_force_cases"):
        gas_lines = esc(row["gas_force_cases"]).replace("; ", "<br>")
        gas_check_text = (badge("disagrees", "bad") + " " if gas_check == "disagrees" else "") + gas_lines
    else:
        gas_check_text = "no case declares a gas force"
    check = offset_check(row, d.diagnosis)
    verdict = esc(check.text) if check.status != "disagree" else f"{badge('disagree', 'bad')} {esc(check.text)}"
    label = ("static force at rest (standstill cases)" if standstill else
             "static force at v &rarr; 0 (mean of the + and &minus; branches)")
    items = [(label, value, src.title(sel, "static_force_N,std_error_N,ci_low_N,ci_high_N")),
             ("gas force (manifest <code>gas_force_N</code>)", gas, src.title(sel, "gas_force_N")),
             ("declared gas forces against what is left", gas_check_text,
              src.title(sel, "gas_force_check,gas_force_cases")),
             ("against the diagnosis' load-cell offset", verdict,
              d.source("diagnosis", "json").title("instrument.force_offset_N", "force_offset_N"))]
    if row["note"] and not missing(row["static_force_N"]):
        items.append(("note", esc(row["note"]), src.title(sel, "note")))
    return {"table": kv_table(items), "lineage": lineage_of(src), "disagree": check.status == "disagree"}


def _models_section(d: CampaignData, captions: Mapping[str, str]) -> dict:
    figures = d.figures("models", captions)
    models = d.models
    src = d.source("models", "models")
    if models is None or not len(models):
        return {"figures": figures, "models": None, "produced": models is not None, "lineage": lineage_of(src),
                "static_force": _static_force(d), "csv": _export_link(d, "models_csv")}
    views = [_model_view(d, model, group) for model, group in models.groupby("model", sort=False)]
    return {"figures": figures, "models": views, "comparison": _comparison(d), "implausible": _implausible_note(models),
            "static_force": _static_force(d), "csv": _export_link(d, "models_csv")}


HARMONIC_COLS = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
                 Col("kind", "kind", text, False), Col("direction", "dir", text, False),
                 Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_N", "force [N]"),
                 Col("frequency_Hz", "f [Hz]"), Col("amplitude_m", "amplitude [mm]", scale=1e3),
                 Col("lag_s", "force lag [s]", lambda x: fmt(x, 3)), Col("n_points", "points")]


ENERGY_COLS = [Col("case", "case", text, False), Col("frequency_Hz", "f [Hz]"),
               Col("displacement_amplitude_m", "amplitude [mm]", scale=1e3),
               Col("velocity_amplitude_m_s", "peak velocity [mm/s]", scale=1e3),
               Col("energy_J", "energy per cycle [J]"), Col("energy_se_J", "standard error [J]"),
               Col("n_cycles", "cycles"), Col("equivalent_damping_N_s_m", "equivalent damping [N s/m]")]


def _energy_table(d: CampaignData) -> Table | None:
    """Each sine case's energy dissipated per cycle (the force-displacement loop's area, energy.parquet)."""
    e = d.energy
    if e is None or not len(e):
        return None
    return table_view(e.reset_index(drop=True), ENERGY_COLS, d.source("characteristic", "energy"), ["case"],
                      table_id="energy-per-cycle")


def _harmonic_section(d: CampaignData, captions: Mapping[str, str]) -> dict:
    figures = d.figures("harmonic", captions)
    h = d.harmonic
    src = d.source("harmonic", "table")
    energy = _energy_table(d)
    if h is None or not len(h):
        return {"figures": figures, "table": None, "empty": h is not None, "lineage": lineage_of(src),
                "energy": energy}
    h = h.reset_index(drop=True)
    keys = ["case", "kind", "direction"]
    if h.duplicated(keys).any():  # binned points of free records: by position in the file
        h, keys = h.assign(row=h.index), ["row"]
    return {"figures": figures, "table": table_view(h, HARMONIC_COLS, src, keys, table_id="harmonic-points"),
            "energy": energy}


# ----------------------------------------------------------------------------------------------
# quarantine, lineage of the page, the page
# ----------------------------------------------------------------------------------------------

QUARANTINE_COLS = [Col("case", "case", text, False), Col("stage", "stage", text, False),
                   Col("column", "column", text, False), Col("row", "first bad row"),
                   Col("reason", "reason", text, False)]


def _quarantine_section(d: CampaignData) -> dict:
    q = d.quarantine
    src = d.source("validate", "quarantine")
    if q is None or not len(q):
        return {"table": None, "empty": q is not None, "lineage": lineage_of(src)}
    return {"n": q["case"].nunique(),
            "table": table_view(q, QUARANTINE_COLS, src, ["case", "stage"], row_class=lambda r: "flagged",
                                table_id="quarantine")}


def _viscosity_note(d: CampaignData) -> str | None:
    """The diagnosis' viscosity deviation as a temperature offset at the cases' median temperature."""
    meta = d.meta
    temps = None if d.cases is None or "temperature_C" not in d.cases else \
        pd.to_numeric(d.cases.loc[d.cases["status"] == "ok", "temperature_C"], errors="coerce").dropna()
    reference = float(temps.median()) if temps is not None and len(temps) else meta and meta.temperature_C
    nominal = None if meta is None or meta.damper is None else meta.damper.viscosity_Pa_s
    return viscosity_as_temperature(d.diagnosis or {}, d.viscosity_law(), reference, nominal)


def render_campaign_report(campaign_root: str | os.PathLike, *, captions_dir: str | os.PathLike | None = None,
                           lineage_record: Mapping | None = None, index_href: str | None = "../index.html") -> str:
    """The HTML page of one campaign, read from ``results/<campaign>/`` (missing parts are said)."""
    d = CampaignData.read(campaign_root)
    captions = read_captions(captions_dir)
    meta = d.meta
    diagnosis = diagnosis_section(d.diagnosis, d.source("diagnosis", "json"), d.figures("diagnosis", captions),
                                  _viscosity_note(d))
    sections = {"head": _header_section(d), "plan": _plan_section(d), "cases": _cases_section(d, captions),
                "characteristic": _characteristic_section(d, captions), "repeatability": _repeatability_section(d),
                "models": _models_section(d, captions), "harmonic": _harmonic_section(d, captions),
                "design": d.figures("design", captions), "diagnosis": diagnosis, "quarantine": _quarantine_section(d)}
    return render("campaign_report.html.j2", title=f"isokinetic - {d.name}", nav=CAMPAIGN_NAV,
                  lineage_record=lineage_record, name=d.name, description=(meta and meta.description) or "",
                  source=(meta and meta.source) or "-", index_href=index_href, **sections,
                  lineage_files=lineage_rows(d.sources.all()), footer=footer(lineage_record, d.sources.all()))


def write_campaign_report(campaign_root: str | os.PathLike, out_path: str | os.PathLike, **kwargs) -> Path:
    """Write :func:`render_campaign_report` to ``out_path`` atomically."""
    return write_text(render_campaign_report(campaign_root, **kwargs), out_path)
