"""Stage ``compare``: one comparison of campaigns (config ``comparisons``) read, compared and written to
``results/compare/<name>/``: the table, its CSV export, the summary and Fig. 18-19. The method (points, matching,
the model path, the z-test) is :mod:`isokinetic.measurement.comparison`."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_of
from isokinetic.io import write_json, write_parquet, write_text
from isokinetic.measurement.comparison import CompareSpec, compare_campaigns
from isokinetic.plots.compare import difference_figure, overlay_figure
from isokinetic.plots.style import save_figure
from isokinetic.stages.exports import csv_text

#: Files of the stage, relative to the comparison's folder.
TABLE_FILE, CSV_FILE, SUMMARY_FILE = (STAGE_OUTPUTS["compare"][k] for k in ("table", "csv", "summary"))
FIGURE_FILES = tuple(f.path for f in figures_of("compare"))


def read_campaign(root: str | os.PathLike) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """(characteristic, models or None) of a campaign's results folder."""
    root = Path(root)
    models_path = root / STAGE_OUTPUTS["models"]["models"]
    char = pd.read_parquet(root / STAGE_OUTPUTS["characteristic"]["characteristic"])
    return char, pd.read_parquet(models_path) if models_path.is_file() else None


def write_compare(spec: CompareSpec, campaign_roots: Mapping[str, str | os.PathLike],
                  out_dir: str | os.PathLike) -> list[Path]:
    """Compare the campaigns (results folders by name) and write the table, its CSV export, the
    summary and Fig. 18-19 to ``out_dir``; returns the written paths."""
    out = Path(out_dir)
    read = {c: read_campaign(campaign_roots[c]) for c in spec.campaigns}
    result = compare_campaigns(spec, {c: r[0] for c, r in read.items()}, {c: r[1] for c, r in read.items()})
    paths = [write_parquet(result.table, out / TABLE_FILE), write_text(csv_text(result.table), out / CSV_FILE),
             write_json(result.summary, out / SUMMARY_FILE)]
    figs = [overlay_figure(result.points, result.curves, spec.campaigns, name=spec.name),
            difference_figure(result.table, spec.campaigns, name=spec.name)]
    paths += [save_figure(fig, out / path) for fig, path in zip(figs, FIGURE_FILES, strict=True)]
    return paths
