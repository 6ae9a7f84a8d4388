"""Rule blind_generate: one chunk of the seeded blind suite (:mod:`isokinetic.blind.generate`) drawn and exported
as raw campaigns, ``<raw_root>/<scenario>/``, with the withheld truth apart, ``<truth_root>/<scenario>.json``."""

from __future__ import annotations

import os
from collections.abc import Sequence

from isokinetic.blind.generate import Scenario, generate_scenarios, write_suite
from isokinetic.contracts.settings import Settings


def write_chunk(seed: int, counts: Sequence[int], names: Sequence[str], settings: Settings,
                raw_root: str | os.PathLike, truth_root: str | os.PathLike) -> list[Scenario]:
    """Draw the scenarios ``names`` of the suite of ``seed`` and ``counts`` (n_per_effect, n_pairs, n_none,
    n_out_of_catalogue, n_sine: :func:`isokinetic.blind.generate.generate_scenarios`) with the build's window
    settings, and export them. Raises RuntimeError when the suite names other scenarios than the workflow
    planned (its chunks would then miss or repeat some)."""
    scenarios = generate_scenarios(seed, *counts, spec=settings.window, names=list(names))
    drawn = [s.name for s in scenarios]
    if drawn != list(names):
        raise RuntimeError(f"generated scenarios {drawn} differ from the workflow's {list(names)}")
    write_suite(scenarios, raw_root, truth_root)
    return scenarios
