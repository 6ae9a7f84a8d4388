"""The re-derivation of each kind of table the trace command knows (:data:`isokinetic.audit.trace.KINDS`).

Per kind: ``intro_<kind>(ctx, t)``, the derivation in words (the first step printed, when the kind
has one), and ``rederive_<kind>(ctx, t, src)``, which re-runs the package's own stage functions on
the raw evidence ``src`` in a scratch folder, prints each step, and returns the re-derived row
matched to the traced row ``t`` by the kind's keys. Only the cases the row needs are re-derived
for per-case tables, every case for fits and the diagnosis. Stage parameters (window fractions,
tolerances, design limits) come from the lineage record of the traced file or of the stage's own
output when present, else from the config (:func:`isokinetic.audit.trace_core.param`).

Equation numbers, in the docstrings and in the steps printed, are those of the paper "A method for
the identification of hydraulic damper characteristics from steady velocity inputs" (Titurus et al.).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd

from isokinetic.audit.trace_core import (
    FIT_RTOL,
    NOT_DERIVED_KEYS,
    Comparison,
    Context,
    MissingFile,
    Traced,
    TraceStop,
    compare_value,
    ctx_rtol,
    json_get,
    match_row,
    param,
    recorded_settings,
    sha_text,
    value_text,
    window_spec,
)
from isokinetic.audit.trace_evidence import (
    RawSource,
    RawText,
    column_mapping,
    describe_source,
    open_source,
    raw_source,
    rebuild,
)
from isokinetic.blind.score import score
from isokinetic.contracts.campaign import case_plan, timeseries_relpath
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS, ingest_path
from isokinetic.contracts.settings import Settings
from isokinetic.io import sha256_file, write_parquet
from isokinetic.measurement.model_fit import fit_models
from isokinetic.measurement.repeatability import relative_difference, repeatability
from isokinetic.measurement.windows import WindowSpec, motion_start, windowed_half_periods
from isokinetic.stages.characteristic import assemble, paired_repeatability, records_stage, windows_stage
from isokinetic.stages.design import plan_check
from isokinetic.stages.diagnosis import diagnose
from isokinetic.stages.harmonic import harmonic_stage
from isokinetic.stages.nominal import nominal_stage

DIAGNOSIS_DEFAULT_KEYS = ("gap_before", "gap_after", "verdict")
#: The files a trace reads and re-derives, relative to a campaign's folder (the registry's).
CASES, QUARANTINE = STAGE_OUTPUTS["validate"]["cases"], STAGE_OUTPUTS["validate"]["quarantine"]
WINDOWS, REPEATABILITY = STAGE_OUTPUTS["windows"]["windows"], STAGE_OUTPUTS["repeatability"]["repeatability"]
CHARACTERISTIC, DIAGNOSIS = STAGE_OUTPUTS["characteristic"]["characteristic"], STAGE_OUTPUTS["diagnosis"]["json"]
PLAN_CHECK = STAGE_OUTPUTS["design"]["plan_check"]


# ----------------------------------------------------------------------------------------------
# shared steps
# ----------------------------------------------------------------------------------------------

def _rep_tolerance(ctx: Context, root: Path, files: Sequence[Path]) -> tuple[float, str]:
    tol, where = param(ctx, ["tolerance", "repeatability_tolerance"], [*files, root / REPEATABILITY],
                       ["repeatability", "tolerance"])
    return float(tol), where


def _chain_settings(ctx: Context, root: Path, files: Sequence[Path]) -> Settings:
    """What ingest and validate applied when the traced files were made (:func:`recorded_settings`: their
    lineage params, else the config): the file-size limit, the sample rate's and the dropped samples' tolerances."""
    return recorded_settings(ctx, [root / CASES, root / ingest_path("cases"), *files])


def _series_step(ctx: Context, src: RawSource, scratch: Path, case: str) -> pd.DataFrame:
    series = pd.read_parquet(scratch / timeseries_relpath(case))
    cases = pd.read_parquet(scratch / CASES).set_index("case")
    status = cases.loc[case, "status"]
    if status != "ok":
        q = pd.read_parquet(scratch / QUARANTINE)
        reasons = "; ".join(q[q["case"] == case]["reason"]) or "?"
        ctx.report.step(f"Validation (validate.case_problems): case {case} is quarantined now: {reasons}")
    raw = RawText(ctx, src, scratch, case)
    how = "stages.ingest.ingest_case" if src.kind == "raw" else "physics.virtual_rig.simulate_cases"
    ctx.report.step(f"Canonical SI series of {case} ({how}; validation: status {status}): {len(series)} samples, "
                    f"t = {series['time_s'].iloc[0]:g} .. "
                    f"{series['time_s'].iloc[-1]:g} s",
                    *column_mapping(src, case), f"{raw.label} {raw.header_text()}")
    return series


def _window_steps(ctx: Context, src: RawSource, scratch: Path, row: pd.Series, spec: WindowSpec, spec_where: str,
                  series: pd.DataFrame) -> None:
    cases = pd.read_parquet(scratch / CASES).set_index("case", drop=False)
    case_row = cases.loc[str(row["case"])]
    plan = case_plan(case_row)
    start = motion_start(case_row)
    k = int(row["segment"])
    t = series["time_s"].to_numpy()
    segs = windowed_half_periods(plan, float(t[-1]), spec, start)
    half = plan.period_s / 2.0
    raw = RawText(ctx, src, scratch, str(row["case"]))
    delay = case_row.get("delay_s", math.nan)
    delay_text = f", delay {float(delay) * 1e3:.4g} ms after the first sample" if pd.notna(delay) else ""
    motion = (f"motion start (validate, motion.estimate_motion from the displacement): plan t = 0 at record "
              f"t = {start:.6g} s{delay_text}; windows at motion start + plan times")
    if len(segs) >= k:
        t0, t1, sign = segs[k - 1]
        geometry = (f"half-period {k}: t = {t0:g} .. {t1:g} s, direction {'+' if sign > 0 else '-'} "
                    f"(triangle T = {plan.period_s:g} s, Y = {plan.amplitude_m:g} m, phase {plan.phase_rad:.6g} rad, "
                    f"planned |v| = 4Y/T = {plan.velocity_m_s:.6g} m/s)")
        window = (f"window [{spec.start_fraction:g}, {spec.end_fraction:g}] x T/2 = "
                  f"{t0 + spec.start_fraction * half:g} .. {t0 + spec.end_fraction * half:g} s "
                  f"(fractions from {spec_where})")
    else:
        geometry, window = f"half-period {k}: not in the re-derived record", ""
    ctx.report.step("Window selection (windows.window_ranges)", motion, geometry, window,
                    f"stored rows [{int(row['row_start'])}, {int(row['row_stop'])}), t = {row['window_start_s']:g} .. "
                    f"{row['window_end_s']:g} s, n = {int(row['n_samples'])}",
                    f"first sample, {raw.label} {raw.line(int(row['row_start']))}",
                    f"last sample,  {raw.label} {raw.line(int(row['row_stop']) - 1)}")


def _stats_step(ctx: Context, new: pd.Series) -> None:
    spikes = int(new["spikes_excluded"]) if pd.notna(new.get("spikes_excluded")) else 0
    missing = int(new["missing_samples"]) if pd.notna(new.get("missing_samples")) else 0
    ctx.report.step("Window statistics (windows.case_windows) on the re-derived samples",
                    (f"force_N     = least-squares line of force_N at the window's time centre, over the "
                     f"{int(new['n_samples'])} samples ({missing} dropped, {spikes} left out as "
                     f"spikes by measurement.spikes.spike_mask; windows.window_mean_force) = {new['force_N']:.10g} N"
                     if spikes or missing else
                     f"force_N     = mean of force_N over the {int(new['n_samples'])} samples = "
                     f"{new['force_N']:.10g} N"),
                    f"force_std_N = standard deviation (ddof = 1) = {new['force_std_N']:.10g} N",
                    "velocity_m_s = least-squares slope of displacement_m against time_s = "
                    f"{new['velocity_m_s']:.10g} m/s",
                    f"window t = {new['window_start_s']:g} .. {new['window_end_s']:g} s, rows "
                    f"[{int(new['row_start'])}, {int(new['row_stop'])})")


def plan_text(c: Mapping) -> str:
    """A case plan in words (cases-table row)."""
    wf = str(c["waveform"])
    rate = f"{float(c['sample_rate_Hz']):g} Hz"
    record = f", record {float(c['duration_s']):g} s" if pd.notna(c.get("duration_s")) else ""
    if wf == "triangle":
        period, amp = float(c["period_s"]), float(c["amplitude_m"])
        return (f"triangle T = {period:g} s, Y = {amp:g} m (|v| = 4Y/T = {4 * amp / period:.6g} m/s), "
                f"phase {float(c['phase_rad']):.6g} rad, {rate}{record}")
    if wf == "sine":
        return f"sine f = {float(c['frequency_Hz']):g} Hz, Y = {float(c['amplitude_m']):g} m, {rate}{record}"
    return f"{wf}, {rate}{record}"


def damper_step(ctx: Context, src: RawSource) -> None:
    """The nominal damper data of the campaign (the manifest's damper block or the rig spec's damper)."""
    d = src.damper
    where = (f"damper block of {ctx.rel(src.manifest_path)}" if src.kind == "raw" else
             f"damper of the virtual-rig spec ({src.spec_where})")
    if d is None:
        ctx.report.step(f"Damper data: none ({where} missing)")
        return
    ctx.report.step(f"Nominal damper data from the {where}",
                    f"A_p = {d.piston_area_m2:g} m^2, V1 = {d.chamber_volume_1_m3:g} m^3, "
                    f"V2 = {d.chamber_volume_2_m3:g} m^3, A_O = {d.orifice_area_m2:g} m^2, "
                    f"l_O = {d.orifice_length_m:g} m, C_D = {d.discharge_coefficient:g}, "
                    f"rho = {d.density_kg_m3:g} kg/m^3, mu = {d.viscosity_Pa_s:g} Pa s, "
                    f"beta = {d.oil_compressibility_1_Pa:g} 1/Pa")


def _characteristic_chain(ctx: Context, src: RawSource, root: Path, files: Sequence[Path]) -> tuple[Path, WindowSpec]:
    """Every case re-derived, windows -> repeatability -> characteristic written in the scratch folder."""
    spec, spec_where = window_spec(ctx, [*files, root / WINDOWS])
    tol, tol_where = _rep_tolerance(ctx, root, files)
    scratch = rebuild(ctx, src, settings=_chain_settings(ctx, root, files))
    cases = pd.read_parquet(scratch / CASES)
    win = windows_stage(scratch, spec)
    records, _energy = records_stage(scratch)          # the sine and free cases' points
    rep = paired_repeatability(win, records, tol)
    char = assemble(win, rep, records)
    write_parquet(win, scratch / WINDOWS)
    write_parquet(rep, scratch / REPEATABILITY)
    write_parquet(char, scratch / CHARACTERISTIC)
    n_ok = int((cases["status"] == "ok").sum())
    ctx.report.step(f"Characteristic re-derived from the raw data: {n_ok} of {len(cases)} cases ok after validation, "
                    f"{len(win)} windows (fractions [{spec.start_fraction:g}, {spec.end_fraction:g}] from "
                    f"{spec_where}), repeatability tolerance {tol:g} ({tol_where})",
                    "stages: ingest -> validate -> windows.windows_stage -> repeatability.repeatability -> "
                    "characteristic.assemble")
    return scratch, spec


def _diagnosis_run(ctx: Context, src: RawSource, root: Path, files: Sequence[Path]) -> dict:
    scratch, spec = _characteristic_chain(ctx, src, root, files)
    ctx.report.step("Running diagnosis.diagnose on the re-derived campaign (windows + transient bins, candidate fits; "
                    "this takes a few seconds per campaign)")
    result, _obs, _pred = diagnose(scratch, spec, design=_chain_settings(ctx, root, files).design)
    return result


# ----------------------------------------------------------------------------------------------
# cases and time series
# ----------------------------------------------------------------------------------------------

def intro_cases(ctx: Context, t: Traced) -> str:
    row = t.row
    return (f"Provenance in the row: raw file {row['raw_file']}, sha256 {sha_text(row['raw_sha256'])}, "
            f"{int(row['n_samples'])} samples, status {row['status']}")


def rederive_cases(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """The cases table (validated, or the ingest's own) of the row's case, re-read or re-simulated."""
    case = str(t.row["case"])
    scratch = rebuild(ctx, src, [case], expected={case: str(t.row["raw_sha256"])},
                      settings=_chain_settings(ctx, t.root, [t.path]))
    new = match_row(pd.read_parquet(scratch / t.kind.path), t, "cases table")
    if new["status"] == "ok":
        _series_step(ctx, src, scratch, case)
    else:
        q = pd.read_parquet(scratch / QUARANTINE)
        ctx.report.step(f"Case {case} is quarantined: " + ("; ".join(q[q["case"] == case]["reason"]) or "?"))
    return new


def rederive_timeseries(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One row of a case's canonical SI series, next to its raw CSV line."""
    case = t.path.stem
    scratch = rebuild(ctx, src, [case], validate=False, settings=_chain_settings(ctx, t.root, [t.path]))
    new_path = scratch / timeseries_relpath(case)
    if not new_path.is_file():
        raise TraceStop(f"case {case} no longer ingests (quarantined now): no time series to compare")
    raw = RawText(ctx, src, scratch, case)
    new = match_row(pd.read_parquet(new_path), t, "time series")
    ctx.report.step(f"Row {int(t.row['row'])} of {case} in the raw CSV and its conversion to SI",
                    f"{raw.label} {raw.header_text()}", f"{raw.label} {raw.line(int(t.row['row']))}",
                    *column_mapping(src, case))
    return new


# ----------------------------------------------------------------------------------------------
# windows, characteristic, repeatability
# ----------------------------------------------------------------------------------------------

def intro_windows(ctx: Context, t: Traced) -> str:
    row = t.row
    return (f"Provenance in the row: raw file {row['raw_file']}, sha256 {sha_text(row['raw_sha256'])}, "
            f"rows [{int(row['row_start'])}, {int(row['row_stop'])}) (t = {row['window_start_s']:g} .. "
            f"{row['window_end_s']:g} s)")


def _case_windows(ctx: Context, t: Traced, src: RawSource) -> tuple[pd.DataFrame, pd.Series, float, str]:
    """(windows of the row's case, the row's window, repeatability tolerance, where it came from)."""
    case = str(t.row["case"])
    spec, spec_where = window_spec(ctx, [t.path, t.root / WINDOWS])
    tol, tol_where = _rep_tolerance(ctx, t.root, [t.path])
    scratch = rebuild(ctx, src, [case], expected={case: str(t.row["raw_sha256"])},
                      settings=_chain_settings(ctx, t.root, [t.path]))
    series = _series_step(ctx, src, scratch, case)
    _window_steps(ctx, src, scratch, t.row, spec, spec_where, series)
    win = windows_stage(scratch, spec)
    new = match_row(win, t, "windows of the case")
    _stats_step(ctx, new)
    return win, new, tol, tol_where


def rederive_windows(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One steady window: the samples of its half-period, their mean force and velocity."""
    return _case_windows(ctx, t, src)[1]


def _rederive_record_point(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """A sine case's peak-velocity point or a free record's velocity bin: the case re-derived, its points
    recomputed (stages.characteristic.records_stage) with the repeatability flag of its two periods."""
    case = str(t.row["case"])
    spec, _spec_where = window_spec(ctx, [t.path, t.root / WINDOWS])
    tol, tol_where = _rep_tolerance(ctx, t.root, [t.path])
    scratch = rebuild(ctx, src, [case], expected={case: str(t.row["raw_sha256"])},
                      settings=_chain_settings(ctx, t.root, [t.path]))
    _series_step(ctx, src, scratch, case)
    win = windows_stage(scratch, spec)
    records, _energy = records_stage(scratch)
    new = match_row(assemble(win, paired_repeatability(win, records, tol), records), t, f"{t.row['method']} points")
    ctx.report.step(f"{t.row['method']} point re-derived (characteristic.records_stage; repeatability tolerance "
                    f"{tol:g} from {tol_where})",
                    f"rows [{int(new['row_start'])}, {int(new['row_stop'])}), n_samples = {int(new['n_samples'])} "
                    f"({'cycles' if new['method'] == 'sine_peak' else 'samples in the bin'}), force_N = "
                    f"{new['force_N']:.10g} N")
    return new


def rederive_characteristic(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One characteristic point: its window and the repeatability flag of its case and direction."""
    if str(t.row.get("method", "triangle_window")) != "triangle_window":
        return _rederive_record_point(ctx, t, src)
    win, _window, tol, tol_where = _case_windows(ctx, t, src)
    rep = repeatability(win, tol)
    new = match_row(assemble(win, rep), t, "characteristic of the case")
    r = rep[rep["direction"] == new["direction"]].iloc[0]
    ctx.report.step(f"Repeatability flag (repeatability.repeatability, tolerance {tol:g} from {tol_where})",
                    f"case {t.row['case']}, direction {new['direction']}: rel_diff = (F2 - F1)/mean(|F1|, |F2|) = "
                    f"{r['rel_diff']:.6g} -> repeatability_flagged = {bool(new['repeatability_flagged'])}")
    return new


def intro_repeatability(ctx: Context, t: Traced) -> str:
    return (f"Derivation: rel_diff = (F2 - F1) / mean(|F1|, |F2|) of the windows of case {t.row['case']}, direction "
            f"{t.row['direction']}, period 1 (F1) and period 2 (F2), from {ctx.rel(t.root / WINDOWS)}")


def rederive_repeatability(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """Period 2 against period 1 of one case and direction."""
    case, direction = str(t.row["case"]), str(t.row["direction"])
    spec, spec_where = window_spec(ctx, [t.root / WINDOWS])
    tol, tol_where = _rep_tolerance(ctx, t.root, [t.path])
    scratch = rebuild(ctx, src, [case], settings=_chain_settings(ctx, t.root, [t.path]))
    series = _series_step(ctx, src, scratch, case)
    win = windows_stage(scratch, spec)
    mine = win[win["direction"] == direction].sort_values("period")
    for _, w in mine.iterrows():
        _window_steps(ctx, src, scratch, w, spec, spec_where, series)
        ctx.report.step(f"Period {int(w['period'])} window (windows.case_windows): force_N = {w['force_N']:.10g} N "
                        f"over {int(w['n_samples'])} samples, velocity_m_s = {w['velocity_m_s']:.10g} m/s")
    f1, f2 = float(mine.iloc[0]["force_N"]), float(mine.iloc[-1]["force_N"])
    rel = float(relative_difference(f1, f2))
    ctx.report.step(f"repeatability.relative_difference: ({f2:.10g} - {f1:.10g}) / mean(|{f1:.10g}|, |{f2:.10g}|) = "
                    f"{rel:.10g}", f"flagged = |rel_diff| > {tol:g} (tolerance from {tol_where}) = {abs(rel) > tol}")
    return match_row(repeatability(win, tol), t, "repeatability of the case")


# ----------------------------------------------------------------------------------------------
# nominal model, plan check, harmonic
# ----------------------------------------------------------------------------------------------

def intro_nominal(ctx: Context, t: Traced) -> str:
    return (f"Derivation: the noise-free nominal model (no added effects) simulated through case {t.row['case']}'s "
            f"plan and reduced over the same window (nominal.nominal_stage -> nominal.model_windows)")


def rederive_nominal(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One window of the nominal model run at the case's measured speeds."""
    case = str(t.row["case"])
    spec, spec_where = window_spec(ctx, [t.path])
    scratch = rebuild(ctx, src, [case], settings=_chain_settings(ctx, t.root, [t.path]))
    c = pd.read_parquet(scratch / CASES).set_index("case").loc[case]
    ctx.report.step(f"Case plan of {case} (from the raw manifest / spec; status after validation {c['status']})",
                    plan_text(c),
                    f"window fractions [{spec.start_fraction:g}, {spec.end_fraction:g}] from {spec_where}")
    measured = windows_stage(scratch, spec)
    write_parquet(measured, scratch / WINDOWS)
    speeds = ", ".join(f"{abs(v) * 1e3:.6g}" for v in measured.sort_values("segment")["velocity_m_s"])
    ctx.report.step(f"Measured kinematics that drive the model (windows of {case}, re-derived)",
                    f"half-period speeds [mm/s]: {speeds}; motion start {c.get('motion_start_s', 0.0):g} s "
                    "(the model runs each half-period at its measured speed, nominal.case_drives)")
    new = match_row(nominal_stage(scratch, spec), t, "nominal model windows of the case")
    ctx.report.step(f"Model window {int(new['segment'])} (direction {new['direction']}): rows "
                    f"[{int(new['row_start'])}, {int(new['row_stop'])}) of the model's sample grid k/fs, "
                    f"t = {new['window_start_s']:g} .. {new['window_end_s']:g} s",
                    f"force_N = mean of A_p dp (Eq. 8; the nominal model has no friction) = {new['force_N']:.10g} N, "
                    f"velocity_m_s = slope of the actuator displacement = {new['velocity_m_s']:.10g} m/s")
    return new


def locate_plan_check(ctx: Context, path: Path, row: pd.Series) -> Path:
    """The campaign folder of a plan-check row; a row of the all-campaigns summary names its campaign."""
    root = path.parent.parent
    if not CampaignFolder.at(root).ingest_dir.is_dir():  # the all-campaigns summary results/design/plan_check.parquet
        root = path.parent.parent / str(row["campaign"])
        own = root / PLAN_CHECK
        ctx.report.step(f"Summary row: copied by rule report_index (stage design_summary) from {ctx.rel(own)} "
                        f"(campaign {row['campaign']})")
        if not root.is_dir():
            raise MissingFile(f"campaign folder {ctx.rel(root)} of this summary row not found")
    return root


def rederive_plan_check(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """The plan check of one case: G-numbers (Eq. (19)-(22)) and the stroke to converge (Eq. (28))."""
    case = str(t.row["case"])
    files = [t.path, t.root / t.kind.path]
    phi, phi_where = param(ctx, ["phi"], files, ["design", "convergence_fraction"])
    max_a, _ = param(ctx, ["max_amplitude_m"], files, ["design", "max_amplitude_mm"], scale=1e-3)
    min_a, _ = param(ctx, ["min_amplitude_m"], files, ["design", "min_amplitude_mm"], scale=1e-3)
    start, start_where = param(ctx, ["start_fraction"], files, ["windows", "start_fraction"])
    scratch = rebuild(ctx, src, [case], settings=_chain_settings(ctx, t.root, files))
    cases = pd.read_parquet(scratch / CASES)
    c = cases.set_index("case").loc[case]
    ctx.report.step(f"Planned case {case} from the raw manifest / spec (status after validation {c['status']})",
                    plan_text(c),
                    f"design limits: phi = {phi:g} ({phi_where}), max amplitude {max_a:g} m, "
                    f"min amplitude {min_a:g} m, window start fraction {start:g} ({start_where})")
    name = str(cases["campaign"].iloc[0])
    new_df = plan_check(name, cases[cases["case"] == case], src.damper, phi=float(phi), max_amplitude_m=float(max_a),
                        min_amplitude_m=float(min_a), start_fraction=float(start))
    new = match_row(new_df, t, "plan check of the case")
    g = f"G1 = {new['G1']:.6g}, G2 = {new['G2']:.6g}, G3 = {new['G3']:.6g} (Eq. 19-22)"
    if new["waveform"] == "triangle":
        detail = [f"W = 4Y/T = {new['velocity_m_s']:.6g} m/s; {g}",
                  f"stroke to converge (mixed flow, Eq. 28) = {new['stroke_to_converge_m']:.6g} m; the window starts "
                  f"after {new['window_start_stroke_m']:.6g} m of stroke"]
    elif new["waveform"] == "sine":
        detail = [f"peak velocity 2 pi f Y = {new['velocity_m_s']:.6g} m/s; {g}; travel and noise floor checked only"]
    else:
        detail = ["free waveform: nothing planned to check"]
    ctx.report.step("design.plan_check", *detail,
                    f"flagged = {bool(new['flagged'])}; reasons: {new['reasons'] or '(none)'}")
    return new


def intro_harmonic(ctx: Context, t: Traced) -> str:
    row = t.row
    return (f"Derivation: {row['kind']} point of {row['waveform']} case {row['case']}: velocity from a Savitzky-Golay "
            f"derivative of the displacement (window {row['window_s']:g} s), settled loop, extremes per "
            "direction (harmonic.harmonic_stage)")


def rederive_harmonic(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One point of a sine or free record: its settled loop's extremes per direction."""
    case = str(t.row["case"])
    scratch = rebuild(ctx, src, [case], settings=_chain_settings(ctx, t.root, [t.path]))
    _series_step(ctx, src, scratch, case)
    table, loops = harmonic_stage(scratch)
    new = match_row(table, t, "harmonic table of the case")
    lp = loops.get(case)
    if "row_start" in new.index and int(new["row_start"]) >= 0:
        raw = RawText(ctx, src, scratch, case)
        ctx.report.step(f"Samples used: rows [{int(new['row_start'])}, {int(new['row_stop'])}) of the raw record",
                        f"first sample, {raw.label} {raw.line(int(new['row_start']))}",
                        f"last sample,  {raw.label} {raw.line(int(new['row_stop']) - 1)}")
    ctx.report.step(f"harmonic.harmonic_stage on the re-derived series: loop of {0 if lp is None else len(lp)} "
                    f"samples, f = {new['frequency_Hz']:g} Hz, derivative window {new['window_s']:g} s",
                    f"direction {new['direction']}: velocity_m_s = {new['velocity_m_s']:.10g} m/s, force_N = "
                    f"{new['force_N']:.10g} N, lag_s = {new['lag_s']:.6g} s over {int(new['n_points'])} half-cycles")
    return new


# ----------------------------------------------------------------------------------------------
# fitted models, diagnosis, blind scores
# ----------------------------------------------------------------------------------------------

def _fit_intro(ctx: Context, t: Traced, what: str) -> str:
    return (f"Derivation: {what}: weighted least squares (weights 1/(window standard error)^2) over "
            f"the whole characteristic {ctx.rel(t.root / CHARACTERISTIC)} (models.fit_models)")


def intro_models(ctx: Context, t: Traced) -> str:
    row = t.row
    source = f", from {row['derived_from']}" if row.get("derived_from") else ""
    return _fit_intro(ctx, t, f"{row['model']} model, direction {row['direction']}, parameter {row['parameter']} "
                              f"({row['kind']}{source})")


def intro_residuals(ctx: Context, t: Traced) -> str:
    row = t.row
    return _fit_intro(ctx, t, f"{row['model']} model residual at case {row['case']}, segment {row['segment']}")


def _fits(ctx: Context, t: Traced, src: RawSource) -> tuple[int, pd.DataFrame, pd.DataFrame]:
    """(number of characteristic points, fitted parameters, residuals) of the re-derived campaign."""
    scratch, _spec = _characteristic_chain(ctx, src, t.root, [t.path])
    char = pd.read_parquet(scratch / CHARACTERISTIC)
    models, residuals = fit_models(char, src.damper)
    return len(char), models, residuals


def rederive_models(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One fitted model parameter, re-fitted to the re-derived characteristic."""
    n, models, _residuals = _fits(ctx, t, src)
    new = match_row(models, t, "models table")
    ctx.report.step(f"models.fit_models on {n} points: {new['parameter']} = {new['estimate']:.10g} "
                    f"{new['unit']} (95 % interval {new['ci_low']:.6g} .. {new['ci_high']:.6g}), "
                    f"{int(new['n_points'])} points, residual scale {new['residual_scale']:.6g}",
                    f"{new['description']}" + (f"; assumes {new['assumption']}" if new['assumption'] else ""))
    return new


def rederive_residuals(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """One model residual, re-fitted to the re-derived characteristic."""
    n, _models, residuals = _fits(ctx, t, src)
    new = match_row(residuals, t, "residuals table")
    ctx.report.step(f"models.fit_models on {n} points: predicted {new['predicted_N']:.10g} N, "
                    f"residual {new['residual_N']:.10g} N")
    return new


def trace_diagnosis(ctx: Context, path: Path, selector: str | None) -> tuple[list[Comparison], list[str]]:
    """Keys of a diagnosis.json (a key path, or the default keys) against a fresh diagnosis."""
    stored = json.loads(path.read_text(encoding="utf-8"))
    keys = [selector] if selector else list(DIAGNOSIS_DEFAULT_KEYS)
    if keys == ["."]:
        keys = [k for k in stored if k not in NOT_DERIVED_KEYS]
    for k in keys:
        if k.split(".")[0] in NOT_DERIVED_KEYS:
            raise TraceStop(f"{k!r} is not re-derivable (wall-clock time / provenance)")
    values = {k: json_get(stored, k) for k in keys}
    ctx.report.step(f"Stored in {ctx.rel(path)}: " + "; ".join(f"{k} = {value_text(v)}" for k, v in values.items()),
                    f"campaign {stored.get('campaign')}, status {stored.get('status')}, metric {stored.get('metric')} "
                    "(rms over the characteristic windows of z = (F_meas - F_model)/sigma)")
    root = path.parent
    src = open_source(ctx, root)
    describe_source(ctx, src)
    damper_step(ctx, src)
    result = _diagnosis_run(ctx, src, root, [path])
    noise = result.get("noise") or {}
    ctx.report.step(f"Re-derived: verdict {result.get('verdict')}, gap_before {value_text(result.get('gap_before'))}"
                    f" -> gap_after {value_text(result.get('gap_after'))}, shrink {value_text(result.get('shrink'))}",
                    f"sigma^2 = (window force std)^2/n + (r F)^2 with r = {value_text(noise.get('repeatability_rel'))} "
                    f"(period-to-period scatter); {noise.get('n_windows')} windows, {noise.get('n_transient_bins')} "
                    f"transient bins; {len(result.get('candidates') or [])} candidate effect sets fitted")
    comps = []
    for k in keys:
        try:
            new = json_get(result, k)
        except TraceStop:
            new = "<absent>"
        comps += compare_value(k, values[k], new, ctx_rtol(ctx, FIT_RTOL))
    return comps, keys


def _truth_path(ctx: Context, path: Path, row: pd.Series) -> Path:
    """The truth file of a blind score row (its provenance column when the scores carry it, else the layout)."""
    if row.get("truth_file"):
        return ctx.resolve(str(row["truth_file"]))
    return path.parent / "truth" / f"{row['scenario']}.json"


def locate_scores(ctx: Context, path: Path, row: pd.Series) -> Path:
    """The scenario's processed folder (rule blind_diagnose), else its raw campaign; shows the truth first."""
    blind_root, name = path.parent, str(row["scenario"])
    truth_path = _truth_path(ctx, path, row)
    raw_dir = ctx.resolve(str(row["raw_dir"])) if row.get("raw_dir") else blind_root / "raw" / name
    if not truth_path.is_file():
        raise MissingFile(f"truth file {ctx.rel(truth_path)} not found")
    truth = json.loads(truth_path.read_text(encoding="utf-8"))
    ctx.report.step(f"Truth of {name}: {ctx.rel(truth_path)} (sha256 {sha_text(sha256_file(truth_path))}): effects "
                    f"{truth.get('truth') or '[]'}, magnitude {value_text(truth.get('magnitude_x_detection'))} x "
                    "detection level",
                    "the diagnosis never sees this file; blind.score compares its verdict with it")
    processed = sorted(p for p in blind_root.glob(f"diagnosis/*/{name}") if (p / CASES).is_file())
    if row.get("diagnosis_file"):
        named = ctx.resolve(str(row["diagnosis_file"])).parent
        processed = [named] if (named / CASES).is_file() else processed
    if processed:
        ctx.report.step(f"Diagnosed (rule blind_diagnose) in {ctx.rel(processed[0])} from the raw campaign "
                        f"{ctx.rel(raw_dir)}")
        return processed[0]
    if not (raw_dir / "campaign.yaml").is_file():
        raise MissingFile(f"raw scenario {ctx.rel(raw_dir)} not found")
    ctx.report.step(f"No processed folder of {name} under {ctx.rel(blind_root / 'diagnosis')}: the raw hashes "
                    "cannot be checked against a record")
    return raw_dir


def source_scores(ctx: Context, root: Path) -> RawSource:
    """A processed scenario's recorded evidence, or (not processed) its raw campaign with nothing recorded."""
    if (root / CASES).is_file():
        return open_source(ctx, root)
    return raw_source(ctx, root / "campaign.yaml", "", "", None, None)


def rederive_scores(ctx: Context, t: Traced, src: RawSource) -> pd.Series:
    """A blind score: a fresh diagnosis of the scenario, scored against its truth file."""
    name = str(t.row["scenario"])
    truth = json.loads(_truth_path(ctx, t.path, t.row).read_text(encoding="utf-8"))
    processed = (t.root / CASES).is_file()
    files = [t.root / DIAGNOSIS, t.root / CASES] if processed else []
    result = _diagnosis_run(ctx, src, t.root, files)
    ctx.report.step(f"Re-derived diagnosis: verdict {result.get('verdict')}, "
                    f"gap_before {value_text(result.get('gap_before'))} -> "
                    f"gap_after {value_text(result.get('gap_after'))}")
    new = match_row(score([truth], {name: result}), t, "score")
    ctx.report.step(f"blind.score: truth {new['truth'] or '(none)'} against verdict {new['verdict'] or '(none)'} -> "
                    f"exact = {bool(new['exact'])}, shrink = {value_text(new['shrink'])}")
    return new
