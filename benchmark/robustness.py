"""Robustness table: damage a good raw campaign in every way we know, run ingest + validate, count.

    .venv/bin/python benchmark/robustness.py [--keep DIR]

A small good campaign is exported with the virtual rig (``python -m isokinetic export-virtual``,
config campaign ``lag-damper-backlash``, cases T01, T03, H01). Each damage kind is applied to a
fresh copy in its own working directory (``data/raw/<campaign>/``), then ingest and validate run
in-process, exactly as the pipeline's two rules call them. Per kind:

* manifest kinds (hostile or broken ``campaign.yaml``) are *caught* when ``ManifestError`` is raised
  (the campaign is refused as a whole, nothing is written);
* data kinds (one damaged case file) are *caught* when the damaged case is quarantined;
  *good cases lost* counts the undamaged cases that did not come out ``ok`` (must be 0);
* *raw bytes changed* counts files under ``data/raw/`` whose sha256 after the run differs from
  before it (must be 0).

Prints one row per kind and a summary; exits 1 when a kind is not caught, a good case is lost or a
raw byte changed. Damage helpers: this script defines its own (tests/conftest.py holds none that fit
a virtual-rig export at the time of writing).
"""

from __future__ import annotations

import argparse
import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from isokinetic.contracts.manifest import MAX_CASES, MAX_MANIFEST_BYTES, ManifestError  # noqa: E402
from isokinetic.stages.ingest import ingest_campaign  # noqa: E402
from isokinetic.stages.validate import write_validated  # noqa: E402

CONFIG_CAMPAIGN = "lag-damper-backlash"
CASES = ("T01", "T03", "H01")
NAME = "robust"          # campaign id of the exported copy


# --------------------------------------------------------------------------------------------
# damage kinds: fn(raw_dir) edits the campaign folder in place
# --------------------------------------------------------------------------------------------

def _text(p: Path) -> str:
    return p.read_text(encoding="utf-8")


def _yaml(raw: Path, old: str, new: str, count: int = 1) -> None:
    p = raw / "campaign.yaml"
    text = _text(p)
    if old not in text:
        raise RuntimeError(f"damage helper: {old!r} not in campaign.yaml")
    p.write_text(text.replace(old, new, count), encoding="utf-8")


def _append_yaml(raw: Path, text: str) -> None:
    p = raw / "campaign.yaml"
    p.write_text(_text(p) + text, encoding="utf-8")


def _lines(raw: Path, case: str, edit) -> None:
    p = raw / f"{case}.csv"
    lines = _text(p).splitlines(keepends=True)
    p.write_text("".join(edit(lines)), encoding="utf-8")


def _cell(case: str, row: int, col: int, value: str):
    def edit(lines):
        cells = lines[row + 1].rstrip("\n").split(",")
        cells[col] = value
        lines[row + 1] = ",".join(cells) + "\n"
        return lines
    return lambda raw: _lines(raw, case, edit)


def _symlink_outside(raw: Path) -> None:
    outside = raw.parent.parent / "outside.csv"
    shutil.copy(raw / "T03.csv", outside)
    (raw / "T03.csv").unlink()
    (raw / "T03.csv").symlink_to(outside.resolve())


BILLION_LAUGHS = "".join(
    [f"lol0: &l0 [{','.join(['lol'] * 9)}]\n"]
    + [f"lol{k}: &l{k} [{','.join([f'*l{k - 1}'] * 9)}]\n" for k in range(1, 9)])


def _many_cases(raw: Path) -> None:
    entries = "".join(f"- id: X{k}\n  waveform: free\n  file: X{k}.csv\n" for k in range(MAX_CASES + 1))
    p = raw / "campaign.yaml"
    text = _text(p)
    p.write_text(text[:text.index("\ncases:\n")] + "\ncases:\n" + entries, encoding="utf-8")


#: (kind, words the refusal must contain, function): caught = ManifestError with these words
MANIFEST_DAMAGE = [
    ("YAML syntax error", 'invalid YAML at line',
     lambda r: _append_yaml(r, "broken: [unclosed\n")),
    ("empty manifest", 'empty file',
     lambda r: (r / "campaign.yaml").write_text("")),
    ("unknown format_version", "key 'format_version'",
     lambda r: _yaml(r, "format_version: 1", "format_version: 7")),
    ("campaign id differs from folder", "key 'campaign'",
     lambda r: _yaml(r, f"campaign: {NAME}", "campaign: someone-else")),
    ("duplicate case id", 'duplicate case id',
     lambda r: _yaml(r, "- id: T03", "- id: T01")),
    ("file name with a path separator", "key 'cases.T03.file'",
     lambda r: _yaml(r, "file: T03.csv", "file: sub/T03.csv")),
    ("file name with ..", "key 'cases.T03.file'",
     lambda r: _yaml(r, "file: T03.csv", "file: ../T03.csv")),
    ("absolute file path", "key 'cases.T03.file'",
     lambda r: _yaml(r, "file: T03.csv", "file: /etc/passwd")),
    ("symlink leading outside the folder", 'outside the campaign folder',
     _symlink_outside),
    ("YAML tag constructing an object", "tag '!!python/object/apply:os.system' is not allowed",
     lambda r: _append_yaml(r, "x: !!python/object/apply:os.system [id]\n")),
    ("alias bomb (billion laughs)", 'anchor &l0 is not allowed',
     lambda r: _append_yaml(r, BILLION_LAUGHS)),
    ("duplicate YAML key", "key 'sample_rate_Hz': invalid YAML",
     lambda r: _append_yaml(r, "sample_rate_Hz: 5.0\n")),
    ("absurd sample rate", "key 'sample_rate_Hz': 1e+12 is above",
     lambda r: _yaml(r, "sample_rate_Hz: 100.0", "sample_rate_Hz: 1.0e+12")),
    ("absurd period", "key 'cases.T03.period_s'",
     lambda r: _yaml(r, "period_s: 20.0", "period_s: 1.0e+9")),
    ("absurd amplitude", "key 'cases.T03.amplitude_mm'",
     lambda r: _yaml(r, "amplitude_mm: 2.5", "amplitude_mm: 2.5e+6")),
    ("record needing > 1e7 samples", 'samples (40 s at 900000 Hz)',
     lambda r: _yaml(r, "duration_s: 40.0", "duration_s: 40.0\n  sample_rate_Hz: 900000.0")),
    ("too many cases", "key 'cases': 1001 cases",
     _many_cases),
    ("manifest > 1 MB", 'bytes a manifest may have',
     lambda r: _append_yaml(r, "# " + "x" * MAX_MANIFEST_BYTES + "\n")),
]

#: (kind, damaged case, function): caught = that case quarantined, the others ok
DATA_DAMAGE = [
    ("file missing", "T03", lambda r: (r / "T03.csv").unlink()),
    ("empty file", "T03", lambda r: (r / "T03.csv").write_text("")),
    ("binary garbage", "T03", lambda r: (r / "T03.csv").write_bytes(bytes(range(256)) * 64)),
    ("not UTF-8", "T03", lambda r: (r / "T03.csv").write_bytes(
        (r / "T03.csv").read_bytes().replace(b"time_s", b"t\xe9me_s", 1))),
    ("truncated mid-line", "T03", lambda r: (r / "T03.csv").write_bytes((r / "T03.csv").read_bytes()[:20_017])),
    ("column renamed", "T03", lambda r: _lines(r, "T03", lambda ls: [ls[0].replace("force_kN", "force")] + ls[1:])),
    ("non-numeric cell", "T03", _cell("T03", 1500, 2, "abc")),
    ("empty cell", "T03", _cell("T03", 1500, 2, "")),
    ("NaN cell", "T03", _cell("T03", 1500, 1, "nan")),
    ("inf cell", "T03", _cell("T03", 1500, 2, "inf")),
    ("time not increasing", "T03", lambda r: _lines(r, "T03", lambda ls: ls[:1000] + [ls[1001], ls[1000]] + ls[1002:])),
    ("record shorter than plan", "T03", lambda r: _lines(r, "T03", lambda ls: ls[:2001])),
    ("rows missing (gap in windows)", "T03", lambda r: _lines(r, "T03", lambda ls: ls[:1500] + ls[1600:])),
    ("sample rate off", "T03", lambda r: _lines(r, "T03", lambda ls: [ls[0]] + [
        ",".join([f"{float(line.split(',')[0]) * 2:.2f}"] + line.split(",")[1:]) for line in ls[1:]])),
    ("unit mix-up (kN written as N)", "T03", lambda r: _lines(r, "T03", lambda ls: [ls[0]] + [
        ",".join(c[:2] + [f"{float(c[2]) * 1e3:.4f}"] + c[3:]) for c in (line.split(",") for line in ls[1:])])),
    ("saturated force (flat top)", "T03", lambda r: _lines(r, "T03", lambda ls: [ls[0]] + [
        ",".join(c[:2] + [f"{min(float(c[2]), 0.0):.4f}"] + c[3:]) for c in (line.split(",") for line in ls[1:])])),
    ("header only", "T03", lambda r: _lines(r, "T03", lambda ls: ls[:1])),
]


def tree_hashes(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def export(work: Path) -> Path:
    out = work / "pristine" / NAME
    subprocess.run([sys.executable, "-m", "isokinetic", "export-virtual", "--config", str(ROOT / "config/config.yaml"),
                    "--campaign", CONFIG_CAMPAIGN, "--cases", ",".join(CASES), "--out", str(out)],
                   check=True, stdout=subprocess.DEVNULL, cwd=ROOT)
    return out


def run_one(pristine: Path, work: Path, damage) -> dict:
    """Copy, damage, run ingest + validate in ``work``; outcome of the run."""
    raw = work / "data" / "raw" / NAME
    shutil.copytree(pristine, raw)
    if damage is not None:
        damage(raw)
    before = tree_hashes(work / "data" / "raw")
    cwd = os.getcwd()
    os.chdir(work)
    out = {"error": None, "manifest_error": None, "status": {}}
    t0 = time.perf_counter()
    try:
        ingest_campaign(Path("data/raw") / NAME, Path("results") / NAME)
        cases, _ = write_validated(Path("results") / NAME)
        out["status"] = dict(zip(cases["case"], cases["status"]))
    except ManifestError as exc:
        out["manifest_error"] = str(exc)
    except Exception as exc:  # noqa: BLE001 - a crash is a finding
        out["error"] = f"{type(exc).__name__}: {exc}".splitlines()[0][:200]
        out["traceback"] = traceback.format_exc()
    finally:
        os.chdir(cwd)
    out["seconds"] = time.perf_counter() - t0
    out["raw_changed"] = sum(1 for k, v in tree_hashes(work / "data" / "raw").items() if before.get(k) != v) + len(
        set(before) - set(tree_hashes(work / "data" / "raw")))
    out["results_written"] = (work / "results" / NAME).exists()
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--keep", help="work in this folder and keep it (default: a temporary folder)")
    parser.add_argument("-v", "--verbose", action="store_true", help="print the message of each refusal")
    args = parser.parse_args(argv)
    if not args.verbose:   # the quarantine log lines; the table says it all
        logging.getLogger("isokinetic").setLevel(logging.CRITICAL)
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="isokinetic-robustness-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        pristine = export(work)
        base = run_one(pristine, work / "baseline", None)
        if base["error"] or base["manifest_error"] or set(base["status"].values()) != {"ok"}:
            print(f"the good campaign does not pass unharmed: {base}")
            return 1
        rows = []
        for k, (kind, words, damage) in enumerate(MANIFEST_DAMAGE):
            r = run_one(pristine, work / f"m{k:02d}", damage)
            caught = r["manifest_error"] is not None and words in r["manifest_error"] and not r["results_written"]
            rows.append(("manifest", kind, caught, 0, r))
        for k, (kind, case, damage) in enumerate(DATA_DAMAGE):
            r = run_one(pristine, work / f"d{k:02d}", damage)
            caught = r["status"].get(case) == "quarantined"
            lost = 0 if r["error"] or r["manifest_error"] else sum(
                1 for c in CASES if c != case and r["status"].get(c) != "ok")
            if r["error"] or r["manifest_error"]:   # the whole campaign lost: its good cases too
                lost = len(CASES) - 1
            rows.append(("data", kind, caught, lost, r))
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)

    print(f"Robustness of ingest + validate on a copy of '{CONFIG_CAMPAIGN}' ({', '.join(CASES)}), "
          "one damage per run\n")
    print(f"{'category':9} {'damage kind':36} {'caught':7} {'good lost':9} {'raw changed':11} outcome")
    for category, kind, caught, lost, r in rows:
        if r["error"]:
            outcome = f"CRASH {r['error']}"
        elif r["manifest_error"]:
            said = r["manifest_error"]
            outcome = "refused: " + (said if args.verbose else said.split(": ", 1)[1][:90])
        else:
            outcome = ", ".join(f"{c} {s}" for c, s in r["status"].items())
        print(f"{category:9} {kind:36} {'yes' if caught else 'NO':7} {lost:<9d} {r['raw_changed']:<11d} {outcome}")
    n_caught = sum(1 for row in rows if row[2])
    lost = sum(row[3] for row in rows)
    changed = sum(row[4]["raw_changed"] for row in rows)
    n_manifest = sum(1 for row in rows if row[0] == "manifest")
    print()
    print("| figure | value | target |")
    print("|---|---|---|")
    print(f"| damage kinds tried | {len(rows)} ({n_manifest} manifest, {len(rows) - n_manifest} data) | |")
    print(f"| damage kinds caught | {n_caught} | {len(rows)} |")
    print(f"| good cases lost | {lost} | 0 |")
    print(f"| raw bytes changed (files under data/raw/ whose sha256 changed) | {changed} | 0 |")
    print("| interrupted runs recovered | not measured by this script (see the kill test of the workflow) | |")
    return 0 if (n_caught == len(rows) and lost == 0 and changed == 0) else 1


if __name__ == "__main__":
    sys.exit(main())
