"""The page frame: templates, style sheet and script shipped as package data, autoescaped."""

from __future__ import annotations

from isokinetic.report import layout


def test_templates_and_style_ship_as_package_data():
    page = layout.page("t", "", [("a", "A & B")], "<p>x</p>", "")
    assert layout.asset("report.css").strip() in page and layout.asset("image_check.js").strip() in page
    assert '<a href="#a">A &amp; B</a>' in page  # autoescaped
    for name in ("page.html.j2", "macros.html.j2", "campaign_report.html.j2", "diagnosis_section.html.j2",
                 "report_index.html.j2", "blind_section.html.j2"):
        layout.environment().get_template(name)
