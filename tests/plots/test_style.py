"""Shared figure helpers (isokinetic.plots.style): units, byte-stable PNGs and their text chunks."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from isokinetic.plots import figures, style
from plots.synthetic import synthetic_campaign

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_save_figure_gives_identical_bytes(tmp_path):
    *_, char = synthetic_campaign()
    a = style.save_figure(figures.characteristic(char), tmp_path / "a.png").read_bytes()
    b = style.save_figure(figures.characteristic(char), tmp_path / "b.png").read_bytes()
    assert a == b and a.startswith(PNG_MAGIC)


def test_save_figure_writes_metadata_as_png_text_without_software_stamp(tmp_path):
    fig = style.new_figure(2.0, 1.5)
    fig.add_subplot().plot([0, 1, 2], [0, 1, 0])
    plain = style.save_figure(fig, tmp_path / "plain.png")
    stamped = style.save_figure(fig, tmp_path / "stamped.png", metadata={"lineage": '{"rule": "figures"}'})
    with Image.open(plain) as im_plain, Image.open(stamped) as im_stamped:
        assert "Software" not in im_plain.text and "Software" not in im_stamped.text
        assert im_stamped.text["lineage"] == '{"rule": "figures"}'
        assert np.array_equal(np.asarray(im_plain), np.asarray(im_stamped))
        assert im_plain.size == (2 * style.DPI, int(1.5 * style.DPI))


@pytest.mark.slow
def test_save_figure_places_the_axes_where_matplotlibs_constrained_layout_does(tmp_path):
    """Laid out once before saving (style.lay_out: one pass of the constrained layout, the spines left out of
    it), a figure's axes sit within 1.5 % of the figure of where matplotlib's own engine (two passes, spines
    in) puts them, and all it draws stays inside the figure: several axes, a twin and a shared axis, mathtext,
    an outside legend and a footnote."""
    cases, series, _, char = synthetic_campaign()
    picked = list(cases["case"])[:3]
    for k, make in enumerate((lambda: figures.time_and_loops(cases, series, picked),
                              lambda: figures.noise(char))):
        fig_a, fig_b = make(), make()
        for fig in (fig_a, fig_b):
            style.footnote(fig, "a note under the axes, long enough to be wrapped onto a second line " * 2)
        style.save_figure(fig_a, tmp_path / f"a{k}.png")
        assert fig_a.get_layout_engine() is None                      # laid out, then saved without the engine
        fig_b.savefig(tmp_path / f"b{k}.png", format="png", dpi=style.DPI)   # matplotlib's layout engine
        at_a, at_b = (np.array([ax.get_position().bounds for ax in f.axes]) for f in (fig_a, fig_b))
        assert np.abs(at_a - at_b).max() <= 0.015
        drawn = fig_a.get_tightbbox(fig_a.canvas.get_renderer())     # inches, every artist in the layout
        width_in, height_in = fig_a.get_size_inches()
        assert drawn.x0 >= -0.01 and drawn.y0 >= -0.01 and drawn.x1 <= width_in + 0.01 and drawn.y1 <= height_in + 0.01


def test_constrained_layout_once_leaves_other_engines_to_themselves():
    fig = style.new_figure(3.0, 2.0)
    fig.add_subplot().plot([0, 1], [0, 1])
    fig.set_layout_engine("tight")
    before = fig.axes[0].get_position().bounds
    assert style.constrained_layout_once(fig, fig.get_layout_engine()) is False
    assert fig.axes[0].get_position().bounds == before


def test_force_unit_is_newtons_as_in_the_tables_at_any_magnitude():
    for forces in ([999.0, -20.0], np.array([10.0, -1000.0]), pd.Series([np.nan, np.inf, 5.0]), [], [-2.5e5]):
        assert style.force_unit(forces) == (1.0, "N")


def test_footnote_wraps_to_the_figure_width_unless_asked_for_one_line():
    text = "; ".join(f"note {i} about the data" for i in range(12))
    wrapped, single = style.new_figure(8.0, 6.0), style.new_figure(8.0, 6.0)
    style.footnote(wrapped, text)
    style.footnote(single, text, width=0)
    assert all(len(line) <= 80 for line in wrapped._supxlabel.get_text().split("\n"))
    assert single._supxlabel.get_text() == text
    empty = style.new_figure(8.0, 6.0)
    style.footnote(empty, "")
    assert empty._supxlabel is None
