"""Figures of the stage design (plots.design): Fig. 5 (stroke to converge) and Fig. 6 (A-T diagram)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from isokinetic.physics.convergence import stroke_to_converge
from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.plots import design as design_plots
from isokinetic.stages.design import plan_check

PHI = 0.999
MAX_AMP, MIN_AMP = 10.0e-3, 0.1e-3     # the workflow test's design block: 10 mm, 0.1 mm
START = 0.45                          # the paper's window start, a fraction of T/2
MM = 1e3


def triangle(case, y_m, period_s, rate_Hz=100.0, periods=2.0):
    return CasePlan(case=case, waveform="triangle", sample_rate_Hz=rate_Hz, amplitude_m=y_m, period_s=period_s,
                    phase_rad=-math.pi / 2, duration_s=periods * period_s)


def check(cases, damper=TABLE_1, **kw):
    kw = {"phi": PHI, "max_amplitude_m": MAX_AMP, "min_amplitude_m": MIN_AMP, "start_fraction": START, **kw}
    return plan_check("design-test", cases, damper, **kw).set_index("case")


def _lines(ax, gid):
    return [ln for ln in ax.get_lines() if ln.get_gid() == gid]


def test_fig5_has_labelled_axes_curves_band_and_planned_strokes(default_plan):
    df = check(list(default_plan.cases), damper=default_plan.damper).reset_index()
    w = np.geomspace(1e-6, 1e-2, 60)
    fig = design_plots.stroke_to_converge_figure(TABLE_1, w, phi=PHI, planned=df, campaign="paper-lag-damper")
    ax = fig.axes[0]
    assert ax.get_xscale() == "log"
    assert "[mm/s]" in ax.get_xlabel() and "[mm]" in ax.get_ylabel()
    assert "paper-lag-damper" in fig.get_suptitle()
    for gid in ("laminar", "turbulent", "mixed", "mixed-air-0.001", "mixed-air-0.005", "mixed-air-0.01",
                "planned-half-period", "planned-window-start"):
        assert len(_lines(ax, gid)) == 1, gid
    assert any(c.get_gid() == "band" for c in ax.collections)
    # more air, longer stroke (Eq. 3): compare at 0.1 mm/s
    at = lambda gid: np.interp(0.1, *_lines(ax, gid)[0].get_data())  # noqa: E731
    assert at("mixed") < at("mixed-air-0.001") < at("mixed-air-0.005") < at("mixed-air-0.01")
    assert at("mixed") == pytest.approx(float(stroke_to_converge(1e-4, TABLE_1, phi=PHI)) * MM, rel=0.02)


def test_fig6_has_log_axes_iso_velocity_points_and_constraint_boundaries(default_plan):
    df = check(list(default_plan.cases), damper=default_plan.damper).reset_index()
    fig = design_plots.at_diagram_figure("paper-lag-damper", df, TABLE_1, MAX_AMP, MIN_AMP, 0.45, PHI)
    ax = fig.axes[0]
    assert ax.get_xscale() == ax.get_yscale() == "log"
    assert ax.get_xlabel() == "Period T [s]" and ax.get_ylabel() == "Amplitude Y [mm]"
    assert "paper-lag-damper" in fig.get_suptitle()
    assert _lines(ax, "max-travel")[0].get_ydata()[0] == pytest.approx(10.0)
    assert _lines(ax, "noise-floor")[0].get_ydata()[0] == pytest.approx(0.1)
    assert len(_lines(ax, "iso-velocity")) >= 3
    assert any("mm/s" in t.get_text() for t in ax.texts if t.get_gid() == "iso-velocity-label")
    assert {ln.get_gid() for ln in ax.get_lines()} >= {"planned-T20", "planned-T80", "planned-T240"}
    assert len(_lines(ax, "flagged")[0].get_xdata()) == 5
    # on the quasi-steady boundary the window starts exactly at the stroke to converge (from -Y)
    t_b, y_b = (np.asarray(a, float) for a in _lines(ax, "quasi-steady")[0].get_data())
    y = y_b / MM
    w = 4 * y / t_b
    need = stroke_to_converge(w, TABLE_1, phi=PHI, start_position_m=-y)
    assert np.allclose(0.45 * t_b / 2 * w, need, rtol=1e-6)


def test_fig6_without_damper_has_no_boundary_and_says_why():
    fig = design_plots.at_diagram_figure("camp-z", plan_check("camp-z", [triangle("T01", 2e-3, 80.0)], None, phi=PHI,
                                                        max_amplitude_m=MAX_AMP, min_amplitude_m=MIN_AMP,
                                                        start_fraction=START),
                               None, MAX_AMP, MIN_AMP, 0.45, PHI)
    ax = fig.axes[0]
    assert not _lines(ax, "quasi-steady") and _lines(ax, "max-travel") and _lines(ax, "noise-floor")
    assert "damper block missing" in fig.get_supxlabel()
