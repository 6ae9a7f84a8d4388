"""What a fresh interpreter imports: the start-up a Snakemake job pays (issue 23)."""

from __future__ import annotations

import ast
import subprocess
import sys


def modules_loaded(code: str, package: str) -> list[str]:
    """The modules of ``package`` (its top-level name) that a fresh Python holds after running ``code``."""
    probe = f"{code}\nimport sys\nprint(sorted(m for m in sys.modules if m.split('.')[0] == {package!r}))"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return ast.literal_eval(out.stdout.strip().splitlines()[-1])
