"""The house rules a newcomer relies on: a rule, its script and its module share one name, and so do
a stage and its module; every module is listed in the README; every figure has its caption; facts
have one source; no function or module outgrows what a reader can hold."""

from __future__ import annotations

import ast
import json
import re
from pathlib import Path

import pytest
import yaml

from isokinetic.contracts.outputs import CAMPAIGN_ID_PATTERN, FIGURES, RULE_STAGES, STAGE_OUTPUTS, stage_rule

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "isokinetic"
RULE_MODULE_KINDS = ("stages", "audit", "report")
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 800


def rule_names() -> list[str]:
    names = []
    for smk in sorted((ROOT / "workflow" / "rules").glob("*.smk")):
        names += re.findall(r"^rule (\w+):", smk.read_text(encoding="utf-8"), flags=re.M)
    return names


def modules() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def module_named(name: str) -> list[Path]:
    return [p for kind in RULE_MODULE_KINDS for p in (PACKAGE / kind).rglob(f"{name}.py")]


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
        assert len(module_named(stage)) == 1, f"stage {stage}: modules {module_named(stage)}"
    assert set(STAGE_OUTPUTS) <= set(stages)


def test_every_script_belongs_to_a_rule():
    rules = set(rule_names())
    scripts = {p.stem for p in (ROOT / "workflow" / "scripts").glob("*.py")}
    assert scripts <= rules, f"scripts without a rule: {sorted(scripts - rules)}"


def test_readme_layout_lists_every_module():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    layout = readme.split("## Layout", 1)[1].split("\n## ", 1)[0]
    for module in modules():
        rel = module.relative_to(PACKAGE.parent).as_posix()
        if module.name == "__init__.py":
            continue
        assert rel in layout, f"README's layout section does not list {rel}"


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


def test_package_cites_the_paper_by_title_not_by_a_path_outside_it():
    for module in modules():
        text = module.read_text(encoding="utf-8")
        assert "shared/reference" not in text, f"{module.name} cites the paper by a path outside the package"
