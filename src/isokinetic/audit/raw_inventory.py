"""No invisible state (issue 34, part 5): every folder under the raw data folder accounted for, and every
campaign's results under ``results/`` matched to an input of this build.

- :func:`unusable_folders`: each folder under ``data/raw/`` the workflow cannot build (no ``campaign.yaml``,
  or a name that is no campaign id, such as ``Bench 3``), with why and how to fix it; the index lists them
  and the run's closing summary names them. Hidden folders (a name starting with ``.``) and plain files are
  no campaign folders and are not listed.
- :func:`orphaned_results`: each ``results/<name>/`` holding a campaign's results whose input is gone (its
  raw folder deleted or renamed, or its virtual campaign taken out of the config). They are shown apart on
  the index, never with their numbers or a link to their old page, and never deleted: whether they are
  orphans depends on the run's config (``--configfile``, ``raw_dir``) and on a disk being mounted, and a
  result whose input is gone cannot be made again. The blind suite, the comparisons and the design summary
  (``results/blind``, ``results/compare``, ``results/design``) are no campaign's; a comparison, or the blind
  suite, that the config no longer asks for is orphaned the same way.
"""

from __future__ import annotations

import os
import re
import unicodedata
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.manifest import MANIFEST_NAME
from isokinetic.contracts.outputs import BLIND_DIR, CAMPAIGN_ID, COMPARE_DIR, STAGE_OUTPUTS, ingest_path

#: Folders of ``results/`` that are no campaign's (the blind suite, the comparisons, the design summary).
RESERVED_RESULTS = frozenset({BLIND_DIR, COMPARE_DIR, "design"})
#: Files of which any one makes ``results/<name>/`` a campaign's results.
CAMPAIGN_RESULT_MARKERS = (STAGE_OUTPUTS["campaign_report"]["page"], STAGE_OUTPUTS["provenance"]["provenance"],
                           STAGE_OUTPUTS["validate"]["cases"], ingest_path("meta"))


@dataclass(frozen=True)
class UnusableFolder:
    """A folder under the raw data folder that the workflow does not build: why, and what to do."""

    folder: str
    reason: str
    fix: str

    def line(self) -> str:
        """The folder as one line of the run's closing summary."""
        return f"{self.folder}/: not built: {self.reason}; {self.fix}"


def suggested_id(name: str) -> str | None:
    """A campaign id close to a folder name (``Bench 3`` -> ``bench-3``, accents dropped), or None when none is."""
    plain = unicodedata.normalize("NFKD", name).encode("ascii", "ignore").decode("ascii")
    candidate = re.sub(r"[^a-z0-9_-]+", "-", plain.strip().lower()).strip("-_")
    candidate = re.sub(r"-{2,}", "-", candidate)
    return candidate if candidate and CAMPAIGN_ID.fullmatch(candidate) else None


def folder_issue(folder: Path) -> UnusableFolder | None:
    """Why the workflow does not build the raw folder ``folder`` and how to fix it, or None when it does."""
    name = folder.name
    has_manifest = (folder / MANIFEST_NAME).is_file()
    shown = folder.as_posix()
    if CAMPAIGN_ID.fullmatch(name):
        if has_manifest:
            return None
        return UnusableFolder(shown, f"no {MANIFEST_NAME}",
                              f"draft one with `python -m isokinetic init-campaign {shown}`, check it with "
                              f"`--check`, then rerun")
    new = suggested_id(name)
    target = f"rename it to {new}" if new else "rename it"
    rule = "lowercase letters, digits, '-' and '_', starting with a letter or digit"
    fix = (f"{target} ({rule})"
           + (f" and set `campaign: {new or '<new name>'}` in its {MANIFEST_NAME}" if has_manifest
              else f", then draft its {MANIFEST_NAME} with `python -m isokinetic init-campaign`"))
    return UnusableFolder(shown, f"folder name {name!r} is not a campaign id"
                          + ("" if has_manifest else f" and it has no {MANIFEST_NAME}"), fix)


def unusable_folders(raw_dir: str | os.PathLike) -> list[UnusableFolder]:
    """Every folder directly under ``raw_dir`` that the workflow does not build (module docstring), by name."""
    raw = Path(raw_dir)
    try:
        entries = sorted(raw.iterdir(), key=lambda p: p.name)
    except OSError:
        return []
    out = []
    for entry in entries:
        if entry.name.startswith(".") or not entry.is_dir():
            continue
        issue = folder_issue(entry)
        if issue is not None:
            out.append(issue)
    return out


def is_campaign_results(folder: Path) -> bool:
    """True when ``folder`` holds a campaign's results (any of :data:`CAMPAIGN_RESULT_MARKERS`)."""
    return any((folder / marker).is_file() for marker in CAMPAIGN_RESULT_MARKERS)


def orphan_reason(folder: Path, raw_dir: Path) -> str:
    """Why ``results/<name>/`` is no result of this build: its raw folder or manifest is gone, or its virtual
    campaign is not in the config (read from its ``ingest/campaign.json``), and what to do."""
    name = folder.name
    try:
        manifest = CampaignFolder.at(folder).meta.manifest_file
    except (OSError, ValueError):        # none, not JSON, or not a campaign.json (CampaignMetaError)
        manifest = None
    raw_folder = (raw_dir / name).as_posix()
    if manifest == "":
        why = f"virtual campaign {name!r} is not in the config (virtual_campaigns)"
        what = "put it back into the config to rebuild it"
    elif (raw_dir / name).is_dir():
        why = f"raw folder missing: {raw_folder}/ has no {MANIFEST_NAME}"
        what = f"restore {raw_folder}/{MANIFEST_NAME} to rebuild it"
    else:
        why = f"raw folder missing: {raw_folder}/ is gone (deleted or renamed)"
        what = f"restore {raw_folder}/ to rebuild it"
    return (f"orphaned: {why}; its results, and its old page, describe inputs this build does not have; "
            f"{what}, or delete {folder.as_posix()}/ and logs/{name}/")


def _folders(root: Path) -> list[Path]:
    """The folders directly under ``root`` (hidden ones left out), by name; none when it cannot be listed."""
    try:
        return sorted((p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")), key=lambda p: p.name)
    except OSError:
        return []


def _not_in_config(folder: Path, what: str, key: str) -> str:
    return (f"orphaned: {what} is not in the config ({key}); its old page shows results this build does not "
            f"make; put it back into the config to rebuild it, or delete {folder.as_posix()}/")


def orphaned_results(results_root: str | os.PathLike, campaigns: Collection[str], raw_dir: str | os.PathLike,
                     comparisons: Collection[str] | None = None, blind: bool = True) -> dict[str, str]:
    """Folder under ``results_root`` -> why it is orphaned: each folder holding a campaign's results whose name
    is no campaign of this build (``campaigns``: raw and virtual; :func:`orphan_reason`); with
    ``comparisons`` (the config's), each ``compare/<name>/`` holding a comparison that is none of them; and
    ``blind/`` holding the blind suite's summary when the build has no blind suite (``blind`` False)."""
    root = Path(results_root)
    out = {p.name: orphan_reason(p, Path(raw_dir)) for p in _folders(root)
           if p.name not in campaigns and p.name not in RESERVED_RESULTS and is_campaign_results(p)}
    if comparisons is not None:
        out.update({f"{COMPARE_DIR}/{p.name}": _not_in_config(p, f"comparison {p.name!r}", "comparisons")
                    for p in _folders(root / COMPARE_DIR)
                    if p.name not in comparisons and (p / STAGE_OUTPUTS["compare"]["summary"]).is_file()})
    if not blind and (root / BLIND_DIR / STAGE_OUTPUTS["blind_score"]["summary"]).is_file():
        out[BLIND_DIR] = _not_in_config(root / BLIND_DIR, "the blind suite", "blind")
    return out


__all__ = ["UnusableFolder", "suggested_id", "folder_issue", "unusable_folders", "is_campaign_results",
           "orphan_reason", "orphaned_results", "RESERVED_RESULTS"]
