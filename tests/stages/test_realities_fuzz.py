"""Fuzz test of what real labs produce (issue 34, part 6), beside the hostile-input one (test_fuzz.py).

Each input of the issue is written from a good campaign (:mod:`stages.realities`: a triangle campaign and a crank
dyno's sine campaign, both from ``tests/rigfiles.py``), the damage placed by seeded randomness (which case, which
window, which row and cell) over several seeds, and the campaign run in-process as the ``ingest`` and
``characteristic`` rules run it (:func:`isokinetic.stages.ingest.ingest_campaign`,
:func:`isokinetic.stages.characteristic.write_characteristic`). Its outcome is checked against the good campaign's
own run, its clean twin:

- no silently wrong point: every characteristic point is a point of the twin (same case and segment), its force
  within ``Z_SE`` of the twin's standard errors and its velocity within ``VELOCITY_TOLERANCE``, or its case is set
  aside with a reason naming it (a record played backwards with its load cell upside down is, for a damper whose
  force has too little memory to tell, a faithful record of the mirrored damper: it is set aside or gives the
  mirrored twin's points, each the negated point of the other direction); a damaged temperature channel gives
  no temperature the twin does not have;
- no good window lost: where the damage leaves a window intact (none of its rows touched, its case not damaged
  whole), its point is there;
- no crash: nothing escapes ingest or the characteristic, and no campaign is refused whole for one case's damage;
- the index complete: every case of the manifest is in ``cases.parquet`` once, a case set aside has a reason
  naming it, and the index page (:func:`isokinetic.report.report_index.render_index`) counts them all;
- nothing under ``data/raw/`` is written.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import tree_hashes
from isokinetic.contracts.manifest import ManifestError
from isokinetic.report.report_index import render_index
from isokinetic.stages.characteristic import write_characteristic
from isokinetic.stages.ingest import ingest_campaign
from stages.realities import DAMAGES, Campaign, Damage, Windows, crank_base, load_yaml, triangle_base, windows_of

#: 96 runs of a second or less each: about 55 s of CPU in all, split over CI's two workers (pytest -n 2)
pytestmark = pytest.mark.slow

SEEDS = (0, 1, 2)
BASES = ("tri", "crank")
#: A point agrees with its twin within this many of the twin's standard errors: the damaged run drops or keeps a
#: sample or two of the twin's, which moves a mean by a small fraction of one standard error.
Z_SE = 3.0
#: ... and its velocity within this fraction of the twin's (a window's line fit, a sine's peak speed).
VELOCITY_TOLERANCE = 0.01
#: A damaged temperature channel may give no temperature, the manifest's, or the twin's within this.
TEMPERATURE_TOLERANCE_C = 1.0


@dataclass(frozen=True)
class Twin:
    """The good campaign's run: its characteristic, cases and windows."""

    characteristic: pd.DataFrame
    cases: pd.DataFrame
    windows: Windows


@dataclass(frozen=True)
class Outcome:
    """A damaged campaign's run: its tables, or what stopped it."""

    characteristic: pd.DataFrame | None = None
    cases: pd.DataFrame | None = None
    quarantine: pd.DataFrame | None = None
    stopped: str | None = None


def run(folder: Path, root: Path) -> Outcome:
    """Ingest and characteristic in-process, as the rules chain them; a refusal or an exception is recorded."""
    try:
        ingest_campaign(folder, root)
    except ManifestError as exc:
        return Outcome(stopped=f"the campaign was refused whole: {exc}")
    except Exception as exc:  # noqa: BLE001 - a crash is what the test reports
        return Outcome(stopped=f"ingest crashed: {type(exc).__name__}: {exc}")
    try:
        char = write_characteristic(root)
    except Exception as exc:  # noqa: BLE001
        return Outcome(stopped=f"the characteristic crashed: {type(exc).__name__}: {exc}")
    return Outcome(char, pd.read_parquet(root / "cases.parquet"), pd.read_parquet(root / "quarantine.parquet"))


@pytest.fixture(scope="module")
def good(tmp_path_factory) -> tuple[dict[str, Campaign], dict[str, Twin]]:
    """The two good campaigns and their clean runs (every case ok, nothing set aside)."""
    work = tmp_path_factory.mktemp("realities")
    bases = {"tri": triangle_base(), "crank": crank_base(work / "crank-writer")}
    twins = {}
    for name, campaign in bases.items():
        out = run(campaign.write(work / "data" / "raw" / name, name), work / "results" / name)
        assert out.stopped is None, out.stopped
        assert (out.cases["status"] == "ok").all() and out.quarantine.empty, out.quarantine["reason"].tolist()
        assert set(out.characteristic["case"]) == set(campaign.cases())
        assert np.isfinite(standard_error_N(out.characteristic)).all()
        twins[name] = Twin(out.characteristic, out.cases, windows_of(out.characteristic))
    return bases, twins


def standard_error_N(char: pd.DataFrame) -> np.ndarray:
    """Each point's standard error: ``force_se_N``, else its scatter over sqrt(samples) (test_real_rig_files)."""
    se = char["force_se_N"].to_numpy(float)
    fallback = char["force_std_N"].to_numpy(float) / np.sqrt(char["n_samples"].to_numpy(float))
    return np.where(np.isfinite(se), se, fallback)


def intact(twin: Twin, damage: Damage, case: str) -> list[tuple[int, int, int]]:
    """(segment, row_start, row_stop) of the twin's windows of ``case`` that the damage left intact."""
    if case in damage.whole:
        return []
    rows = damage.touched.get(case, set())
    pts = twin.characteristic[twin.characteristic["case"] == case].sort_values("segment")
    return [(int(p.segment), int(p.row_start), int(p.row_stop)) for p in pts.itertuples()
            if not any(p.row_start <= r < p.row_stop for r in rows)]


def mirrored_problems(twin: Twin, out: Outcome, case: str) -> list[str]:
    """A record of the mirrored damper (:func:`stages.realities.reversed_upside_down`) kept: every point is the
    negated point of a twin point of the other direction, within the tolerances of :func:`point_problems`."""
    want = twin.characteristic[twin.characteristic["case"] == case]
    se = pd.Series(standard_error_N(twin.characteristic), index=twin.characteristic.index)[want.index]
    problems = []
    for p in out.characteristic[out.characteristic["case"] == case].itertuples():
        other = want["direction"] != p.direction
        ok = other & (np.abs(p.force_N + want["force_N"]) <= Z_SE * se) \
            & (np.abs(p.velocity_m_s + want["velocity_m_s"]) <= VELOCITY_TOLERANCE * want["velocity_m_s"].abs())
        if not ok.any():
            problems.append(f"silently wrong: case {case} kept, played backwards and upside down, segment "
                            f"{p.segment}: {p.velocity_m_s:.5g} m/s, {p.force_N:.6g} N is no negated twin point "
                            f"of the other direction")
    return problems


def point_problems(twin: Twin, out: Outcome, damage: Damage, case: str) -> list[str]:
    """A status-ok case: every point its twin's within tolerance, every intact window's point there."""
    if damage.mirrored and case in damage.whole:
        return mirrored_problems(twin, out, case)
    want = twin.characteristic[twin.characteristic["case"] == case].set_index("segment")
    want_se = pd.Series(standard_error_N(twin.characteristic), index=twin.characteristic.index)
    got = out.characteristic[out.characteristic["case"] == case]
    problems = []
    for p in got.itertuples():
        if p.segment not in want.index:
            problems.append(f"silently wrong: case {case} has a point the twin has not (segment {p.segment}, "
                            f"{p.velocity_m_s:.5g} m/s, {p.force_N:.5g} N)")
            continue
        w = want.loc[p.segment]
        se = float(want_se[twin.characteristic.index[(twin.characteristic["case"] == case)
                                                      & (twin.characteristic["segment"] == p.segment)][0]])
        if abs(p.force_N - w.force_N) > Z_SE * se or \
                abs(p.velocity_m_s - w.velocity_m_s) > VELOCITY_TOLERANCE * abs(w.velocity_m_s):
            problems.append(f"silently wrong: case {case} segment {p.segment}: {p.velocity_m_s:.5g} m/s, "
                            f"{p.force_N:.6g} N (quality {p.quality!r}); twin {w.velocity_m_s:.5g} m/s, "
                            f"{w.force_N:.6g} N +- {se:.3g} N")
    have = set(got["segment"])
    problems += [f"good window lost: case {case} segment {seg} (rows {a}-{b} intact) has no point"
                 for seg, a, b in intact(twin, damage, case) if seg not in have]
    return problems


def temperature_problems(twin: Twin, out: Outcome, manifest: dict, case: str) -> list[str]:
    """A damaged temperature channel: the case's temperature is unknown, the manifest's, or the twin's."""
    got = out.cases.set_index("case").loc[case, "temperature_C"]
    want = twin.cases.set_index("case").loc[case, "temperature_C"]
    fine = pd.isna(got) or any(abs(got - t) <= TEMPERATURE_TOLERANCE_C for t in (want, manifest["temperature_C"]))
    return [] if fine else [f"silently wrong: case {case} is given {got:.4g} C from a temperature channel that is "
                            f"the command (twin: {want:.4g} C)"]


def index_problems(out: Outcome, root: Path, name: str, manifest: dict) -> list[str]:
    """Every case of the manifest in cases.parquet once, every one set aside with a reason naming it, and the
    index page counting them all."""
    ids = [str(c["id"]) for c in manifest["cases"]]
    problems = []
    if sorted(out.cases["case"]) != sorted(ids):
        problems.append(f"index incomplete: cases.parquet holds {sorted(out.cases['case'])}, manifest {ids}")
    for r in out.cases.itertuples():
        reasons = out.quarantine.loc[out.quarantine["case"] == r.case, "reason"].tolist()
        if r.status != "ok" and not any(f"case {r.case}" in s for s in reasons):
            problems.append(f"index: case {r.case} is {r.status!r} without a reason naming it: {reasons}")
    page = re.sub(r"<[^>]+>", " ", render_index(root.parent, [name]))
    n_ok = int((out.cases["status"] == "ok").sum())
    if name not in page or f"{n_ok} / {len(ids)}" not in re.sub(r"\s+", " ", page):
        problems.append(f"index: the page does not count {n_ok} / {len(ids)} cases of {name}")
    return problems


def outcome_problems(twin: Twin, out: Outcome, damage: Damage, root: Path, name: str, manifest: dict) -> list[str]:
    """Every property of the module docstring that the damaged run breaks, one line each."""
    if out.stopped is not None:
        return [out.stopped]
    problems = index_problems(out, root, name, manifest)
    status = out.cases.set_index("case")["status"]
    for case in (str(c["id"]) for c in manifest["cases"]):
        if status.get(case) != "ok":
            reasons = "; ".join(out.quarantine.loc[out.quarantine["case"] == case, "reason"])
            problems += [f"good window lost: case {case} set aside ({reasons}) although its segment {seg} "
                         f"(rows {a}-{b}) is intact" for seg, a, b in intact(twin, damage, case)]
            continue
        problems += point_problems(twin, out, damage, case)
        if damage.temperature:
            problems += temperature_problems(twin, out, manifest, case)
    return problems


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("base", BASES)
@pytest.mark.parametrize("reality", list(DAMAGES))
def test_reality_gives_no_wrong_point_and_keeps_every_good_window(good, tmp_path, reality, base, seed):
    bases, twins = good
    campaign = bases[base].copy()
    rng = np.random.default_rng([seed, list(DAMAGES).index(reality), BASES.index(base)])
    damage = DAMAGES[reality](campaign, twins[base].windows, rng)
    name = f"{base}-{reality.lower().replace('_', '-')}-{seed}"
    folder = campaign.write(tmp_path / "data" / "raw" / name, name)
    before = tree_hashes(folder)
    out = run(folder, tmp_path / "results" / name)
    problems = outcome_problems(twins[base], out, damage, tmp_path / "results" / name, name,
                                load_yaml(folder / "campaign.yaml"))
    if tree_hashes(folder) != before:
        problems.append("the run wrote under data/raw")
    assert not problems, f"{reality} in the {base} campaign, seed {seed}:\n  " + "\n  ".join(problems)
