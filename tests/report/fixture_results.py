"""A small, schema-valid results tree for the report pages, made without running the pipeline.

Tables follow the pandera schemas of :mod:`isokinetic.contracts.tables`, the diagnosis its JSON
schema, the models are the real fit; figures are tiny PNGs. :func:`build_campaign` and
:func:`build_blind` make ``results/<campaign>/`` and ``results/blind/``; :class:`Cells`,
:func:`parse` and :func:`plain` read a built page back.
"""

from __future__ import annotations

import html
import json
import re
import struct
import zlib
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd

from isokinetic.audit.lineage import stage_lineage
from isokinetic.contracts import tables
from isokinetic.contracts.outputs import FIGURES
from isokinetic.diagnosis.result import validate_diagnosis
from isokinetic.io import lineage_context, write_json, write_parquet
from isokinetic.measurement.model_fit import comparison_table, fit_models
from isokinetic.physics.damper import TABLE_1
from isokinetic.report.browser import CAMPAIGN_SECTIONS
from isokinetic.report.embed import PNG_SIGNATURE

CAMPAIGN = "demo"
DAMPER = TABLE_1.to_dict()
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
#: The figures of a campaign page, in page order.
CAMPAIGN_FIGURES = [f for f in FIGURES if f.section in CAMPAIGN_SECTIONS]


def tiny_png(rgb: tuple[int, int, int], size: int = 4) -> bytes:
    """A valid size x size PNG of one colour (no image library needed)."""
    def chunk(kind: bytes, payload: bytes) -> bytes:
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))
    raw = b"".join(b"\0" + bytes(rgb) * size for _ in range(size))
    return (PNG_SIGNATURE + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def record(rule: str, commit: str = COMMIT) -> dict:
    rec = stage_lineage(rule, {"tolerance": 0.05}, [], campaign=CAMPAIGN)
    rec.update(git_commit=commit, git_dirty=False)
    return rec


def stamp(path: Path, rec: dict) -> None:
    """Rewrite a fixture file with a lineage record, as the pipeline's writers attach it."""
    with lineage_context(rec):
        if path.suffix == ".json":
            write_json({k: v for k, v in json.loads(path.read_text(encoding="utf-8")).items() if k != "lineage"}, path)
        else:
            write_parquet(pd.read_parquet(path), path)


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


def build_campaign(root: Path, *, damper: bool = True, stamped: bool = True) -> Path:
    """results/<campaign>/ with every table and figure a campaign page reads."""
    meta = {"format_version": 1, "campaign": root.name, "source": "rig", "description": "Report fixture campaign",
            "temperature_C": 40.0, "damper": DAMPER if damper else None, "manifest_file": "data/raw/demo/campaign.yaml",
            "manifest_sha256": "cd" * 32, "metadata": {}}
    write_json(meta, root / "ingest" / "campaign.json")
    cases = pd.DataFrame([
        {"campaign": CAMPAIGN, "case": c, "waveform": "triangle", "sample_rate_Hz": 50.0, "amplitude_m": w * 10,
         "period_s": 40.0, "frequency_Hz": np.nan, "phase_rad": -np.pi / 2, "duration_s": 80.0,
         "raw_file": f"data/raw/demo/{c}.csv", "raw_sha256": "ab" * 32,
         "timeseries_file": f"ingest/timeseries/{c}.parquet", "n_samples": 4000, "status": "ok",
         **MOTION.get(c, MOTION_NONE)} for c, w in SPEEDS.items()]
        + [{"campaign": CAMPAIGN, "case": "T04", "waveform": "triangle", "sample_rate_Hz": 50.0, "amplitude_m": 0.01,
            "period_s": 20.0, "frequency_Hz": np.nan, "phase_rad": 0.0, "duration_s": 40.0,
            "raw_file": "data/raw/demo/T04.csv", "raw_sha256": "ef" * 32, "timeseries_file": "", "n_samples": 0,
            "status": "quarantined", "motion_start_s": np.nan, "delay_s": np.nan, "velocity_ratio": np.nan,
            "motion_rms_m": np.nan, "quality": "quarantined"},
           {"campaign": CAMPAIGN, "case": "H01", "waveform": "sine", "sample_rate_Hz": 200.0, "amplitude_m": 2.3e-4,
            "period_s": np.nan, "frequency_Hz": 1.75, "phase_rad": 0.0, "duration_s": 6.0,
            "raw_file": "data/raw/demo/H01.csv", "raw_sha256": "12" * 32,
            "timeseries_file": "ingest/timeseries/H01.parquet", "n_samples": 1200, "status": "ok",
            **MOTION_NONE}])
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
    models, _ = fit_models(char, TABLE_1 if damper else None)
    write_parquet(models, root / "models" / "models.parquet")
    write_parquet(comparison_table(char, None, models, None), root / "models" / "comparison.parquet")
    harmonic = pd.DataFrame([{"campaign": CAMPAIGN, "case": "H01", "waveform": "sine", "kind": "peak_to_peak",
                              "direction": d, "velocity_m_s": s * 2.527e-3, "force_N": s * 5539.8, "n_points": 8,
                              "lag_s": 0.0953, "frequency_Hz": 1.75, "amplitude_m": 2.3e-4}
                             for d, s in (("+", 1), ("-", -1))])
    write_parquet(tables.validate_table(harmonic, tables.HARMONIC), root / "harmonic" / "harmonic.parquet")
    write_json(diagnosis() if damper else {"format_version": 1, "campaign": CAMPAIGN, "status": "not_diagnosed",
                                           "reason": "campaign.yaml has no damper block: there is no nominal model"},
               root / "diagnosis.json")
    for k, fig in enumerate(CAMPAIGN_FIGURES):
        (root / fig.path).parent.mkdir(parents=True, exist_ok=True)
        (root / fig.path).write_bytes(tiny_png((20 * k % 256, 100, (200 - 10 * k) % 256)))
    if stamped:
        stamp(root / "characteristic.parquet", record("characteristic"))
        stamp(root / "models" / "models.parquet", record("models"))
        stamp(root / "diagnosis.json", record("diagnosis"))
        fig09 = record("figures", PROV_COMMIT)  # provenance.json's per-file index (isokinetic.audit.provenance)
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
               "bins": {"1-2x": {"n": 2, "exact": 1, "rate": 0.5, "n_single": 1, "exact_single": 1,
                                 "rate_single": 1.0},
                        "2-3x": {"n": 1, "exact": 1, "rate": 1.0, "n_single": 1, "exact_single": 1,
                                 "rate_single": 1.0}},
               "targets": {"a_single_at_2x": {"description": "single-effect scenarios at >= 2x detection attributed "
                                                             "exactly", "exact": 1, "n": 1, "rate": 1.0,
                                              "threshold": 0.95,
                                              "pass": True, "misses": []},
                           "b_none_clean": {"description": "no effect claimed on any scenario without effects",
                                            "claimed": 0, "n": 1, "pass": True, "misses": []},
                           "c_median_shrink": {"description": "median shrink where an effect was present",
                                               "median": 3.21, "n": 3, "threshold": 5.0, "pass": False}}}
    write_json(summary, root / "summary.json")
    scores = pd.DataFrame({"scenario": ["blind-000", "blind-001", "blind-002", "blind-003"],
                           "truth": ["air", "", "friction+leakage", "leakage"],
                           "verdict": ["air", "", "friction", "leakage"], "exact": [True, True, False, True],
                           "magnitude_x_detection": [2.3, np.nan, 1.2, 1.5],
                           "magnitude_bin": ["2-3x", "", "1-2x", "1-2x"],
                           "gap_before": [2.45, 0.99, 12.6, 4.1], "gap_after": [0.93, 0.99, 3.9, 0.93],
                           "shrink": [2.64, 1.0, 3.21, 4.4], "error": ["", "", "", ""]})
    write_parquet(scores, root / "scores.parquet")
    (root / "fig17_blind_confusion.png").write_bytes(tiny_png((0, 0, 0)))
    return root


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
    return html.unescape(re.sub(r"<[^>]+>", "", page))
