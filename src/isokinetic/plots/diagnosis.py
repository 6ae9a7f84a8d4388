"""Fig. 16: the sim-to-real gap, relative residual against velocity, before and after the verdict, and a panel per
axis along which the verdict's residuals show structure (:mod:`isokinetic.diagnosis.structure`).

A pipeline figure beyond those of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.): it compares the characteristic
identified by the paper's method with the nominal damper simulated through the same cases
(Eq. 13-14), before and after adding the effects that the rule ``diagnosis``
(:mod:`isokinetic.stages.diagnosis`) names.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from isokinetic.diagnosis.structure import axis_units
from isokinetic.plots.style import new_figure, say_missing

#: Axis labels of the structure panels: (label, scale of the value).
STRUCTURE_LABELS = {"position": ("stroke amplitude [mm]", 1e3), "time": ("campaign time [s]", 1.0),
                    "temperature": ("temperature [°C]", 1.0), "frequency": ("frequency [Hz]", 1.0),
                    "acceleration": ("peak acceleration [m/s²]", 1.0),
                    "phase": ("phase from the reversal [rad]", 1.0), "direction": ("direction", 1.0),
                    "position_within": ("piston position within the windows [mm]", 1e3)}


def gap_figure(result: dict, obs, predictions: dict) -> Figure:
    """Relative residual of the force magnitude, sign(v)(F_meas - F_model)/|F_meas| (negative: the
    damper is weaker than the model), of each characteristic point against |v|, per direction:
    nominal model (before) and nominal + the verdict's effects (after), with the band ±3σ/|F| that
    noise and repeatability explain."""
    structured = structure_axes(result, obs, predictions)
    fig = new_figure(11, 4.8 + (3.2 if structured else 0.0))
    if structured:
        grid = fig.add_gridspec(2, 2 * len(structured), height_ratios=[3, 2])
        axes = [fig.add_subplot(grid[0, :len(structured)])]
        axes.append(fig.add_subplot(grid[0, len(structured):], sharey=axes[0]))
        structure_panels(fig, grid, result, obs, predictions, structured)
    else:
        axes = fig.subplots(1, 2, sharey=True)
    campaign = result.get("campaign", "")
    verdict = result.get("verdict") or []
    fig.suptitle(f"{campaign}: gap between identified characteristic and model")
    if obs is None:
        for ax in axes:
            say_missing(ax, result.get("reason", "not diagnosed"))
            ax.set_xlabel("Piston speed |v| [mm/s]")
        axes[0].set_ylabel("Relative residual of |F| (meas − model)/|meas| [%]")
        return fig
    win = obs.is_window
    speed = obs.speed_m_s[win] * 1e3
    force = obs.force_N[win]
    band = 3.0 * obs.sigma_N[win] / np.abs(force) * 100.0
    for ax, sign, name in ((axes[0], 1.0, "+ (quadrant 1)"), (axes[1], -1.0, "− (quadrant 3)")):
        m = obs.sign[win] == sign
        order = np.argsort(speed[m])
        ax.fill_between(speed[m][order], -band[m][order], band[m][order], color="0.85",
                        label="±3σ: noise and repeatability", gid="noise-band")
        for key, style, label in (("nominal", {"color": "tab:red", "marker": "o"}, "nominal model (before)"),
                                  ("verdict", {"color": "tab:blue", "marker": "s"},
                                   "nominal + " + " + ".join(verdict) + " (after)")):
            pred = predictions.get(key)
            if pred is None:
                continue
            rel = obs.sign[win] * (force - pred[win]) / np.abs(force) * 100.0
            ax.plot(speed[m][order], rel[m][order], ls="none", ms=4, alpha=0.8, label=label, gid=key, **style)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xlabel("Piston speed |v| [mm/s]")
        ax.set_title(f"direction {name}")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("Relative residual of |F| (meas − model)/|meas| [%]")
    axes[0].legend(loc="best", fontsize=8)
    fig.suptitle(f"{campaign}: gap between identified characteristic and model\n"
                 f"verdict: {' + '.join(verdict) if verdict else 'none needed'}; {_gap_text(result)}")
    return fig


def structure_axes(result: dict, obs, predictions: dict) -> list[str]:
    """The axes along which the verdict's residuals show structure (``structure.axes``), where the figure has
    the observations and the verdict's prediction to show them."""
    if obs is None or (predictions.get("structure") or {}).get("prediction") is None:
        return []
    tests = (result.get("structure") or {}).get("tests") or []
    return list(dict.fromkeys(panel_of(t) for t in tests if t.get("significant")))


def panel_of(test: dict) -> str:
    """The structure panel a test or a ``where`` entry belongs to: the position within the windows has its own,
    every other test its axis' (a drift over time is drawn on the time panel)."""
    within = test.get("test") == "within_window" or "within the triangle windows" in str(test.get("quantity"))
    return "position_within" if within else test["axis"]


def structure_panels(fig, grid, result: dict, obs, predictions: dict, structured: list[str]) -> None:
    """A panel per axis with structure: each unit's residual U = Σz/√n (z signed in the direction of motion:
    > 0, the damper stronger than the verdict) against the axis' value (the position within the windows: each
    position bin's z), ±3 dashed, the ``where`` ranges shaded."""
    inputs = predictions["structure"]
    units = axis_units(obs, inputs["prediction"], inputs.get("time_s"), inputs.get("temperature_C"))
    structure = result.get("structure") or {}
    tests: dict[str, dict] = {}
    for t in structure.get("tests") or []:   # a panel's title: its most significant test
        if t.get("p_adjusted") is not None and t["p_adjusted"] < tests.get(panel_of(t), {}).get("p_adjusted", 2.0):
            tests[panel_of(t)] = t
    bins = (structure.get("within_window") or {}).get("bins") or []
    units["position_within"] = (np.array([0.5 * sum(b["range"]) for b in bins]), np.array([b["z"] for b in bins]))
    for k, axis in enumerate(structured):
        ax = fig.add_subplot(grid[1, 2 * k:2 * k + 2])
        label, scale = STRUCTURE_LABELS.get(axis, (axis, 1.0))
        x, u = units.get(axis, (np.zeros(0), np.zeros(0)))
        for entry in (e for e in result.get("where") or [] if "range" in e and panel_of(e) == axis):
            lo, hi = (v * scale for v in entry["range"])
            pad = 0.02 * (float(np.ptp(x)) * scale if x.size else 1.0)
            ax.axvspan(lo - pad, hi + pad, color="tab:orange", alpha=0.25, gid=f"structure-{axis}-range")
        ax.plot(x * scale, u, ls="none", marker="o", ms=3.5, color="tab:blue", gid=f"structure-{axis}")
        for level in (-3.0, 3.0):
            ax.axhline(level, color="0.5", ls="--", lw=0.8)
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set_xlabel(label)
        p = tests.get(axis, {}).get("p_adjusted")
        ax.set_title(f"{axis}: structure, Holm p = {p:.2g}" if p is not None else axis, fontsize=9)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.set_ylabel("unit residual Σz/√n, bin z (verdict)")


def _gap_text(result: dict) -> str:
    """'rms_z 4.31e+03 → 0.959 (holdout 1.08), shrink 4.49e+03×'."""
    def fmt(x):
        return "n/a" if x is None else format(x, ".3g")
    return (f"{result.get('metric', 'gap')} {fmt(result.get('gap_before'))} → {fmt(result.get('gap_after'))} "
            f"(holdout {fmt(result.get('holdout_gap_after'))}), shrink {fmt(result.get('shrink'))}×")
