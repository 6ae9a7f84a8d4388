"""Rule ``analysis``: what a campaign's characteristic and records give apart from the diagnosis.

One process runs, in order (each stage is its own module and writes its own files):

- design (:mod:`isokinetic.stages.design`): plan check, G-numbers, Fig. 5 and Fig. 6 (Sec. 3.3, 4.2-4.3);
- nominal (:mod:`isokinetic.stages.nominal`): the nominal model through the campaign's plan and windows;
- harmonic (:mod:`isokinetic.stages.harmonic`): sine and free-waveform records, Fig. 15;
- static_force (:mod:`isokinetic.stages.static_force`): the force at v -> 0 (gas force, load-cell zero);
- models (:mod:`isokinetic.stages.models`): nominal families, fitted models, comparison, Fig. 13-14;
- exports (:mod:`isokinetic.stages.exports`): characteristic.csv and models/models.csv for spreadsheets;
- figures (:mod:`isokinetic.stages.figures`): the characteristic figures, Fig. 7-12.

They share one job because each is cheap next to the 1-2 s of imports a job starts with.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_of
from isokinetic.contracts.settings import DEFAULTS, DesignLimits, Settings
from isokinetic.io import write_parquet
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.design import plan_warnings, write_design
from isokinetic.stages.exports import write_exports
from isokinetic.stages.figures import write_campaign_figures
from isokinetic.stages.harmonic import write_harmonic
from isokinetic.stages.models import write_models
from isokinetic.stages.nominal import nominal_stage
from isokinetic.stages.static_force import write_static_force

log = logging.getLogger(__name__)


def _folder(stage: str, name: str) -> str:
    """The folder (relative to the campaign's) of a stage's named table."""
    return str(Path(STAGE_OUTPUTS[stage][name]).parent)


def write_analysis(campaign_root: str | os.PathLike, spec: WindowSpec = DEFAULTS.window,
                   limits: DesignLimits = DEFAULTS.design) -> list[Path]:
    """design -> nominal -> harmonic -> static_force -> models -> exports -> figures of a campaign folder with its
    characteristic; returns every file written. Flagged plan checks are logged as warnings."""
    root = Path(campaign_root)
    plan_check, written = write_design(root, root / _folder("design", "plan_check"),
                                       phi=limits.convergence_fraction, max_amplitude_m=limits.max_amplitude_m,
                                       min_amplitude_m=limits.min_amplitude_m, start_fraction=spec.start_fraction)
    for line in plan_warnings(plan_check):
        log.info("plan check: %s", line)  # shown on the report page (plan check); info: not a failure
    nominal = nominal_stage(root, spec)
    written.append(write_parquet(nominal, root / STAGE_OUTPUTS["nominal"]["nominal"]))
    written += write_harmonic(root, root / _folder("harmonic", "table"))
    written += write_static_force(root)
    written += write_models(root, root / _folder("models", "models"), spec)
    written += write_exports(root)
    written += write_campaign_figures(root, root / str(Path(figures_of("figures")[0].path).parent))
    log.info("%d cases checked (%d flagged), %d nominal-model windows, %d files written", len(plan_check),
             int(plan_check["flagged"].sum()), len(nominal), len(written))
    return written


def run_analysis(campaign_root: str | os.PathLike, settings: Settings) -> list[Path]:
    """The chain's analysis step (:mod:`isokinetic.stages.chain`): :func:`write_analysis` with the settings'
    window and design limits."""
    return write_analysis(campaign_root, settings.window, settings.design)
