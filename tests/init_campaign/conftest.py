"""A small campaign exported by the virtual rig (two triangle cases at the 20 s period and a sine case of the
paper campaign), its characteristic, and helpers to run the pipeline's characteristic in-process."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign
from testconfig import TEST_CONFIG as CONFIG

#: Two triangle cases at T = 20 s (100 Hz, 4000 samples) and the first sine case (1000 Hz, 5714 samples).
CASES = ("T16", "T22", "H01")
CAMPAIGN = "lag"


def characteristic(raw_dir: Path, root: Path) -> pd.DataFrame:
    """Ingest and characteristic of a raw campaign folder, in-process, into ``root``."""
    ingest_campaign(raw_dir, root)
    return write_characteristic(root)


@pytest.fixture(scope="session")
def exported(tmp_path_factory) -> Path:
    """The exported raw campaign folder ``.../lag`` (campaign.yaml and three case files); never modified."""
    spec = yaml.safe_load(CONFIG.read_text(encoding="utf-8"))["virtual_campaigns"]["paper-lag-damper"]
    vc = VirtualCampaign.from_config("paper-lag-damper", spec)
    return export_raw_campaign(vc, tmp_path_factory.mktemp("exported") / CAMPAIGN, cases=list(CASES))


@pytest.fixture(scope="session")
def reference(exported, tmp_path_factory) -> pd.DataFrame:
    """The characteristic of the exported campaign under its own manifest."""
    return characteristic(exported, tmp_path_factory.mktemp("reference") / CAMPAIGN)


@pytest.fixture
def campaign_copy(exported, tmp_path) -> Path:
    """A writable copy of the exported campaign folder (with its manifest)."""
    return Path(shutil.copytree(exported, tmp_path / CAMPAIGN))
