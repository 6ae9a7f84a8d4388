"""Reports for people: the campaign page and the index, their content, lineage and self-containment,
and (in headless Chromium) that every figure loads.

The results tree is made here, small and schema-valid (pandera schemas of isokinetic.tables, the
diagnosis JSON schema, the real model fit), so the pages are tested without running the pipeline.
"""

from __future__ import annotations

import base64
import os
import re
import struct
import zlib
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from isokinetic import report, tables
from isokinetic.damper import Damper
from isokinetic.diagnosis import validate_diagnosis
from isokinetic.io import write_json, write_parquet
from isokinetic.lineage import stage_lineage, stamp_json, stamp_parquet
from isokinetic.models import comparison_table, fit_models

CAMPAIGN = "demo"
DAMPER = {"piston_area_m2": 4.0e-3, "chamber_volume_1_m3": 3.0e-4, "chamber_volume_2_m3": 3.0e-4,
          "orifice_area_m2": 6.0e-8, "orifice_length_m": 5.0e-4, "discharge_coefficient": 0.6,
          "density_kg_m3": 815.0, "viscosity_Pa_s": 0.03, "oil_compressibility_1_Pa": 3.8e-9}
SPEEDS = {"T01": 1.0e-5, "T02": 1.0e-4, "T03": 1.0e-3}
QUARANTINE_REASON = "campaign demo, case T04, column 'force_kN', row 12: 'abc' is not a number"
PLAN_REASON = "window starts after 2.39 mm of stroke (0.45 T/2), before the 2.89 mm needed (Eq. 28)"
COMMIT = "0123456789abcdef0123456789abcdef01234567"
#: Measured motion of the cases (validate): T02 starts 23.4 ms late on a time axis offset by 7.3 s.
MOTION_NONE = {"motion_start_s": 0.0, "delay_s": 0.0, "velocity_ratio": 1.0002, "motion_rms_m": 1.0e-6, "quality": "ok"}
TIME_NOTE = "time axis offset: the motion starts at t = 7.3234 s of the record"
MOTION = {"T02": {"motion_start_s": 7.3234, "delay_s": 0.0234, "velocity_ratio": 0.9987, "motion_rms_m": 1.2e-6,
                  "quality": TIME_NOTE}}
PROV_COMMIT = "feedc0defeedc0defeedc0defeedc0defeedc0de"
CI = os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


def tiny_png(rgb: tuple[int, int, int], size: int = 4) -> bytes:
    """A valid size x size PNG of one colour (no image library needed)."""
    def chunk(kind: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))
    raw = b"".join(b"\0" + bytes(rgb) * size for _ in range(size))
    return (report.PNG_SIGNATURE + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def record(rule: str, commit: str = COMMIT) -> dict:
    rec = stage_lineage(rule, {"tolerance": 0.05}, [], campaign=CAMPAIGN)
    rec.update(git_commit=commit, git_dirty=False)
    return rec


def characteristic() -> pd.DataFrame:
    rows = []
    for case, w in SPEEDS.items():
        for segment, direction, period in ((1, "+", 1), (2, "-", 1), (3, "+", 2), (4, "-", 2)):
            v = w if direction == "+" else -w
            f = np.sign(v) * (150.0 + 4.0e5 * w + 2.0e9 * w * w) * (1 + 0.002 * period + 0.001 * segment)
            start = 100 * segment
            rows.append({"campaign": CAMPAIGN, "case": case, "segment": segment, "direction": direction,
                         "period": period, "planned_velocity_m_s": v, "velocity_m_s": v * 1.0001, "force_N": f,
                         "force_std_N": 5.0, "n_samples": 50, "window_start_s": start / 10,
                         "window_end_s": (start + 50) / 10, "row_start": start, "row_stop": start + 50,
                         "raw_file": f"data/raw/demo/{case}.csv", "raw_sha256": "ab" * 32,
                         "repeatability_flagged": case == "T03" and direction == "-"})
    return tables.validate_table(pd.DataFrame(rows), tables.CHARACTERISTIC)


def diagnosis() -> dict:
    d = {"format_version": 1, "campaign": CAMPAIGN, "status": "ok", "metric": "rms_z", "gap_before": 52.5,
         "gap_after": 0.98, "holdout_gap_after": 1.07, "shrink": 53.57, "verdict": ["friction"], "explained": True,
         "params": {"coulomb_force_N": 149.7},
         "identifiability": {"identifiable": True, "correlation": {},
                             "parameters": {"coulomb_force_N": {"estimate": 149.7, "std_error": 0.31,
                                                                "relative_std_error": 0.002}}},
         "where": [{"direction": "+", "v_min_m_s": 1e-5, "v_max_m_s": 1e-4, "mean_rel_error": -0.4321,
                    "mean_z": -17.5, "n_cases": 2, "significant": True}],
         "candidates": [
             {"effects": ["friction"], "params": {"coulomb_force_N": 149.7}, "gap_after": 0.98,
              "holdout_gap_after": 1.07, "score": 14.2, "explained": True},
             {"effects": ["leakage"], "params": {"leakage_conductance_m3_s_Pa": 1.3e-12}, "gap_after": 7.7,
              "holdout_gap_after": 7.9, "score": 4051.0, "explained": False}],
         "confounded": [["friction", "air"]],
         "instrument": {"delay_s": 0.0123, "force_offset_N": 4.56, "force_gain": None},
         "rms_rel_before": 0.41, "rms_rel_after": 0.004}
    validate_diagnosis(d)
    return d


def build_campaign(root: Path, *, damper: bool = True, stamp: bool = True) -> Path:
    """results/<campaign>/ with every table and figure a campaign page reads."""
    meta = {"format_version": 1, "campaign": root.name, "source": "rig", "description": "Report fixture campaign",
            "temperature_C": 40.0, "damper": DAMPER if damper else None, "manifest_file": "data/raw/demo/campaign.yaml",
            "manifest_sha256": "cd" * 32, "metadata": {}}
    write_json(meta, root / "ingest" / "campaign.json")
    cases = pd.DataFrame([
        {"campaign": CAMPAIGN, "case": c, "waveform": "triangle", "sample_rate_Hz": 50.0, "amplitude_m": w * 10,
         "period_s": 40.0, "frequency_Hz": np.nan, "phase_rad": -np.pi / 2, "duration_s": 80.0,
         "raw_file": f"data/raw/demo/{c}.csv", "raw_sha256": "ab" * 32, "timeseries_file": f"ingest/timeseries/{c}.parquet",
         "n_samples": 4000, "status": "ok", **MOTION.get(c, MOTION_NONE)} for c, w in SPEEDS.items()]
        + [{"campaign": CAMPAIGN, "case": "T04", "waveform": "triangle", "sample_rate_Hz": 50.0, "amplitude_m": 0.01,
            "period_s": 20.0, "frequency_Hz": np.nan, "phase_rad": 0.0, "duration_s": 40.0,
            "raw_file": "data/raw/demo/T04.csv", "raw_sha256": "ef" * 32, "timeseries_file": "", "n_samples": 0,
            "status": "quarantined", "motion_start_s": np.nan, "delay_s": np.nan, "velocity_ratio": np.nan,
            "motion_rms_m": np.nan, "quality": "quarantined"}])
    write_parquet(tables.validate_table(cases, tables.CASES), root / "cases.parquet")
    quarantine = pd.DataFrame({"campaign": [CAMPAIGN], "case": ["T04"], "stage": ["validate"], "column": ["force_kN"],
                               "row": pd.array([12], dtype="Int64"), "reason": [QUARANTINE_REASON]})
    write_parquet(tables.validate_table(quarantine, tables.QUARANTINE), root / "quarantine.parquet")
    char = characteristic()
    write_parquet(char, root / "characteristic.parquet")
    rep = pd.DataFrame([{"campaign": CAMPAIGN, "case": c, "direction": d, "velocity_m_s": w if d == "+" else -w,
                         "force_period1_N": 100.0, "force_period2_N": 108.1 if (c, d) == ("T03", "-") else 100.1,
                         "rel_diff": 0.0778 if (c, d) == ("T03", "-") else 0.001, "tolerance": 0.05,
                         "flagged": (c, d) == ("T03", "-")} for c, w in SPEEDS.items() for d in "+-"])
    write_parquet(tables.validate_table(rep, tables.REPEATABILITY), root / "repeatability.parquet")
    plan = pd.DataFrame([{"campaign": CAMPAIGN, "case": c, "waveform": "triangle", "status": "ok", "velocity_m_s": w,
                          "period_s": 40.0, "amplitude_m": w * 10, "G1": 10.0, "G2": 20.0, "G3": 4321.0,
                          "stroke_to_converge_m": 2.89e-3 if c == "T03" else 1e-5, "window_start_stroke_m": 2.39e-3,
                          "flagged": c == "T03", "reasons": PLAN_REASON if c == "T03" else ""}
                         for c, w in SPEEDS.items()])
    write_parquet(tables.validate_table(plan, tables.PLAN_CHECK), root / "design" / "plan_check.parquet")
    models, _ = fit_models(char, Damper.from_mapping(DAMPER) if damper else None)
    write_parquet(models, root / "models" / "models.parquet")
    write_parquet(comparison_table(char, None, models, None), root / "models" / "comparison.parquet")
    harmonic = pd.DataFrame([{"campaign": CAMPAIGN, "case": "H01", "waveform": "sine", "kind": "peak_to_peak",
                              "direction": d, "velocity_m_s": s * 2.527e-3, "force_N": s * 5539.8, "n_points": 8,
                              "lag_s": 0.0953, "frequency_Hz": 1.75, "amplitude_m": 2.3e-4} for d, s in (("+", 1), ("-", -1))])
    write_parquet(tables.validate_table(harmonic, tables.HARMONIC), root / "harmonic" / "harmonic.parquet")
    write_json(diagnosis() if damper else {"format_version": 1, "campaign": CAMPAIGN, "status": "not_diagnosed",
                                           "reason": "campaign.yaml has no damper block: there is no nominal model"},
               root / "diagnosis.json")
    for k, (rel, _) in enumerate(report.CAMPAIGN_FIGURES):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(tiny_png((20 * k, 100, 200 - 10 * k)))
    if stamp:
        stamp_parquet(root / "characteristic.parquet", record("characteristic"))
        stamp_parquet(root / "models" / "models.parquet", record("models"))
        stamp_json(root / "diagnosis.json", record("diagnosis"))
        fig09 = record("figures", PROV_COMMIT)  # provenance.json's per-file index (isokinetic.provenance)
        outputs = {f"results/{root.name}/figures/fig09_characteristic.png": {
            k: fig09[k] for k in ("rule", "created_utc", "params_sha256", "git_commit", "git_dirty")}}
        write_json({"format_version": 1, "campaign": root.name, "created_utc": "2026-11-21T08:00:00Z",
                    "git": {"commit": PROV_COMMIT, "dirty": False}, "outputs": outputs,
                    "checks": {"ok": False, "changed_raw_files": [], "missing_raw_files": [],
                               "stale_stages": ["models"], "inconsistent_stages": [], "files_without_lineage": []}},
                   root / "provenance.json")
    return root


def build_blind(root: Path) -> Path:
    summary = {"format_version": 1, "all_pass": False, "n_scenarios": 4, "n_single": 2, "n_pairs": 1, "n_none": 1,
               "n_errors": 0, "exact_rate": 0.75,
               "bins": {"1-2x": {"n": 2, "exact": 1, "rate": 0.5, "n_single": 1, "exact_single": 1, "rate_single": 1.0},
                        "2-3x": {"n": 1, "exact": 1, "rate": 1.0, "n_single": 1, "exact_single": 1, "rate_single": 1.0}},
               "targets": {"a_single_at_2x": {"description": "single-effect scenarios at >= 2x detection attributed "
                                                             "exactly", "exact": 1, "n": 1, "rate": 1.0, "threshold": 0.95,
                                              "pass": True, "misses": []},
                           "b_none_clean": {"description": "no effect claimed on any scenario without effects",
                                            "claimed": 0, "n": 1, "pass": True, "misses": []},
                           "c_median_shrink": {"description": "median shrink where an effect was present",
                                               "median": 3.21, "n": 3, "threshold": 5.0, "pass": False}}}
    write_json(summary, root / "summary.json")
    scores = pd.DataFrame({"scenario": ["blind-000", "blind-001", "blind-002", "blind-003"],
                           "truth": ["air", "", "friction+leakage", "leakage"],
                           "verdict": ["air", "", "friction", "leakage"], "exact": [True, True, False, True],
                           "magnitude_x_detection": [2.3, np.nan, 1.2, 1.5], "magnitude_bin": ["2-3x", "", "1-2x", "1-2x"],
                           "gap_before": [2.45, 0.99, 12.6, 4.1], "gap_after": [0.93, 0.99, 3.9, 0.93],
                           "shrink": [2.64, 1.0, 3.21, 4.4], "error": ["", "", "", ""]})
    write_parquet(scores, root / "scores.parquet")
    (root / "fig17_blind_confusion.png").write_bytes(tiny_png((0, 0, 0)))
    return root


@pytest.fixture
def results(tmp_path, monkeypatch) -> Path:
    """results/ with one campaign and the blind suite; cwd is tmp_path (paths as in the pipeline)."""
    monkeypatch.chdir(tmp_path)
    build_campaign(Path("results", CAMPAIGN))
    build_blind(Path("results", "blind"))
    return Path("results")


@pytest.fixture
def built(results) -> Path:
    report.write_campaign_report(results / CAMPAIGN, results / CAMPAIGN / "report.html")
    report.write_index(results, results / "index.html", [CAMPAIGN], blind_dir=results / "blind")
    return results


class Cells(HTMLParser):
    """Every <td class="num"> (its title and text), <img> and <a href> of a page."""

    def __init__(self):
        super().__init__()
        self.cells, self.images, self.links, self._td = [], [], [], None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "td" and "num" in (a.get("class") or "").split():
            self._td = {"title": a.get("title"), "text": ""}
        elif tag == "img":
            self.images.append(a)
        elif tag == "a":
            self.links.append(a.get("href"))

    def handle_data(self, data):
        if self._td is not None:
            self._td["text"] += data

    def handle_endtag(self, tag):
        if tag == "td" and self._td is not None:
            self.cells.append(self._td)
            self._td = None


def parse(page: str) -> Cells:
    p = Cells()
    p.feed(page)
    return p


def plain(page: str) -> str:
    """The page's text with tags removed and entities decoded (to look for numbers)."""
    import html
    return html.unescape(re.sub(r"<[^>]+>", "", page))


# ----------------------------------------------------------------------------------------------
# the campaign page
# ----------------------------------------------------------------------------------------------

def test_campaign_page_embeds_every_figure_and_nothing_external(built):
    root = built / CAMPAIGN
    page = (root / "report.html").read_text(encoding="utf-8")
    assert report.page_problems(page, report.campaign_figure_files()) == []
    images = {Path(a["data-file"]).name: a["src"] for a in parse(page).images}
    assert sorted(images) == sorted(report.campaign_figure_files())
    for rel, _ in report.CAMPAIGN_FIGURES:  # each figure is the file's own bytes, base64 in the page
        assert base64.b64decode(images[Path(rel).name].split(",", 1)[1]) == (root / rel).read_bytes()
    assert "<link" not in page and "http://" not in page and "https://" not in page
    assert "<style>" in page and 'data-images-total' in page


def test_campaign_page_shows_the_numbers(built):
    root = built / CAMPAIGN
    text = plain((root / "report.html").read_text(encoding="utf-8"))
    models = pd.read_parquet(root / "models" / "models.parquet")
    fc = models[(models["model"] == "wallaschek") & (models["parameter"] == "F_C")].iloc[0]
    d = diagnosis()
    expected = [
        "Report fixture campaign", "rig", "40.00",                                # header
        report.fmt_text(DAMPER["orifice_area_m2"]).split("e")[0],               # damper data
        PLAN_REASON, "T03",                                                      # plan check
        report.fmt_text(fc["estimate"]), report.fmt_text(fc["ci_low"]), report.fmt_text(fc["ci_high"]),
        report.fmt_text(models.loc[models["kind"] == "derived", "estimate"].iloc[0]).split("e")[0],
        "7.78 %",                                                                # flagged repeatability pair
        "friction", report.fmt_text(d["gap_before"]), report.fmt_text(d["gap_after"]),
        report.fmt_text(d["holdout_gap_after"]), report.fmt_text(d["shrink"]), "-43.2 %",   # diagnosis
        "friction, air", "Confounded",                                           # confounded group
        QUARANTINE_REASON,                                                       # quarantine
        report.fmt_text(5539.8), "0.0953",                                       # harmonic
        report.fmt_text(characteristic()["force_N"].iloc[0]),                    # a characteristic point
        "delay [ms]", "motion start [s]", "23.4", "7.3234", "0.9987", TIME_NOTE,  # cases: measured motion
    ]
    missing = [e for e in expected if e not in text]
    assert not missing, missing
    for section in ("header", "plan", "cases", "characteristic", "repeatability", "models", "harmonic", "design",
                    "diagnosis", "quarantine", "lineage"):
        assert f'<section id="{section}">' in (root / "report.html").read_text(encoding="utf-8")


def test_every_number_cell_names_its_file_rule_and_audit_command(built):
    page = (built / CAMPAIGN / "report.html").read_text(encoding="utf-8")
    cells = parse(page).cells
    assert len(cells) > 100
    for cell in cells:
        title = cell["title"] or ""
        source = re.search(r"results/demo/(\S+\.(?:parquet|json))", title)
        assert source and "rule " in title, cell
        # a value of a table trace re-derives carries the command that audits its row / key path
        if Path(source.group(1)).name in report.TRACEABLE and "counted by" not in title:
            assert f"audit: python -m isokinetic trace results/demo/{source.group(1)} " in title, cell
    # a characteristic point: its raw file and row range, the stamped record's commit and params hash
    point = next(c for c in cells if "characteristic.parquet [case=T01,segment=1]" in c["title"])
    params_sha = record("characteristic")["params_sha256"]
    assert "raw data/raw/demo/T01.csv rows 100-150" in point["title"]
    assert f"commit {COMMIT[:10]}" in point["title"] and f"params {params_sha[:10]}" in point["title"]
    assert "rule characteristic" in point["title"]
    # a fitted parameter: the rows the fit used; an unstamped table: said so, with its rule
    fc = next(c for c in cells if "model=wallaschek,direction=both,parameter=F_C" in c["title"])
    assert "fitted on 12 rows (case/segment)" in fc["title"] and "T01/1" in fc["title"]
    rep = next(c for c in cells if "repeatability.parquet [case=T03,direction=-]" in c["title"])
    assert "rule repeatability" in rep["title"] and "lineage not recorded" in rep["title"]
    # the per-table lineage lines carry the audit command for a row
    assert "python -m isokinetic trace results/demo/characteristic.parquet case=T01,segment=1" in page
    # JSON values: the key path of the value; a quarantined case: audited through cases.parquet
    assert any("trace results/demo/diagnosis.json where.0.mean_rel_error" in c["title"] for c in cells)
    assert any("trace results/demo/diagnosis.json candidates.1.gap_after" in c["title"] for c in cells)
    assert "python -m isokinetic trace results/demo/cases.parquet case=T04" in page


def test_figure_lineage_comes_from_provenance_json_when_the_file_has_none(built):
    page = (built / CAMPAIGN / "report.html").read_text(encoding="utf-8")
    fig09 = page[page.index('id="fig09_characteristic"'):]
    fig09 = fig09[:fig09.index("</figure>")]
    assert PROV_COMMIT[:12] in fig09 and "record from provenance" in fig09
    fig16 = page[page.index('id="fig16_gap"'):]
    fig16 = fig16[:fig16.index("</figure>")]  # same job as diagnosis.json, which is stamped
    assert COMMIT[:12] in fig16 and "same job as results/demo/diagnosis.json" in fig16
    assert '<a href="provenance.json">' in page
    assert "Provenance checks report problems" in page
    assert "stages whose inputs changed since they ran: <code>models</code>" in page


def test_page_without_damper_or_diagnosis_says_so(results):
    root = build_campaign(results / "nodamper", damper=False, stamp=False)
    (root / "models" / "comparison.parquet").unlink()
    (root / "figures" / "fig12_noise.png").write_bytes(b"")
    page = report.render_campaign_report(root)
    assert "No damper block" in page and "Not diagnosed: campaign.yaml has no damper block" in page
    assert "figure missing or not a PNG" in page and "results/nodamper/figures/fig12_noise.png" in page
    problems = report.page_problems(page, report.campaign_figure_files())
    assert any("fig12_noise.png not on the page" in p for p in problems)
    assert "lineage not recorded in the file" in page


def test_cases_table_shows_the_delay_of_each_case(built):
    page = (built / CAMPAIGN / "report.html").read_text(encoding="utf-8")
    table = page[page.index('<table id="cases-table">'):]
    table = table[:table.index("</table>")]
    rows = {}
    for r in table.split("<tr")[2:]:
        cells = [plain(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", r)]
        rows[cells[0]] = cells
    # case, waveform, status, samples, motion start [s], delay [ms], speed / planned, motion rms [um], quality
    assert rows["T02"][4:] == ["7.3234", "23.4", "0.9987", "1.20", TIME_NOTE]
    assert rows["T01"][4:] == ["0", "0", "1.000", "1.00", "ok"]
    assert rows["T04"][2:] == ["quarantined", "0", "-", "-", "-", "-", "quarantined"]
    assert 'class="warned"' in table
    cell = next(c for c in parse(page).cells if "cases.parquet [case=T02]" in c["title"] and "delay_s" in c["title"])
    assert "audit: python -m isokinetic trace results/demo/cases.parquet case=T02" in cell["title"]


def test_cases_table_written_before_the_motion_was_measured(results):
    root = build_campaign(results / "oldcases", stamp=False)
    cases = pd.read_parquet(root / "cases.parquet").drop(columns=["motion_start_s", "delay_s", "velocity_ratio",
                                                                  "motion_rms_m", "quality"])
    write_parquet(cases, root / "cases.parquet")
    page = report.render_campaign_report(root)
    assert '<section id="cases">' in page and "delay [ms]" in page


def test_page_problems_catches_external_resources_and_bad_images():
    good = f'<img src="data:image/png;base64,{base64.b64encode(tiny_png((1, 2, 3))).decode()}" data-file="a.png">'
    assert report.page_problems(good, ["a.png"]) == []
    for bad in ('<img src="https://example.org/x.png">', '<link rel="stylesheet" href="//cdn.example/x.css">',
                '<style>body{background:url(http://x/y.png)}</style>', '<style>@import "x.css";</style>',
                '<script src="http://x/y.js"></script>', '<img src="fig.png" data-file="fig.png">',
                '<img src="data:image/png;base64,AAAA" data-file="b.png">'):
        assert report.page_problems(good + bad), bad
    assert report.page_problems(good, ["a.png", "missing.png"]) == ["figure missing.png not on the page"]


def test_numbers_are_formatted_for_reading():
    assert report.fmt_text(4309.893) == "4310"
    assert report.fmt_text(0.959494) == "0.9595"
    assert report.fmt_text(2.1998e-12) == "2.200e-12"
    assert report.fmt(2.1998e-12) == "2.200&#8239;&times;&#8239;10<sup>-12</sup>"
    assert report.fmt_text(float("nan")) == "-" and report.fmt_text(None) == "-"
    assert report.fmt_text(np.int64(501)) == "501" and report.fmt_text(True) == "yes"
    assert report.fmt_pct(-0.4321) == "-43.2 %"
    assert report.formula("A_O^2") == "A<sub>O</sub><sup>2</sup>"
    assert report.trace_command("results/c/x.parquet", "case=T01,direction=+") == \
        "python -m isokinetic trace results/c/x.parquet case=T01,direction=+"


# ----------------------------------------------------------------------------------------------
# the index
# ----------------------------------------------------------------------------------------------

def test_index_lists_campaigns_with_verdicts_and_the_blind_scores(built):
    page = (built / "index.html").read_text(encoding="utf-8")
    parsed = parse(page)
    assert "demo/report.html" in parsed.links
    text = plain(page)
    for expected in ("friction", "explained", report.fmt_text(52.5), report.fmt_text(0.98, 3), report.fmt_text(53.57, 3),
                     "3 / 4", "a_single_at_2x", "c_median_shrink", "FAIL", "PASS", "NOT ALL PASS", "1-2x detection",
                     "50.0 %", "median 3.21 over 3", "blind-002"):
        assert expected in text, expected
    assert report.page_problems(page, ["fig17_blind_confusion.png"]) == []
    for cell in parsed.cells:
        assert re.search(r"results/(demo|blind)/\S+\.(parquet|json)", cell["title"] or ""), cell


def test_check_pages_reports_missing_pages(built):
    assert report.check_pages(built, [CAMPAIGN], browser=False) == []
    (built / "index.html").write_text("", encoding="utf-8")
    assert report.check_pages(built, [CAMPAIGN], browser=False) == [f"{built / 'index.html'}: missing or empty"]
    assert report.check_pages(built, ["other"], index=False, browser=False) == [
        f"{built / 'other' / 'report.html'}: missing or empty"]


# ----------------------------------------------------------------------------------------------
# in a browser
# ----------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def chromium() -> str:
    found = report.find_chromium()
    if found is None:
        message = ("headless Chromium is needed to check that the report pages load (Debian: apt-get install "
                   "chromium; or set ISOKINETIC_CHROMIUM)")
        if CI:
            pytest.fail(f"CI: {message}")
        pytest.skip(message)
    return found


def test_every_figure_loads_in_headless_chromium(built, chromium):
    campaign = report.check_in_browser(built / CAMPAIGN / "report.html", chromium)
    assert campaign["total"] == len(report.CAMPAIGN_FIGURES) == campaign["loaded"], campaign
    assert campaign["broken"] == []
    index = report.check_in_browser(built / "index.html", chromium)
    assert index["total"] == 1 == index["loaded"], index
    assert report.check_pages(built, [CAMPAIGN], browser=True) == []


def test_the_browser_check_sees_a_broken_figure(tmp_path, chromium):
    """Control: the check is not vacuous - an undecodable image is counted as not loaded."""
    good = base64.b64encode(tiny_png((9, 9, 9))).decode()
    page = report.page("control", "", [], f'<img src="data:image/png;base64,{good}" data-file="good.png">'
                       '<img src="data:image/png;base64,iVBORw0KGgoAAAA" data-file="broken.png">', "")
    (tmp_path / "control.html").write_text(page, encoding="utf-8")
    result = report.check_in_browser(tmp_path / "control.html", chromium)
    assert (result["loaded"], result["total"], result["broken"]) == (1, 2, ["broken.png"])
