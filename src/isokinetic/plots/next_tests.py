"""Fig. 21: the next tests on the A-T diagram (issue 37).

Fig. 6's A-T diagram (:func:`isokinetic.plots.design.at_diagram_figure`: iso-velocity lines, the design limits and
the quasi-steady boundary of Eq. 28) of the campaign's triangle cases, with the triangle cases the diagnosis proposes
(``next_tests.plan`` of diagnosis.json, :mod:`isokinetic.diagnosis.next_tests`) marked and named; a standstill has
no period and is named in the footnote. Where no test is needed the diagram says so.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import pandas as pd
from matplotlib.figure import Figure

from isokinetic.contracts.settings import DEFAULTS, DesignLimits, WindowSpec
from isokinetic.physics.damper import Damper
from isokinetic.physics.plan import CasePlan
from isokinetic.plots.design import at_diagram_figure
from isokinetic.plots.style import MM, footnote

#: Marker of a proposed case.
PROPOSED_STYLE = {"ls": "none", "marker": "*", "ms": 15, "color": "tab:green", "mec": "k", "mew": 0.8, "zorder": 7}


def campaign_triangles(plans: Sequence[CasePlan]) -> pd.DataFrame:
    """The campaign's triangle cases as the A-T diagram reads them (case, waveform, speed, amplitude, period)."""
    rows = [{"case": p.case, "waveform": p.waveform, "velocity_m_s": p.velocity_m_s, "amplitude_m": p.amplitude_m,
             "period_s": p.period_s} for p in plans if p.waveform == "triangle"]
    return pd.DataFrame(rows, columns=["case", "waveform", "velocity_m_s", "amplitude_m", "period_s"])


def next_tests_figure(campaign: str, block: Mapping | None, plans: Sequence[CasePlan], damper: Damper | None,
                      design: DesignLimits = DEFAULTS.design, spec: WindowSpec = DEFAULTS.window) -> Figure:
    """Fig. 21: the campaign's triangle cases on the A-T diagram, the proposed ones as green stars named N01..
    (gid 'proposed'), the axes widened to hold them."""
    fig = at_diagram_figure(campaign, campaign_triangles(plans), damper, design.max_amplitude_m,
                            design.min_amplitude_m, spec.start_fraction, design.convergence_fraction)
    ax = fig.axes[0]
    fig.suptitle(f"{campaign}: the next tests on the A\u2013T diagram", fontsize=12)
    for line in ax.get_lines():   # Fig. 6's planned cases are the campaign's own here
        if str(line.get_gid()).startswith("planned"):
            line.set_label(line.get_label().replace("planned", "campaign", 1))
    plan = list((block or {}).get("plan") or [])
    tri = [e for e in plan if e["waveform"] == "triangle"]
    if tri:
        t = [e["period_s"] for e in tri]
        y = [e["amplitude_m"] * MM for e in tri]
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        ax.set_xlim(min(x0, min(t) / 2.0), max(x1, max(t) * 2.0))
        ax.set_ylim(min(y0, min(y) / 2.0), max(y1, max(y) * 2.0))
        ax.plot(t, y, gid="proposed", label=f"proposed next tests ({len(tri)})", **PROPOSED_STYLE)
        for e, ti, yi in zip(tri, t, y, strict=True):
            ax.annotate(f"{e['case']}: {e['separation_se']:.1f} SE", (ti, yi), xytext=(8, 6),
                        textcoords="offset points", fontsize=8, color="tab:green", zorder=8)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8)
    other = [f"{e['case']}: {e['waveform']}" for e in plan if e["waveform"] != "triangle"]
    note = (block or {}).get("note") or "no next_tests in diagnosis.json"
    text = "; ".join([f"next tests: {note}", *([f"not on the diagram: {', '.join(other)}"] if other else [])])
    footnote(fig, text, width=max(40, int(fig.get_figwidth() * 10)))
    return fig
