"""Fuzz: the hostile inputs of issue 20 and seeded random damage of a good campaign, all in one scratch project,
one Snakemake build (keep-going), under an address-space limit.

Every campaign-level input is its own raw campaign; the case-level ones are cases of one campaign (``f-cases``)
beside four good cases; an untouched campaign (``good``) sits beside them all. To stay within the time budget
(about a minute on 2 cores) the good campaign, ``f-cases`` and the one with hostile file names are built through
every stage to their page, the others as far as their input matters (:data:`BUILDS`). The run fails (refused
campaigns), so the index and the design summary are the ones the failure handler rebuilds.

For the build as a whole: the good campaign is built, the index and the design summary list every campaign,
``data/raw/`` (and the folder a symlinked campaign leads to) is unchanged entry by entry, nothing stops the
whole build (no ``ProtectedOutputException``, ``WildcardError``, ``MemoryError``), and the peak resident memory
of any process of the build stays below :data:`MAX_RSS_MB`. For each input: it costs its case or its campaign
alone, and every reason (a quarantined case's, a failed campaign's) names its campaign and, where one case is at
fault, that case, in a line of bounded length.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign
from scratch_project import SNAKEMAKE, TINY, make_project

from .hostile import protect, release

pytestmark = [pytest.mark.slow, pytest.mark.workflow]

#: Peak resident memory of any one process of the build (the largest job, or Snakemake itself), MB.
MAX_RSS_MB = 1000
#: Address-space limit of the build and every job: a runaway stops with a MemoryError instead of taking the machine.
ADDRESS_SPACE_BYTES = 3 * 1024**3
#: The whole build may take at most this long (seconds) before it is killed.
BUILD_TIMEOUT_S = 300
#: Case files above this size (MB) are set aside unread (config ingest.max_case_file_MB); the good files are ~10 kB.
MAX_CASE_FILE_MB = 0.5
SEED = 20
N_RANDOM = 4

#: Four short triangle cases (one set aside leaves the three the models stage needs).
SPEC = dict(TINY["virtual_campaigns"]["tiny"], description="four short triangle cases",
            plan={"triangle": {"velocities_mm_s": [0.05, 0.5, 1.0, 1.5], "periods_s": [8, 8, 8, 8],
                               "sample_rate_Hz": 20.0}})
CONFIG = {k: v for k, v in TINY.items() if k != "virtual_campaigns"} | {
    "ingest": {"max_case_file_MB": MAX_CASE_FILE_MB}}
GOOD = "good"
#: Written into the project when a file cannot be write-protected here (root without chattr +i).
UNPROTECTED = "unprotected.txt"


# --- the inputs ----------------------------------------------------------------------------------

def read_rows(path: Path) -> list[list[str]]:
    return [line.split(",") for line in path.read_text(encoding="utf-8").splitlines()]


def write_rows(path: Path, rows: list[list[str]]) -> None:
    path.write_text("\n".join(",".join(r) for r in rows) + "\n", encoding="utf-8")


def set_cell(path: Path, row: int, col: int, value: str) -> None:
    """Data row ``row`` (0-based, under the header), column ``col`` of a case CSV set to ``value``."""
    rows = read_rows(path)
    rows[row + 1][col] = value
    write_rows(path, rows)


def manifest(folder: Path) -> dict:
    return yaml.safe_load((folder / "campaign.yaml").read_text(encoding="utf-8"))


def write_manifest(folder: Path, doc: dict) -> None:
    (folder / "campaign.yaml").write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")


def bad_case(folder: Path, case: str, **keys) -> Path:
    """A case ``case`` added to the campaign: a copy of T02 (entry and file ``<case>.csv``), ``keys`` set."""
    doc = manifest(folder)
    entry = dict(next(c for c in doc["cases"] if c["id"] == "T02"), id=case, file=f"{case}.csv", **keys)
    doc["cases"].append(entry)
    write_manifest(folder, doc)
    shutil.copy(folder / "T02.csv", folder / f"{case}.csv")
    return folder / f"{case}.csv"


def last_time_1e308(folder: Path, work: Path) -> None:
    path = bad_case(folder, "TIME1E308")
    set_cell(path, len(read_rows(path)) - 2, 0, "1e308")


def iso_year_typo(folder: Path, work: Path) -> None:
    """Time as ISO stamps of 2022, the last one mistyped 2062."""
    path = bad_case(folder, "YEARTYPO", columns={"time": {"unit": "datetime"}})
    start = pd.Timestamp("2022-05-01T10:00:00")
    rows = read_rows(path)
    for r in rows[1:]:
        r[0] = (start + pd.Timedelta(seconds=float(r[0]))).strftime("%Y-%m-%dT%H:%M:%S.%f")
    rows[-1][0] = "2062" + rows[-1][0][4:]
    write_rows(path, rows)


def big_file(folder: Path, work: Path) -> None:
    """A case file grown past the size limit (config ingest.max_case_file_MB) by a long trailing comment."""
    with bad_case(folder, "BIGFILE").open("a", encoding="utf-8") as fh:
        fh.write(("# padding " + "x" * 89 + "\n") * int(3 * MAX_CASE_FILE_MB * 1e6 / 100))


def long_cell(folder: Path, work: Path) -> None:
    set_cell(bad_case(folder, "LONGCELL"), 100, 2, "7" * 200_000)


def absurd_force(folder: Path, work: Path) -> None:
    set_cell(bad_case(folder, "FORCE1E305"), 100, 2, "1e305")          # the force column is in kN


def gzip_renamed(folder: Path, work: Path) -> None:
    path = bad_case(folder, "GZIP")
    path.write_bytes(gzip.compress(path.read_bytes(), mtime=0))


def hostile_names(folder: Path, work: Path) -> None:
    """Stray names Snakemake would read as patterns, an unreferenced symlink to /etc/passwd, and case files in
    a subfolder and with braces in their name (all named by the manifest)."""
    for name in ("notes <old>.txt", "notes {old}.txt", "notes <results>.txt"):
        (folder / name).write_text("old notes\n", encoding="utf-8")
    (folder / "passwd.csv").symlink_to("/etc/passwd")
    (folder / "run1").mkdir()
    (folder / "T01.csv").rename(folder / "run1" / "T01.csv")
    (folder / "T03.csv").rename(folder / "T{03}.csv")
    doc = manifest(folder)
    for case in doc["cases"]:
        case["file"] = {"T01.csv": "run1/T01.csv", "T03.csv": "T{03}.csv"}.get(case["file"], case["file"])
    write_manifest(folder, doc)


def protected_outputs(folder: Path, work: Path) -> None:
    """Stale outputs of the campaign, write-protected (undone by the fixture); where this process cannot
    write-protect a file, a marker file says so and the input's test is skipped."""
    root = work / "results" / folder.name
    (root / "ingest").mkdir(parents=True)
    (root / "cases.parquet").write_bytes(b"stale")
    if not protect(root / "cases.parquet"):
        release(root / "cases.parquet")
        (work / UNPROTECTED).write_text(folder.name, encoding="utf-8")


def folder_outside(folder: Path, work: Path) -> None:
    """The campaign folder a symlink to a place outside data/raw/."""
    outside = work.parent / "outside" / folder.name
    outside.parent.mkdir(exist_ok=True)
    shutil.move(folder, outside)
    folder.symlink_to(outside)


def case_symlink_out(folder: Path, work: Path) -> None:
    (folder / "T02.csv").unlink()
    (folder / "T02.csv").symlink_to("/etc/passwd")


def thousand_cases(folder: Path, work: Path) -> None:
    doc = manifest(folder)
    template = next(c for c in doc["cases"] if c["id"] == "T02")
    doc["cases"] = [dict(template, id=f"C{i:04d}") for i in range(1000)]
    write_manifest(folder, doc)


@dataclass(frozen=True)
class Hostile:
    """One input of the issue: the campaign it goes into, how it is made, the case at fault (None: the campaign
    as a whole), what must come of it, and how far the campaign is built (``page``: everything; ``cases``:
    ingest to the characteristic; ``ingest``; ``refused``: its refusal)."""

    name: str
    campaign: str
    make: Callable[[Path, Path], None]
    case: str | None
    outcome: str        # "case set aside" (or "trimmed": kept, its quality says so) | "campaign fails" | "built"
    build: str


#: The case-level inputs share one campaign (each its own case beside the four good ones), so that it is built
#: once through every stage; the campaign-level ones have a campaign each.
CASES = "f-cases"
HOSTILE = [
    Hostile("1: 1e308 time stamp", CASES, last_time_1e308, "TIME1E308", "case set aside or trimmed", "page"),
    Hostile("1: ISO year typo", CASES, iso_year_typo, "YEARTYPO", "case set aside or trimmed", "page"),
    Hostile("3: file above the size limit", CASES, big_file, "BIGFILE", "case set aside", "page"),
    Hostile("4: 200,000-character cell", CASES, long_cell, "LONGCELL", "case set aside", "page"),
    Hostile("6: 1e305 kN force sample", CASES, absurd_force, "FORCE1E305", "case set aside", "page"),
    Hostile("10: gzip renamed .csv", CASES, gzip_renamed, "GZIP", "case set aside", "page"),
    Hostile("2: pattern names, stray symlink, subfolder", "f02-names", hostile_names, None, "built", "page"),
    Hostile("7: write-protected stale outputs", "f07-protected", protected_outputs, None, "campaign fails",
            "refused"),
    Hostile("8: campaign folder leading outside", "f08-folder-outside", folder_outside, None, "campaign fails",
            "refused"),
    Hostile("8: case file symlink to /etc/passwd", "f08-case-symlink", case_symlink_out, "T02",
            "case set aside or campaign fails", "ingest"),
    Hostile("9: 1,000 cases naming one file", "f09-thousand-cases", thousand_cases, None, "built", "ingest"),
]


# --- seeded random damage --------------------------------------------------------------------------

def random_damage(folder: Path, rng: np.random.Generator) -> list[str]:
    """One to three seeded mutations of time stamps, values, names or sizes; what was done."""
    done = []
    for _ in range(int(rng.integers(1, 4))):
        case = f"T0{int(rng.integers(1, 5))}"
        path = folder / f"{case}.csv"
        if not path.is_file():
            continue
        n = len(read_rows(path)) - 1
        kind = str(rng.choice(["time", "value", "name", "size"]))
        if kind == "time":
            value = str(rng.choice(["1e308", "-1e9", "nan", "0", "2022-13-01", "1e-300", "inf", "9" * 400]))
            set_cell(path, int(rng.integers(0, n)), 0, value)
        elif kind == "value":
            value = str(rng.choice(["1e305", "-1e305", "abc", "", "nan", "1e-320", "0x1F", "7" * 5000]))
            set_cell(path, int(rng.integers(0, n)), int(rng.integers(1, 4)), value)
        elif kind == "name":
            target = str(rng.choice([f"{case}.CSV", f"{case} {{x}}.csv", f"<{case}>.csv", f"{case}.csv.bak"]))
            path.rename(folder / target)
            value = target
        else:
            data = path.read_bytes()
            choice = str(rng.choice(["truncate", "repeat", "empty"]))
            cut = int(rng.integers(1, len(data)))
            path.write_bytes({"truncate": data[:cut], "repeat": data * 3, "empty": b""}[choice])
            value = choice
        done.append(f"{kind} {case}: {value[:20]}")
    return done


# --- the build ---------------------------------------------------------------------------------------

def tree_state(*roots: Path) -> dict[str, tuple]:
    """Every entry under ``roots``, symlinks not followed: its type, mode, size, mtime and sha256 (files) or
    target (symlinks)."""
    out = {}
    for root in roots:
        for top, dirs, files in os.walk(root, followlinks=False):
            for name in sorted(dirs + files):
                path = Path(top) / name
                st = os.lstat(path)
                if path.is_symlink():
                    what = os.readlink(path)
                elif path.is_file():
                    what = hashlib.sha256(path.read_bytes()).hexdigest()
                else:
                    what = ""
                out[path.as_posix()] = (st.st_mode, st.st_size, st.st_mtime_ns, what)
    return out


@dataclass
class Build:
    work: Path
    returncode: int
    output: str
    seconds: float
    max_rss_MB: float
    raw_before: dict
    raw_after: dict
    damage: dict[str, list[str]]


def limited_build(work: Path, targets: list[str]) -> tuple[subprocess.CompletedProcess, float]:
    """Snakemake under the address-space limit, in a child that reports its children's peak RSS (MB)."""
    code = ("import resource, subprocess, sys\n"
            f"resource.setrlimit(resource.RLIMIT_AS, ({ADDRESS_SPACE_BYTES}, {ADDRESS_SPACE_BYTES}))\n"
            "p = subprocess.run(sys.argv[1:])\n"
            "print('MAXRSS_KB', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr)\n"
            "sys.exit(p.returncode)\n")
    proc = subprocess.run([sys.executable, "-c", code, SNAKEMAKE, "--cores", "2", *targets], cwd=work,
                          capture_output=True, text=True, timeout=BUILD_TIMEOUT_S)
    rss = [line for line in proc.stderr.splitlines() if line.startswith("MAXRSS_KB ")]
    return proc, (int(rss[-1].split()[1]) / 1024 if rss else float("inf"))


#: How far each campaign is built (within the time budget: every stage for the good campaign, the one holding
#: the case-level inputs and the one with hostile names; the seeded damage up to the characteristic).
BUILDS = {GOOD: "page", **{h.campaign: h.build for h in HOSTILE}, **{f"random-{i}": "cases" for i in range(N_RANDOM)}}


def targets(campaign: str, how: str) -> list[str]:
    """The files that build ``campaign`` as far as ``how`` says (:class:`Hostile`)."""
    return {"page": [f"results/{campaign}/report.html", f"results/{campaign}/provenance.json"],
            "cases": [f"results/{campaign}/quarantine.parquet"],
            "ingest": [f"results/{campaign}/ingest"],
            "refused": [f"logs/_refused/{campaign}.txt"]}[how]


@pytest.fixture(scope="module")
def build(tmp_path_factory):
    """The scratch project with the good campaign, every hostile input and the random damage, built once. The
    run fails (refused campaigns), so the index is the one its failure handler rebuilds over every campaign."""
    base = tmp_path_factory.mktemp("fuzz")
    work = make_project(base / "project", CONFIG)
    raw = work / "data" / "raw"
    template = export_raw_campaign(VirtualCampaign.from_config("template", SPEC), base / "template")
    for name in BUILDS:
        shutil.copytree(template, raw / name)
        text = (raw / name / "campaign.yaml").read_text(encoding="utf-8")
        (raw / name / "campaign.yaml").write_text(text.replace("campaign: template", f"campaign: {name}"),
                                                  encoding="utf-8")
    for h in HOSTILE:
        h.make(raw / h.campaign, work)
    rng = np.random.default_rng(SEED)
    damage = {f"random-{i}": random_damage(raw / f"random-{i}", rng) for i in range(N_RANDOM)}
    before = tree_state(raw, base / "outside")
    start = time.monotonic()
    try:
        unprotected = (work / UNPROTECTED).read_text(encoding="utf-8") if (work / UNPROTECTED).is_file() else None
        plan = {c: "cases" if c == unprotected else how for c, how in BUILDS.items()}
        proc, rss = limited_build(work, [t for c, how in plan.items() for t in targets(c, how)])
    finally:
        for path in (work / "results").glob("*/cases.parquet"):
            release(path)
    seconds = time.monotonic() - start
    print(f"fuzz build: {seconds:.0f} s, peak RSS {rss:.0f} MB, exit {proc.returncode}")
    return Build(work, proc.returncode, proc.stdout + proc.stderr, seconds, rss, before,
                 tree_state(raw, base / "outside"), damage)


def index_row(build: Build, campaign: str) -> str:
    page = (build.work / "results" / "index.html").read_text(encoding="utf-8")
    start = page.index(f'id="campaign-{campaign}"')
    return " ".join(re.sub(r"<[^>]+>", " ", page[start:].split("</tr>")[0]).split())


def failure_lines(build: Build, campaign: str) -> list[str]:
    """The closing summary's lines for ``campaign``."""
    return [line.strip() for line in build.output.splitlines() if line.strip().startswith(f"campaign {campaign}: ")]


def read_table(build: Build, campaign: str, name: str) -> pd.DataFrame | None:
    try:
        return pd.read_parquet(build.work / "results" / campaign / name)
    except (OSError, ValueError):
        return None


def quarantine(build: Build, campaign: str) -> pd.DataFrame:
    table = read_table(build, campaign, "quarantine.parquet")
    return pd.DataFrame(columns=["campaign", "case", "reason"]) if table is None else table


def ingested_cases(build: Build, campaign: str) -> pd.DataFrame | None:
    """The cases table as far as the campaign was built (the characteristic's, else ingest's)."""
    for name in ("cases.parquet", "ingest/cases.parquet"):
        table = read_table(build, campaign, name)
        if table is not None:
            return table
    return None


def reasons_name_campaign_and_case(build: Build, campaign: str) -> None:
    """Every quarantine reason starts with its campaign and case and stays short; every failure line is short."""
    q = quarantine(build, campaign)
    for r in q.itertuples():
        assert r.campaign == campaign and str(r.reason).startswith(f"campaign {campaign}, case {r.case}"), r.reason
        assert len(str(r.reason)) <= 300, r.reason
    for line in failure_lines(build, campaign):
        assert len(line) <= 400, line


# --- the whole build ---------------------------------------------------------------------------------

def test_build_stays_within_its_time_and_memory(build):
    assert build.seconds < BUILD_TIMEOUT_S
    assert build.max_rss_MB < MAX_RSS_MB, f"peak RSS {build.max_rss_MB:.0f} MB"


def test_good_campaign_is_built_whatever_the_others_hold(build):
    root = build.work / "results" / GOOD
    for name in ("characteristic.parquet", "models/models.parquet", "diagnosis.json", "report.html",
                 "provenance.json"):
        assert (root / name).is_file(), f"{name} missing:\n{build.output[-3000:]}"
    assert set(pd.read_parquet(root / "cases.parquet")["status"]) == {"ok"}
    assert "failed" not in index_row(build, GOOD)


def test_raw_data_is_unchanged(build):
    assert build.raw_after == build.raw_before


def test_index_and_design_summary_are_built_and_list_every_campaign(build):
    assert (build.work / "results" / "design" / "plan_check.parquet").is_file()
    for campaign, how in BUILDS.items():
        row = index_row(build, campaign)
        if how == "page":
            assert (build.work / "results" / campaign / "report.html").is_file() or "failed" in row, row
        else:
            assert "failed" in row, row


def test_no_crash_outside_the_campaigns_own_jobs(build):
    for marker in ("ProtectedOutputException", "WildcardError", "UndefinedPathvarException", "MemoryError",
                   "could not be rebuilt"):
        assert marker not in build.output, marker
    assert build.returncode != 0 and "index.html rebuilt" in build.output, build.output[-3000:]


# --- each input ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("hostile", HOSTILE, ids=[h.name for h in HOSTILE])
def test_hostile_input_costs_its_case_or_its_campaign_alone_with_a_reason(build, hostile):
    campaign = hostile.campaign
    if hostile.make is protected_outputs and (build.work / UNPROTECTED).is_file():
        pytest.skip("no way to write-protect a file here")
    reasons_name_campaign_and_case(build, campaign)
    cases = ingested_cases(build, campaign)
    failed = failure_lines(build, campaign)
    if hostile.outcome == "campaign fails" or (cases is None and "campaign fails" in hostile.outcome):
        assert cases is None or hostile.build == "refused", cases
        assert failed and "failed" in index_row(build, campaign), build.output[-3000:]
        if hostile.case is not None:
            assert any(hostile.case in line for line in failed), failed
        return
    assert cases is not None, f"{campaign} not ingested: {failed}"
    status = cases.set_index("case")["status"]
    if hostile.case is None:
        assert set(status) == {"ok"}, status.to_dict()
        return
    row = cases.set_index("case").loc[hostile.case]
    if "trimmed" in hostile.outcome and row["status"] == "ok":
        assert "trimmed" in row["quality"] and row["n_samples"] < len(read_rows(
            build.work / "data" / "raw" / campaign / f"{hostile.case}.csv")) - 1, row.to_dict()
    else:
        assert row["status"] == "quarantined", row.to_dict()
        assert hostile.case in set(quarantine(build, campaign)["case"]) or hostile.build == "ingest"
    if campaign == CASES:
        assert (status[[f"T0{i}" for i in range(1, 5)]] == "ok").all(), status.to_dict()


def test_the_case_level_inputs_cost_their_cases_only(build):
    assert (build.work / "results" / CASES / "report.html").is_file(), failure_lines(build, CASES)
    cases = pd.read_parquet(build.work / "results" / CASES / "cases.parquet").set_index("case")
    ok = set(cases.index[cases["status"] == "ok"])
    trimmed = {h.case for h in HOSTILE if "trimmed" in h.outcome}
    assert {"T01", "T02", "T03", "T04"} <= ok <= {"T01", "T02", "T03", "T04"} | trimmed, cases["status"].to_dict()
    assert all("trimmed" in cases.loc[c, "quality"] for c in ok & trimmed)


def test_stray_names_and_symlinks_are_listed_as_unused_never_hashed(build):
    prov = json.loads((build.work / "results" / "f02-names" / "provenance.json").read_text(encoding="utf-8"))
    unused = {u["path"] for u in prov["raw"]["unused_files"]}
    folder = "data/raw/f02-names"
    assert unused == {f"{folder}/{n}" for n in ("notes <old>.txt", "notes {old}.txt", "notes <results>.txt",
                                                "passwd.csv")}
    page = (build.work / "results" / "f02-names" / "report.html").read_text(encoding="utf-8")
    assert "Not used" in page and "notes &lt;old&gt;.txt" in page and "passwd.csv" in page
    secret = hashlib.sha256(Path("/etc/passwd").read_bytes()).hexdigest().encode()
    for path in (build.work / "results").rglob("*"):
        if path.is_file() and not path.is_symlink():
            assert secret not in path.read_bytes(), path


def test_one_file_named_by_a_thousand_cases_is_warned_about(build):
    meta = json.loads((build.work / "results" / "f09-thousand-cases" / "ingest" / "campaign.json").read_text(
        encoding="utf-8"))
    assert any("T02.csv" in w for w in meta["warnings"]), meta["warnings"]


def test_gzip_and_long_cells_give_short_reasons_without_byte_dumps(build):
    q = quarantine(build, CASES).set_index("case")
    for case in ("GZIP", "LONGCELL"):
        for reason in q.loc[[case], "reason"]:
            assert len(reason) <= 250 and "\\x" not in reason and "7777777777" not in reason, reason


@pytest.mark.parametrize("i", range(N_RANDOM))
def test_random_damage_costs_its_campaign_at_most(build, i):
    campaign = f"random-{i}"
    reasons_name_campaign_and_case(build, campaign)
    cases = ingested_cases(build, campaign)
    if cases is None:
        assert failure_lines(build, campaign) and "failed" in index_row(build, campaign), build.damage[campaign]
    else:
        bad = set(cases["case"][cases["status"] != "ok"])
        assert bad <= set(quarantine(build, campaign)["case"]), build.damage[campaign]
