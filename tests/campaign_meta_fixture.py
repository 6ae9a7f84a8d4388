"""A complete ingest/campaign.json for tests that build a campaign folder by hand."""

from __future__ import annotations

import json
from pathlib import Path

from isokinetic.contracts.outputs import ingest_path


def write_campaign_meta(root: str | Path, campaign: str, **keys) -> Path:
    """``root/ingest/campaign.json`` holding every key the schema requires (the ones not given empty or null,
    as for a simulated campaign) and ``keys``; returns its path."""
    meta = {"format_version": 1, "campaign": campaign, "source": "simulation", "description": "",
            "temperature_C": None, "damper": None, "manifest_file": "", "manifest_sha256": "", "metadata": {}}
    meta.update(keys)
    path = Path(root) / ingest_path("meta")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(meta), encoding="utf-8")
    return path
