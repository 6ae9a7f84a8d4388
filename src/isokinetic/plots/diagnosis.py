"""Fig. 16: the sim-to-real gap, relative residual against velocity, before and after the verdict.

A pipeline figure beyond those of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.): it compares the characteristic
identified by the paper's method with the nominal damper simulated through the same cases
(Eq. 13-14), before and after adding the effects that the rule ``diagnosis``
(:mod:`isokinetic.stages.diagnosis`) names.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from isokinetic.plots.style import new_figure, say_missing


def gap_figure(result: dict, obs, predictions: dict) -> Figure:
    """Relative residual of the force magnitude, sign(v)(F_meas - F_model)/|F_meas| (negative: the
    damper is weaker than the model), of each characteristic point against |v|, per direction:
    nominal model (before) and nominal + the verdict's effects (after), with the band ±3σ/|F| that
    noise and repeatability explain."""
    fig = new_figure(11, 4.8)
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


def _gap_text(result: dict) -> str:
    """'rms_z 4.31e+03 → 0.959 (holdout 1.08), shrink 4.49e+03×'."""
    def fmt(x):
        return "n/a" if x is None else format(x, ".3g")
    return (f"{result.get('metric', 'gap')} {fmt(result.get('gap_before'))} → {fmt(result.get('gap_after'))} "
            f"(holdout {fmt(result.get('holdout_gap_after'))}), shrink {fmt(result.get('shrink'))}×")
