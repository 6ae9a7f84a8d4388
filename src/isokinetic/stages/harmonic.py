"""The rule ``harmonic``: sine and free-waveform records, their loops, peak-to-peak and binned curves
(the method: :mod:`isokinetic.measurement.loops`).

Stage
    :func:`harmonic_stage` reads ``results/<campaign>/cases.parquet`` and the status-ok sine and
    free time series; :func:`write_harmonic` writes ``harmonic.parquet`` (tables.HARMONIC) and
    ``fig15_harmonic_loops.png`` (drawn by :mod:`isokinetic.plots.harmonic`). Deterministic: same
    inputs, same bytes.
"""

from __future__ import annotations

import logging
import math
import os
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_of
from isokinetic.io import write_parquet
from isokinetic.measurement.loops import (
    binned_characteristic,
    free_loop,
    loop,
    peak_to_peak,
    peak_velocity_characteristic,
)
from isokinetic.measurement.quasi_static import quasi_static

log = logging.getLogger("isokinetic")

#: Output file names of :func:`write_harmonic`.
TABLE_FILE = Path(STAGE_OUTPUTS["harmonic"]["table"]).name
FIGURE_FILE = Path(figures_of("harmonic")[0].path).name

#: Columns of the harmonic table (tables.HARMONIC plus the extras, in this order).
COLUMNS = ["campaign", "case", "waveform", "kind", "direction", "velocity_m_s", "force_N",
           "velocity_std_m_s", "force_std_N", "n_points", "time_s", "lag_s", "phase_lag_rad",
           "amplitude_m", "displacement_amplitude_m", "frequency_Hz", "window_s",
           "row_start", "row_stop", "loop_start_s", "loop_end_s", "raw_file", "raw_sha256", "quasi_static"]


# ----------------------------------------------------------------------------------------------
# stage
# ----------------------------------------------------------------------------------------------

def _read_cases(root: Path) -> pd.DataFrame | None:
    """Validate's cases table, else ingest's (:meth:`CampaignFolder.cases`); None when the folder has neither."""
    return CampaignFolder.at(root).cases_if_any()


def _empty_table() -> pd.DataFrame:
    df = tables.empty(tables.HARMONIC)
    for c in COLUMNS:
        if c not in df:
            df[c] = pd.Series(dtype="int64" if c in ("n_points", "row_start", "row_stop") else bool
                              if c == "quasi_static" else object if c in ("raw_file", "raw_sha256") else "float64")
    return df[COLUMNS]


def _harmonic(campaign_root) -> tuple[pd.DataFrame, dict[str, pd.DataFrame], list[str], str, pd.DataFrame]:
    """(table, loops, notes, campaign name, the sine/free case rows) of one campaign folder."""
    root = Path(campaign_root)
    cases = _read_cases(root)
    notes: list[str] = []
    if cases is None or cases.empty:
        return _empty_table(), {}, ["cases table missing or empty"], root.name, pd.DataFrame()
    name = "+".join(sorted(set(cases["campaign"].astype(str)))) or root.name
    wanted = cases[cases["waveform"].isin(["sine", "free"])]
    bad = wanted[wanted["status"] != "ok"]
    if len(bad):
        notes.append(f"quarantined sine/free case(s) not used: {', '.join(bad['case'].astype(str))}")
    ok = wanted[wanted["status"] == "ok"]
    rows: list[dict] = []
    loops: dict[str, pd.DataFrame] = {}
    for _, c in ok.iterrows():
        case, waveform = str(c["case"]), str(c["waveform"])
        path = root / str(c["timeseries_file"])
        if not path.is_file():
            notes.append(f"{case}: time series missing")
            log.warning("campaign %s, case %s: time series %s missing", name, case, path)
            continue
        series = pd.read_parquet(path)
        base = {"campaign": str(c["campaign"]), "case": case, "waveform": waveform,
                "amplitude_m": float(c["amplitude_m"]) if pd.notna(c["amplitude_m"]) else math.nan,
                "raw_file": str(c.get("raw_file", "")), "raw_sha256": str(c.get("raw_sha256", ""))}
        try:
            if waveform == "sine":
                freq = float(c["frequency_Hz"]) if pd.notna(c["frequency_Hz"]) else None
                lp = loop(series, freq)
                parts = [("peak_to_peak", peak_to_peak(lp))]
            else:
                lp = free_loop(series)
                parts = [("binned", binned_characteristic(lp)), ("peak_velocity", peak_velocity_characteristic(lp))]
        except ValueError as exc:
            notes.append(f"{case}: {exc}")
            log.warning("campaign %s, case %s: %s", name, case, exc)
            continue
        loops[case] = lp
        verdict = quasi_static(lp)
        if waveform == "free" and not verdict.passed:
            notes.append(f"{case}: {verdict.reason}; its bins are loops, not characteristic points")
        amp = 0.5 * float(lp["displacement_m"].max() - lp["displacement_m"].min()) if len(lp) else math.nan
        extra = {"displacement_amplitude_m": amp, "frequency_Hz": float(lp.attrs["frequency_Hz"]),
                 "window_s": float(lp.attrs["window_s"]), "row_start": int(lp.attrs.get("row_start", -1)),
                 "row_stop": int(lp.attrs.get("row_stop", -1)),
                 "loop_start_s": float(lp["time_s"].iloc[0]) if len(lp) else math.nan,
                 "loop_end_s": float(lp["time_s"].iloc[-1]) if len(lp) else math.nan,
                 "quasi_static": verdict.passed}
        for kind, pts in parts:
            if pts.empty:
                notes.append(f"{case}: no {kind.replace('_', '-')} point")
            for r in pts.to_dict("records"):
                rows.append({**base, **extra, "kind": kind, "direction": r["direction"],
                             "velocity_m_s": r["velocity_m_s"], "force_N": r["force_N"],
                             "velocity_std_m_s": r.get("velocity_std_m_s", math.nan),
                             "force_std_N": r.get("force_std_N", math.nan),
                             "n_points": int(r.get("n_points", 1)), "time_s": r.get("time_s", math.nan),
                             "lag_s": r.get("lag_s", math.nan), "phase_lag_rad": r.get("phase_lag_rad", math.nan)})
        log.info("campaign %s, case %s (%s): %d loop samples, window %.4g s, %d points", name, case, waveform,
                 len(lp), lp.attrs["window_s"], sum(len(p) for _, p in parts))
    if not rows:
        table = _empty_table()
    else:
        table = pd.DataFrame(rows, columns=COLUMNS).astype({"n_points": "int64", "row_start": "int64",
                                                            "row_stop": "int64", "quasi_static": bool})
        order = {c: i for i, c in enumerate(ok["case"].astype(str))}
        kind_order = {"peak_to_peak": 0, "binned": 1, "peak_velocity": 2}
        table = table.assign(_c=table["case"].map(order), _k=table["kind"].map(kind_order),
                             _d=(table["direction"] == "+").astype(int))
        table = table.sort_values(["_c", "_k", "_d", "velocity_m_s", "time_s"], kind="stable",
                                  ignore_index=True).drop(columns=["_c", "_k", "_d"])
    return tables.validate_table(table, tables.HARMONIC), loops, notes, name, ok


def harmonic_stage(campaign_root) -> tuple[pd.DataFrame, dict[str, pd.DataFrame]]:
    """Harmonic table (tables.HARMONIC, columns :data:`COLUMNS`) and the loops {case: loop} of the
    status-ok sine and free cases of ``results/<campaign>/`` (``cases.parquet``, falling back to
    ``ingest/cases.parquet``; time series from ``timeseries_file``).

    Sine cases: :func:`loop` + :func:`peak_to_peak` (kind 'peak_to_peak'); free cases:
    :func:`free_loop` + :func:`binned_characteristic` ('binned') and
    :func:`peak_velocity_characteristic` ('peak_velocity'). Every row carries its case's ``quasi_static``
    verdict (:func:`isokinetic.measurement.quasi_static.quasi_static`): a free record that fails it gives
    no characteristic point, and its binned loop here is the view of it (the figure's note says so). A case
    that cannot be analysed (time series missing, shorter than a period) is skipped with a logged warning.
    """
    table, loops, _, _, _ = _harmonic(campaign_root)
    return table, loops


def write_harmonic(campaign_root, out_dir) -> list[Path]:
    """Write ``harmonic.parquet`` and ``fig15_harmonic_loops.png`` of ``results/<campaign>/`` into
    ``out_dir``; returns the two paths. A campaign without sine/free cases gives an empty table
    and a figure that says so."""
    from isokinetic.plots.harmonic import harmonic_figure  # matplotlib only where the figure is drawn
    from isokinetic.plots.style import save_figure

    root, out = Path(campaign_root), Path(out_dir)
    table, loops, notes, name, ok = _harmonic(root)
    if not loops and not notes:
        notes.append("the campaign has no sine or free cases")
    fig = harmonic_figure(table, loops, ok, campaign=name, note="; ".join(notes))
    os.makedirs(out, exist_ok=True)
    paths = [write_parquet(table, out / TABLE_FILE), save_figure(fig, out / FIGURE_FILE)]
    log.info("campaign %s: %d harmonic rows from %d case(s)", name, len(table), len(loops))
    return paths
