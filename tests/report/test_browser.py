"""Checks of the built pages: self-contained and complete, and (in headless Chromium) every figure decoded."""

from __future__ import annotations

import base64

import pytest

from isokinetic.report import browser, layout

from .fixture_results import CAMPAIGN, CAMPAIGN_FIGURES, tiny_png


def test_page_problems_catches_external_resources_and_bad_images():
    good = f'<img src="data:image/png;base64,{base64.b64encode(tiny_png((1, 2, 3))).decode()}" data-file="a.png">'
    assert browser.page_problems(good, ["a.png"]) == []
    for bad in ('<img src="https://example.org/x.png">', '<link rel="stylesheet" href="//cdn.example/x.css">',
                '<style>body{background:url(http://x/y.png)}</style>', '<style>@import "x.css";</style>',
                '<script src="http://x/y.js"></script>', '<img src="fig.png" data-file="fig.png">',
                '<img src="data:image/png;base64,AAAA" data-file="b.png">'):
        assert browser.page_problems(good + bad), bad
    assert browser.page_problems(good, ["a.png", "missing.png"]) == ["figure missing.png not on the page"]


def test_check_pages_reports_missing_pages(built):
    assert browser.check_pages(built, [CAMPAIGN], browser=False) == []
    (built / "index.html").write_text("", encoding="utf-8")
    assert browser.check_pages(built, [CAMPAIGN], browser=False) == [f"{built / 'index.html'}: missing or empty"]
    assert browser.check_pages(built, ["other"], index=False, browser=False) == [
        f"{built / 'other' / 'report.html'}: missing or empty"]


@pytest.mark.slow
def test_every_figure_loads_in_headless_chromium(built, chromium):
    campaign = browser.check_in_browser(built / CAMPAIGN / "report.html", chromium)
    assert campaign["total"] == len(CAMPAIGN_FIGURES) == campaign["loaded"], campaign
    assert campaign["broken"] == []
    index = browser.check_in_browser(built / "index.html", chromium)
    assert index["total"] == 1 == index["loaded"], index
    assert browser.check_pages(built, [CAMPAIGN], browser=True) == []


@pytest.mark.slow
def test_the_browser_check_sees_a_broken_figure(tmp_path, chromium):
    """Control: the check is not vacuous - an undecodable image is counted as not loaded."""
    good = base64.b64encode(tiny_png((9, 9, 9))).decode()
    page = layout.page("control", "", [], f'<img src="data:image/png;base64,{good}" data-file="good.png">'
                       '<img src="data:image/png;base64,iVBORw0KGgoAAAA" data-file="broken.png">', "")
    (tmp_path / "control.html").write_text(page, encoding="utf-8")
    result = browser.check_in_browser(tmp_path / "control.html", chromium)
    assert (result["loaded"], result["total"], result["broken"]) == (1, 2, ["broken.png"])
