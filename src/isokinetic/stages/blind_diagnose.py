"""Rule blind_diagnose: one chunk of blind scenarios, each taken from its raw campaign to its diagnosis.

Every scenario exported by :mod:`isokinetic.blind.generate` is an ordinary raw campaign; it
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

from isokinetic.blind.generate import effect_text
from isokinetic.contracts.settings import Settings, load_settings
from isokinetic.stages.chain import run_chain, run_step

log = logging.getLogger(__name__)

def diagnose_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                          settings: Settings | None = None) -> dict:
    """The per-campaign chain of a real raw campaign, into ``work_root/<campaign>/``; the diagnosis.

    The chain's steps ingest, characteristic (validate, windows, repeatability, characteristic) and diagnosis
    (diagnosis.json as rule diagnosis writes it; no gap figure, which nothing scores), run as the workflow's
    rules run them (:func:`isokinetic.stages.chain.run_chain`) with ``settings`` (None: the project's around the
    working directory, :func:`isokinetic.contracts.settings.load_settings`). Reads only ``raw_dir``. An existing
    ``work_root/<campaign>/`` is replaced.
    """
    settings = settings or load_settings()
    root = process_raw_campaign(raw_dir, work_root, settings)
    return run_step("diagnosis", root, settings, figures=False)


def process_raw_campaign(raw_dir: str | os.PathLike, work_root: str | os.PathLike,
                         settings: Settings | None = None) -> Path:
    """ingest -> characteristic of a raw campaign into ``work_root/<campaign>/`` (replaced if it exists) with
    ``settings`` (None: the project's around the working directory); returns that folder. Reads only ``raw_dir``."""
    raw_dir = Path(raw_dir)
    root = Path(work_root) / raw_dir.name
    if root.exists():
        shutil.rmtree(root)
    return run_chain(raw_dir, root, settings or load_settings(), until="characteristic")


def diagnose_suite(raw_root: str | os.PathLike, names: Sequence[str], work_root: str | os.PathLike,
                   settings: Settings | None = None) -> dict[str, dict | None]:
    """:func:`diagnose_raw_campaign` of each named scenario; a failure is logged, written to
    ``work_root/<name>/error.txt`` and returned as None (scored as a wrong verdict)."""
    settings = settings or load_settings()
    out: dict[str, dict | None] = {}
    for name in names:
        try:
            out[name] = diagnose_raw_campaign(Path(raw_root) / name, work_root, settings)
            log.info("%s: verdict %s", name, effect_text(out[name].get("verdict") or []) or "none")
        except Exception as exc:  # noqa: BLE001 - one scenario fails alone, scoring counts it
            log.exception("%s: diagnosis failed", name)
            folder = Path(work_root) / name
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "error.txt").write_text(f"{type(exc).__name__}: {exc}\n", encoding="utf-8")
            out[name] = None
    return out
