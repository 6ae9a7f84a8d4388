"""The rule ``figures``: Fig. 7-12 and Fig. 20 of one campaign from its tables.

The figures of the paper "A method for the identification of hydraulic damper characteristics from
steady velocity inputs" (Titurus et al.), Sec. 4.4-4.5, are drawn by :mod:`isokinetic.plots.figures`.
This stage reads a campaign's results folder (the cases, windows and characteristic tables and the
time series of the chosen cases), chooses the three cases of Fig. 7 and the case of Fig. 8 (paper:
cases 4, 12, 22 of 23), says on every figure what is missing or quarantined, and writes the seven
PNGs named by :data:`isokinetic.contracts.outputs.FIGURES`, and Fig. 20, the temperature of each case
(:mod:`isokinetic.plots.temperature`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import figure, figures_of
from isokinetic.physics.viscosity import ViscosityLaw
from isokinetic.plots.figures import (
    campaign_name,
    case_speed_m_s,
    characteristic,
    loglog_characteristic,
    low_velocity_detail,
    noise,
    time_and_loops,
    window_selection,
)
from isokinetic.plots.style import footnote, save_figure
from isokinetic.plots.temperature import case_temperature

#: File names written by :func:`write_campaign_figures`, in order (Fig. 20, 7-12: report order).
FIGURE_FILES = tuple(Path(f.path).name for f in figures_of("figures"))

#: Rank fractions of the speed-ordered triangle cases chosen for Fig. 7 (paper: cases 4, 12, 22 of 23).
SELECT_FRACTIONS = (0.15, 0.5, 0.95)

_CHAR_COLUMNS = ["case", "segment", "direction", "period", "velocity_m_s", "force_N", "force_std_N",
                 "repeatability_flagged"]


# ----------------------------------------------------------------------------------------------
# case selection
# ----------------------------------------------------------------------------------------------

def _planned_speed_m_s(cases: pd.DataFrame) -> pd.Series:
    """Planned W_p = 4 Y / T of each triangle case (Eq. 26), indexed by case."""
    if cases is None or cases.empty:
        return pd.Series(dtype=float)
    amp = pd.to_numeric(cases["amplitude_m"], errors="coerce").to_numpy(dtype=float)
    per = pd.to_numeric(cases["period_s"], errors="coerce").to_numpy(dtype=float)
    w = np.full(len(cases), np.nan)
    good = np.isfinite(amp) & np.isfinite(per) & (per > 0)
    w[good] = 4.0 * amp[good] / per[good]
    return pd.Series(w, index=cases["case"].astype(str).to_numpy())


def _ok_triangles(cases: pd.DataFrame | None) -> pd.DataFrame:
    if cases is None or cases.empty:
        return pd.DataFrame(columns=["case", "waveform", "status"])
    return cases[(cases["waveform"] == "triangle") & (cases["status"] == "ok")]


def select_cases(cases: pd.DataFrame, char: pd.DataFrame | None = None, n: int = 3) -> list[str]:
    """Low / mid / high speed status-ok triangle cases for Fig. 7, ordered by speed.

    Speed is the mean measured |velocity| from ``char`` where the case has windows, else the
    planned 4Y/T. The cases sit at rank fractions 0.15, 0.5, 0.95 of the speed-ordered list
    (the paper's cases 4, 12, 22 of 23); for ``n != 3`` the fractions are spread evenly over
    [0.15, 0.95]. With fewer than ``n`` candidates all of them are returned.
    """
    ok = _ok_triangles(cases)
    ids = [str(c) for c in ok["case"]]
    if not ids or n <= 0:
        return []
    speed = _planned_speed_m_s(ok)
    measured = case_speed_m_s(char)
    speed = pd.Series({c: float(measured.get(c, speed.get(c, np.nan))) for c in ids})
    order = sorted(ids, key=lambda c: (not math.isfinite(speed[c]), speed[c] if math.isfinite(speed[c]) else 0.0, c))
    if len(order) <= n:
        return order
    fractions = SELECT_FRACTIONS if n == 3 else tuple(np.linspace(0.15, 0.95, n))
    picked: list[int] = []
    for f in fractions:
        i = int(round(f * (len(order) - 1)))
        while i in picked and i + 1 < len(order):
            i += 1
        if i not in picked:
            picked.append(i)
    return [order[i] for i in sorted(picked)]


def _fig8_case(picked: list[str], series: dict[str, pd.DataFrame], windows: pd.DataFrame) -> str | None:
    """Fig. 8: the middle selected case, else the nearest one with a time series and windows."""
    with_windows = set(windows["case"].astype(str))
    by_mid = sorted(picked, key=lambda c: abs(picked.index(c) - (len(picked) - 1) / 2))
    return next((c for c in by_mid if c in series and c in with_windows), by_mid[0] if by_mid else None)


# ----------------------------------------------------------------------------------------------
# tables
# ----------------------------------------------------------------------------------------------

def _rows(df: pd.DataFrame | None) -> pd.DataFrame | None:
    """The table, or None when it is missing or has no rows (an empty file may lack columns)."""
    return None if df is None or df.empty or "case" not in df else df


def _read_tables(root: Path) -> tuple[pd.DataFrame | None, pd.DataFrame, pd.DataFrame, str]:
    """(cases, windows, characteristic, note) of a campaign, status-ok cases only.

    The characteristic falls back to the windows without repeatability flags (said in the note),
    the windows to the characteristic; both are empty tables when neither exists.
    """
    folder = CampaignFolder.at(root)
    cases = _rows(folder.cases_if_any())
    windows = _rows(folder.table("windows", "windows"))
    char = _rows(folder.table("characteristic", "characteristic"))
    char_note = ""
    if char is None and windows is not None:
        char = windows.assign(repeatability_flagged=False)
        char_note = "characteristic.parquet missing: windows shown without repeatability flags"
    if windows is None:
        windows = char
    if char is not None and cases is not None and not cases.empty:  # only status-ok cases
        ok_ids = set(cases.loc[cases["status"] == "ok", "case"].astype(str))
        char = char[char["case"].astype(str).isin(ok_ids)]
        windows = windows[windows["case"].astype(str).isin(ok_ids)]
    empty_char = pd.DataFrame(columns=_CHAR_COLUMNS)
    char = empty_char if char is None else char
    windows = empty_char if windows is None else windows
    return cases, windows, char, char_note


def _triangle_rows(char: pd.DataFrame) -> pd.DataFrame:
    """The triangle windows of a characteristic (all of it when it has no ``method`` column)."""
    return char[char["method"] == "triangle_window"] if "method" in char else char


def _status_note(cases: pd.DataFrame | None, char: pd.DataFrame | None) -> str:
    if cases is None or cases.empty:
        return "cases table missing: figures drawn from the characteristic table only"
    tri = cases[cases["waveform"] == "triangle"]
    ok = tri[tri["status"] == "ok"]
    parts = [f"{len(ok)} of {len(tri)} triangle case(s) ok"]
    bad = sorted(tri.loc[tri["status"] != "ok", "case"].astype(str))
    if bad:
        parts.append(f"quarantined: {', '.join(bad[:12])}{' ...' if len(bad) > 12 else ''}")
    with_windows = set() if char is None or char.empty else set(char["case"].astype(str))
    no_win = sorted(set(ok["case"].astype(str)) - with_windows)
    if no_win:
        parts.append(f"ok but without windows: {', '.join(no_win[:12])}{' ...' if len(no_win) > 12 else ''}")
    other = cases[cases["waveform"].isin(["sine", "free"])]
    if len(other):
        parts.append(f"{len(other)} sine/free case(s): in Fig. 9-11 (force at peak velocity, velocity bins) and "
                     f"{figure('fig15_harmonic_loops').path}")
    return "; ".join(parts)


def _fig7_note(picked: list[str], series: dict[str, pd.DataFrame], note: str) -> str:
    """The campaign note, preceded by what Fig. 7 lacks (cases, time series)."""
    if len(picked) < 3:
        note = f"only {len(picked)} status-ok triangle case(s) available (3 wanted); " + note
    missing_ts = [c for c in picked if c not in series]
    if missing_ts:
        note = f"time series missing for {', '.join(missing_ts)}; " + note
    return note


# ----------------------------------------------------------------------------------------------
# the rule
# ----------------------------------------------------------------------------------------------

def _viscosity_law(root: Path) -> ViscosityLaw | None:
    """The campaign's viscosity law (ingest/campaign.json, format 1.1), None without one."""
    folder = CampaignFolder.at(root)
    return folder.meta.viscosity_law() if folder.has_meta() else None


def write_campaign_figures(campaign_root: str | os.PathLike, out_dir: str | os.PathLike,
                           campaign: str | None = None) -> list[Path]:
    """Read ``campaign_root`` (``results/<campaign>``) and write the figure PNGs to ``out_dir`` (Fig. 7-12
    and Fig. 20, the temperature of each case).

    Tables: ``cases.parquet`` (at the root or in ``ingest/``), ``characteristic.parquet`` (falls back
    to ``windows.parquet`` without repeatability flags), ``windows.parquet`` for Fig. 8 (falls back
    to the characteristic), and the time series named by ``cases.timeseries_file`` (relative to the
    root) for the cases of Fig. 7-8. Missing tables or cases are stated on the figures.
    Returns the paths written, in :data:`FIGURE_FILES` order.
    """
    root, out = Path(campaign_root), Path(out_dir)
    cases, windows, char, char_note = _read_tables(root)
    name = campaign_name(campaign, cases, char)
    if name == "campaign ?":
        name = root.name
    note = "; ".join(x for x in (_status_note(cases, char), char_note) if x)

    char_all, char = char, _triangle_rows(char)
    windows = _triangle_rows(windows)
    picked = select_cases(cases, char) if cases is not None else []
    case_rows = {} if cases is None else {str(r["case"]): r for _, r in cases.iterrows()}
    series = {c: pd.read_parquet(p) for c in picked if (p := root / str(case_rows[c]["timeseries_file"])).is_file()}
    f8_case = _fig8_case(picked, series, windows)
    figs = [time_and_loops(cases, series, picked, campaign=name)]
    footnote(figs[0], _fig7_note(picked, series, note))
    if f8_case is None:
        figs.append(window_selection({}, None, None, campaign=name))
    else:
        figs.append(window_selection(case_rows[f8_case], series.get(f8_case),
                                     windows[windows["case"].astype(str) == f8_case], campaign=name))
    footnote(figs[1], note)
    for make, rows in ((characteristic, char_all), (low_velocity_detail, char_all), (loglog_characteristic, char_all),
                       (noise, char)):
        fig = make(rows, campaign=name)
        footnote(fig, note)
        figs.append(fig)
    figs.insert(0, case_temperature(cases, _viscosity_law(root), campaign=name))  # Fig. 20 leads: the cases section
    return [save_figure(fig, out / fname) for fig, fname in zip(figs, FIGURE_FILES, strict=True)]


__all__ = ["FIGURE_FILES", "SELECT_FRACTIONS", "select_cases", "write_campaign_figures"]
