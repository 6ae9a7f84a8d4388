"""The house rules a newcomer relies on: a rule, its script and its module share one name, and so do
a stage and its module; every module is listed in docs/architecture.md; every figure has its caption; facts
have one source; no function or module outgrows what a reader can hold; the README and docs/ name only
files, links and modules that exist, and nothing outside the repository."""

from __future__ import annotations

import ast
import json
import re
import tomllib
from pathlib import Path

import pytest
import yaml

from isokinetic.contracts.outputs import CAMPAIGN_ID_PATTERN, FIGURES, RULE_STAGES, STAGE_OUTPUTS, stage_rule

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "isokinetic"
DOCS = [ROOT / "README.md", ROOT / "config" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MAX_README_LINES = 200
# a backticked name starting with one of these is a path in the repository
REPO_DIRS = ("src/", "tests/", "workflow/", "benchmark/", "docs/", "config/", "profiles/", ".ci/", ".test/",
             "data/raw/")
PLACEHOLDER = re.compile(r"[<>{}*…|]|\.\.\.")
RULE_MODULE_KINDS = ("stages", "audit", "report")
# a stage that is pure method (windows, repeatability) has its module in measurement/ and its runner in its
# rule's module
STAGE_MODULE_KINDS = (*RULE_MODULE_KINDS, "measurement")
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 800


def rule_names() -> list[str]:
    names = []
    for smk in sorted((ROOT / "workflow" / "rules").glob("*.smk")):
        names += re.findall(r"^rule (\w+):", smk.read_text(encoding="utf-8"), flags=re.M)
    return names


def modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def module_named(name: str, kinds: tuple[str, ...] = RULE_MODULE_KINDS) -> list[Path]:
    return [p for kind in kinds for p in (PACKAGE / kind).rglob(f"{name}.py")]


def test_every_rule_has_a_script_and_one_module_of_its_name():
    rules = [r for r in rule_names() if r != "all"]
    assert set(RULE_STAGES) <= set(rules)
    for rule in rules:
        assert (ROOT / "workflow" / "scripts" / f"{rule}.py").is_file(), f"rule {rule}: no workflow/scripts/{rule}.py"
        found = module_named(rule)
        assert len(found) == 1, f"rule {rule}: modules {found}"


def test_every_stage_has_one_module_of_its_name_and_one_rule_that_runs_it():
    stages = [s for run in RULE_STAGES.values() for s in run]
    assert len(stages) == len(set(stages)), "a stage run by two rules"
    for stage in stages:
        found = module_named(stage, STAGE_MODULE_KINDS)
        assert len(found) == 1, f"stage {stage}: modules {found}"
    assert set(STAGE_OUTPUTS) <= set(stages)


def test_every_script_belongs_to_a_rule():
    rules = set(rule_names())
    scripts = {p.stem for p in (ROOT / "workflow" / "scripts").glob("*.py")}
    assert scripts <= rules, f"scripts without a rule: {sorted(scripts - rules)}"


def architecture_layout() -> str:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    assert "\n## Layout\n" in text, "docs/architecture.md has no '## Layout' section"
    return text.split("\n## Layout\n", 1)[1].split("\n## ", 1)[0]


def test_architecture_layers_are_those_of_the_import_contract():
    contracts = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["importlinter"]
    (layers,) = [c["layers"] for c in contracts["contracts"] if c["type"] == "layers"]
    enforced = [sorted(re.findall(r"isokinetic\.(\w+)", layer)) for layer in layers]
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    section = text.split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|")[2] for line in section.splitlines() if line.startswith("| ") and "---" not in line]
    documented = [sorted(re.findall(r"`(\w+)`", row)) for row in rows[1:]]
    assert documented == enforced, "docs/architecture.md's layers table differs from pyproject's [tool.importlinter]"


def test_architecture_layout_lists_every_module():
    layout = architecture_layout()
    for module in modules():
        rel = module.relative_to(PACKAGE.parent).as_posix()
        if module.name == "__init__.py":
            continue
        assert rel in layout, f"docs/architecture.md's layout section does not list {rel}"


def test_architecture_layout_lists_no_module_that_does_not_exist():
    listed = re.findall(r"^src/(isokinetic/\S+\.py)\b", architecture_layout(), flags=re.M)
    assert listed, "no module found in docs/architecture.md's layout section"
    missing = [rel for rel in listed if not (ROOT / "src" / rel).is_file()]
    assert not missing, f"docs/architecture.md lists modules that do not exist: {missing}"


def test_readme_is_short():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md: {len(lines)} lines; move details to docs/"


def test_readme_holds_the_two_commands_ci_runs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for marker, last in (("main", ".venv/bin/snakemake --cores 2"), ("test", ".venv/bin/pytest -n 2")):
        block = re.search(rf"^<!-- ci:{marker} -->\n```\n(.+)\n```$", readme, flags=re.M)
        assert block, f"README.md: no fenced command after <!-- ci:{marker} -->"
        assert block.group(1).startswith("python3.11 -m venv .venv && ") and block.group(1).endswith(last)


def relative_links(doc: Path) -> list[str]:
    links = re.findall(r"\[[^\]]*\]\(([^)\s]+)\)", doc.read_text(encoding="utf-8"))
    return [link.split("#", 1)[0] for link in links if not re.match(r"[a-z]+:|#", link)]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(doc):
    broken = [link for link in relative_links(doc) if not (doc.parent / link).exists()]
    assert not broken, f"{doc.name}: links to files that do not exist: {broken}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_paths_named_in_the_docs_exist(doc):
    names = re.findall(r"`([^`\s]+)`", doc.read_text(encoding="utf-8"))
    paths = {n.split(":", 1)[0] for n in names if n.startswith(REPO_DIRS) and not PLACEHOLDER.search(n)}
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, f"{doc.name} names paths that do not exist: {missing}"


def names_something_in(module_path: str) -> bool:
    """True if a dotted name (isokinetic.kind.module[.attribute]) is a module (a compiled one: its C source), or a
    name in one."""
    parts = module_path.split(".")
    for i in range(len(parts), 0, -1):
        base = PACKAGE.parent.joinpath(*parts[:i])
        found = [p for p in (base.with_suffix(".py"), base.with_suffix(".c")) if p.is_file()]
        source = found[0] if found else base / "__init__.py"
        if source.is_file():
            rest = parts[i:]
            return not rest or re.search(rf"\b{re.escape(rest[0])}\b", source.read_text(encoding="utf-8")) is not None
    return False


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_modules_named_in_the_docs_exist(doc):
    text = doc.read_text(encoding="utf-8")
    named = set(re.findall(r"\b(isokinetic(?:\.\w+)+)", text))
    if doc != ROOT / "config" / "README.md":  # there `measurement.force_noise_N` is a config key
        kinds = "|".join(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file())
        named |= {f"isokinetic.{ref}" for ref in re.findall(rf"`((?:{kinds})\.\w+(?:\.\w+)*)", text)}
    missing = sorted(name for name in named if not names_something_in(name))
    assert not missing, f"{doc.name} names modules or attributes that do not exist: {missing}"


def test_every_registered_output_is_described_in_the_docs():
    text = "".join((ROOT / "docs" / name).read_text(encoding="utf-8") for name in ("method.md", "diagnosis.md"))
    undescribed = sorted({path for outputs in STAGE_OUTPUTS.values() for path in outputs.values() if path not in text})
    assert not undescribed, f"outputs not described in docs/method.md or docs/diagnosis.md: {undescribed}"


def test_nothing_cites_a_path_outside_the_repository():
    """Neither the docs nor the package (the paper is cited by its title) name the shared/ folder of a checkout."""
    texts = [*DOCS, *(p for p in PACKAGE.rglob("*") if p.is_file() and p.suffix in {".py", ".json", ".j2", ".md"})]
    citing = [p.relative_to(ROOT).as_posix() for p in texts if "shared/" in p.read_text(encoding="utf-8")]
    assert not citing, f"cite a path outside the repository (shared/): {citing}"


def test_every_figure_has_a_caption_and_every_caption_a_figure():
    captions = {p.stem for p in (ROOT / "workflow" / "report").glob("*.rst")} - {"workflow"}
    assert captions == {f.name for f in FIGURES}
    assert all((ROOT / f.caption).is_file() for f in FIGURES)


def test_figures_are_drawn_by_stages_of_rules_that_exist():
    rules = set(rule_names())
    assert {stage_rule(f.stage) for f in FIGURES} <= rules


def test_schemas_use_the_one_campaign_id_pattern():
    config_schema = yaml.safe_load((ROOT / "workflow" / "schemas" / "config.schema.yaml").read_text())
    assert config_schema["properties"]["virtual_campaigns"]["propertyNames"]["pattern"] == f"^{CAMPAIGN_ID_PATTERN}$"
    diagnosis_schema = (PACKAGE / "contracts" / "diagnosis.schema.json").read_text(encoding="utf-8")
    assert json.dumps(f"^{CAMPAIGN_ID_PATTERN}$") in diagnosis_schema


@pytest.mark.parametrize("module", modules(), ids=lambda p: p.relative_to(PACKAGE).as_posix())
def test_module_and_functions_stay_readable(module):
    text = module.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= MAX_MODULE_LINES, f"{module.name}: {len(text.splitlines())} lines"
    long = [(node.name, node.end_lineno - node.lineno + 1) for node in ast.walk(ast.parse(text))
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines: {long}"
