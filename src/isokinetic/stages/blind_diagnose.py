"""Rule blind_diagnose: one chunk of blind scenarios, each taken from its raw campaign to its diagnosis.

Every scenario exported by :mod:`isokinetic.stages.blind_generate` is an ordinary raw campaign; it
goes through exactly the chain a real raw campaign gets (ingest -> validate -> windows ->
repeatability -> characteristic -> diagnosis, :func:`diagnose_raw_campaign`) and never sees its
truth. A scenario whose chain fails is recorded and scored as a wrong verdict.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.measurement.windows import WindowSpec
from isokinetic.stages.blind_generate import effect_text
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.diagnosis import write_diagnosis
from isokinetic.stages.ingest import ingest_campaign

log = logging.getLogger(__name__)

#: Where the diagnosis goes in a scenario's work folder, as rule diagnosis names it.
DIAGNOSIS_FILE = STAGE_OUTPUTS["diagnosis"]["json"]


def diagnose_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                          spec: WindowSpec = WindowSpec(), *, repeatability_tolerance: float = 0.05,
                          sample_rate_tolerance: float = 0.05) -> dict:
    """The per-campaign chain of a real raw campaign, into ``work_root/<campaign>/``; the diagnosis.

    ingest -> :func:`isokinetic.stages.characteristic.write_characteristic` (validate, windows,
    repeatability, characteristic: the job of rule characteristic) ->
    :func:`isokinetic.stages.diagnosis.write_diagnosis` (diagnosis.json as rule diagnosis writes it;
    no gap figure, which nothing scores). Reads only ``raw_dir``. An existing
    ``work_root/<campaign>/`` is replaced.
    """
    root = process_raw_campaign(raw_dir, work_root, spec, repeatability_tolerance=repeatability_tolerance,
                                sample_rate_tolerance=sample_rate_tolerance)
    return write_diagnosis(root, root / DIAGNOSIS_FILE, None, spec)


def process_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                         spec: WindowSpec = WindowSpec(), *, repeatability_tolerance: float = 0.05,
                         sample_rate_tolerance: float = 0.05) -> Path:
    """ingest -> validate -> windows -> repeatability -> characteristic of a raw campaign into
    ``work_root/<campaign>/`` (replaced if it exists); returns that folder. Reads only ``raw_dir``."""
    raw_dir = Path(raw_dir)
    root = Path(work_root) / raw_dir.name
    if root.exists():
        shutil.rmtree(root)
    ingest_campaign(raw_dir, root)
    write_characteristic(root, spec, repeatability_tolerance=repeatability_tolerance,
                         sample_rate_tolerance=sample_rate_tolerance)
    return root


def diagnose_suite(raw_root: str | os.PathLike, names: Sequence[str], work_root: str | os.PathLike,
                   spec: WindowSpec = WindowSpec(), **kwargs) -> dict[str, dict | None]:
    """:func:`diagnose_raw_campaign` of each named scenario; a failure is logged, written to
    ``work_root/<name>/error.txt`` and returned as None (scored as a wrong verdict)."""
    out: dict[str, dict | None] = {}
    for name in names:
        try:
            out[name] = diagnose_raw_campaign(Path(raw_root) / name, work_root, spec, **kwargs)
            log.info("%s: verdict %s", name, effect_text(out[name].get("verdict") or []) or "none")
        except Exception as exc:  # noqa: BLE001 - one scenario fails alone, scoring counts it
            log.exception("%s: diagnosis failed", name)
            folder = Path(work_root) / name
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "error.txt").write_text(f"{type(exc).__name__}: {exc}\n", encoding="utf-8")
            out[name] = None
    return out
