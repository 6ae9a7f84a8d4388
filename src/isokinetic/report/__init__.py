"""Reports for people: one self-contained HTML page per campaign and an index of all campaigns.

- :mod:`~isokinetic.report.campaign_report`: rule ``campaign_report``, ``results/<campaign>/report.html``;
- :mod:`~isokinetic.report.diagnosis_section`: that page's sim-to-real gap diagnosis section;
- :mod:`~isokinetic.report.report_index`: rule ``report_index``, ``results/index.html`` and the blind suite;
- :mod:`~isokinetic.report.sources`: the lineage of every number (file, rule, commit, params, audit command);
- :mod:`~isokinetic.report.cells`: tables as rows of already-formatted cells;
- :mod:`~isokinetic.report.numbers`: number formatting;
- :mod:`~isokinetic.report.embed`: figures embedded as PNG data URIs, their captions;
- :mod:`~isokinetic.report.layout`: Jinja2 templates (``templates/``), inline style sheet and script, footer;
- :mod:`~isokinetic.report.browser`: checks of the built pages, headless Chromium.
"""
