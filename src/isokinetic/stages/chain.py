"""A campaign's chain of stages, one function per rule, run the same way by the workflow and elsewhere (issue 36,
part 2).

Each step is one function of its stage's module taking one :class:`Settings` record (``run_ingest``,
``run_characteristic``, ``run_diagnosis``, ``run_analysis``): the rules' scripts (``workflow/scripts/``) call
their own step's, the blind suite (:mod:`isokinetic.stages.blind_diagnose`) runs them through :func:`run_chain`
and ``trace``'s rebuild runs the ingest step (:func:`isokinetic.audit.trace_evidence.rebuild`), so that none of
them applies other settings than the build: ``ingest`` (a raw folder into
``<root>/ingest``), ``characteristic`` (validate, windows, repeatability, characteristic), ``diagnosis``
(diagnosis.json, and Fig. 16 unless ``figures`` is off) and ``analysis`` (design check, models, figures).
:func:`run_chain` runs them in that order into one campaign folder.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from isokinetic.contracts.settings import Settings

#: The chain's steps, in the order they run (a rule each; analysis, the figures, needs no diagnosis but comes
#: last so that ``until="diagnosis"`` stops before it).
CHAIN = ("ingest", "characteristic", "diagnosis", "analysis")


def _steps() -> dict[str, Callable]:
    """step -> its function (each stage module's ``run_<step>``), imported here only: a rule's script imports its
    own step's module, so that its code hash (:mod:`isokinetic.code_closure`) covers that step alone."""
    from isokinetic.stages.analysis import run_analysis
    from isokinetic.stages.characteristic import run_characteristic
    from isokinetic.stages.diagnosis import run_diagnosis
    from isokinetic.stages.ingest import run_ingest

    return {"ingest": lambda root, settings, raw_dir, figures, cases: run_ingest(root, settings, raw_dir, cases),
            "characteristic": lambda root, settings, raw_dir, figures, cases: run_characteristic(root, settings),
            "diagnosis": lambda root, settings, raw_dir, figures, cases: run_diagnosis(root, settings, figures),
            "analysis": lambda root, settings, raw_dir, figures, cases: run_analysis(root, settings)}


def run_step(step: str, campaign_root: str | os.PathLike, settings: Settings,
             raw_dir: str | os.PathLike | None = None, figures: bool = True, cases: Sequence[str] | None = None):
    """Run one step of the chain (CHAIN) on the campaign folder ``campaign_root`` with ``settings``; ``raw_dir``
    for ingest, ``cases`` its cases (default all: ``trace`` re-derives only those it traces); ``figures`` off: the
    diagnosis draws no Fig. 16. Returns what the step's stage returns."""
    if step == "ingest" and raw_dir is None:
        raise ValueError("the ingest step needs the raw campaign folder")
    return _steps()[step](Path(campaign_root), settings, None if raw_dir is None else Path(raw_dir), figures, cases)


def run_chain(raw_dir: str | os.PathLike, campaign_root: str | os.PathLike, settings: Settings,
              until: str = "analysis", figures: bool = True) -> Path:
    """The chain from the raw campaign folder ``raw_dir`` into ``campaign_root``, every step of CHAIN up to and
    including ``until``, as the workflow's rules run them; returns ``campaign_root``."""
    if until not in CHAIN:
        raise ValueError(f"until: unknown step {until!r}; the chain: {', '.join(CHAIN)}")
    root = Path(campaign_root)
    for step in CHAIN[: CHAIN.index(until) + 1]:
        run_step(step, root, settings, raw_dir, figures)
    return root
