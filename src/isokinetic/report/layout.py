"""The page frame: Jinja2 templates, the inline style sheet and script, the footer.

Templates (``templates/*.html.j2``), the style sheet (``report.css``) and the script
(``image_check.js``) ship as package data and are read through :mod:`importlib.resources`
(:class:`jinja2.PackageLoader`), so an installed package renders its pages without the
checkout. Autoescape is on: Python hands the templates plain text (escaped there) and, marked
safe, the HTML of already-formatted cells. The pages are self-contained: style and script inline,
figures as ``data:`` URIs, no network.
"""

from __future__ import annotations

import datetime as dt
import functools
import json
from collections.abc import Iterable, Mapping, Sequence
from importlib import resources

import jinja2
from markupsafe import Markup

from isokinetic.report.numbers import short
from isokinetic.report.sources import Source

PACKAGE = "isokinetic.report"


@functools.cache
def environment() -> jinja2.Environment:
    """The templates of the report pages (autoescaped)."""
    return jinja2.Environment(loader=jinja2.PackageLoader(PACKAGE, "templates"), autoescape=True,
                              trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                              undefined=jinja2.StrictUndefined)


@functools.cache
def asset(name: str) -> Markup:
    """A package data file inlined into every page (style sheet, script)."""
    return Markup(resources.files(PACKAGE).joinpath(name).read_text(encoding="utf-8"))


def lineage_json(lineage_record: Mapping | None) -> Markup | None:
    """The page's own lineage record as inert JSON data (``</`` escaped so it cannot end the tag)."""
    if not lineage_record:
        return None
    return Markup(json.dumps(lineage_record, sort_keys=True, default=str).replace("</", "<\\/"))


def render(template: str, *, title: str, nav: Sequence[tuple[str, str]], lineage_record: Mapping | None = None,
           **context) -> str:
    """A whole page from ``template`` (which extends ``page.html.j2``)."""
    return environment().get_template(template).render(
        title=title, nav=nav, css=asset("report.css"), js=asset("image_check.js"),
        lineage_json=lineage_json(lineage_record), **context)


def page(title: str, header_html: str, nav: Sequence[tuple[str, str]], body: str, footer_html: str,
         lineage_record: Mapping | None = None) -> str:
    """A page around ready HTML (the frame alone: header, navigation, body and footer as given)."""
    return render("page.html.j2", title=title, nav=nav, lineage_record=lineage_record,
                  header_html=Markup(header_html), body_html=Markup(body), footer_html=Markup(footer_html))


def now_utc() -> str:
    return dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def footer(lineage_record: Mapping | None, sources: Iterable[Source]) -> dict:
    """What the footer says: when and by which job the page was made, and the commits it mixes."""
    rec = lineage_record or {}
    job = {"rule": rec.get("rule"), "commit": short(rec.get("git_commit"), 12), "dirty": bool(rec.get("git_dirty")),
           "params": short(rec.get("params_sha256"), 12)} if rec else None
    commits = sorted({s.commit for s in sources if s.commit})
    return {"made": rec.get("created_utc") or now_utc(), "job": job,
            "commits": [short(c, 10) for c in commits] if len(commits) > 1 else []}
