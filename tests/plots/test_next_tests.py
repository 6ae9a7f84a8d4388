"""Fig. 21 (isokinetic.plots.next_tests): the proposed next tests marked on the A-T diagram."""

import numpy as np
import pytest

from isokinetic.physics.damper import TABLE_1
from isokinetic.physics.plan import CasePlan
from isokinetic.plots.next_tests import next_tests_figure

PLANS = [CasePlan("T01", "triangle", 50.0, amplitude_m=4e-4, period_s=40.0),
         CasePlan("T02", "triangle", 50.0, amplitude_m=1.25e-3, period_s=10.0)]
TRIANGLE = {"case": "N01", "waveform": "triangle", "velocity_m_s": 6.35e-5, "amplitude_m": 1e-4, "period_s": 6.3,
            "separation_se": 17.5}
STANDSTILL = {"case": "N02", "waveform": "standstill", "velocity_m_s": None, "amplitude_m": 0.0, "period_s": None,
              "separation_se": 0.4}


def proposed(fig):
    return [line for line in fig.axes[0].get_lines() if line.get_gid() == "proposed"]


def test_each_proposed_triangle_is_marked_at_its_period_and_amplitude():
    block = {"needed": True, "note": "2 case(s)", "plan": [TRIANGLE, STANDSTILL]}
    fig = next_tests_figure("small", block, PLANS, TABLE_1)
    (marks,) = proposed(fig)
    assert marks.get_xdata() == pytest.approx([6.3]) and marks.get_ydata() == pytest.approx([0.1])   # mm
    assert "not on the diagram: N02: standstill" in fig._supxlabel.get_text().replace("\n", " ")
    lo, hi = fig.axes[0].get_xlim()
    assert lo < 6.3 < hi and np.all([lo < p.period_s < hi for p in PLANS])


def test_a_campaign_without_a_plan_has_no_marks_and_says_why():
    block = {"needed": False, "note": "no confounding: no further test proposed", "plan": []}
    fig = next_tests_figure("small", block, PLANS, TABLE_1)
    assert proposed(fig) == []
    assert "no confounding" in fig._supxlabel.get_text()


def test_a_campaign_without_triangle_cases_gets_its_diagram():
    # a sine-only campaign (a real MTS sweep, a crank dyno) has no triangle case to place: the diagram still draws
    sines = [CasePlan("S01", "sine", 500.0, amplitude_m=1e-3, frequency_Hz=2.0)]
    fig = next_tests_figure("sweep", {"needed": False, "note": "no confounding: no further test proposed",
                                      "plan": []}, sines, TABLE_1)
    assert proposed(fig) == [] and "no confounding" in fig._supxlabel.get_text()


def test_the_campaigns_own_cases_are_named_as_such():
    fig = next_tests_figure("small", {"needed": True, "note": "1 case(s)", "plan": [TRIANGLE]}, PLANS, TABLE_1)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert any(label.startswith("campaign, T = 40 s") for label in labels)
    assert not any(label.startswith("planned") for label in labels)
