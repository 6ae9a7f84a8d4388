"""Fig. 18-19 (isokinetic.plots.compare): what the overlay and difference figures draw and say.

The data are the synthetic campaigns of tests/measurement/test_comparison.py (two plans without a common speed).
"""

from __future__ import annotations

import numpy as np
import pytest

from isokinetic.measurement.comparison import CompareSpec
from isokinetic.plots.compare import difference_figure, overlay_figure
from isokinetic.stats import Z_95
from measurement.test_comparison import SPEEDS_A, SPEEDS_B, characteristic, compare

SPEC = CompareSpec("ab", ("a", "b"))


def result(offset_N: float = 0.0, speeds_b=SPEEDS_B):
    return compare(SPEC, {"a": characteristic("a", SPEEDS_A, seed=1),
                          "b": characteristic("b", speeds_b, seed=2, offset_N=offset_N)})


def gids(ax) -> set[str]:
    return {a.get_gid() for a in ax.get_children() if a.get_gid()}


def test_overlay_draws_points_models_and_bands_of_every_campaign_on_log_axes():
    r = result()
    fig = overlay_figure(r.points, r.curves, SPEC.campaigns, name="ab")
    assert len(fig.axes) == 2
    for ax, d in zip(fig.axes, "+-", strict=True):
        assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
        assert {f"{kind}:{c}:{d}" for kind in ("points", "model", "band") for c in "ab"} <= gids(ax)
        assert "[mm/s]" in ax.get_xlabel() and ax.get_ylabel().endswith("[N]")
    assert "reference a" in fig._suptitle.get_text() and "95 % prediction band" in fig._supxlabel.get_text()


def test_overlay_bars_are_1_96_standard_errors_of_each_point():
    r = result()
    ax = overlay_figure(r.points, r.curves, SPEC.campaigns).axes[1]
    bars = next(c for c in ax.containers if c.lines[0].get_gid() == "points:a:-")
    pts = r.points[(r.points["campaign"] == "a") & (r.points["direction"] == "-")]
    assert np.allclose(bars.lines[0].get_xdata(), np.abs(pts["velocity_m_s"].to_numpy()) * 1e3)
    half = np.array([np.ptp(seg[:, 1]) / 2 for seg in bars.lines[2][0].get_segments()])
    scale = 1e3 if ax.get_ylabel().endswith("[kN]") else 1.0  # the axis' force unit
    assert half == pytest.approx(Z_95 * pts["se_N"].to_numpy() / scale)


def test_difference_marks_model_rows_and_rings_the_significant_ones():
    quiet, shifted = result(), result(offset_N=30.0)
    ax = difference_figure(quiet.table, SPEC.campaigns, name="ab").axes[0]
    assert {"difference:b:+:model"} <= gids(ax) and not any(g.startswith("significant") for g in gids(ax))
    assert ax.get_xscale() == "log" and "[N]" in ax.get_ylabel()
    fig = difference_figure(shifted.table, SPEC.campaigns, name="ab")
    assert {"significant:b:+"} <= gids(fig.axes[0]) and {"significant:b:-"} <= gids(fig.axes[1])
    n = len(shifted.table)
    assert f"{n} of {n} rows" in " ".join(fig._supxlabel.get_text().split())


def test_difference_draws_measured_rows_filled_apart_from_model_rows():
    r = result(speeds_b=np.concatenate([SPEEDS_A[:3], SPEEDS_B[3:]]))
    assert {"measured", "model:surace"} <= set(r.table["basis"])
    names = gids(difference_figure(r.table, SPEC.campaigns).axes[0])
    assert {"difference:b:+:measured", "difference:b:+:model"} <= names


def test_empty_comparison_says_so_on_both_figures():
    r = result()
    fig = difference_figure(r.table.iloc[0:0], SPEC.campaigns)
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    assert any("no rows to compare in direction +" in t for t in texts)
    plus_only = r.points[r.points["direction"] == "+"]
    texts = [t.get_text() for ax in overlay_figure(plus_only, r.curves.iloc[0:0], SPEC.campaigns).axes
             for t in ax.texts]
    assert any("no points in direction -" in t for t in texts)
