"""The campaign page: its figures, numbers, the lineage of every number, and what it says when parts are missing."""

from __future__ import annotations

import base64
import re
from pathlib import Path

import pandas as pd
import pytest

from fresh_imports import modules_loaded
from isokinetic.contracts.campaign_meta import CampaignMetaError
from isokinetic.io import write_parquet
from isokinetic.report import browser, numbers, sources
from isokinetic.report.campaign_report import render_campaign_report

from .fixture_results import (
    CAMPAIGN,
    CAMPAIGN_FIGURES,
    COMMIT,
    DAMPER,
    PLAN_REASON,
    PROV_COMMIT,
    QUARANTINE_REASON,
    TIME_NOTE,
    build_campaign,
    characteristic,
    diagnosis,
    parse,
    plain,
    record,
)


def test_campaign_page_embeds_every_figure_and_nothing_external(built):
    root = built / CAMPAIGN
    page = (root / "report.html").read_text(encoding="utf-8")
    assert browser.page_problems(page, browser.campaign_figure_files()) == []
    images = {Path(a["data-file"]).name: a["src"] for a in parse(page).images}
    assert sorted(images) == sorted(browser.campaign_figure_files())
    for fig in CAMPAIGN_FIGURES:  # each figure is the file's own bytes, base64 in the page
        assert base64.b64decode(images[Path(fig.path).name].split(",", 1)[1]) == (root / fig.path).read_bytes()
    assert "<link" not in page and "http://" not in page and "https://" not in page
    assert "<style>" in page and 'data-images-total' in page


def test_a_figure_with_a_vector_copy_links_it_beside_its_caption(results):
    root = build_campaign(results)
    (root / "figures" / "fig09_characteristic.svg").write_text("<svg/>", encoding="utf-8")
    page = render_campaign_report(root)
    assert page.count(" download>SVG</a>") == 1 and '<a href="figures/fig09_characteristic.svg" download>' in page
    assert "PDF</a>" not in page


def test_campaign_page_shows_the_numbers(built):
    root = built / CAMPAIGN
    text = plain((root / "report.html").read_text(encoding="utf-8"))
    models = pd.read_parquet(root / "models" / "models.parquet")
    fc = models[(models["model"] == "wallaschek") & (models["parameter"] == "F_C")].iloc[0]
    d = diagnosis()
    expected = [
        "Report fixture campaign", "rig", "40.00",                                # header
        numbers.fmt_text(DAMPER["orifice_area_m2"]).split("e")[0],               # damper data
        PLAN_REASON, "T03",                                                      # plan check
        numbers.fmt_text(fc["estimate"]), numbers.fmt_text(fc["ci_low"]), numbers.fmt_text(fc["ci_high"]),
        numbers.fmt_text(models.loc[models["kind"] == "derived", "estimate"].iloc[0]).split("e")[0],
        "7.78 %",                                                                # flagged repeatability pair
        "friction", numbers.fmt_text(d["gap_before"]), numbers.fmt_text(d["gap_after"]),
        numbers.fmt_text(d["holdout_gap_after"]), numbers.fmt_text(d["shrink"]), "-43.2 %",   # diagnosis
        "friction, air", "Confounded",                                           # confounded group
        QUARANTINE_REASON,                                                       # quarantine
        numbers.fmt_text(5539.8), "0.0953",                                       # harmonic
        numbers.fmt_text(characteristic()["force_N"].iloc[0]),                    # a characteristic point
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
        if Path(source.group(1)).name in sources.TRACEABLE and "counted by" not in title:
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
    assert "rule characteristic" in rep["title"] and "lineage not recorded" in rep["title"]
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
    root = build_campaign(results / "nodamper", damper=False, stamped=False)
    (root / "models" / "comparison.parquet").unlink()
    (root / "figures" / "fig12_noise.png").write_bytes(b"")
    page = render_campaign_report(root)
    assert "No damper block" in page and "Not diagnosed: campaign.yaml has no damper block" in page
    assert "figure missing or not a PNG" in page and "results/nodamper/figures/fig12_noise.png" in page
    problems = browser.page_problems(page, browser.campaign_figure_files())
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
    # case, waveform, status, samples, motion start [s], delay [ms], speed / planned, motion rms [um],
    # temperature [C], T span [K], T from, quality (the fixture's cases carry no temperature)
    assert rows["T02"][4:] == ["7.3234", "23.4", "0.9987", "1.20", "-", "-", "-", TIME_NOTE]
    assert rows["T01"][4:] == ["0", "0", "1.000", "1.00", "-", "-", "-", "ok"]
    assert rows["T04"][2:] == ["quarantined", "0", "-", "-", "-", "-", "-", "-", "-", "quarantined"]
    assert 'class="warned"' in table
    cell = next(c for c in parse(page).cells if "cases.parquet [case=T02]" in c["title"] and "delay_s" in c["title"])
    assert "audit: python -m isokinetic trace results/demo/cases.parquet case=T02" in cell["title"]


def test_cases_table_written_before_the_motion_was_measured(results):
    root = build_campaign(results / "oldcases", stamped=False)
    cases = pd.read_parquet(root / "cases.parquet").drop(columns=["motion_start_s", "delay_s", "velocity_ratio",
                                                                  "motion_rms_m", "quality"])
    write_parquet(cases, root / "cases.parquet")
    page = render_campaign_report(root)
    assert '<section id="cases">' in page and "delay [ms]" in page


def _table(page: str, table_id: str) -> str:
    table = page[page.index(f'<table id="{table_id}">'):]
    return table[:table.index("</table>")]


def test_reading_outside_its_physical_range_is_shown_with_its_reason(built):
    root = built / CAMPAIGN
    page = (root / "report.html").read_text(encoding="utf-8")
    models = pd.read_parquet(root / "models" / "models.parquet")
    cd = models[(models["model"] == "wallaschek") & (models["parameter"] == "discharge_coefficient_eq")].iloc[0]
    assert not cd["plausible"]            # the fixture's quadratic term gives C_D ~ 1.9 with the nominal A_O
    derived = _table(page, "models-wallaschek-derived")
    row = next(r for r in derived.split("<tr")[2:] if "<td>discharge_coefficient_eq</td>" in r)
    assert row.startswith(' class="flagged"')
    assert "<td>(0, 1]</td>" in row and '<span class="badge bad">outside its range</span>' in row
    assert numbers.esc(cd["plausibility"]) in row
    in_range = next(r for r in derived.split("<tr")[2:] if "<td>viscosity_eq</td>" in r)
    assert 'class="flagged"' not in in_range and "<td>in range</td>" in in_range
    text = plain(page)
    assert "3 reading(s) lie wholly outside their physical range" in text
    assert "readings outside their physical range" in text        # the summary card


def test_reading_not_excluded_is_shown_apart_from_an_implausible_one(results):
    root = build_campaign(results / "straddle", stamped=False)
    models = pd.read_parquet(root / "models" / "models.parquet")
    at = (models["model"] == "wallaschek") & (models["parameter"] == "discharge_coefficient_eq")
    note = "not excluded: discharge_coefficient_eq = 1.05 lies outside (0, 1], but its 95 % interval reaches into it"
    models.loc[at, ["plausible", "plausibility"]] = [True, note]
    write_parquet(models, root / "models" / "models.parquet")
    row = next(r for r in _table(render_campaign_report(root), "models-wallaschek-derived").split("<tr")[2:]
               if "<td>discharge_coefficient_eq</td>" in r)
    assert row.startswith(' class="warned"') and '<span class="badge warn">not excluded</span>' in row
    assert "discharge_coefficient_eq = 1.05 lies outside (0, 1]" in plain(row)


def test_models_table_written_before_the_plausibility_check(results):
    root = build_campaign(results / "oldmodels", stamped=False)
    models = pd.read_parquet(root / "models" / "models.parquet")
    write_parquet(models.drop(columns=["physical_range", "plausible", "plausibility"]),
                  root / "models" / "models.parquet")
    page = render_campaign_report(root)
    assert '<table id="models-wallaschek-derived">' in page
    assert "physical range" not in page and "outside its range" not in page


def test_characteristic_points_are_shown_open_with_their_method(built):
    page = (built / CAMPAIGN / "report.html").read_text(encoding="utf-8")
    table = page[page.index('id="characteristic-points"'):]
    before = page[page.index('id="characteristic"'):page.index('id="characteristic-points"')]
    assert "<details" not in before  # not folded away
    assert len(re.findall(r"<tr", table.split("</table>")[0])) == len(characteristic()) + 1


def test_sine_only_campaign_leaves_out_the_triangle_figures_saying_why(results):
    root = results / CAMPAIGN
    cases = pd.read_parquet(root / "cases.parquet")
    write_parquet(cases[cases["waveform"] == "sine"].reset_index(drop=True), root / "cases.parquet")
    char = characteristic().assign(method="sine_peak", case="H01")
    write_parquet(char, root / "characteristic.parquet")
    rep = pd.read_parquet(root / "repeatability.parquet")
    write_parquet(rep.iloc[:0], root / "repeatability.parquet")
    page = render_campaign_report(root)
    shown = {Path(a["data-file"]).name for a in parse(page).images}
    for name in ("fig07_time_and_loops", "fig08_window_selection", "fig12_noise"):
        assert f"{name}.png" not in shown
        line = re.search(rf'<p class="note info left-out" id="{name}">(.*?)</p>', page).group(1)
        assert "left out, does not apply to this campaign (no status-ok triangle case" in line, line
    assert {"fig09_characteristic.png", "fig15_harmonic_loops.png", "fig20_case_temperature.png"} <= shown
    assert browser.page_problems(page, browser.campaign_figure_files(pd.read_parquet(root / "cases.parquet"))) == []
    assert f"Points by method: {len(char)} sine peak." in plain(page)
    methods = [row[1] for row in re.findall(r'<tr[^>]*>\s*<td>([^<]*)</td>\s*<td>([^<]*)</td>',
                                            page[page.index('id="characteristic-points"'):].split("</table>")[0])]
    assert methods == ["sine peak"] * len(char)
    rep_section = page[page.index('id="repeatability"'):page.index('id="models"')]
    assert "does not apply to this campaign (no status-ok triangle case" in rep_section
    assert "No pair of the 0" not in rep_section


def test_a_status_ok_case_without_a_characteristic_point_is_named(results):
    root = results / CAMPAIGN
    cases = pd.read_parquet(root / "cases.parquet")
    sine = cases[cases["waveform"] == "sine"].reset_index(drop=True)
    write_parquet(pd.concat([sine, sine.assign(case="H02")], ignore_index=True), root / "cases.parquet")
    write_parquet(characteristic().assign(method="sine_peak", case="H01"), root / "characteristic.parquet")
    page = plain(render_campaign_report(root))
    assert "1 status-ok case(s) gave no characteristic point: H02" in page
    write_parquet(sine, root / "cases.parquet")
    assert "gave no characteristic point" not in plain(render_campaign_report(root))


def test_static_force_from_standstills_and_each_gas_force_check_are_shown(results):
    root = results / CAMPAIGN
    row = {"campaign": CAMPAIGN, "static_force_N": 0.31, "std_error_N": 0.05, "ci_low_N": 0.21, "ci_high_N": 0.41,
           "confidence": 0.95, "source": "standstill", "method": "standstill_mean", "n_speeds": 0, "n_matched": 0,
           "v_min_m_s": float("nan"), "v_max_m_s": float("nan"), "gas_force_N": float("nan"),
           "note": "from the standstill cases' mean force", "n_standstill": 2, "gas_force_check": "disagrees",
           "gas_force_cases": "Z01: +0.30 ± 0.05 N left of the declared 120 N: agrees; "
                              "Z02: +9.80 ± 0.05 N left of the declared 80 N: disagrees"}
    write_parquet(pd.DataFrame([row]), root / "static_force.parquet")
    page = plain(render_campaign_report(root))
    assert "static force at rest (standstill cases)" in page and "mean of 2 standstill case(s)" in page
    assert "lowest speeds" not in page
    assert "Z02: +9.80 ± 0.05 N left of the declared 80 N: disagrees" in page


def test_the_report_jobs_modules_load_no_scipy():
    # the report job uses the statistics' constants only: scipy would cost it ~0.1 s of start-up (issue 23)
    code = ("import isokinetic.report.campaign_report, isokinetic.audit.provenance, isokinetic.audit.raw_check, "
            "isokinetic.report.browser")
    assert modules_loaded(code, "scipy") == []


def test_a_campaign_json_that_breaks_its_schema_stops_the_page_naming_file_and_key(results):
    meta = results / CAMPAIGN / "ingest" / "campaign.json"
    meta.write_text(meta.read_text(encoding="utf-8").replace('"source": "rig"', '"source": 7'), encoding="utf-8")
    with pytest.raises(CampaignMetaError, match=r"ingest/campaign\.json: key 'source' must be"):
        render_campaign_report(results / CAMPAIGN)
