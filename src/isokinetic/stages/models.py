"""The rule ``models``: fits, compares and draws one campaign (paper Sec. 4.5, Fig. 13-14).

The method (nominal families, weighted least squares, physical readings, plausibility, the comparison
table) is :mod:`isokinetic.measurement.model_fit`; the figures are :mod:`isokinetic.plots.models`.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_of
from isokinetic.io import write_parquet
from isokinetic.measurement.loops import loop as harmonic_loop
from isokinetic.measurement.model_fit import (
    MODEL_NAMES,
    comparison_table,
    family_velocities,
    fit_models,
    nominal_families,
)
from isokinetic.measurement.windows import WindowSpec
from isokinetic.plots.models import comparison_figure, comparison_loglog_figure
from isokinetic.plots.style import save_figure
from isokinetic.stages.nominal import nominal_stage

log = logging.getLogger("isokinetic.models")


#: Files written by :func:`write_models`, in order: the tables, then Fig. 13-14.
TABLE_FILES = tuple(Path(p).name for p in STAGE_OUTPUTS["models"].values())
FIGURE_FILES = tuple(Path(f.path).name for f in figures_of("models"))


# ----------------------------------------------------------------------------------------------
# nominal curves
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# weighted least squares
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# physical readings
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# plausibility of the readings
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# fitting
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# comparison table
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# stage
# ----------------------------------------------------------------------------------------------


def sine_loops(campaign_root, max_cases: int = 8) -> dict[str, pd.DataFrame]:
    """Force against velocity of the status-ok sine cases, first period (start from rest) left out.

    Uses :func:`isokinetic.measurement.loops.loop` (the harmonic stage's velocity estimator, so the loops
    agree with its peak-to-peak points). A case whose series cannot be read or holds no whole
    period is left out (logged).
    """
    folder = CampaignFolder.at(campaign_root)
    cases = folder.table("validate", "cases")
    if cases is None:
        return {}
    sines = cases[(cases["waveform"] == "sine") & (cases["status"] == "ok")].head(max_cases)
    out = {}
    for _, row in sines.iterrows():
        try:
            ts = folder.timeseries(row, ["time_s", "displacement_m", "force_N"])
        except (FileNotFoundError, OSError) as exc:
            log.warning("sine loop of case %s not read: %s", row["case"], exc)
            continue
        try:
            lp = harmonic_loop(ts, float(row["frequency_Hz"]))
        except ValueError as exc:
            log.warning("sine loop of case %s skipped: %s", row["case"], exc)
            continue
        out[str(row["case"])] = lp[["velocity_m_s", "force_N"]].reset_index(drop=True)
    return out


def write_models(campaign_root, out_dir, spec: WindowSpec, figures_dir=None,
                 loops: bool = True) -> list[Path]:
    """Fit, compare and draw one campaign; returns the written paths (TABLE_FILES then FIGURE_FILES).

    Reads ``characteristic.parquet``, ``nominal_windows.parquet`` (computed with ``spec`` by
    :func:`isokinetic.stages.nominal.nominal_stage` when absent), ``ingest/campaign.json`` and, when present,
    ``harmonic/harmonic.parquet`` and the sine cases' time series (loops).
    Tables go to ``out_dir``, figures to ``figures_dir`` (default ``out_dir``). Without a damper
    block: no nominal curves or physical readings, said on the figures.
    """
    root = Path(campaign_root)
    out = Path(out_dir)
    fig_dir = out if figures_dir is None else Path(figures_dir)
    folder = CampaignFolder(root)
    campaign, damper = folder.meta.campaign, folder.damper
    char = folder.characteristic()
    nominal_windows = folder.table("nominal", "nominal")
    if nominal_windows is None:
        nominal_windows = nominal_stage(root, spec) if damper is not None else tables.empty(tables.WINDOWS)
    harmonic = folder.table("harmonic", "table")
    harmonic = None if harmonic is None else tables.validate_table(harmonic, tables.HARMONIC)
    loop_data = sine_loops(root) if loops else {}

    models_df, residuals = fit_models(char, damper)
    comparison = comparison_table(char, nominal_windows, models_df, damper)
    families = nominal_families(damper, family_velocities(char, harmonic)) if damper is not None else None
    if damper is None:
        log.info("campaign %s: no damper block; nominal curves and physical readings skipped", campaign)
    for m in MODEL_NAMES:
        sub = models_df[(models_df["model"] == m) & (models_df["kind"] == "fitted")]
        for r in sub.itertuples():
            log.info("campaign %s: %s %s %s = %.6g [%.6g, %.6g] %s", campaign, m, r.direction, r.parameter, r.estimate,
                     r.ci_low, r.ci_high, r.unit)
    for r in models_df[~models_df["plausible"]].itertuples():
        log.info("campaign %s: %s %s: implausible reading: %s", campaign, r.model, r.direction, r.plausibility)
    paths = [write_parquet(models_df, out / TABLE_FILES[0]),
             write_parquet(residuals, out / TABLE_FILES[1]),
             write_parquet(comparison, out / TABLE_FILES[2])]
    figs = [comparison_figure(char, nominal_windows, families, models_df, harmonic, loop_data, campaign=campaign),
            comparison_loglog_figure(char, nominal_windows, families, models_df, harmonic, campaign=campaign)]
    paths += [save_figure(fig, fig_dir / fname) for fig, fname in zip(figs, FIGURE_FILES, strict=True)]
    return paths


__all__ = ["sine_loops", "write_models", "TABLE_FILES", "FIGURE_FILES"]
