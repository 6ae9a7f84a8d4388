"""The import closure of each workflow script inside the package, and its code hash (isokinetic.code_closure)."""

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import isokinetic
from isokinetic.code_closure import closure, code_hash, imported_modules, package_graph

ROOT = Path(isokinetic.__file__).parent
SCRIPTS = Path(__file__).resolve().parents[1] / "workflow" / "scripts"


def script_closure(name: str) -> set[str]:
    return closure(imported_modules((SCRIPTS / name).read_text(encoding="utf-8"), "__main__"), package_graph(ROOT))


def test_imports_are_read_anywhere_relative_ones_resolved_and_type_checking_ones_left_out():
    source = """
import os
from isokinetic.physics import damper
from . import sibling
from ..contracts.outputs import STAGE_OUTPUTS
from typing import TYPE_CHECKING
if TYPE_CHECKING:
    from isokinetic.plots.style import new_figure
def f():
    import isokinetic.stats
"""
    found = imported_modules(source, "isokinetic.diagnosis.structure")
    assert {"isokinetic.physics", "isokinetic.physics.damper", "isokinetic.diagnosis.sibling",
            "isokinetic.contracts.outputs", "isokinetic.stats"} <= found
    assert not any(m.startswith("isokinetic.plots") for m in found)
    assert "os" not in found


def test_the_characteristic_rule_reaches_the_window_method_and_no_figure():
    reached = script_closure("characteristic.py")
    assert {"isokinetic.measurement.windows", "isokinetic.stages.characteristic", "isokinetic"} <= reached
    assert not any(m.startswith("isokinetic.plots") for m in reached)



def test_the_blind_suites_scoring_reruns_the_scoring_rule_not_the_scenarios_or_their_diagnoses():
    # the blind package's method reaches the rules through their runners in stages/
    assert {"isokinetic.blind.score", "isokinetic.stages.blind_score"} <= script_closure("blind_score.py")
    assert "isokinetic.blind.generate" in script_closure("blind_generate.py")
    for script in ("blind_generate.py", "blind_diagnose.py"):
        assert "isokinetic.blind.score" not in script_closure(script)

@pytest.mark.parametrize("script", sorted(p.name for p in SCRIPTS.glob("*.py")))
def test_the_static_closure_holds_every_module_the_script_imports_at_run_time(script):
    # an independent reading: what Python itself loads when the script's imports run (function-level imports
    # the static closure also holds are not triggered here, so this is a lower bound)
    source = (SCRIPTS / script).read_text(encoding="utf-8")
    header = "\n".join(line for line in source.splitlines() if line.startswith(("import ", "from ")))
    probe = header + "\nimport sys\nprint('\\n'.join(m for m in sys.modules if m.split('.')[0] == 'isokinetic'))"
    loaded = set(subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                                check=True).stdout.split())
    assert loaded and loaded <= script_closure(script)


def test_no_module_of_the_package_imports_by_a_computed_name():
    for path in ROOT.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert "import_module(" not in text and "__import__(" not in text, path


@pytest.mark.parametrize("module", ["measurement/windows.py", "plots/diagnosis.py", "physics/_sine_kernel.c"])
def test_editing_a_module_changes_the_hash_of_the_rules_that_reach_it_only(tmp_path, module):
    copy = tmp_path / "isokinetic"
    shutil.copytree(ROOT, copy, ignore=shutil.ignore_patterns("__pycache__"))
    scripts = sorted(p.name for p in SCRIPTS.glob("*.py"))
    before = {s: code_hash(SCRIPTS / s, copy) for s in scripts}
    edited = copy / module
    edited.write_text(edited.read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8")
    package_graph.cache_clear()
    after = {s: code_hash(SCRIPTS / s, copy) for s in scripts}
    name = "isokinetic." + str(Path(module).with_suffix("")).replace("/", ".")
    reaches = {s: name in closure(imported_modules((SCRIPTS / s).read_text(encoding="utf-8"), "__main__"),
                                  package_graph(copy)) for s in scripts}
    assert {s: after[s] != before[s] for s in scripts} == reaches
    assert any(reaches.values()) and not all(reaches.values())
    package_graph.cache_clear()


def ast_imports(path: Path, name: str) -> set[str]:
    """An independent reading of a module's imports: Python's own parser (the package's is a pattern)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    guarded = {id(n) for node in ast.walk(tree)
               if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
               for stmt in node.body for n in ast.walk(stmt)}
    here = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(tree):
        if id(node) in guarded:
            continue
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = here.split(".")[: len(here.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            out |= {base} | {f"{base}.{a.name}" for a in node.names}
    return out


def test_the_pattern_reading_finds_what_pythons_parser_finds_in_every_module():
    graph = package_graph(ROOT)
    for name, (path, found) in graph.items():
        if not path.endswith(".py"):   # a compiled module's C source imports nothing of the package
            assert found == set(), name
            continue
        expected = {m for m in ast_imports(Path(path), name) if m in graph}
        assert found >= expected, (name, expected - found)
        assert found - expected == set(), (name, found - expected)   # and nothing a string merely mentions
