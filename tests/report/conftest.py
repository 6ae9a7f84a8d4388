"""Fixtures of the report tests: a results tree with one campaign and the blind suite, its pages, Chromium."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from isokinetic.report.browser import find_chromium
from isokinetic.report.campaign_report import write_campaign_report
from isokinetic.report.report_index import write_index

from .fixture_results import CAMPAIGN, build_blind, build_campaign

CI = os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


@pytest.fixture
def results(tmp_path, monkeypatch) -> Path:
    """results/ with one campaign and the blind suite; cwd is tmp_path (paths as in the pipeline)."""
    monkeypatch.chdir(tmp_path)
    build_campaign(Path("results", CAMPAIGN))
    build_blind(Path("results", "blind"))
    return Path("results")


@pytest.fixture
def built(results) -> Path:
    write_campaign_report(results / CAMPAIGN, results / CAMPAIGN / "report.html")
    write_index(results, results / "index.html", [CAMPAIGN], blind_dir=results / "blind")
    return results


@pytest.fixture(scope="module")
def chromium() -> str:
    found = find_chromium()
    if found is None:
        message = ("headless Chromium is needed to check that the report pages load (Debian: apt-get install "
                   "chromium; or set ISOKINETIC_CHROMIUM)")
        if CI:
            pytest.fail(f"CI: {message}")
        pytest.skip(message)
    return found
