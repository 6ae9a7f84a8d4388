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
def test_save_figure_draws_the_pixels_savefig_draws(tmp_path):
    """Laid out once before saving (style.lay_out), a figure has the very pixels of a plain savefig:
    several axes, a shared axis, mathtext, an outside legend and a footnote."""
    cases, series, _, char = synthetic_campaign()
    picked = list(cases["case"])[:3]
    for k, make in enumerate((lambda: figures.time_and_loops(cases, series, picked),
                              lambda: figures.noise(char))):
        fig_a, fig_b = make(), make()
        for fig in (fig_a, fig_b):
            style.footnote(fig, "a note under the axes, long enough to be wrapped onto a second line " * 2)
        a = style.save_figure(fig_a, tmp_path / f"a{k}.png")
        assert fig_a.get_layout_engine() is None                      # laid out, then saved without the engine
        fig_b.savefig(tmp_path / f"b{k}.png", format="png", dpi=style.DPI)
        with Image.open(a) as im_a, Image.open(tmp_path / f"b{k}.png") as im_b:
            assert im_a.size == im_b.size and np.array_equal(np.asarray(im_a), np.asarray(im_b))


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
