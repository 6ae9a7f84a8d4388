"""The comparison page (isokinetic.report.compare_report) and its row on the index: self-contained,
every link resolving, each row's basis said, every number naming its file."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from isokinetic.io import write_parquet
from isokinetic.measurement.comparison import CompareSpec
from isokinetic.measurement.model_fit import fit_models
from isokinetic.report import browser
from isokinetic.report.compare_report import write_compare_report
from isokinetic.report.report_index import write_index
from isokinetic.stages.compare import write_compare

from .fixture_results import CAMPAIGN, build_campaign, parse, plain

OTHER = "demo-after"
NAME = "demo-vs-after"
FIGURES = ["fig18_compare_overlay.png", "fig19_compare_difference.png"]


@pytest.fixture
def compared(results) -> Path:
    """results/ with the fixture campaign, a second one whose fastest case ran 1.5 times faster (no match:
    compared through the models) and the comparison's files, page and index."""
    other = build_campaign(results / OTHER)
    char = pd.read_parquet(other / "characteristic.parquet")
    fast = char["case"] == "T03"
    char.loc[fast, ["velocity_m_s", "planned_velocity_m_s"]] *= 1.5
    write_parquet(char, other / "characteristic.parquet")
    write_parquet(fit_models(char)[0], other / "models" / "models.parquet")
    for c in (CAMPAIGN, OTHER):
        (results / c / "report.html").write_text("<html></html>", encoding="utf-8")
    folder = results / "compare" / NAME
    spec = CompareSpec(NAME, (CAMPAIGN, OTHER), description="before and after a repair")
    write_compare(spec, {c: results / c for c in spec.campaigns}, folder)
    write_compare_report(folder, folder / "report.html", captions_dir=Path(__file__).parents[2] / "workflow" / "report")
    write_index(results, results / "index.html", [CAMPAIGN, OTHER], comparisons=[NAME])
    return results


def links(page: Path) -> list[str]:
    return [h for h in parse(page.read_text(encoding="utf-8")).links if h and not h.startswith("#")]


def test_page_is_self_contained_with_both_figures(compared):
    page = (compared / "compare" / NAME / "report.html").read_text(encoding="utf-8")
    assert browser.page_problems(page, FIGURES) == []


def test_every_link_of_the_page_resolves(compared):
    page = compared / "compare" / NAME / "report.html"
    hrefs = links(page)
    assert {"../../index.html", f"../../{CAMPAIGN}/report.html", f"../../{OTHER}/report.html", "compare.csv"} <= set(
        hrefs)
    for href in hrefs:
        assert (page.parent / href).resolve().is_file(), href


def test_page_says_each_rows_basis_and_what_was_left_out(compared):
    text = plain((compared / "compare" / NAME / "report.html").read_text(encoding="utf-8"))
    assert "model:surace" in text and "measured" in text
    assert "compared through their fitted model" in text and "prediction standard error" in text
    assert "before and after a repair" in text and "two-sided z, alpha = 0.05" in text
    assert "2 velocities left out" in text                      # the 1.5x faster case, both directions
    assert f"outside {CAMPAIGN}'s measured speeds" in text


def test_every_number_names_its_file(compared):
    cells = parse((compared / "compare" / NAME / "report.html").read_text(encoding="utf-8")).cells
    assert cells
    for cell in cells:
        assert re.search(rf"results/compare/{NAME}/compare\.(parquet|json)", cell["title"] or ""), cell


def test_index_links_the_comparison_page(compared):
    index = compared / "index.html"
    hrefs = links(index)
    assert f"compare/{NAME}/report.html" in hrefs
    assert (index.parent / "compare" / NAME / "report.html").is_file()
    text = plain(index.read_text(encoding="utf-8"))
    assert NAME in text and f"{CAMPAIGN}, {OTHER}" in text and "Comparisons" in text


def test_index_without_comparisons_has_no_comparison_section(built):
    assert 'id="comparisons"' not in (built / "index.html").read_text(encoding="utf-8")
