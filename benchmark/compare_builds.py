"""Compare the content of two builds' results: every table, JSON document and CSV file.

    python benchmark/compare_builds.py BEFORE/results AFTER/results

Used to show that a change of code layout changed no result. Tables (Parquet) are compared
cell by cell, exactly (NaN equal to NaN), with their column names, order and dtypes; their
schema metadata (the lineage record) is not compared. JSON documents are compared value by
value, exactly, apart from what names the run rather than the result: the lineage record, time
stamps, durations, the git commit, and, in provenance.json, the sha256 of derived files (each
carries its own lineage record, so its bytes differ when the commit does). Raw and exported CSV
files are compared byte for byte. Figures and HTML pages are not compared (they embed
their lineage); their presence is. Prints one line per difference and exits 1 if there is any.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path

import pandas as pd

import isokinetic  # noqa: F401  (single-threaded Arrow pools: a clean exit, see isokinetic/__init__.py)

#: JSON keys whose values name the run, not the result.
RUN_KEYS = {"lineage", "created_utc", "last_run_utc", "git", "git_commit", "git_dirty", "seconds"}
SHA256 = re.compile(r"^[0-9a-f]{64}$")
COMPARED = (".parquet", ".json", ".csv", ".yaml")
PRESENT_ONLY = (".png", ".html")


def json_differences(a, b, where: str, hashes_are_run: bool) -> list[str]:
    """Differences between two JSON values (paths named ``where``)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            if key in RUN_KEYS:
                continue
            if key not in a or key not in b:
                out.append(f"{where}.{key}: only in {'after' if key in b else 'before'}")
                continue
            out += json_differences(a[key], b[key], f"{where}.{key}", hashes_are_run)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{where}: {len(a)} items before, {len(b)} after"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in json_differences(x, y, f"{where}[{i}]",
                                                                                     hashes_are_run)]
    if hashes_are_run and isinstance(a, str) and isinstance(b, str) and SHA256.match(a) and SHA256.match(b):
        return []
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if a == b and type(a) is type(b) else [f"{where}: {a!r} before, {b!r} after"]


def table_differences(a: Path, b: Path, where: str) -> list[str]:
    """Differences between two Parquet tables (content, columns, dtypes)."""
    x, y = pd.read_parquet(a), pd.read_parquet(b)
    try:
        pd.testing.assert_frame_equal(x, y, check_exact=True)
    except AssertionError as exc:
        return [f"{where}: {' '.join(str(exc).split())[:400]}"]
    return []


def file_differences(a: Path, b: Path, rel: str) -> list[str]:
    if a.suffix == ".parquet":
        return table_differences(a, b, rel)
    if a.suffix == ".json":
        return json_differences(json.loads(a.read_text(encoding="utf-8")), json.loads(b.read_text(encoding="utf-8")),
                                rel, hashes_are_run=a.name == "provenance.json")
    return [] if a.read_bytes() == b.read_bytes() else [f"{rel}: bytes differ"]


def compare(before: Path, after: Path) -> tuple[int, list[str]]:
    """(files compared, differences) between two results folders."""
    def files(root: Path) -> set[str]:
        return {str(p.relative_to(root)) for p in root.rglob("*")
                if p.is_file() and p.suffix in COMPARED + PRESENT_ONLY}
    a, b = files(before), files(after)
    out = [f"{rel}: only in {'after' if rel in b else 'before'}" for rel in sorted(a ^ b)]
    compared = sorted(rel for rel in a & b if Path(rel).suffix in COMPARED)
    for rel in compared:
        out += file_differences(before / rel, after / rel, rel)
    return len(compared), out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    n, differences = compare(args.before, args.after)
    for line in differences:
        print(line)
    print(f"{n} tables, JSON documents and CSV files compared: "
          f"{'identical content' if not differences else f'{len(differences)} differences'}")
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())
