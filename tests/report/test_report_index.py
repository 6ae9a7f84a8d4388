"""The index page: every campaign with its verdict, and the blind-suite scores."""

from __future__ import annotations

import re

from isokinetic.report import browser, numbers

from .fixture_results import CAMPAIGN, parse, plain


def test_index_lists_campaigns_with_verdicts_and_the_blind_scores(built):
    page = (built / "index.html").read_text(encoding="utf-8")
    parsed = parse(page)
    assert "demo/report.html" in parsed.links
    text = plain(page)
    for expected in ("friction", "explained", numbers.fmt_text(52.5), numbers.fmt_text(0.98, 3),
                     numbers.fmt_text(53.57, 3), "4 / 5", "a_single_at_2x", "c_median_shrink", "FAIL", "PASS",
                     "NOT ALL PASS", "1-2x detection", "50.0 %", "median 3.21 over 3", "blind-002"):
        assert expected in text, expected
    assert browser.page_problems(page, ["fig17_blind_confusion.png"]) == []
    for cell in parsed.cells:
        assert re.search(r"results/(demo|blind)/\S+\.(parquet|json)", cell["title"] or ""), cell


def _rgb(text: str, under: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> tuple[float, float, float]:
    """A CSS colour (#rrggbb or rgba(r,g,b,a)) as RGB in [0, 1], an alpha blended over ``under``."""
    if text.startswith("#"):
        digits = text[1:] if len(text) == 7 else "".join(2 * x for x in text[1:])
        return tuple(int(digits[i:i + 2], 16) / 255 for i in (0, 2, 4))
    r, g, b, a = (float(x) for x in re.findall(r"[\d.]+", text))
    return tuple(a * c / 255 + (1 - a) * u for c, u in zip((r, g, b), under, strict=True))


def _contrast(a, b) -> float:
    """WCAG 2 contrast ratio of two RGB colours."""
    def lum(c):
        lin = [x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in c]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]
    hi, lo = sorted((lum(a), lum(b)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)


def test_code_in_the_dark_header_is_readable():
    from isokinetic.report.layout import asset

    css = str(asset("report.css"))
    rules = {k.strip(): v for k, v in re.findall(r"([^{}]+)\{([^{}]*)\}", css)}

    def prop(selector, name):
        return re.search(rf"(?:^|;){name}:([^;]+)", rules[selector]).group(1).strip()

    header_bg = _rgb(prop("header.top", "background"))
    code_bg = _rgb(prop("header.top code", "background"), under=header_bg)
    assert _contrast(_rgb(prop("header.top code", "color")), code_bg) >= 4.5


def test_index_links_snakemakes_report_only_when_it_exists(built):
    from isokinetic.report.report_index import render_index

    page = render_index(built, [CAMPAIGN], blind_dir=built / "blind")
    assert 'href="report.html"' not in page and "snakemake --report results/report.html" in plain(page)
    (built / "report.html").write_text("<html></html>", encoding="utf-8")
    assert 'href="report.html"' in render_index(built, [CAMPAIGN], blind_dir=built / "blind")


def test_a_failed_campaign_is_listed_with_its_reason_and_without_stale_numbers(built):
    from isokinetic.report.report_index import render_index

    page = render_index(built, [CAMPAIGN, "broken"], blind_dir=built / "blind",
                        failures={CAMPAIGN: "rule analysis failed: boom (log: logs/demo/analysis.log)",
                                  "broken": "not built (no error in logs/broken/)"})
    rows = {c: page[page.index(f'id="campaign-{c}"'):].split("</tr>")[0] for c in (CAMPAIGN, "broken")}
    assert "rule analysis failed: boom (log: logs/demo/analysis.log)" in rows[CAMPAIGN]
    assert "not built (no error in logs/broken/)" in rows["broken"]
    for row in rows.values():
        assert "failed" in row and "report.html" not in row and "title=" not in row  # no number cells
    assert "2 of 2 campaign(s) failed in the last run" in plain(page)


def test_a_failed_campaign_whose_campaign_json_does_not_read_is_still_listed(built):
    from isokinetic.report.report_index import render_index

    results = built
    (results / "stale" / "ingest").mkdir(parents=True)
    (results / "stale" / "ingest" / "campaign.json").write_text('{"campaign": "stale"}', encoding="utf-8")
    page = render_index(results, [CAMPAIGN, "stale"], failures={"stale": "rule ingest failed: boom"})
    row = page[page.index('id="campaign-stale"'):].split("</tr>")[0]
    assert "rule ingest failed: boom" in row


def test_unbuilt_raw_folders_are_listed_with_why_and_the_fix(built):
    from isokinetic.report.report_index import render_index

    unusable = [{"folder": "data/raw/Bench 3", "reason": "folder name 'Bench 3' is not a campaign id",
                 "fix": "rename it to bench-3"},
                {"folder": "data/raw/notes", "reason": "no campaign.yaml",
                 "fix": "draft one with `python -m isokinetic init-campaign data/raw/notes`"}]
    page = render_index(built, [CAMPAIGN], blind_dir=built / "blind", unusable=unusable)
    table = page[page.index('id="unusable-table"'):].split("</table>")[0]
    rows = table.split("<tr")[2:]
    assert len(rows) == 2
    assert "data/raw/Bench 3/" in plain(rows[0]) and "rename it to bench-3" in plain(rows[0])
    assert "no campaign.yaml" in plain(rows[1]) and "init-campaign data/raw/notes" in plain(rows[1])
    assert "2 folder(s) under the raw data folder not built" in plain(page)
    assert 'href="demo/report.html"' in page  # the campaigns are listed as before


def test_orphaned_results_are_shown_apart_without_their_numbers_or_checks_pass(built):
    import shutil

    from isokinetic.report.report_index import render_index

    shutil.copytree(built / CAMPAIGN, built / "gone")      # a campaign whose raw folder was deleted since
    (built / "gone" / "report.html").write_text("Provenance checks pass", encoding="utf-8")
    reason = "orphaned: raw folder missing: data/raw/gone/ is gone (deleted or renamed)"
    page = render_index(built, [CAMPAIGN], blind_dir=built / "blind", orphaned={"gone": reason})
    row = page[page.index('id="orphaned-gone"'):].split("</tr>")[0]
    assert reason in plain(row) and "results/gone/" in plain(row)
    assert "gone/report.html" not in page and 'id="campaign-gone"' not in page
    assert "checks pass" not in plain(page) and "title=" not in row
