"""Which of the package's modules a workflow script runs, and one hash of their code (issue 36, part 5).

Snakemake reruns a job when its script changes, but the scripts in ``workflow/scripts/`` are thin: the
method lives in ``src/isokinetic/``. Each rule therefore takes the hash of its script's *import closure*
inside the package as a param (``workflow/rules/common.smk``, ``code_hash``): edit a module and every rule
whose script reaches it reruns, with everything downstream of it, and no other rule does.

The closure is read from the source (by pattern, :func:`imported_modules`), not from ``sys.modules``:
every ``import isokinetic.x`` and ``from isokinetic.x import y`` (relative ones too), at the top of a
module or inside a function (the package imports heavy modules lazily, where they are needed), and the
packages above each module (their ``__init__`` runs first). An import guarded by ``if TYPE_CHECKING:``
never runs and is left out, as the import contracts leave it out. A dynamic import
(``importlib.import_module`` of a computed name) is not seen; the package has none
(``tests/test_code_closure.py`` checks, and checks the pattern reading against Python's parser).
"""

from __future__ import annotations

import functools
import hashlib
import re
from collections.abc import Iterable
from pathlib import Path

PACKAGE = "isokinetic"


def module_name(path: Path, root: Path) -> str:
    """The dotted name of the module at ``path`` under the package folder ``root`` (``.../isokinetic``)."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


#: ``from X import names`` (names possibly in parentheses over several lines) and ``import X[, Y]``, at any
#: indentation: a function's lazy import counts as well.
_FROM = re.compile(r"^([ \t]*)from[ \t]+(\.*[\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)", re.MULTILINE)
_IMPORT = re.compile(r"^([ \t]*)import[ \t]+([\w. ,]+)", re.MULTILINE)
_TYPE_CHECKING = re.compile(r"^([ \t]*)if[ \t]+(?:typing\.)?TYPE_CHECKING[ \t]*:", re.MULTILINE)


def _type_checking_spans(source: str) -> list[tuple[int, int]]:
    """(start, end) offsets of the bodies of ``if TYPE_CHECKING:`` blocks: the lines after it indented deeper."""
    spans = []
    for match in _TYPE_CHECKING.finditer(source):
        indent, end = len(match.group(1)), match.end()
        for line in source[match.end():].splitlines(keepends=True)[1:]:
            stripped = line.lstrip(" \t")
            if stripped.strip() and len(line) - len(stripped) <= indent:
                break
            end += len(line)
        spans.append((match.end(), end + len(source[match.end():].splitlines(keepends=True)[0])))
    return spans


def imported_modules(source: str, name: str, is_package: bool = False) -> set[str]:
    """The package's modules imported anywhere in ``source`` (the module ``name``): ``import a.b``, ``from a.b
    import c`` (c itself where it is a module: the caller keeps only names that exist), relative imports
    resolved against ``name``; imports under ``if TYPE_CHECKING:`` left out. Read by pattern, not parsed (a
    build reads the whole package at every start: ast.parse costs ten times more); an import-like line in a
    string can only add a module, never lose one."""
    skipped = _type_checking_spans(source)
    here = name if is_package else name.rpartition(".")[0]
    out: set[str] = set()
    for match in _FROM.finditer(source):
        if any(a <= match.start() < b for a, b in skipped):
            continue
        base = match.group(2)
        level = len(base) - len(base.lstrip("."))
        if level:
            anchor = here.split(".")[: len(here.split(".")) - level + 1]
            base = ".".join([*anchor, base[level:]] if base[level:] else anchor)
        names = re.findall(r"[A-Za-z_]\w*(?:[ \t]+as[ \t]+\w+)?", match.group(3).strip("()"))
        out.add(base)
        out |= {f"{base}.{n.split()[0]}" for n in names}
    for match in _IMPORT.finditer(source):
        if not any(a <= match.start() < b for a, b in skipped):
            out |= {part.split()[0] for part in match.group(2).split(",") if part.strip()}
    return {m for m in out if m == PACKAGE or m.startswith(PACKAGE + ".")}


@functools.cache
def package_graph(root: Path) -> dict[str, tuple[str, frozenset[str]]]:
    """Module -> (its file, the package's modules it imports) for every module under ``root``: the Python modules
    and the C sources of the compiled ones (``physics/_sine_kernel.c``, imported as ``physics._sine_kernel``)."""
    files = {module_name(p, root): p for p in sorted([*root.rglob("*.py"), *root.rglob("*.c")])}
    graph = {}
    for name, path in files.items():
        found = imported_modules(path.read_text(encoding="utf-8"), name, path.name == "__init__.py")
        graph[name] = (str(path), frozenset(m for m in found if m in files))
    return graph


def parents(name: str) -> list[str]:
    """The packages above a module, whose ``__init__`` runs before it: 'a.b.c' -> ['a', 'a.b']."""
    parts = name.split(".")
    return [".".join(parts[:k]) for k in range(1, len(parts))]


def closure(start: Iterable[str], graph: dict[str, tuple[str, frozenset[str]]]) -> set[str]:
    """Every module of ``graph`` that importing the modules ``start`` runs (their imports, transitively, and
    the packages above each)."""
    seen: set[str] = set()
    todo = [m for m in start if m in graph]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        todo += [m for m in (*graph[name][1], *parents(name)) if m in graph and m not in seen]
    return seen


def code_hash(script: Path, root: Path) -> str:
    """sha256 over the name and bytes of every module of the package under ``root`` that ``script`` runs
    (:func:`closure` of its own imports), in name order: the version of the code a rule's job runs."""
    graph = package_graph(root)
    start = imported_modules(script.read_text(encoding="utf-8"), "__main__")
    digest = hashlib.sha256()
    for name in sorted(closure(start, graph)):
        stat = Path(graph[name][0]).stat()
        digest.update(name.encode() + b"\0" + _file_digest(graph[name][0], stat.st_mtime_ns, stat.st_size) + b"\0")
    return digest.hexdigest()


@functools.cache
def _file_digest(path: str, _mtime_ns: int, _size: int) -> bytes:
    """sha256 of one file's bytes (read once per build and version of the file)."""
    return hashlib.sha256(Path(path).read_bytes()).digest()
