"""Fig. 17 of rule blind_score: the blind suite's confusion matrix, truth effect set against verdict.

The counts and the title come from :mod:`isokinetic.blind.score` (``confusion_counts``,
``confusion_title``); this module only draws them.
"""

from __future__ import annotations

import pandas as pd
from matplotlib.figure import Figure

from isokinetic.plots.style import new_figure, say_missing


def confusion_figure(table: pd.DataFrame, title: str) -> Figure:
    """Fig. 17: counts of truth set (rows) against verdict set (columns); exact attributions, where
    the row and column names agree, in bold."""
    n_r, n_c = table.shape
    fig = new_figure(max(5.0, 1.0 + 0.55 * n_c), max(3.5, 1.4 + 0.4 * n_r))
    ax = fig.add_subplot()
    if n_r == 0:
        say_missing(ax, "no scenarios scored")
        ax.set_axis_off()
        return fig
    counts = table.to_numpy()
    ax.imshow(counts, cmap="Blues", vmin=0, vmax=max(1, counts.max()), aspect="auto")
    for i in range(n_r):
        for j in range(n_c):
            if counts[i, j]:
                exact = table.index[i] == table.columns[j]
                ax.text(j, i, str(counts[i, j]), ha="center", va="center", fontsize=9,
                        color="white" if counts[i, j] > 0.6 * counts.max() else "black",
                        fontweight="bold" if exact else "normal")
    ax.set_xticks(range(n_c), table.columns, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(n_r), table.index, fontsize=8)
    ax.set_xlabel("verdict (effect set)")
    ax.set_ylabel("truth (effect set)")
    ax.set_title(title, fontsize=10)
    return fig
