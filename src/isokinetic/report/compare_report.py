"""Stage ``compare_report``: ``results/compare/<name>/report.html``, one self-contained page per comparison.

The page shows what :mod:`isokinetic.stages.compare` found: the campaigns (the first is the reference,
each linked to its own page), how the standard errors and the test are made, per compared campaign the
number of rows on each basis (``measured`` or ``model:<name>``) and of significant rows against the
number expected by chance, the notes (models used, models that cannot show their misfit) and the
velocities left out, Fig. 18-19 and every row of the table. As on the campaign pages, every number
cell's title names its file, row, rule and commit, and a lineage section lists every file read.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import pandas as pd

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import STAGE_OUTPUTS, figures_in
from isokinetic.io import write_text
from isokinetic.report.cells import Col, Table, badge, json_table_view, kv_table, table_view
from isokinetic.report.embed import figure_views, read_captions
from isokinetic.report.layout import footer, render
from isokinetic.report.numbers import esc, fmt, fmt_pct, text, yes_no
from isokinetic.report.sources import Sources, lineage_of, lineage_rows, read_json, read_parquet
from isokinetic.stats import Z_95

TABLE, CSV, SUMMARY = (STAGE_OUTPUTS["compare"][k] for k in ("table", "csv", "summary"))
NAV = [("comparison", "Comparison"), ("method", "Method"), ("figures", "Figures"), ("rows", "All rows"),
       ("lineage", "Lineage")]
ROW_KEYS = ["campaign", "direction", "velocity_m_s"]
ROW_COLS = [Col("campaign", "campaign", text, False), Col("direction", "dir", text, False),
            Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("basis", "basis", text, False),
            Col("reference_case", "ref. case", text, False), Col("campaign_case", "case", text, False),
            Col("reference_force_N", "F reference [N]"), Col("reference_se_N", "SE [N]", lambda x: fmt(x, 3)),
            Col("campaign_force_N", "F campaign [N]"), Col("campaign_se_N", "SE [N]", lambda x: fmt(x, 3)),
            Col("velocity_shift_N", "velocity shift [N]", lambda x: fmt(x, 3)),
            Col("difference_N", "difference [N]"), Col("difference_se_N", "SE [N]", lambda x: fmt(x, 3)),
            Col("z", "z", lambda x: fmt(x, 3)), Col("p_value", "p", lambda x: fmt(x, 3)),
            Col("significant", "significant", yes_no, False)]
EXCLUDED_COLS = [Col("direction", "dir", text, False), Col("velocity_m_s", "velocity [mm/s]", scale=1e3),
                 Col("campaign", "from campaign", text, False), Col("case", "case", text, False),
                 Col("reason", "left out because", text, False)]


def campaign_href(campaign: str) -> str:
    """A campaign's page, relative to the comparison's page (``results/compare/<name>/``)."""
    return f"../../{campaign}/{STAGE_OUTPUTS['campaign_report']['page']}"


def _campaign_links(campaigns: list[str], results_root: Path) -> str:
    links = []
    for k, c in enumerate(campaigns):
        label = f"<strong>{esc(c)}</strong>" + (" (reference)" if k == 0 else "")
        page = CampaignFolder.at(results_root / c).path("campaign_report", "page")
        links.append(f'<a href="{campaign_href(c)}">{label}</a>' if page.is_file() else f"{label} (no page)")
    return ", ".join(links)


def _alpha(summary: Mapping) -> str:
    """The comparison's alpha as configured (0.05, not 0.05000)."""
    alpha = summary.get("alpha")
    return f"{float(alpha):g}" if isinstance(alpha, int | float) else "?"


def _settings(summary: Mapping, srcs: Sources, results_root: Path) -> Table:
    src = srcs(SUMMARY)
    return kv_table([
        ("campaigns", _campaign_links(list(summary.get("campaigns") or []), results_root), src.title("campaigns")),
        ("description", text(summary.get("description") or "-"), src.title("description")),
        ("test", f"{esc(summary.get('test', '?'))}, alpha = {_alpha(summary)}",
         src.title("test", "test,alpha")),
        ("velocities match within", fmt_pct(summary.get("velocity_tolerance")), src.title("velocity_tolerance")),
        ("model for velocities that do not match", text(summary.get("model")), src.title("model"))])


def _resolution(rows: pd.DataFrame | None, src) -> tuple[str, str, str] | None:
    """The card of the smallest and largest 95 % half-width of a campaign's differences (computed here)."""
    if rows is None or rows.empty:
        return None
    half = Z_95 * rows["difference_se_N"].to_numpy(float)
    return ("95 % half-width of the difference", f"{fmt(half.min(), 3)} to {fmt(half.max(), 3)} N",
            src.title("", "difference_se_N", [f"computed by the report: 1.96 x min and max over {len(rows)} rows"]))


def _pair_view(pair: Mapping, k: int, srcs: Sources, rows: pd.DataFrame | None) -> dict:
    """One compared campaign: counts, significance against chance, notes, velocities left out."""
    src = srcs(SUMMARY)
    base = f"pairs.{k}"
    n, n_sig, expected = pair.get("n_rows", 0), pair.get("n_significant", 0), pair.get("expected_by_chance", 0.0)
    kind = "good" if n_sig == 0 else ("warn" if n_sig <= max(1.0, 2 * expected) else "bad")
    cards = [(f"rows ({pair.get('n_measured', 0)} measured, {pair.get('n_model', 0)} through a model)", str(n),
              src.title(base, "n_rows,n_measured,n_model")),
             ("significant rows", f"{n_sig} {badge('none', 'good') if n_sig == 0 else ''}",
              src.title(base, "n_significant")),
             ("expected by chance alone", fmt(expected, 2), src.title(base, "expected_by_chance")),
             ("largest |z|", fmt(pair.get("max_abs_z"), 3), src.title(base, "max_abs_z"))]
    mine = None if rows is None else rows[rows["campaign"] == pair.get("campaign")]
    cards += [c for c in [_resolution(mine, srcs(TABLE))] if c]
    excluded = pd.DataFrame(pair.get("excluded") or [])
    return {"campaign": pair.get("campaign"), "kind": kind, "n": n, "n_sig": n_sig, "expected": fmt(expected, 2),
            "cards": [{"k": a, "v": v, "title": t} for a, v, t in cards], "notes": list(pair.get("notes") or []),
            "models": ", ".join(pair.get("models_used") or []) or "none (every velocity matched)",
            "excluded": json_table_view(excluded.assign(key=[f"{base}.excluded.{i}" for i in range(len(excluded))]),
                                        EXCLUDED_COLS, src, "key", f"excluded-{k}") if len(excluded) else None,
            "n_excluded": len(excluded)}


def _rows(table: pd.DataFrame | None, srcs: Sources) -> Table | None:
    if table is None:
        return None
    return table_view(table, ROW_COLS, srcs(TABLE), ROW_KEYS, table_id="compare-rows",
                      row_class=lambda r: "flagged" if r.get("significant") else
                      ("warned" if str(r.get("basis", "")).startswith("model:") else ""))


def _input_sources(campaigns: list[str], results_root: Path) -> list:
    """The campaign tables the comparison read, for the lineage section."""
    out = []
    for c in campaigns:
        srcs = Sources(results_root / c)
        out += [srcs(STAGE_OUTPUTS["characteristic"]["characteristic"]), srcs(STAGE_OUTPUTS["models"]["models"])]
    return out


def render_compare_report(compare_dir: str | os.PathLike, *, captions_dir: str | os.PathLike | None = None,
                          lineage_record: Mapping | None = None, index_href: str | None = "../../index.html") -> str:
    """The HTML page of one comparison, read from ``results/compare/<name>/`` (missing parts are said)."""
    root = Path(compare_dir)
    results_root = root.parents[1]
    srcs = Sources(root)
    summary = read_json(root / SUMMARY)
    table = read_parquet(root / TABLE)
    captions = read_captions(captions_dir)
    name = (summary or {}).get("comparison") or root.name
    campaigns = list((summary or {}).get("campaigns") or [])
    view = None
    if summary is not None:
        view = {"settings": _settings(summary, srcs, results_root), "reference": summary.get("reference"),
                "pairs": [_pair_view(p, k, srcs, table) for k, p in enumerate(summary.get("pairs") or [])],
                "lineage": lineage_of(srcs(SUMMARY)), "alpha": _alpha(summary),
                "tolerance": fmt_pct(summary.get("velocity_tolerance")), "model": summary.get("model"),
                "one_in": fmt(1.0 / float(summary["alpha"]), 2) if summary.get("alpha") else "?"}
    figures = figure_views(srcs, figures_in("compare"), captions)
    rows = _rows(table, srcs)
    sources = srcs.all() + _input_sources(campaigns, results_root)
    return render("compare_report.html.j2", title=f"isokinetic - comparison {name}", nav=NAV,
                  lineage_record=lineage_record, name=name, description=(summary or {}).get("description") or "",
                  index_href=index_href, view=view, figures=figures, rows=rows,
                  n_rows=0 if table is None else len(table), table_lineage=lineage_of(srcs(TABLE)),
                  csv=CSV if (root / CSV).is_file() else None, lineage_files=lineage_rows(sources),
                  footer=footer(lineage_record, sources))


def write_compare_report(compare_dir: str | os.PathLike, out_path: str | os.PathLike, **kwargs) -> Path:
    """Write :func:`render_compare_report` to ``out_path`` atomically."""
    return write_text(render_compare_report(compare_dir, **kwargs), out_path)
