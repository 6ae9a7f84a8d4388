"""Fig. 13-14 (isokinetic.plots.models): what each comparison figure draws and says.

The data are the exact Eq. (31) characteristic of the model tests (tests/stages/test_models.py).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from isokinetic.measurement.model_fit import fit_models, nominal_families
from isokinetic.physics.damper import TABLE_1
from isokinetic.plots.models import comparison_figure, comparison_loglog_figure
from stages.test_models import nominal_characteristic


def test_comparison_figures_label_everything():
    char = nominal_characteristic()
    models_df, _ = fit_models(char, TABLE_1)
    fam = nominal_families(TABLE_1, np.linspace(-1.5e-3, 1.5e-3, 31))
    harmonic = pd.DataFrame({"campaign": "nominal", "case": ["H01", "H01"], "waveform": "sine",
                             "kind": "peak_to_peak", "direction": ["+", "-"], "velocity_m_s": [2e-3, -2e-3],
                             "force_N": [9e3, -9e3]})
    loops = {"H01": pd.DataFrame({"velocity_m_s": 2e-3 * np.cos(np.linspace(0, 6.3, 50)),
                                  "force_N": 9e3 * np.sin(np.linspace(0, 6.3, 50) + 1.0)})}
    fig = comparison_figure(char, char.assign(force_N=char["force_N"] * 1.1), fam, models_df, harmonic, loops)
    ax = fig.axes[0]
    gids = {line.get_gid() for line in ax.get_lines()}
    assert {"measured+", "measured-", "nominal-plan", "family-T-0.6", "family-L-T-0.8", "wallaschek", "surace+",
            "surace-", "peak-to-peak", "loop-H01"} <= gids
    assert "[mm/s]" in ax.get_xlabel() and ax.get_ylabel().endswith("[N]") and "nominal" in fig._suptitle.get_text()
    log_fig = comparison_loglog_figure(char, None, fam, models_df, harmonic)
    lax = log_fig.axes[0]
    assert lax.get_xscale() == "log" and lax.get_yscale() == "log"
    assert {"measured+", "measured-", "peak-to-peak+", "surace-"} <= {line.get_gid() for line in lax.get_lines()}


def test_comparison_figure_says_when_the_damper_block_is_missing():
    char = nominal_characteristic().assign(campaign="nodamper")
    models_df, _ = fit_models(char)
    fig = comparison_figure(char, None, None, models_df)
    assert "no damper block" in fig._supxlabel.get_text()


def test_comparison_legend_stays_off_the_data_and_its_abbreviations_are_explained():
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    char = nominal_characteristic()
    models_df, _ = fit_models(char, TABLE_1)
    fam = nominal_families(TABLE_1, np.linspace(-1.5e-3, 1.5e-3, 31))
    harmonic = pd.DataFrame({"campaign": "nominal", "case": ["H01", "H01"], "waveform": "sine",
                             "kind": "peak_to_peak", "direction": ["+", "-"], "velocity_m_s": [2e-3, -2e-3],
                             "force_N": [9e3, -9e3]})
    loops = {"H01": pd.DataFrame({"velocity_m_s": 2e-3 * np.cos(np.linspace(0, 6.3, 50)),
                                  "force_N": 9e3 * np.sin(np.linspace(0, 6.3, 50) + 1.0)})}
    for fig in (comparison_figure(char, None, fam, models_df, harmonic, loops),
                comparison_loglog_figure(char, None, fam, models_df, harmonic)):
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        renderer = canvas.get_renderer()
        (ax,) = fig.axes
        assert ax.get_legend() is None and len(fig.legends) == 1
        legend = fig.legends[0]
        assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
        assert not legend.get_window_extent(renderer).overlaps(fig._suptitle.get_window_extent(renderer))
        labels = [t.get_text() for t in legend.get_texts()]
        assert any("HE " in label for label in labels) and len(labels) <= 12
        note = fig._supxlabel.get_text().replace("\n", " ")
        assert "HE: harmonic excitation" in note and "laminar-turbulent orifice flow solid" in note


def test_each_method_of_the_characteristic_is_its_own_line():
    char = nominal_characteristic().assign(method="triangle_window")
    sine = char.assign(method="sine_peak", velocity_m_s=char["velocity_m_s"] * 3, force_N=char["force_N"] * 2)
    both = pd.concat([char, sine], ignore_index=True)
    models_df, _ = fit_models(both, TABLE_1)
    for fig in (comparison_figure(both, None, None, models_df), comparison_loglog_figure(both, None, None, models_df)):
        lines = {line.get_gid(): line for line in fig.axes[0].get_lines()}
        for gid, part in (("measured+", char), ("measured-sine_peak+", sine)):
            x = np.sort(np.abs(lines[gid].get_xdata()))
            own = np.sort(np.abs(part.loc[part["velocity_m_s"] > 0, "velocity_m_s"].to_numpy()) * 1e3)
            assert np.allclose(x, own[own > 0] if len(x) < len(own) else own), gid
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert any("(triangle)" in label for label in labels) and any("(sine peak)" in label for label in labels)
