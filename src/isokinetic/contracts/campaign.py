"""The ingested-campaign folder: what the virtual rig and raw ingest both write.

Layout of ``results/<campaign>/ingest/``::

    campaign.json          campaign metadata (CAMPAIGN_KEYS), damper data in SI or null; raw ingest adds
                           gas_force_N, csv (the files' format), viscosity_law and warnings (manifest
                           keys that look like slips, 1.2)
    cases.parquet          one row per planned case (tables.CASES), status ok|quarantined
    quarantine.parquet     cases set aside while ingesting (tables.QUARANTINE)
    timeseries/<case>.parquet   canonical SI time series (tables.TIMESERIES), status-ok cases only

``cases.timeseries_file`` is relative to the folder that holds ``cases.parquet``'s campaign
results (``results/<campaign>/``), e.g. ``ingest/timeseries/T01.parquet``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from isokinetic.contracts import tables
from isokinetic.io import write_json, write_parquet
from isokinetic.physics.damper import Damper
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.viscosity import ViscosityLaw, case_viscosity_scales, law_from_mapping

#: Keys of campaign.json; ``damper`` is a dict of Damper fields or None.
CAMPAIGN_KEYS = ("format_version", "campaign", "source", "description", "temperature_C",
                 "damper", "manifest_file", "manifest_sha256", "metadata")

TIMESERIES_DIR = "timeseries"
#: The files of the ingest folder (``results/<campaign>/ingest/``).
META_FILE = "campaign.json"
CASES_FILE = "cases.parquet"
QUARANTINE_FILE = "quarantine.parquet"


def timeseries_relpath(case: str) -> str:
    """Path of a case's time series relative to ``results/<campaign>/``."""
    return f"ingest/{TIMESERIES_DIR}/{case}.parquet"


@dataclass(frozen=True)
class IngestedCampaign:
    """An ingested campaign read back from ``results/<campaign>/ingest``."""

    root: Path           # results/<campaign>
    meta: dict
    cases: pd.DataFrame
    quarantine: pd.DataFrame

    @property
    def damper(self) -> Damper | None:
        return None if self.meta.get("damper") is None else Damper.from_mapping(self.meta["damper"])

    def timeseries(self, case: str) -> pd.DataFrame:
        row = self.cases.set_index("case").loc[case]
        return pd.read_parquet(self.root / row["timeseries_file"])


def case_plan(row) -> CasePlan:
    """The CasePlan of one row of a cases table."""
    return CasePlan(case=row["case"], waveform=row["waveform"], sample_rate_Hz=float(row["sample_rate_Hz"]),
                    amplitude_m=float(row["amplitude_m"]), period_s=float(row["period_s"]),
                    frequency_Hz=float(row["frequency_Hz"]), phase_rad=float(row["phase_rad"]),
                    duration_s=float(row["duration_s"]))


def viscosity_law(meta: dict) -> ViscosityLaw | None:
    """The oil's viscosity-temperature law of a campaign.json (``viscosity_law``, format 1.1), None without one
    or without a damper block (the law's kinematic form needs the damper's density)."""
    block, damper = meta.get("viscosity_law"), meta.get("damper")
    if not block or not damper:
        return None
    return law_from_mapping(block, float(damper["density_kg_m3"]))


def viscosity_scales(meta: dict, cases: pd.DataFrame) -> dict[str, float]:
    """case -> μ(T_case) / damper.viscosity_Pa_s for a campaign with a viscosity law and case temperatures
    (``temperature_C`` of cases.parquet); empty when either is missing (every case at the damper block's
    viscosity). :func:`isokinetic.physics.viscosity.case_viscosity_scales`."""
    law = viscosity_law(meta)
    if law is None or "temperature_C" not in cases or cases.empty:
        return {}
    scales = case_viscosity_scales(cases["temperature_C"].to_numpy(float), law,
                                   float(meta["damper"]["viscosity_Pa_s"]))
    return dict(zip(cases["case"].astype(str), scales.tolist(), strict=True))


def write_ingested(ingest_dir: str | Path, meta: dict, cases: pd.DataFrame, quarantine: pd.DataFrame,
                   series: dict[str, pd.DataFrame]) -> None:
    """Write an ingested campaign (time series first, the tables that index them last)."""
    ingest_dir = Path(ingest_dir)
    missing = set(CAMPAIGN_KEYS) - set(meta)
    if missing:
        raise KeyError(f"campaign.json: missing keys {sorted(missing)}")
    for case, df in series.items():
        write_parquet(tables.validate_table(df, tables.TIMESERIES), ingest_dir / TIMESERIES_DIR / f"{case}.parquet")
    write_parquet(tables.validate_table(quarantine, tables.QUARANTINE), ingest_dir / QUARANTINE_FILE)
    write_parquet(tables.validate_table(cases, tables.CASES), ingest_dir / CASES_FILE)
    write_json(meta, ingest_dir / META_FILE)


def read_ingested(campaign_root: str | Path) -> IngestedCampaign:
    """Read ``results/<campaign>/ingest`` written by :func:`write_ingested`."""
    root = Path(campaign_root)
    meta = json.loads((root / "ingest" / META_FILE).read_text(encoding="utf-8"))
    return IngestedCampaign(root=root, meta=meta,
                            cases=pd.read_parquet(root / "ingest" / CASES_FILE),
                            quarantine=pd.read_parquet(root / "ingest" / QUARANTINE_FILE))
