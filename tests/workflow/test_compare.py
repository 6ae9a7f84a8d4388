"""End-to-end: a config with a comparison builds it (rule compare), the index waits for it and links it, an
unknown campaign is named, and without a `comparisons` block there is no compare job."""

import copy

import pandas as pd
import pytest

from scratch_project import TINY, export, make_project
from workflow.test_workflow import snakemake

#: Snakemake builds of a scratch project (quick loop: -m "not slow and not workflow")
pytestmark = [pytest.mark.slow, pytest.mark.workflow]

NAME = "tiny-vs-export"
#: The tiny config with one comparison: the simulated campaign against its own export (same data).
COMPARED = {**copy.deepcopy(TINY), "comparisons": {NAME: {"campaigns": ["tiny", "tiny-export"],
                                                          "description": "a campaign against its export"}}}
PAGE = f"results/compare/{NAME}/report.html"


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    """A scratch project with the comparison built (only its job and the jobs it needs)."""
    work = make_project(tmp_path_factory.mktemp("compare"), COMPARED)
    export(work, "tiny-export")
    snakemake(work, PAGE)
    return work


def test_comparison_writes_every_output_and_its_benchmark(project):
    folder = project / "results" / "compare" / NAME
    for name in ("compare.parquet", "compare.csv", "compare.json", "report.html", "fig18_compare_overlay.png",
                 "fig19_compare_difference.png"):
        assert (folder / name).stat().st_size > 0, name
    assert (project / "logs" / "compare" / NAME / "compare.benchmark.tsv").is_file()
    table = pd.read_parquet(folder / "compare.parquet")
    assert len(table) == 6 and set(table["basis"]) == {"measured"}     # 3 speeds x 2 directions, same plan
    assert (table["difference_N"].abs() < 1e-6).all() and not table["significant"].any()


def test_index_waits_for_the_comparison_page(project):
    planned = snakemake(project, "-n", "results/index.html").stdout
    index_job = next(b for b in planned.split("\nrule ")[1:] if b.startswith("report_index:"))
    assert PAGE in index_job


def test_unknown_campaign_of_a_comparison_is_named(tmp_path):
    config = copy.deepcopy(COMPARED)
    config["comparisons"][NAME]["campaigns"] = ["tiny", "nope"]
    proc = snakemake(make_project(tmp_path / "bad", config), "-n", check=False)
    assert proc.returncode != 0
    assert f"comparison '{NAME}' names campaign 'nope'" in proc.stdout + proc.stderr


def test_without_comparisons_there_is_no_compare_job(tmp_path):
    planned = snakemake(make_project(tmp_path / "plain", TINY), "-n").stdout
    assert "rule compare:" not in planned and "rule report_index:" in planned
