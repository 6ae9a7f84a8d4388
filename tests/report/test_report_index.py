"""The index page: every campaign with its verdict, and the blind-suite scores."""

from __future__ import annotations

import re

from isokinetic.report import browser, numbers

from .fixture_results import parse, plain


def test_index_lists_campaigns_with_verdicts_and_the_blind_scores(built):
    page = (built / "index.html").read_text(encoding="utf-8")
    parsed = parse(page)
    assert "demo/report.html" in parsed.links
    text = plain(page)
    for expected in ("friction", "explained", numbers.fmt_text(52.5), numbers.fmt_text(0.98, 3),
                     numbers.fmt_text(53.57, 3), "3 / 4", "a_single_at_2x", "c_median_shrink", "FAIL", "PASS",
                     "NOT ALL PASS", "1-2x detection", "50.0 %", "median 3.21 over 3", "blind-002"):
        assert expected in text, expected
    assert browser.page_problems(page, ["fig17_blind_confusion.png"]) == []
    for cell in parsed.cells:
        assert re.search(r"results/(demo|blind)/\S+\.(parquet|json)", cell["title"] or ""), cell
