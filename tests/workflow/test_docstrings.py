"""Every public function of the method's physics and measurement packages says what it returns.

Public: a module-level function, or a method of a module-level class, of src/isokinetic/physics/*.py or
src/isokinetic/measurement/*.py whose name and class name have no leading underscore. Its docstring must exist and
state the return in one of these ways (the house style of CalebBell/fluids and scipy, kept short):

1. it returns nothing: annotated ``-> None`` (the docstring says what it checks or does);
2. a "Returns" section or a sentence with "returns" / "Returns";
3. its summary line opens with the value returned: ``(`` a tuple listing its members, ``{`` a mapping, ``[`` a
   list, a quoted literal, an article ("The", "A", "An", "One", "Each", "Every") before a noun phrase, a noun clause
   ("Whether" for a bool, "What", "Which", "How"), a cross-reference (":func:`x` of many cases": the value of that
   function), or it defines the value by a formula (" = " in the summary line: "c1 = 8 π μ l_O / A_O²");
4. its summary line names the value with its unit in brackets: "μ(T) [Pa s] (Walther, ASTM D341)".

Units are stated as ``[unit]`` after the value, or carried by a name (force_N): rule 4 accepts a unit as the
statement of a value, but a unit is not required of every function (a bool, a table, a record has none). An
imperative summary ("Compute the force.") or a bare noun phrase without an article or unit fails, and so does a new
function without a docstring."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("physics", "measurement")
OPENINGS = re.compile(
    r"""^(?:[(\[{'"]|``|:(?:func|meth|class|attr):`|(?:The|A|An|One|Each|Every|Whether|What|Which|How)\b)""")
RETURNS = re.compile(r"\b[Rr]eturns?\b")
UNIT = re.compile(r"(?<=\s)\[[^\],\s][^\],]*\]")  # ' [m/s]', ' [Pa s]', ' [-]'; not 'x[k]' nor '[0, 1)'


def public_functions(path: Path) -> list[tuple[str, ast.FunctionDef]]:
    """(qualified name, node) of each public function and public method of a public class of the module."""
    found = []
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_"):
            found.append((node.name, node))
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            found += [(f"{node.name}.{sub.name}", sub) for sub in node.body
                      if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)) and not sub.name.startswith("_")]
    return found


def return_problem(node: ast.FunctionDef) -> str:
    """'' when the function's docstring states its return by the module's rule, else what is missing."""
    doc = ast.get_docstring(node)
    if not doc:
        return "no docstring"
    if isinstance(node.returns, ast.Constant) and node.returns.value is None:
        return ""
    summary = doc.strip().splitlines()[0]
    if RETURNS.search(doc) or OPENINGS.match(summary) or " = " in summary or UNIT.search(summary):
        return ""
    return f"the summary {summary[:60]!r} neither opens with the value returned nor gives its unit, no 'Returns'"


MODULES = sorted(p for pkg in PACKAGES for p in (ROOT / "src" / "isokinetic" / pkg).glob("*.py"))


@pytest.mark.parametrize("module", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_public_functions_state_what_they_return(module):
    problems = [f"{name} (line {node.lineno}): {problem}" for name, node in public_functions(module)
                if (problem := return_problem(node))]
    assert not problems, "\n".join(problems)


def test_the_rule_fails_a_function_without_docstring_or_stated_return():
    source = '''
def bare(x):
    return x
def imperative(x):
    """Compute the force."""
    return x
def noun(x):
    """Mean force of the window."""
    return x
def stated(x):
    """The mean force of the window."""
    return x
def unit(x):
    """Mean force of the window [N]."""
    return x
def index(x):
    """Force of the window x[k] over [0, 1)."""
    return x
def checks(x) -> None:
    """Raises ValueError for a negative x."""
'''
    nodes = {n.name: n for n in ast.parse(source).body}
    assert [name for name, node in nodes.items() if return_problem(node)] == ["bare", "imperative", "noun", "index"]
