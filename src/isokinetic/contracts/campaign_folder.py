"""One campaign's results folder ``results/<campaign>/``: the one reader of it, every path from the registry.

Paths come from :mod:`isokinetic.contracts.outputs` (:data:`~isokinetic.contracts.outputs.STAGE_OUTPUTS`,
:data:`~isokinetic.contracts.outputs.INGEST_FILES`); the metadata record (``ingest/campaign.json``) is read once,
typed and checked against its schema (:class:`isokinetic.contracts.campaign_meta.CampaignMeta`).

Two tables share the file name ``cases.parquet``: ingest's (``ingest/cases.parquet``, every case as the
manifest declared it, with ingest's status) and validate's (``cases.parquet``, the same cases after the
per-case checks, with the measured motion). They have a name each here, :meth:`CampaignFolder.ingested_cases`
and :meth:`CampaignFolder.validated_cases`, so a reader says which it means.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from isokinetic.contracts.campaign_meta import CampaignMeta
from isokinetic.contracts.outputs import STAGE_OUTPUTS, ingest_path
from isokinetic.physics.damper import Damper

if TYPE_CHECKING:
    import pandas as pd


def read_parquet(path: Path, columns: list[str] | None = None) -> pd.DataFrame:
    """A table (pandas imported here: the raw check's job reads the metadata without it)."""
    import pandas as pd

    return pd.read_parquet(path, columns=columns)


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

    def ingest_path(self, name: str) -> Path:
        """A file of the ingest folder by its registry name (``meta``, ``cases``, ``quarantine``)."""
        return self.root / ingest_path(name)

    def has_meta(self) -> bool:
        """Whether the folder holds ``ingest/campaign.json`` (a campaign ingested or simulated)."""
        return self.ingest_path("meta").is_file()

    @functools.cached_property
    def meta(self) -> CampaignMeta:
        """``ingest/campaign.json`` as its typed record, read once; FileNotFoundError without one,
        :class:`~isokinetic.contracts.campaign_meta.CampaignMetaError` naming the file and key when it breaks
        the schema."""
        path = self.ingest_path("meta")
        return CampaignMeta.from_mapping(json.loads(path.read_text(encoding="utf-8")), where=path.as_posix())

    @property
    def campaign(self) -> str:
        """The campaign's name: campaign.json's ``campaign``, else (no campaign.json) the folder's name."""
        return self.meta.campaign if self.has_meta() else self.root.name

    @property
    def damper(self) -> Damper | None:
        """The nominal damper of campaign.json, None without one."""
        return self.meta.damper

    def ingested_cases(self) -> pd.DataFrame:
        """Ingest's cases table (``ingest/cases.parquet``)."""
        return read_parquet(self.ingest_path("cases"))

    def ingested_quarantine(self) -> pd.DataFrame:
        """The cases ingest set aside (``ingest/quarantine.parquet``)."""
        return read_parquet(self.ingest_path("quarantine"))

    def validated_cases(self) -> pd.DataFrame:
        """Validate's cases table (``cases.parquet``): the cases after the per-case checks."""
        return read_parquet(self.path("validate", "cases"))

    def cases(self) -> pd.DataFrame:
        """Validate's cases table when the folder has one, else ingest's (a folder not yet validated)."""
        validated = self.path("validate", "cases")
        return read_parquet(validated) if validated.is_file() else self.ingested_cases()

    def cases_if_any(self) -> pd.DataFrame | None:
        """:meth:`cases`, None when the folder holds neither cases table."""
        return self.cases() if self.path("validate", "cases").is_file() or self.ingest_path("cases").is_file() else None

    def windows(self) -> pd.DataFrame:
        return read_parquet(self.path("windows", "windows"))

    def characteristic(self) -> pd.DataFrame:
        return read_parquet(self.path("characteristic", "characteristic"))

    def table(self, stage: str, name: str) -> pd.DataFrame | None:
        """A registered table of a stage, None when the folder does not hold it."""
        path = self.path(stage, name)
        return read_parquet(path) if path.is_file() else None

    def document(self, stage: str, name: str) -> dict | None:
        """A registered JSON document of a stage (``diagnosis.json``), None when the folder does not hold it."""
        path = self.path(stage, name)
        return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None

    def timeseries(self, case, columns: list[str] | None = None) -> pd.DataFrame:
        """The canonical time series of a case: a row of a cases table (its ``timeseries_file``) or a case id
        (looked up in ingest's cases table)."""
        if isinstance(case, str):
            case = self.ingested_cases().set_index("case").loc[case]
        return read_parquet(self.root / case["timeseries_file"], columns=columns)
