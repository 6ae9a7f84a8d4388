"""Runner of the static force (the force at v -> 0) of one campaign folder: reads its tables and standstill
records, estimates with :mod:`isokinetic.measurement.static_force_fit` (method and its reasons there), writes
``static_force.parquet``."""

from __future__ import annotations

import logging
import math
from dataclasses import replace
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_parquet
from isokinetic.measurement.static_force_fit import (
    StaticForce,
    StaticForceSpec,
    block_mean,
    estimate_static_force,
    gas_force_check,
    standstill_estimate,
)

log = logging.getLogger("isokinetic")

#: Output file of :func:`write_static_force`, relative to the campaign's results folder.
TABLE_PATH = STAGE_OUTPUTS["static_force"]["static_force"]


def standstill_points(cases: pd.DataFrame | None, root: Path) -> pd.DataFrame:
    """One row per ok standstill case: case, force_N (mean over the stretch, gas force already subtracted),
    std_error_N (:func:`block_mean`), n_samples, gas_force_N (declared; NaN: none)."""
    columns = ["case", "force_N", "std_error_N", "n_samples", "gas_force_N"]
    if cases is None or cases.empty or "waveform" not in cases:
        return pd.DataFrame(columns=columns)
    ok = cases[(cases["waveform"] == "standstill") & (cases["status"] == "ok")]
    rows = []
    for _, case in ok.iterrows():
        force = pd.read_parquet(root / case["timeseries_file"], columns=["force_N"])["force_N"].to_numpy(float)
        mean, se = block_mean(force)
        gas = float(case["gas_force_N"]) if "gas_force_N" in case and pd.notna(case["gas_force_N"]) else math.nan
        rows.append({"case": str(case["case"]), "force_N": mean, "std_error_N": se, "n_samples": len(force),
                     "gas_force_N": gas})
    return pd.DataFrame(rows, columns=columns)


# ----------------------------------------------------------------------------------------------
# coordination with the diagnosis' load-cell offset
# ----------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------
# stage
# ----------------------------------------------------------------------------------------------

def static_force_stage(campaign_root, spec: StaticForceSpec = StaticForceSpec()) -> StaticForce:
    """The static force of ``results/<campaign>/``: from its standstill cases when it has any, else from
    characteristic.parquet (else the harmonic table's binned points); with the gas force ingest recorded in
    ingest/campaign.json and the check of every declared gas force (:func:`gas_force_check`). Cases: the
    validated cases.parquet, else ingest's."""
    folder = CampaignFolder.at(campaign_root)
    gas_force_N = folder.meta.gas_force_N if folder.has_meta() else None
    harmonic_file = STAGE_OUTPUTS["harmonic"]["table"]
    campaign = folder.campaign
    fitted = estimate_static_force(campaign, folder.table("characteristic", "characteristic"),
                                   folder.table("harmonic", "table"), gas_force_N, spec,
                                   harmonic_file=harmonic_file)
    cases = folder.cases_if_any()
    standstill = standstill_points(cases, folder.root)
    check, lines = gas_force_check(cases, standstill, fitted, spec.confidence)
    result = fitted if standstill.empty else standstill_estimate(campaign, standstill, gas_force_N,
                                                                 spec.confidence)
    return replace(result, n_standstill=len(standstill), gas_force_check=check, gas_force_cases=lines)


def write_static_force(campaign_root, spec: StaticForceSpec = StaticForceSpec()) -> list[Path]:
    """Write ``static_force.parquet`` (tables.STATIC_FORCE, one row) of a campaign; returns the file."""
    root = Path(campaign_root)
    result = static_force_stage(root, spec)
    if math.isfinite(result.static_force_N):
        log.info("static force %.2f N (SE %.2f N, %d speeds, %s)", result.static_force_N, result.std_error_N,
                 result.n_speeds, result.source)
    else:
        log.warning("static force %s", result.note)
    return [write_parquet(tables.validate_table(result.to_frame(), tables.STATIC_FORCE), root / TABLE_PATH)]
