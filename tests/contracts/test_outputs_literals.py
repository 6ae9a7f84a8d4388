"""Every result file's name comes from the registry (isokinetic.contracts.outputs): no string literal outside
contracts/ spells one out, so renaming or moving a file is one edit."""

from __future__ import annotations

import ast
from pathlib import Path

import isokinetic
from isokinetic.contracts.outputs import result_file_names

PACKAGE = Path(isokinetic.__file__).parent
#: Literals allowed, by (module relative to the package, literal), each with its reason. Keep it short.
ALLOWED: dict[tuple[str, str], str] = {}


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the docstring constants of a module, its classes and functions (prose, not file names in use)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def result_file_literals(source: str, names: frozenset[str]) -> list[tuple[int, str]]:
    """(line, literal) of every string literal that is a result file's name or a path ending in one."""
    tree = ast.parse(source)
    docs = _docstrings(tree)
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs
            and any(node.value == n or node.value.endswith("/" + n) for n in names)]


def test_the_scan_finds_names_and_paths_but_not_prose():
    names = frozenset({"windows.parquet", "campaign.json"})
    source = ('"""Reads windows.parquet."""\nA = "windows.parquet"\nB = f"x/{A}"\nC = "ingest/campaign.json"\n'
              'D = "see windows.parquet: it holds"\nE = "mywindows.parquet"\n')
    assert result_file_literals(source, names) == [(2, "windows.parquet"), (4, "ingest/campaign.json")]


def test_the_registry_names_the_files_readers_look_for():
    names = result_file_names()
    assert {"campaign.json", "cases.parquet", "windows.parquet", "diagnosis.json", "report.html",
            "fig09_characteristic.png"} <= names
    assert not any(n.endswith("/") for n in names)


def test_no_module_outside_contracts_spells_out_a_result_file_name():
    names = result_file_names()
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel.startswith("contracts/"):
            continue
        found += [f"{rel}:{line}: {value!r}" for line, value in result_file_literals(path.read_text("utf-8"), names)
                  if (rel, value) not in ALLOWED]
    assert not found, "result file names spelled out instead of taken from contracts/outputs.py:\n" + "\n".join(found)


def test_every_allowed_literal_is_still_there():
    names = result_file_names()
    for (rel, value), reason in ALLOWED.items():
        assert reason
        path = PACKAGE / rel
        left = {v for _, v in result_file_literals(path.read_text("utf-8"), names)} if path.is_file() else set()
        assert value in left, f"{rel} no longer spells out {value!r}: remove its ALLOWED entry"
