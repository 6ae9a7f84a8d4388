"""The ingested-campaign folder: what the virtual rig and raw ingest both write.

Layout of ``results/<campaign>/ingest/`` (file names: :data:`isokinetic.contracts.outputs.INGEST_FILES`)::

    campaign.json          campaign metadata (:class:`isokinetic.contracts.campaign_meta.CampaignMeta`,
                           schema ``campaign.schema.json``), damper data in SI or null; raw ingest adds
                           gas_force_N, csv (the files' format), viscosity_law and warnings (manifest
                           keys that look like slips, 1.2)
    cases.parquet          one row per planned case (tables.CASES), status ok|quarantined
    quarantine.parquet     cases set aside while ingesting (tables.QUARANTINE)
    timeseries/<case>.parquet   canonical SI time series (tables.TIMESERIES), status-ok cases only

``cases.timeseries_file`` is relative to the folder that holds ``cases.parquet``'s campaign
results (``results/<campaign>/``), e.g. ``ingest/timeseries/T01.parquet``. The folder is read back with
:class:`isokinetic.contracts.campaign_folder.CampaignFolder`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.contracts.campaign_meta import CAMPAIGN_KEYS, CampaignMeta
from isokinetic.contracts.outputs import INGEST_FILES, ingest_path
from isokinetic.io import write_json, write_parquet
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.viscosity import case_viscosity_scales

__all__ = ["CAMPAIGN_KEYS", "case_plan", "timeseries_relpath", "viscosity_scales", "write_ingested"]


def timeseries_relpath(case: str) -> str:
    """Path of a case's time series relative to ``results/<campaign>/``."""
    return f"{ingest_path('timeseries')}/{case}.parquet"


def case_plan(row) -> CasePlan:
    """The CasePlan of one row of a cases table."""
    return CasePlan(case=row["case"], waveform=row["waveform"], sample_rate_Hz=float(row["sample_rate_Hz"]),
                    amplitude_m=float(row["amplitude_m"]), period_s=float(row["period_s"]),
                    frequency_Hz=float(row["frequency_Hz"]), phase_rad=float(row["phase_rad"]),
                    duration_s=float(row["duration_s"]))


def viscosity_scales(meta: CampaignMeta, cases: pd.DataFrame) -> dict[str, float]:
    """case -> μ(T_case) / damper.viscosity_Pa_s for a campaign with a viscosity law and case temperatures
    (``temperature_C`` of cases.parquet); empty when either is missing (every case at the damper block's
    viscosity). :func:`isokinetic.physics.viscosity.case_viscosity_scales`."""
    law = meta.viscosity_law()
    if law is None or "temperature_C" not in cases or cases.empty:
        return {}
    scales = case_viscosity_scales(cases["temperature_C"].to_numpy(float), law, float(meta.damper.viscosity_Pa_s))
    return dict(zip(cases["case"].astype(str), scales.tolist(), strict=True))


def write_ingested(ingest_dir: str | Path, meta: CampaignMeta | Mapping, cases: pd.DataFrame,
                   quarantine: pd.DataFrame, series: dict[str, pd.DataFrame]) -> None:
    """Write an ingested campaign (time series first, the tables that index them last); ``meta`` (a record or
    its campaign.json mapping) is checked against its schema before anything is written."""
    ingest_dir = Path(ingest_dir)
    record = meta if isinstance(meta, CampaignMeta) else CampaignMeta.from_mapping(meta)
    document = record.to_mapping()
    timeseries = INGEST_FILES["timeseries"].rstrip("/")
    for case, df in series.items():
        write_parquet(tables.validate_table(df, tables.TIMESERIES), ingest_dir / timeseries / f"{case}.parquet")
    write_parquet(tables.validate_table(quarantine, tables.QUARANTINE), ingest_dir / INGEST_FILES["quarantine"])
    write_parquet(tables.validate_table(cases, tables.CASES), ingest_dir / INGEST_FILES["cases"])
    write_json(document, ingest_dir / INGEST_FILES["meta"])
