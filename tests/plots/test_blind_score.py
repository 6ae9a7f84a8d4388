"""Fig. 17, the blind suite's confusion matrix (isokinetic.plots.blind_score)."""

import pandas as pd

from isokinetic.plots.blind_score import confusion_figure


def test_exact_attributions_are_bold_and_the_title_is_drawn():
    table = pd.DataFrame([[2, 1], [0, 3]], index=["none", "friction"], columns=["none", "friction"])
    fig = confusion_figure(table, "Blind test: 6 scenarios, 5 attributed exactly")
    ax = fig.axes[0]
    weights = {t.get_text(): t.get_fontweight() for t in ax.texts}
    assert weights == {"2": "bold", "1": "normal", "3": "bold"}  # zero counts are not written
    assert ax.get_title() == "Blind test: 6 scenarios, 5 attributed exactly"


def test_an_empty_suite_says_so():
    fig = confusion_figure(pd.DataFrame(), "unused")
    assert [t.get_text() for t in fig.axes[0].texts] == ["no scenarios scored"]
