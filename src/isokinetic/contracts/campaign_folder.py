"""One campaign's results folder ``results/<campaign>/``: every path from the registry, its tables read once.

Two tables share the file name ``cases.parquet``: ingest's (``ingest/cases.parquet``, every case as the
manifest declared it, with ingest's status) and validate's (``cases.parquet``, the same cases after the
per-case checks, with the measured motion). They have a name each here, :meth:`CampaignFolder.ingested_cases`
and :meth:`CampaignFolder.validated_cases`, so a reader says which it means.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from isokinetic.contracts.campaign import CASES_FILE, META_FILE
from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.physics.damper import Damper


@dataclass(frozen=True)
class CampaignFolder:
    """``results/<campaign>/`` of one campaign: paths from :data:`isokinetic.contracts.outputs.STAGE_OUTPUTS`."""

    root: Path

    @classmethod
    def at(cls, root: str | Path) -> CampaignFolder:
        return cls(Path(root))

    def path(self, stage: str, name: str) -> Path:
        """The file (or folder) a stage writes under that name, e.g. ``path("windows", "windows")``."""
        return self.root / STAGE_OUTPUTS[stage][name].rstrip("/")

    @property
    def ingest_dir(self) -> Path:
        return self.path("ingest", "ingest")

    def meta(self) -> dict:
        """``ingest/campaign.json``: the campaign's metadata, damper block, viscosity law, warnings."""
        return json.loads((self.ingest_dir / META_FILE).read_text(encoding="utf-8"))

    def campaign(self, meta: dict | None = None) -> str:
        """The campaign's name: campaign.json's ``campaign``, else the folder's name."""
        return str((self.meta() if meta is None else meta).get("campaign") or self.root.name)

    def damper(self, meta: dict | None = None) -> Damper | None:
        """The damper block of campaign.json, None without one."""
        block = (self.meta() if meta is None else meta).get("damper")
        return None if block is None else Damper.from_mapping(block)

    def ingested_cases(self) -> pd.DataFrame:
        """Ingest's cases table (``ingest/cases.parquet``)."""
        return pd.read_parquet(self.ingest_dir / CASES_FILE)

    def validated_cases(self) -> pd.DataFrame:
        """Validate's cases table (``cases.parquet``): the cases after the per-case checks."""
        return pd.read_parquet(self.path("validate", "cases"))

    def cases(self) -> pd.DataFrame:
        """Validate's cases table when the folder has one, else ingest's (a folder not yet validated)."""
        validated = self.path("validate", "cases")
        return pd.read_parquet(validated) if validated.is_file() else self.ingested_cases()

    def windows(self) -> pd.DataFrame:
        return pd.read_parquet(self.path("windows", "windows"))

    def characteristic(self) -> pd.DataFrame:
        return pd.read_parquet(self.path("characteristic", "characteristic"))

    def table(self, stage: str, name: str) -> pd.DataFrame | None:
        """A registered table of a stage, None when the folder does not hold it."""
        path = self.path(stage, name)
        return pd.read_parquet(path) if path.is_file() else None

    def timeseries(self, case_row, columns: list[str] | None = None) -> pd.DataFrame:
        """The canonical time series of one row of a cases table (its ``timeseries_file``)."""
        return pd.read_parquet(self.root / case_row["timeseries_file"], columns=columns)
