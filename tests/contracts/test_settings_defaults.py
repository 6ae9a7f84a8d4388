"""No stage or method signature holds its own default of a setting (issue 36, part 1): a parameter named as a
setting, or typed as one of the settings' records, defaults to :data:`isokinetic.contracts.settings.DEFAULTS`'
value (or has none), never to a literal or a record built on the spot."""

import ast
from pathlib import Path

from isokinetic.contracts.settings import CONFIG_KEYS

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "isokinetic"
#: Parameter names that carry a setting: the flat names and their config keys (but repeatability's bare
#: "tolerance", which the code calls repeatability_tolerance), and the names stages give them.
SETTING_NAMES = (set(CONFIG_KEYS) | {key for (_block, key), _f in CONFIG_KEYS.values()} | {"max_file_MB"}) - {
    "tolerance"}
#: The settings' records: a parameter typed as one of them is a setting too.
RECORDS = {"WindowSpec", "GapTolerance", "DesignLimits", "Settings"}


def own_defaults(source: str, label: str) -> list[str]:
    """'label:line function(parameter=default)' of every parameter of a setting with a default of its own."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        args = node.args
        positional = args.posonlyargs + args.args
        pairs = list(zip(positional[len(positional) - len(args.defaults):], args.defaults, strict=True))
        pairs += [(a, d) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True) if d is not None]
        for arg, default in pairs:
            typed = arg.annotation is not None and any(
                isinstance(n, ast.Name) and n.id in RECORDS for n in ast.walk(arg.annotation))
            if not (arg.arg in SETTING_NAMES or typed):
                continue
            literal = isinstance(default, ast.Constant) and default.value is not None
            built = isinstance(default, ast.Call) and isinstance(default.func, ast.Name) and default.func.id in RECORDS
            if literal or built:
                out.append(f"{label}:{node.lineno} {node.name}({arg.arg}={ast.unparse(default)})")
    return out


def test_no_signature_holds_its_own_default_of_a_setting():
    found = [hit for path in sorted(PACKAGE.rglob("*.py")) if path.name != "settings.py"
             for hit in own_defaults(path.read_text(encoding="utf-8"), str(path.relative_to(PACKAGE)))]
    assert found == []


def test_the_walk_finds_a_literal_default_of_a_setting_and_passes_the_defaults_record():
    # the guard itself: its own 0.05 and WindowSpec() are found, DEFAULTS' values are not
    source = ("def f(x, sample_rate_tolerance=0.05, spec: WindowSpec = WindowSpec(), *, phi=DEFAULTS.design.x,\n"
              "      gap: GapTolerance = DEFAULTS.gap, max_file_MB: float = 256):\n    pass\n")
    assert [hit.split()[1] for hit in own_defaults(source, "probe")] == [
        "f(sample_rate_tolerance=0.05)", "f(spec=WindowSpec())", "f(max_file_MB=256)"]
