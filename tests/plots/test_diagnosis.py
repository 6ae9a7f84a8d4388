"""Fig. 16 (isokinetic.plots.diagnosis): the gap panels, and a panel per axis with structure."""

from __future__ import annotations

import numpy as np

from diagnosis.test_structure import ALPHA, PATTERNS, case_times_s, noise, triangle_campaign, verdict, with_residuals
from isokinetic.diagnosis.structure import residual_structure, window_position_m
from isokinetic.diagnosis.verdict import structure_keys
from isokinetic.plots.diagnosis import gap_figure


def figure_of(z: np.ndarray):
    """Fig. 16 of the synthetic triangle campaign measured at its model + z·σ, the model as the verdict."""
    obs = triangle_campaign()
    measured = with_residuals(obs, z)
    result = {"campaign": "c", "verdict": [], "where": []}
    inputs = structure_keys(result, measured, verdict(obs.force_N.copy()), ALPHA, {"obs_time_s": case_times_s(obs)})
    return result, gap_figure(result, measured, {"nominal": obs.force_N.copy(), "verdict": None,
                                                 "structure": inputs})


def gids(fig) -> set[str]:
    return {ln.get_gid() for ax in fig.axes for ln in ax.get_lines()} | {
        p.get_gid() for ax in fig.axes for p in ax.patches}


def test_fig16_has_a_panel_per_axis_with_structure_and_shades_its_range():
    obs = triangle_campaign()
    result, fig = figure_of(noise(obs, 21) + PATTERNS["position"](obs) + PATTERNS["direction"](obs))
    axes = result["structure"]["axes"]
    assert {"position", "direction"} <= set(axes)
    assert len(fig.axes) == 2 + len(axes)
    assert {f"structure-{a}" for a in axes} <= gids(fig)
    assert {f"structure-{a}-range" for a in axes} <= gids(fig)


def test_fig16_without_structure_keeps_its_two_gap_panels():
    obs = triangle_campaign()
    result, fig = figure_of(noise(obs, 22))
    assert result["structure"]["axes"] == []
    assert len(fig.axes) == 2



def test_fig16_draws_the_position_within_the_windows_on_a_panel_of_its_own():
    obs = triangle_campaign()
    parts = obs.subwindows
    groove = np.abs(window_position_m(parts)) < 1.2e-3
    measured = with_residuals(obs, noise(obs, 23), np.random.default_rng(23).normal(size=len(parts)) - 5.0 * groove)
    result = {"campaign": "c", "verdict": [], "where": []}
    structure = residual_structure(measured, obs.force_N.copy(), ALPHA, case_times_s(obs),
                                   parts_prediction=parts.force_N.copy())
    result["structure"] = {k: v for k, v in structure.items() if k != "where"}
    result["where"] = structure["where"]
    fig = gap_figure(result, measured, {"nominal": obs.force_N.copy(), "verdict": None,
                                        "structure": {"prediction": obs.force_N.copy(), "time_s": case_times_s(obs)}})
    assert {"structure-position_within", "structure-position_within-range"} <= gids(fig)
    assert "structure-position" not in gids(fig)   # the stroke amplitude shows nothing here
