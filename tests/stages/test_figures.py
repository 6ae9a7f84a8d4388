"""The rule ``figures`` (isokinetic.stages.figures): case selection for Fig. 7 and the campaign writer."""

from __future__ import annotations

import pytest

from isokinetic.stages import figures
from plots.synthetic import synthetic_campaign, write_campaign

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def camp():
    return synthetic_campaign()


# ----------------------------------------------------------------------------------------------
# case selection
# ----------------------------------------------------------------------------------------------

def test_select_cases_takes_paper_ranks_4_12_22_of_23():
    cases, _, _, char = synthetic_campaign(n=23)
    assert figures.select_cases(cases, char) == ["T04", "T12", "T22"]


def test_select_cases_skips_quarantined_and_non_triangle():
    cases, _, _, char = synthetic_campaign(n=5, quarantined=("T01", "T02", "T03", "T04"), sine=2)
    assert figures.select_cases(cases, char) == ["T05"]


# ----------------------------------------------------------------------------------------------
# files
# ----------------------------------------------------------------------------------------------

def test_write_campaign_figures_writes_six_pngs(tmp_path, camp):
    root = tmp_path / "results" / "synthetic-damper"
    write_campaign(root, *camp)
    paths = figures.write_campaign_figures(root, tmp_path / "fig")
    assert [p.name for p in paths] == list(figures.FIGURE_FILES)
    for p in paths:
        data = p.read_bytes()
        assert data.startswith(PNG_MAGIC) and len(data) > 10_000


def test_write_campaign_figures_with_one_triangle_case(tmp_path):
    cases, series, windows, char = synthetic_campaign(n=3, quarantined=("T01", "T03"), sine=1)
    root = tmp_path / "results" / "thin"
    write_campaign(root, cases, series, windows, char, cases_at_root=True)
    paths = figures.write_campaign_figures(root, tmp_path / "fig")
    assert len(paths) == len(figures.FIGURE_FILES) == 7 and all(p.stat().st_size > 5_000 for p in paths)


def test_write_campaign_figures_with_no_ok_triangle_case(tmp_path):
    cases, series, windows, char = synthetic_campaign(n=2, quarantined=("T01", "T02"))
    root = tmp_path / "results" / "none-ok"
    write_campaign(root, cases, series, windows, char)
    paths = figures.write_campaign_figures(root, tmp_path / "fig")
    assert [p.name for p in paths] == list(figures.FIGURE_FILES) and all(p.stat().st_size > 5_000 for p in paths)
