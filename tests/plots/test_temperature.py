"""Fig. 20: the temperature of each case, with the viscosity its law gives."""

from __future__ import annotations

import math

import pandas as pd

from isokinetic.physics.viscosity import ViscosityLaw
from isokinetic.plots.temperature import case_temperature

LAW = ViscosityLaw("walther", ((40.0, 0.030), (100.0, 0.006)), 815.0)


def _cases(temps, spans, sources):
    return pd.DataFrame({"case": [f"T{i:02d}" for i in range(len(temps))], "temperature_C": temps,
                         "temperature_span_C": spans, "temperature_source": sources})


def _texts(fig) -> str:
    return " ".join(t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text")))


def test_the_law_gives_a_viscosity_axis_labelled_at_the_temperature_ticks():
    fig = case_temperature(_cases([38.0, 45.0, 52.0], [0.3, 0.2, math.nan], ["channel", "channel", "case"]), LAW,
                           campaign="warm")
    left, right = fig.axes
    assert "viscosity [mPa s]" in right.get_ylabel() and "30 at 40 °C" in right.get_ylabel()
    assert set(right.get_yticks()) <= set(left.get_yticks()) and len(right.get_yticks()) >= 2
    for tick, label in zip(right.get_yticks(), right.get_yticklabels(), strict=True):
        assert float(label.get_text()) == float(f"{1e3 * float(LAW.viscosity_Pa_s(tick)):.3g}")
    assert {t.get_text() for t in left.get_legend().get_texts()} == {
        "temperature channel (mean; bar: span over the record)", "case's temperature_C"}


def test_without_a_law_the_figure_says_the_damper_viscosity_holds():
    fig = case_temperature(_cases([40.0, 40.0], [math.nan, math.nan], ["campaign", "campaign"]), None)
    assert len(fig.axes) == 1 and "no viscosity law" in _texts(fig)


def test_no_known_temperature_is_said_on_the_figure():
    fig = case_temperature(_cases([math.nan], [math.nan], [""]), LAW)
    assert "no temperature known" in _texts(fig)
    assert "no temperature known" in _texts(case_temperature(None, None))


def _label_boxes(fig):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    return [t.get_window_extent(renderer) for t in fig.axes[0].get_xticklabels() if t.get_text()]


def test_case_labels_never_overlap_however_many_cases_and_however_long_their_names():
    for n, name in ((4, "T{:02d}"), (30, "T{:02d}"), (30, "sweep_step_{:03d}"), (200, "S{:03d}")):
        cases = pd.DataFrame({"case": [name.format(i) for i in range(n)], "temperature_C": 40.0,
                              "temperature_span_C": math.nan, "temperature_source": "campaign"})
        boxes = _label_boxes(case_temperature(cases, None))
        assert boxes, (n, name)
        boxes.sort(key=lambda b: b.x0)
        for a, b in zip(boxes, boxes[1:]):
            assert a.x1 <= b.x0, (n, name, a, b)
