"""Fig. 20: the temperature of each case and the oil viscosity the models take at it.

Not a figure of the paper: its model holds one viscosity (Sec. 2.2), and a campaign whose damper warms
breaks that assumption case by case. The left axis shows each case's temperature (``temperature_C`` of
cases.parquet: the mean of its temperature channel with the record's span as a bar, else the case's or
the campaign's value); the right axis, with a viscosity law (format 1.1), the viscosity the nominal model
and the diagnosis use for that case.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from isokinetic.physics.viscosity import ViscosityLaw
from isokinetic.plots.style import new_figure, say_missing

#: Marker of each temperature source.
SOURCE_STYLE = {"channel": ("o", "tab:red", "temperature channel (mean; bar: span over the record)"),
                "case": ("s", "tab:blue", "case's temperature_C"),
                "campaign": ("D", "tab:gray", "campaign's temperature_C")}


def case_temperature(cases: pd.DataFrame | None, law: ViscosityLaw | None = None, *, campaign: str = ""):
    """Temperature per case in plan order, with the law's viscosity on a second axis."""
    fig = new_figure(7.0, 3.4)
    ax = fig.add_subplot()
    ax.set_title(f"{campaign}: temperature of each case" if campaign else "temperature of each case", fontsize=10)
    if cases is None or cases.empty or "temperature_C" not in cases \
            or not np.isfinite(pd.to_numeric(cases["temperature_C"], errors="coerce")).any():
        say_missing(ax, "no temperature known: neither a temperature channel nor a temperature_C in the manifest")
        return fig
    x = np.arange(len(cases))
    t = pd.to_numeric(cases["temperature_C"], errors="coerce").to_numpy(float)
    span = pd.to_numeric(cases.get("temperature_span_C", pd.Series(np.nan, index=cases.index)),
                         errors="coerce").to_numpy(float)
    source = cases.get("temperature_source", pd.Series("", index=cases.index)).fillna("").astype(str).to_numpy()
    for name, (marker, colour, label) in SOURCE_STYLE.items():
        at = source == name
        if not at.any():
            continue
        half = np.where(np.isfinite(span[at]), span[at] / 2.0, 0.0)
        ax.errorbar(x[at], t[at], yerr=half, fmt=marker, color=colour, ms=5, capsize=3, label=label)
    ax.set_xticks(x, cases["case"].astype(str).tolist(), rotation=90 if len(x) > 12 else 0, fontsize=7)
    ax.set_xlabel("case (manifest order)")
    ax.set_ylabel("temperature [°C]")
    ax.grid(alpha=0.3)
    if law is not None:
        right = ax.twinx()
        lo, hi = ax.get_ylim()
        right.set_ylim(lo, hi)
        ticks = ax.get_yticks()
        ticks = ticks[(ticks >= lo) & (ticks <= hi)]
        right.set_yticks(ticks, [f"{1e3 * v:.3g}" for v in law.viscosity_Pa_s(ticks)])
        right.set_ylabel(f"viscosity [mPa s] ({law.kind}: "
                         + ", ".join(f"{1e3 * mu:.3g} at {tc:g} °C" for tc, mu in law.points) + ")", fontsize=8)
    else:
        ax.text(0.99, 0.02, "no viscosity law: every case is modelled at the damper block's viscosity",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7.5, color="tab:gray")
    ax.legend(fontsize=7, loc="upper left")
    return fig


__all__ = ["SOURCE_STYLE", "case_temperature"]
