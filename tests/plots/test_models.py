"""Fig. 13-14 (isokinetic.plots.models): what each comparison figure draws and says.

The data are the exact Eq. (31) characteristic of the model tests (tests/stages/test_models.py).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from isokinetic.physics.damper import TABLE_1
from isokinetic.plots.models import comparison_figure, comparison_loglog_figure
from isokinetic.stages.models import fit_models, nominal_families
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
    assert "[mm/s]" in ax.get_xlabel() and "[kN]" in ax.get_ylabel() and "nominal" in fig._suptitle.get_text()
    log_fig = comparison_loglog_figure(char, None, fam, models_df, harmonic)
    lax = log_fig.axes[0]
    assert lax.get_xscale() == "log" and lax.get_yscale() == "log"
    assert {"measured+", "measured-", "peak-to-peak+", "surace-"} <= {line.get_gid() for line in lax.get_lines()}


def test_comparison_figure_says_when_the_damper_block_is_missing():
    char = nominal_characteristic().assign(campaign="nodamper")
    models_df, _ = fit_models(char)
    fig = comparison_figure(char, None, None, models_df)
    assert "no damper block" in fig._supxlabel.get_text()
