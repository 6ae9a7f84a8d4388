"""Rule blind_next_test: one scenario built to be confounded, run end to end (issue 37, part 3).

The scenario (:data:`BUILD_KIND` of :mod:`isokinetic.blind.confounded`, seed :data:`BUILD_SEED`) is drawn on the
independent reference rig and exported as a raw campaign, diagnosed through the build's chain; the next tests its
diagnosis proposes and the uniform plan of the same size and rig time are run on its own rig, each appended to a
copy of the campaign, diagnosed again and judged against the truth (:func:`isokinetic.blind.next_tests.proof_row`).
The row is written as JSON; the raw campaign, its copies and their diagnoses stay in the work folder.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from isokinetic.blind import confounded as cf
from isokinetic.blind.next_tests import proof_row
from isokinetic.contracts.settings import Settings
from isokinetic.io import write_json
from isokinetic.stages.blind_diagnose import diagnose_raw_campaign

#: The scenario the default build runs: a load-cell gain error beside discharge (the confounding the benchmark's
#: verdicts list most), drawn for the blind benchmark's seed (benchmark/blind_suite.py), where its verdict lists
#: that confounding (for the default suite's seed it does not: the diagnosis tells the gain apart there).
BUILD_KIND = "gain_discharge"
BUILD_SEED = 777


def run_next_test(settings: Settings, proof_path: str | os.PathLike, work_dir: str | os.PathLike,
                  kind: str = BUILD_KIND, seed: int = BUILD_SEED) -> dict:
    """Draw, export and diagnose the scenario of ``kind`` for ``seed`` into ``work_dir`` (raw/, truth/, proof/),
    run and judge its proposed and uniform plans with ``settings``, write the row to ``proof_path``; returns it."""
    work_dir = Path(work_dir)
    record = cf.BY_NAME[kind]
    scenario = cf.make_confounded(record, seed, cf.KINDS.index(record), settings.window)
    raw = cf.export_confounded(record, scenario, work_dir / "raw", work_dir / "truth")
    truth = json.loads((work_dir / "truth" / f"{scenario.name}.json").read_text(encoding="utf-8"))
    row = proof_row(raw, truth, work_dir / "proof", lambda r, w: diagnose_raw_campaign(r, w, settings))
    write_json(row, proof_path)
    return row
