"""Fig. 15 (isokinetic.plots.harmonic): what the loops figure draws, and what it says when empty."""

from __future__ import annotations

from isokinetic.contracts import tables
from isokinetic.plots.harmonic import harmonic_figure
from isokinetic.stages.harmonic import harmonic_stage


def _texts(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes for t in ax.texts]


def test_figure_of_a_campaign_without_sine_or_free_cases_says_so():
    fig = harmonic_figure(tables.empty(tables.HARMONIC), {}, campaign="demo")
    assert any("no status-ok sine or free case" in s for s in _texts(fig))


def test_figure_draws_every_case_with_its_points(raw_campaign):
    cases, _ = raw_campaign.run()
    table, loops = harmonic_stage(raw_campaign.root)
    fig = harmonic_figure(table, loops, cases, campaign="demo", note="a note")
    gids = {line.get_gid() for ax in fig.axes for line in ax.get_lines()}
    assert {"loop-H01", "peak-to-peak-curve", "peak-to-peak-H01", "loop-F01", "binned-F01",
            "peak-velocity-F01"} <= gids
    assert len([ax for ax in fig.axes if ax.get_lines()]) == 2 * (1 + len(loops))
    assert any("lags v by" in s for s in _texts(fig)) and fig._supxlabel.get_text() == "a note"


def test_panel_titles_stay_apart_and_each_names_its_case(raw_campaign):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    cases, _ = raw_campaign.run()
    table, loops = harmonic_stage(raw_campaign.root)
    fig = harmonic_figure(table, loops, cases, campaign="demo")
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    axes = fig.axes
    for left, right in zip(axes[0::2], axes[1::2], strict=True):
        boxes = [ax.title.get_window_extent(renderer) for ax in (left, right)]
        assert boxes[0].x1 < boxes[1].x0, (left.get_title(), right.get_title())  # a gap between the two titles
        for ax, box in zip((left, right), boxes, strict=True):  # each centred over its own panel
            frame = ax.get_window_extent(renderer)
            assert abs((box.x0 + box.x1) / 2 - (frame.x0 + frame.x1) / 2) < 2.0 and frame.x0 <= box.x0
    for (left, right), case in zip(zip(axes[2::2], axes[3::2], strict=True), loops, strict=True):
        assert left.get_title().startswith(f"{case}:") and right.get_title().startswith(case)


def test_a_campaign_of_one_kind_has_no_empty_overview_panel(raw_campaign):
    cases, _ = raw_campaign.run()
    table, loops = harmonic_stage(raw_campaign.root)
    sine = {c: lp for c, lp in loops.items() if c == "H01"}
    fig = harmonic_figure(table[table["case"] == "H01"], sine, cases, campaign="demo")
    assert not any("no status-ok" in s for s in _texts(fig))
    top = fig.axes[-1]                                   # the overview spans the top row
    assert top.get_title() == "All sine cases: loops, peak-to-peak curve"
    assert top.get_position().width > 1.8 * fig.axes[0].get_position().width
    assert len(fig.axes) == 1 + 2 * len(sine)
