"""Campaigns the workflow refuses before any job runs, each failing alone (issue 20, findings 2 and 7).

Snakemake checks every job's outputs while it builds the job graph: one write-protected output of a job
that must rerun stops the whole build (``ProtectedOutputException``), despite keep-going. So the workflow
looks first (:func:`refusal`) and refuses a campaign whose existing outputs (``results/<c>/``, ``logs/<c>/``)
it could not replace (:func:`unwritable_paths`), or whose raw folder leads outside the raw data folder
(:func:`isokinetic.audit.raw_folder.folder_problem`). A refused campaign gets none of its jobs; the rule
``refused`` fails instead with the reason (:func:`refuse`), so the run ends failed, every other campaign
built, and the index lists the campaign with that reason.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from isokinetic.audit.raw_folder import folder_problem

#: At most this many unwritable paths are named in a reason.
MAX_NAMED = 3


class CampaignRefused(RuntimeError):
    """The workflow cannot process a campaign (the message says why)."""


def unwritable_paths(roots: Sequence[str | os.PathLike]) -> list[str]:
    """Existing folders and files under ``roots`` (each walked, symlinks neither followed nor counted: Snakemake
    never regards them as protected) that this process may not write: a job could neither replace nor
    remove them."""
    out = []
    for root in map(Path, roots):
        if not root.is_dir() or root.is_symlink():
            continue
        for top, _dirs, files in os.walk(root, followlinks=False):
            here = Path(top)
            if not os.access(here, os.W_OK):
                out.append(here.as_posix())
            out += [(here / f).as_posix() for f in files
                    if not (here / f).is_symlink() and not os.access(here / f, os.W_OK)]
    return sorted(out)


def unwritable_reason(paths: Sequence[str]) -> str:
    """One line naming the unwritable outputs of a campaign and what to do."""
    named = ", ".join(paths[:MAX_NAMED]) + (f" and {len(paths) - MAX_NAMED} more" if len(paths) > MAX_NAMED else "")
    return (f"{len(paths)} existing output(s) cannot be replaced (write-protected): {named}; make them writable "
            "(chmod -R u+w) or remove them, then rerun")


def refusal(campaign: str, raw_dir: str | os.PathLike | None, results_dir: str | os.PathLike = "results",
            logs_dir: str | os.PathLike = "logs") -> str | None:
    """Why the workflow refuses ``campaign`` (module docstring), or None. ``raw_dir``: the raw data folder for a
    raw campaign (its folder is ``raw_dir/<campaign>``), None for a simulated one."""
    if raw_dir is not None:
        problem = folder_problem(Path(raw_dir) / campaign, raw_dir)
        if problem is not None:
            return problem
    protected = unwritable_paths([Path(results_dir) / campaign, Path(logs_dir) / campaign])
    return unwritable_reason(protected) if protected else None


def refuse(campaign: str, reason: str) -> None:
    """The refused campaign's job: raises :class:`CampaignRefused` naming the campaign and the reason."""
    raise CampaignRefused(f"campaign {campaign} refused: {reason}")


__all__ = ["CampaignRefused", "unwritable_paths", "unwritable_reason", "refusal", "refuse"]
