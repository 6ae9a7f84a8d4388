"""Rule blind_score: the blind suite scored (:mod:`isokinetic.blind.score`) and written: scores.parquet,
summary.json and Fig. 17 (:mod:`isokinetic.plots.blind_score`)."""

from __future__ import annotations

import os
from collections.abc import Iterable

import pandas as pd

from isokinetic.blind.score import (
    confusion_counts,
    confusion_title,
    read_diagnoses,
    read_truths,
    score,
    score_sources,
    summarize,
)
from isokinetic.io import write_json, write_parquet
from isokinetic.plots.blind_score import confusion_figure
from isokinetic.plots.style import save_figure


def write_scores(truth_root, work_roots: Iterable[str | os.PathLike], scores_path, summary_path,
                 figure_path) -> tuple[pd.DataFrame, dict]:
    """Score the suite: scores.parquet (SCORE_COLUMNS and the sources, SOURCE_COLUMNS), summary.json and
    the confusion figure; returns both. ``truth_root``: one folder of truth files or several (the chunks)."""
    truths = read_truths(truth_root)
    work_roots = list(work_roots)
    diagnoses = read_diagnoses(work_roots, [t["scenario"] for t in truths])
    scores = score(truths, diagnoses)
    scores = scores.merge(score_sources(truth_root, work_roots, scores["scenario"].tolist()), on="scenario",
                          how="left", validate="one_to_one")
    summary = summarize(scores)
    write_parquet(scores, scores_path)
    write_json(summary, summary_path)
    save_figure(confusion_figure(confusion_counts(scores), confusion_title(scores, summary)), figure_path)
    return scores, summary
