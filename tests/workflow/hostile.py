"""Helpers of the hostile-input workflow tests: write-protect a path (also as root), and undo it."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest


def protect(path: Path) -> bool:
    """Make ``path`` unwritable for this process: ``chattr +i`` as root (root ignores file modes), else
    ``chmod a-w``; whether that worked."""
    if os.geteuid() == 0:
        if not shutil.which("chattr") or subprocess.run(["chattr", "+i", str(path)],
                                                         capture_output=True).returncode != 0:
            return False
    else:
        path.chmod(0o555 if path.is_dir() else 0o444)
    return not os.access(path, os.W_OK)


def write_protect(path: Path) -> None:
    """:func:`protect`, skipping the test where it cannot be done."""
    if not protect(path):
        release(path)
        pytest.skip(f"{path} cannot be write-protected here (root without chattr +i?)")


def release(path: Path) -> None:
    """Undo :func:`write_protect` (so that the test's folder can be removed)."""
    if os.geteuid() == 0 and shutil.which("chattr"):
        subprocess.run(["chattr", "-i", str(path)], capture_output=True)
    if path.exists():
        path.chmod(0o755 if path.is_dir() else 0o644)
