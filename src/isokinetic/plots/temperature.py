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


#: Case-label font size [pt] and the room one label needs along the axis, upright per character or rotated [pt].
LABEL_PT = 7.0
_CHAR_PT = 0.62 * LABEL_PT
_ROTATED_PT = 1.5 * LABEL_PT


def figure_width_in(n_cases: int) -> float:
    """The figure's width [in]: 7 in, widened with the number of cases up to 14 in."""
    return float(min(14.0, max(7.0, 1.6 + 0.16 * n_cases)))


def case_ticks(names: list[str], axis_pt: float) -> tuple[list[int], list[str], int]:
    """(positions, labels, rotation) of the case labels along an axis ``axis_pt`` points long, so that no two
    labels overlap: upright when every label fits its slot, else rotated 90 degrees, and every k-th label
    only when even rotated labels do not fit."""
    n = len(names)
    if n == 0:
        return [], [], 0
    slot = axis_pt / n
    longest = max(len(name) for name in names) * _CHAR_PT
    if longest <= 0.9 * slot:
        return list(range(n)), list(names), 0
    step = max(1, int(np.ceil(_ROTATED_PT / slot)))
    at = list(range(0, n, step))
    return at, [names[i] for i in at], 90


def case_temperature(cases: pd.DataFrame | None, law: ViscosityLaw | None = None, *, campaign: str = ""):
    """Temperature per case in plan order, with the law's viscosity on a second axis."""
    n_cases = 0 if cases is None else len(cases)
    fig = new_figure(figure_width_in(n_cases), 3.4)
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
    names = cases["case"].astype(str).tolist()
    at, labels, rotation = case_ticks(names, (fig.get_figwidth() - 1.6) * 72.0)
    ax.set_xticks(at, labels, rotation=rotation, fontsize=LABEL_PT)
    ax.set_xlim(-0.7, len(x) - 0.3)
    shown = "" if len(at) == len(names) else f"; every {at[1] - at[0]}th label shown"
    ax.set_xlabel(f"case (manifest order{shown})")
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


__all__ = ["LABEL_PT", "SOURCE_STYLE", "case_temperature", "case_ticks", "figure_width_in"]
