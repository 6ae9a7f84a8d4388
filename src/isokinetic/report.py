"""Reports for people: one self-contained HTML page per campaign and an index of all campaigns.

``results/<campaign>/report.html`` (:func:`write_campaign_report`) and ``results/index.html``
(:func:`write_index`) open in a browser from the file system, without a server and without the
network: figures are embedded as base64 PNG ``data:`` URIs, the style sheet is inline, and the
only script is a few lines that, after ``load``, write on ``<body>`` how many figures decoded
(``data-images-loaded`` / ``data-images-total`` / ``data-images-broken``), which the browser test
and CI read (:func:`check_in_browser`).

Lineage of every number. Each table is followed by a *lineage line* naming the file it was read
from, the rule that wrote it, the git commit (and whether the tree was dirty), the hash of the
rule's parameters and when it was made -- from the file's own lineage record
(:func:`isokinetic.lineage.read_lineage`), else from ``results/<campaign>/provenance.json``, else
(files written before lineage stamping) the rule named by the workflow and "not recorded" -- plus
the sha256 of the file as the report read it and a command to audit a row
(``python -m isokinetic trace <table> <selector>``, :func:`trace_command`). Every number cell
carries the same facts for its own row in its ``title`` (hover), characteristic points also their
raw file and row range. Numbers the report computes itself (counts, rms of a column) say so in
their title. The figures carry the lineage of the job that drew them.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import json
import math
import os
import re
import shlex
import shutil
import struct
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .io import sha256_file, write_text
from .lineage import read_lineage

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

#: Figures of a campaign page: (path relative to results/<campaign>/, title), per section.
CHARACTERISTIC_FIGURES = (
    ("figures/fig07_time_and_loops.png", "Fig. 7 - time domain and displacement-force loops"),
    ("figures/fig08_window_selection.png", "Fig. 8 - window selection"),
    ("figures/fig09_characteristic.png", "Fig. 9 - steady characteristic"),
    ("figures/fig10_low_velocity.png", "Fig. 10 - low-velocity detail"),
    ("figures/fig11_loglog.png", "Fig. 11 - log-log characteristic"),
    ("figures/fig12_noise.png", "Fig. 12 - force noise per segment"),
)
MODEL_FIGURES = (
    ("models/fig13_comparison.png", "Fig. 13 - identified, nominal and fitted characteristics"),
    ("models/fig14_comparison_loglog.png", "Fig. 14 - comparison on log-log axes"),
)
HARMONIC_FIGURES = (("harmonic/fig15_harmonic_loops.png", "Fig. 15 - harmonic loops"),)
DESIGN_FIGURES = (
    ("design/fig05_stroke_to_converge.png", "Fig. 5 - stroke to converge"),
    ("design/fig06_at_diagram.png", "Fig. 6 - A-T diagram of the plan"),
)
DIAGNOSIS_FIGURES = (("diagnosis/fig16_gap.png", "Fig. 16 - the sim-to-real gap before and after"),)
CAMPAIGN_FIGURES = (CHARACTERISTIC_FIGURES + MODEL_FIGURES + HARMONIC_FIGURES + DESIGN_FIGURES
                    + DIAGNOSIS_FIGURES)
BLIND_FIGURE = ("fig17_blind_confusion.png", "Fig. 17 - blind test: truth against verdict")

#: The rule that writes each file (relative to results/<campaign>/), as the workflow defines it:
#: named when a file carries no lineage record of its own.
RULE_OF = {
    "ingest/campaign.json": "ingest or virtual_rig", "cases.parquet": "validate",
    "quarantine.parquet": "validate", "windows.parquet": "windows", "repeatability.parquet": "repeatability",
    "characteristic.parquet": "characteristic", "nominal_windows.parquet": "nominal",
    "design/plan_check.parquet": "design", "models/models.parquet": "models",
    "models/comparison.parquet": "models", "models/model_residuals.parquet": "models",
    "harmonic/harmonic.parquet": "harmonic", "diagnosis.json": "diagnosis",
    "figures/": "figures", "design/": "design", "models/": "models", "harmonic/": "harmonic",
    "diagnosis/": "diagnosis", "scores.parquet": "blind_score", "summary.json": "blind_score",
    "fig17_blind_confusion.png": "blind_score",
}
#: A figure written by the same job as a table shares that table's lineage record.
FIGURE_SIBLING = {"design/": "design/plan_check.parquet", "models/": "models/models.parquet",
                  "harmonic/": "harmonic/harmonic.parquet", "diagnosis/": "diagnosis.json",
                  "fig17_blind_confusion.png": "scores.parquet"}

TRACE = "python -m isokinetic trace"


# ----------------------------------------------------------------------------------------------
# numbers and text
# ----------------------------------------------------------------------------------------------

def esc(text) -> str:
    return html.escape(str(text), quote=True)


def _missing(x) -> bool:
    if x is None or x is pd.NA:
        return True
    try:
        return isinstance(x, (float, np.floating)) and not math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def fmt_text(x, digits: int = 4) -> str:
    """A number as plain text: ``digits`` significant digits, ``1.235e+05`` beyond 1e-3..1e5."""
    if _missing(x):
        return "-"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    x = float(x)
    if x == 0:
        return "0"
    exponent = math.floor(math.log10(abs(x)))
    if -3 <= exponent < 5:
        decimals = max(digits - 1 - exponent, 0)
        return f"{x:.{decimals}f}"
    return f"{x:.{digits - 1}e}"


def fmt(x, digits: int = 4) -> str:
    """A number as HTML: like :func:`fmt_text`, exponents written as x10<sup>n</sup>."""
    text = fmt_text(x, digits)
    m = re.fullmatch(r"(-?[\d.]+)e([+-]\d+)", text)
    if m:
        return f"{m.group(1)}&#8239;&times;&#8239;10<sup>{int(m.group(2))}</sup>"
    return esc(text)


def fmt_pct(x, digits: int = 3) -> str:
    return "-" if _missing(x) else f"{fmt_text(100 * float(x), digits)} %"


def short(sha: str | None, n: int = 12) -> str:
    return (sha or "")[:n] or "-"


def trace_command(table: str, selector: str) -> str:
    """The command a reader runs to audit one row (or JSON key) of a table."""
    return f"{TRACE} {shlex.quote(table)} {shlex.quote(selector)}" if selector else f"{TRACE} {shlex.quote(table)}"


#: Tables ``python -m isokinetic trace`` re-derives (isokinetic.trace.table_kind).
TRACEABLE = frozenset({"cases.parquet", "windows.parquet", "characteristic.parquet", "repeatability.parquet",
                       "nominal_windows.parquet", "plan_check.parquet", "models.parquet", "model_residuals.parquet",
                       "harmonic.parquet", "diagnosis.json", "scores.parquet"})


def audit_command(path: Path, label: str, selector: str) -> str | None:
    """The trace command auditing one row (or JSON key path) of a file, None where trace has none:
    a quarantined case is audited through cases.parquet; a Parquet table needs a one-row selector."""
    if path.name == "quarantine.parquet":
        case = dict(p.split("=", 1) for p in selector.split(",") if "=" in p).get("case")
        return trace_command(str(Path(label).with_name("cases.parquet").as_posix()), f"case={case}") if case else None
    if path.name not in TRACEABLE or (path.suffix == ".parquet" and not selector):
        return None
    return trace_command(label, selector)


def selector_of(row: Mapping, keys: Sequence[str]) -> str:
    """``case=T05,direction=+,period=1``: the row's values of the key columns."""
    return ",".join(f"{k}={row[k]}" for k in keys if k in row and not _missing(row[k]))


def rst_to_text(text: str) -> str:
    """A figure caption from workflow/report/*.rst as plain text (literal and emphasis marks dropped)."""
    text = re.sub(r"\{\{.*?\}\}", "", text)
    text = text.replace("``", "").replace("**", "")
    return " ".join(text.split())


# ----------------------------------------------------------------------------------------------
# lineage of the files a page reads
# ----------------------------------------------------------------------------------------------

def display_path(path: Path) -> str:
    """Path as the reader types it: relative to the working directory (the project root) if below it."""
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path.cwd().resolve())).as_posix() \
            if Path(path).resolve().is_relative_to(Path.cwd().resolve()) else Path(path).as_posix()
    except (OSError, ValueError):
        return Path(path).as_posix()


def _provenance_record(provenance: Mapping | None, keys: Sequence[str]) -> dict | None:
    """The record of one file in a campaign's provenance.json, whatever its container's shape
    (a mapping path -> record, under 'files'/'outputs'/'lineage' or at the top, or a list of
    records with 'path'/'file')."""
    if not isinstance(provenance, Mapping):
        return None
    for container in (provenance.get("files"), provenance.get("outputs"), provenance.get("lineage"),
                      provenance.get("records"), provenance):
        if isinstance(container, Mapping):
            for key in keys:
                rec = container.get(key)
                if isinstance(rec, Mapping):
                    inner = rec.get("lineage")
                    return dict(inner if isinstance(inner, Mapping) else rec)
        elif isinstance(container, list):
            for rec in container:
                if isinstance(rec, Mapping) and (rec.get("path") in keys or rec.get("file") in keys):
                    inner = rec.get("lineage")
                    return dict(inner if isinstance(inner, Mapping) else rec)
    return None


@dataclass
class Source:
    """A file a page shows numbers from, with its lineage."""

    path: Path
    label: str                   # the path as shown (relative to the project root)
    exists: bool
    rule: str | None = None      # from the record, else from the workflow (RULE_OF)
    record: dict | None = None   # the lineage record (file metadata or provenance.json)
    origin: str = "none"         # 'file', 'provenance', 'same job as <file>' or 'none'
    sha256: str | None = None    # of the file as the report read it

    @property
    def commit(self) -> str | None:
        return (self.record or {}).get("git_commit")

    def facts(self) -> list[str]:
        """Short lineage facts for titles: rule, commit, params hash (or 'not recorded')."""
        out = [f"rule {self.rule or '?'}"]
        if self.record:
            commit = short(self.commit, 10) if self.commit else "unknown (not a git checkout)"
            dirty = (self.record or {}).get("git_dirty")
            out.append(f"commit {commit}{' (dirty)' if dirty else ''}")
            out.append(f"params {short(self.record.get('params_sha256'), 10)}")
        else:
            out.append("lineage not recorded")
        if self.sha256:
            out.append(f"sha256 {short(self.sha256)}")
        return out

    def title(self, selector: str = "", column: str | None = None, extra: Sequence[str] = ()) -> str:
        """A cell's title: which value of which row of which file, made how, and how to audit it."""
        what = f"{column} of " if column else ""
        where = f"{what}{self.label}" + (f" [{selector}]" if selector else "")
        cmd = self.audit(selector)
        parts = [where, *extra, *self.facts()] + ([f"audit: {cmd}"] if cmd else [])
        return " | ".join(parts)

    def audit(self, selector: str = "") -> str | None:
        return audit_command(self.path, self.label, selector)


class Sources:
    """Lineage lookups for one page (cached; one sha256 per file)."""

    def __init__(self, root: Path, provenance: Mapping | None = None):
        self.root = Path(root)
        self.provenance = provenance
        self._cache: dict[str, Source] = {}

    def __call__(self, rel: str) -> Source:
        if rel in self._cache:
            return self._cache[rel]
        path = self.root / rel
        label = display_path(path)
        src = Source(path=path, label=label, exists=path.is_file())
        src.rule = RULE_OF.get(rel) or next((r for k, r in RULE_OF.items() if k.endswith("/") and rel.startswith(k)),
                                            None)
        if src.exists:
            try:
                src.sha256 = sha256_file(path)
            except OSError:
                pass
            if path.suffix in (".parquet", ".json", ".png"):
                try:  # PNG records (iTXt chunk) only where isokinetic.lineage reads them
                    record = read_lineage(path)
                except Exception:  # noqa: BLE001 - an unreadable record is reported as absent
                    record = None
                if isinstance(record, Mapping) and record:
                    src.record, src.origin = dict(record), "file"
        if src.record is None:
            src.record = _provenance_record(self.provenance, [label, rel, path.as_posix()])
            if src.record:
                src.origin = "provenance"
        if src.record is None and path.suffix == ".png":
            sibling = next((t for k, t in FIGURE_SIBLING.items() if rel.startswith(k) or rel == k), None)
            if sibling and sibling != rel:
                sib = self(sibling)
                if sib.record:
                    src.record, src.origin = sib.record, f"same job as {sib.label}"
        if src.record and src.record.get("rule"):
            src.rule = src.record["rule"]
        self._cache[rel] = src
        return src

    def all(self) -> list[Source]:
        return list(self._cache.values())


def lineage_line(src: Source, selector: str = "", note: str = "") -> str:
    """The small 'lineage' paragraph under a table or figure."""
    if not src.exists:
        return f'<p class="lineage missing">lineage: <code>{esc(src.label)}</code> was not produced</p>'
    bits = [f"source <code>{esc(src.label)}</code>", f"rule <code>{esc(src.rule or '?')}</code>"]
    rec = src.record
    if rec:
        commit = rec.get("git_commit")
        dirty = rec.get("git_dirty")
        if commit:
            bits.append(f"commit <code>{esc(short(commit, 12))}</code>"
                        + (" (uncommitted changes)" if dirty else "" if dirty is False else " (tree state unknown)"))
        else:
            bits.append("commit unknown (not made in a git checkout)")
        bits.append(f"params <code>{esc(short(rec.get('params_sha256'), 12))}</code>")
        if rec.get("created_utc"):
            bits.append(f"made {esc(rec['created_utc'])}")
        if src.origin != "file":
            bits.append(f"record from {esc(src.origin)}")
    else:
        bits.append("<em>lineage not recorded in the file</em>")
    if src.sha256:
        bits.append(f"sha256 <code>{esc(short(src.sha256, 16))}</code>")
    audit = src.audit(selector)
    cmd = f' &middot; audit: <code class="cmd">{esc(audit)}</code>' if audit else ""
    note_html = f" &middot; {note}" if note else ""
    return f'<p class="lineage">lineage: {" &middot; ".join(bits)}{cmd}{note_html}</p>'


# ----------------------------------------------------------------------------------------------
# HTML building blocks
# ----------------------------------------------------------------------------------------------

@dataclass
class Col:
    """A column of an HTML table: the DataFrame column, its header, how to show a value."""

    key: str
    header: str
    show: Callable[[object], str] = fmt
    number: bool = True
    scale: float = 1.0     # displayed value = value * scale (e.g. m/s -> mm/s)


def _scaled(value, scale: float):
    if scale == 1.0 or _missing(value) or isinstance(value, (bool, np.bool_, str)):
        return value
    return float(value) * scale


def table_html(df: pd.DataFrame, cols: Sequence[Col], src: Source, keys: Sequence[str],
               row_class: Callable[[Mapping], str] | None = None,
               row_extra: Callable[[Mapping], list[str]] | None = None, table_id: str = "",
               caption: str = "") -> str:
    """A table whose every number cell's title gives its row's lineage and audit command."""
    head = "".join(f"<th>{c.header}</th>" for c in cols)
    body = []
    for row in df.to_dict("records"):
        selector = selector_of(row, keys)
        extra = row_extra(row) if row_extra else []
        cls = row_class(row) if row_class else ""
        cells = []
        for c in cols:
            value = row.get(c.key)
            shown = c.show(_scaled(value, c.scale))
            if c.number:
                title = src.title(selector, c.key, extra)
                cells.append(f'<td class="num" title="{esc(title)}">{shown}</td>')
            else:
                cells.append(f"<td>{shown}</td>")
        audit = src.audit(selector)
        trace_attr = f' data-trace="{esc(audit)}"' if audit else ""
        body.append(f'<tr{f" class={chr(34)}{cls}{chr(34)}" if cls else ""}{trace_attr}>{"".join(cells)}</tr>')
    ident = f' id="{esc(table_id)}"' if table_id else ""
    cap = f"<caption>{caption}</caption>" if caption else ""
    first = selector_of(df.iloc[0].to_dict(), keys) if len(df) else ""
    return (f'<div class="tablewrap"><table{ident}>{cap}<thead><tr>{head}</tr></thead>'
            f'<tbody>{"".join(body)}</tbody></table></div>' + lineage_line(src, first))


def kv_table(items: Sequence[tuple[str, str, str]]) -> str:
    """A two-column table of (label, value html, title)."""
    rows = "".join(f'<tr><th>{label}</th><td class="num" title="{esc(title)}">{value}</td></tr>'
                   for label, value, title in items)
    return f'<div class="tablewrap"><table class="kv"><tbody>{rows}</tbody></table></div>'


def text(x) -> str:
    return "-" if _missing(x) else esc(x)


_GREEK = {"pi": "&pi;", "rho": "&rho;", "mu": "&mu;", "alpha": "&alpha;", "beta": "&beta;"}


def formula(x) -> str:
    """Units and short formulas as HTML: ``A_O^2`` -> A<sub>O</sub><sup>2</sup>, ``rho`` -> &rho;."""
    if _missing(x):
        return "-"
    out = esc(x)
    out = re.sub(r"\b([A-Za-z])_([A-Za-z0-9]{1,2})\b", r"\1<sub>\2</sub>", out)
    out = re.sub(r"\^(-?\d+)", r"<sup>\1</sup>", out)
    return re.sub(r"\b(" + "|".join(_GREEK) + r")\b", lambda m: _GREEK[m.group(1)], out)


def yes_no(x) -> str:
    return "-" if _missing(x) else ("yes" if bool(x) else "no")


def png_ok(data: bytes) -> bool:
    """A complete PNG: signature, an IHDR of non-zero size first, IEND last."""
    if len(data) < 45 or not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR":
        return False
    width, height = struct.unpack(">II", data[16:24])
    return width > 0 and height > 0 and data[-8:-4] == b"IEND"


def png_data_uri(path: Path) -> str | None:
    """``data:image/png;base64,...`` of a PNG file, or None when it is missing, empty or not a PNG."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return None
    if not png_ok(data):
        return None
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def figure_html(src: Source, title: str, caption: str = "", fig_id: str = "") -> str:
    uri = png_data_uri(src.path)
    cap = f"<strong>{esc(title)}.</strong> {esc(caption)}" if caption else f"<strong>{esc(title)}.</strong>"
    ident = f' id="{esc(fig_id)}"' if fig_id else ""
    if uri is None:
        return (f'<figure class="fig missing"{ident}><div class="nofig">figure missing or not a PNG: '
                f'<code>{esc(src.label)}</code></div><figcaption>{cap}</figcaption>{lineage_line(src)}</figure>')
    return (f'<figure class="fig"{ident}><img src="{uri}" alt="{esc(title)}" data-file="{esc(src.label)}" '
            f'title="{esc(src.label)} | {esc(" | ".join(src.facts()))}">'
            f"<figcaption>{cap}</figcaption>{lineage_line(src)}</figure>")


def note(text_html: str, kind: str = "info") -> str:
    return f'<p class="note {kind}">{text_html}</p>'


def badge(text_: str, kind: str) -> str:
    return f'<span class="badge {kind}">{esc(text_)}</span>'


CSS = """
:root{--fg:#1b1f24;--muted:#57606a;--line:#d0d7de;--bg:#fff;--soft:#f6f8fa;--bad:#fde8e8;--badfg:#a40e26;
--good:#e6f4ea;--goodfg:#116329;--warn:#fff4d6;--warnfg:#7a4d00;--accent:#0a58ca}
*{box-sizing:border-box}
body{margin:0;font:15px/1.5 -apple-system,"Segoe UI",Roboto,"DejaVu Sans",Arial,sans-serif;color:var(--fg);
background:var(--bg)}
header.top{background:#12263f;color:#fff;padding:18px 28px}
header.top h1{margin:0 0 4px;font-size:24px}
header.top p{margin:2px 0;color:#d6e2f0}
header.top a{color:#cfe3ff}
nav{position:sticky;top:0;z-index:5;background:var(--soft);border-bottom:1px solid var(--line);padding:6px 28px;
font-size:14px;display:flex;flex-wrap:wrap;gap:2px 14px}
nav a{color:var(--accent);text-decoration:none;white-space:nowrap}
main{max-width:1240px;margin:0 auto;padding:8px 28px 40px}
section,figure{scroll-margin-top:56px}
h2{margin:32px 0 8px;padding-bottom:4px;border-bottom:2px solid var(--line);font-size:20px}
h3{margin:20px 0 6px;font-size:16px}
.tablewrap{overflow-x:auto;margin:6px 0}
table{border-collapse:collapse;font-size:13.5px;min-width:40%}
caption{text-align:left;font-weight:600;padding:4px 0}
th,td{border:1px solid var(--line);padding:3px 8px;text-align:left;vertical-align:top}
thead th{background:var(--soft);position:sticky;top:0}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap;cursor:help}
table.kv th{background:var(--soft);font-weight:600;white-space:nowrap}
table.kv td.num{text-align:left;white-space:normal}
td code{white-space:nowrap}
td.name{white-space:nowrap}
#lineage-table{font-size:12.5px}
#lineage-table td:first-child code,#lineage-table td:last-child code{white-space:normal;word-break:break-all}
#lineage-table details{margin:0}
tbody tr:nth-child(even){background:#fafbfc}
tr.flagged,tr.flagged:nth-child(even){background:var(--bad)}
tr.warned,tr.warned:nth-child(even){background:var(--warn)}
tr.verdict,tr.verdict:nth-child(even){background:var(--good)}
.lineage{font-size:12px;color:var(--muted);margin:2px 0 14px;word-break:break-word}
.lineage code{font-size:11.5px;word-break:break-all}
code{font-family:"DejaVu Sans Mono",Menlo,Consolas,monospace;font-size:12.5px;background:var(--soft);
padding:0 3px;border-radius:3px}
code.cmd{user-select:all}
figure.fig{margin:14px 0 22px;padding:10px;border:1px solid var(--line);border-radius:6px;background:#fff}
figure.fig img{display:block;max-width:100%;height:auto;margin:0 auto}
figcaption{font-size:13.5px;margin-top:6px}
.nofig{padding:40px;text-align:center;background:var(--bad);color:var(--badfg)}
.note{padding:8px 12px;border-radius:6px;margin:8px 0}
.note.info{background:var(--soft)}
.note.bad{background:var(--bad);color:var(--badfg)}
.note.good{background:var(--good);color:var(--goodfg)}
.note.warn{background:var(--warn);color:var(--warnfg)}
.badge{display:inline-block;padding:1px 8px;border-radius:10px;font-size:12.5px;font-weight:600}
.badge.good{background:var(--good);color:var(--goodfg)}
.badge.bad{background:var(--bad);color:var(--badfg)}
.badge.warn{background:var(--warn);color:var(--warnfg)}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:12px 0}
.card{flex:1 1 200px;border:1px solid var(--line);border-radius:6px;padding:8px 12px;background:var(--soft)}
.card .k{font-size:12px;color:var(--muted);text-transform:uppercase;letter-spacing:.03em}
.card .v{font-size:18px;font-weight:600}
.grid2{display:grid;grid-template-columns:repeat(auto-fit,minmax(520px,1fr));gap:12px}
details{margin:6px 0 12px}
summary{cursor:pointer;color:var(--accent)}
footer{max-width:1240px;margin:0 auto;padding:12px 28px 40px;color:var(--muted);font-size:12.5px}
@media print{nav{display:none}thead th{position:static}}
"""

# Counts, after `load`, the figures that decoded; the browser test and CI read the attributes.
IMAGE_CHECK_JS = """
window.addEventListener("load", function () {
  var imgs = document.images, ok = 0, broken = [];
  for (var i = 0; i < imgs.length; i++) {
    if (imgs[i].complete && imgs[i].naturalWidth > 0) { ok++; }
    else { broken.push(imgs[i].getAttribute("data-file") || imgs[i].alt || String(i)); }
  }
  document.body.setAttribute("data-images-loaded", String(ok));
  document.body.setAttribute("data-images-total", String(imgs.length));
  document.body.setAttribute("data-images-broken", broken.join(" "));
});
"""


def page(title: str, header_html: str, nav: Sequence[tuple[str, str]], body: str, footer_html: str,
         lineage_record: Mapping | None = None) -> str:
    nav_html = "".join(f'<a href="#{esc(a)}">{esc(t)}</a>' for a, t in nav)
    record = ""
    if lineage_record:
        # JSON inside <script type="application/json"> is inert data; '</' escaped so it cannot end the tag
        data = json.dumps(lineage_record, sort_keys=True, default=str).replace("</", "<\\/")
        record = f'<script type="application/json" id="lineage">{data}</script>'
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head>\n"
            f"<body>{header_html}<nav>{nav_html}</nav><main>{body}</main>"
            f"<footer>{footer_html}</footer>{record}<script>{IMAGE_CHECK_JS}</script></body></html>\n")


# ----------------------------------------------------------------------------------------------
# reading
# ----------------------------------------------------------------------------------------------

def _read_parquet(path: Path) -> pd.DataFrame | None:
    try:
        return pd.read_parquet(path) if path.is_file() else None
    except (OSError, ValueError):
        return None


def _read_json(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_captions(captions_dir: str | os.PathLike | None) -> dict[str, str]:
    """Figure captions from the Snakemake report's caption files (workflow/report/<figure>.rst)."""
    out: dict[str, str] = {}
    if captions_dir is None or not Path(captions_dir).is_dir():
        return out
    for p in sorted(Path(captions_dir).glob("*.rst")):
        out[p.stem] = rst_to_text(p.read_text(encoding="utf-8"))
    if "blind_confusion" in out:
        out.setdefault("fig17_blind_confusion", out["blind_confusion"])
    return out


def _now_utc() -> str:
    return dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def _generated_footer(lineage_record: Mapping | None, sources: Iterable[Source]) -> str:
    rec = lineage_record or {}
    commit = rec.get("git_commit")
    made = rec.get("created_utc") or _now_utc()
    who = (f"rule <code>{esc(rec.get('rule'))}</code>, commit <code>{esc(short(commit, 12))}</code>"
           + (" (uncommitted changes)" if rec.get("git_dirty") else "")
           + f", params <code>{esc(short(rec.get('params_sha256'), 12))}</code>") if rec else "outside the pipeline"
    commits = sorted({s.commit for s in sources if s.commit})
    mixed = (note(f"The files shown come from {len(commits)} different commits: "
                  + ", ".join(f"<code>{esc(short(c, 10))}</code>" for c in commits), "warn")
             if len(commits) > 1 else "")
    return (f"{mixed}<p>Generated {esc(made)} by isokinetic ({who}). Hover a number for the file, row, rule, "
            f"commit and parameters it comes from; the command after 'audit:' traces it to its raw rows.</p>")


# ----------------------------------------------------------------------------------------------
# campaign page
# ----------------------------------------------------------------------------------------------

DAMPER_LABELS = {
    "piston_area_m2": ("piston area A_p", "m^2"), "chamber_volume_1_m3": ("chamber volume V_1", "m^3"),
    "chamber_volume_2_m3": ("chamber volume V_2", "m^3"), "orifice_area_m2": ("orifice area A_O", "m^2"),
    "orifice_length_m": ("orifice length l_O", "m"), "discharge_coefficient": ("discharge coefficient C_D", "-"),
    "density_kg_m3": ("oil density rho", "kg/m^3"), "viscosity_Pa_s": ("oil viscosity mu", "Pa s"),
    "oil_compressibility_1_Pa": ("oil compressibility beta", "1/Pa"),
}

EFFECT_PARAM_UNITS = {"coulomb_force_N": "N", "leakage_conductance_m3_s_Pa": "m^3/(s Pa)", "asymmetry": "-",
                      "discharge_coefficient": "-", "viscosity_Pa_s": "Pa s", "air_volume_fraction": "-"}


@dataclass
class CampaignData:
    root: Path
    name: str
    meta: dict | None
    cases: pd.DataFrame | None
    quarantine: pd.DataFrame | None
    characteristic: pd.DataFrame | None
    repeatability: pd.DataFrame | None
    plan_check: pd.DataFrame | None
    models: pd.DataFrame | None
    comparison: pd.DataFrame | None
    harmonic: pd.DataFrame | None
    diagnosis: dict | None
    provenance: dict | None = None
    sources: Sources = field(default=None)  # type: ignore[assignment]

    @classmethod
    def read(cls, root: str | os.PathLike) -> CampaignData:
        root = Path(root)
        meta = _read_json(root / "ingest" / "campaign.json")
        provenance = _read_json(root / "provenance.json")
        data = cls(root=root, name=(meta or {}).get("campaign") or root.name, meta=meta,
                   cases=_read_parquet(root / "cases.parquet"),
                   quarantine=_read_parquet(root / "quarantine.parquet"),
                   characteristic=_read_parquet(root / "characteristic.parquet"),
                   repeatability=_read_parquet(root / "repeatability.parquet"),
                   plan_check=_read_parquet(root / "design" / "plan_check.parquet"),
                   models=_read_parquet(root / "models" / "models.parquet"),
                   comparison=_read_parquet(root / "models" / "comparison.parquet"),
                   harmonic=_read_parquet(root / "harmonic" / "harmonic.parquet"),
                   diagnosis=_read_json(root / "diagnosis.json"), provenance=provenance)
        data.sources = Sources(root, provenance)
        return data


def _summary_cards(d: CampaignData) -> str:
    cards = []

    def card(k: str, v: str, title: str) -> None:
        cards.append(f'<div class="card" title="{esc(title)}"><div class="k">{esc(k)}</div><div class="v">{v}</div></div>')

    if d.cases is not None:
        src = d.sources("cases.parquet")
        n_ok = int((d.cases["status"] == "ok").sum())
        card("cases ok / planned", f"{n_ok} / {len(d.cases)}",
             src.title("", "count of rows with status ok", ["counted by the report"]))
    if d.characteristic is not None:
        src = d.sources("characteristic.parquet")
        card("characteristic points", str(len(d.characteristic)), src.title("", "count of rows", ["counted by the report"]))
    if d.plan_check is not None:
        src = d.sources("design/plan_check.parquet")
        card("plan cases flagged", str(int(d.plan_check["flagged"].sum())),
             src.title("", "count of rows with flagged true", ["counted by the report"]))
    if d.repeatability is not None:
        src = d.sources("repeatability.parquet")
        card("repeatability pairs flagged", f"{int(d.repeatability['flagged'].sum())} / {len(d.repeatability)}",
             src.title("", "count of rows with flagged true", ["counted by the report"]))
    diag = d.diagnosis
    if diag and diag.get("status", "ok") == "ok":
        src = d.sources("diagnosis.json")
        verdict = ", ".join(diag.get("verdict") or []) or "none (nominal model explains)"
        explained = diag.get("explained", True)
        card("diagnosis verdict", esc(verdict) + ("" if explained else " " + badge("not explained", "bad")),
             src.title("verdict", "verdict"))
        card(f"gap {diag.get('metric', '')} before -> after",
             f"{fmt(diag.get('gap_before'), 3)} &rarr; {fmt(diag.get('gap_after'), 3)}",
             src.title("gap_before", "gap_before (gap_after: key gap_after)"))
        card("shrink", fmt(diag.get("shrink"), 3), src.title("shrink", "shrink"))
    if d.quarantine is not None:
        src = d.sources("quarantine.parquet")
        card("quarantined cases", str(d.quarantine["case"].nunique() if len(d.quarantine) else 0),
             src.title("", "count of distinct cases", ["counted by the report"]))
    return f'<div class="cards">{"".join(cards)}</div>'


def _header_section(d: CampaignData) -> str:
    meta = d.meta or {}
    src = d.sources("ingest/campaign.json")
    items = [("campaign", esc(d.name), src.title("campaign", "campaign")),
             ("source", text(meta.get("source")), src.title("source", "source")),
             ("description", text(meta.get("description")), src.title("description", "description")),
             ("temperature", f"{fmt(meta.get('temperature_C'))} &deg;C", src.title("temperature_C", "temperature_C"))]
    if meta.get("manifest_file"):
        items.append(("manifest", f"<code>{esc(meta['manifest_file'])}</code> (sha256 "
                                  f"<code>{esc(short(meta.get('manifest_sha256'), 16))}</code>)",
                      src.title("manifest_file", "manifest_file")))
    gen = (meta.get("metadata") or {}).get("generated_by")
    if isinstance(gen, Mapping):
        items.append(("generated by", esc(f"{gen.get('generator', '?')} (config campaign "
                                          f"{gen.get('config_campaign', '?')}, seed {gen.get('seed', '?')})"),
                      src.title("metadata.generated_by", "generated_by")))
    out = ['<section id="header"><h2>Campaign</h2>', kv_table(items)]
    damper = meta.get("damper")
    out.append("<h3>Damper data (nominal, from the manifest)</h3>")
    if isinstance(damper, Mapping) and damper:
        rows = []
        for key, value in damper.items():
            label, unit = DAMPER_LABELS.get(key, (key, ""))
            unit_html = "" if unit in ("", "-") else formula(unit)
            rows.append((formula(label), f"{fmt(value)} {unit_html}", src.title(f"damper.{key}", key)))
        out.append(kv_table(rows))
    else:
        out.append(note("No damper block: there is no nominal model, so the design check, the nominal curves "
                        "and the diagnosis have nothing to compare against.", "warn"))
    out.append(lineage_line(src, "damper"))
    if d.provenance is not None:
        out.append(_provenance_note(d.provenance))
    out.append(_summary_cards(d))
    out.append("</section>")
    return "".join(out)


def _provenance_note(prov: Mapping) -> str:
    """What the campaign's provenance.json checks say: raw files unchanged, stages current."""
    link = '<a href="provenance.json">provenance.json</a>'
    checks = prov.get("checks")
    if not isinstance(checks, Mapping):
        return note(f"Provenance of this campaign's outputs: {link}.")
    git = prov.get("git") or {}
    commit = f"commit <code>{esc(short(git.get('commit'), 12))}</code>" if git.get("commit") else "no git commit"
    made = f" (made {esc(prov.get('created_utc', '?'))}, {commit})"
    if checks.get("ok"):
        return note(f"Provenance checks pass: raw files unchanged since ingest, every stage's inputs current, "
                    f"every output carries lineage &mdash; {link}{made}.", "good")
    problems = []
    labels = (("changed_raw_files", "raw files changed since ingest"), ("missing_raw_files", "raw files missing"),
              ("stale_stages", "stages whose inputs changed since they ran"),
              ("inconsistent_stages", "stages whose outputs come from different runs"),
              ("files_without_lineage", "files without lineage"))
    for key, label in labels:
        items = checks.get(key) or []
        if items:
            problems.append(f"{label}: " + ", ".join(f"<code>{esc(x)}</code>" for x in items[:12])
                            + (f" and {len(items) - 12} more" if len(items) > 12 else ""))
    return note(f"Provenance checks report problems ({link}{made}):<ul>"
                + "".join(f"<li>{p}</li>" for p in problems) + "</ul>", "bad")


def _plan_section(d: CampaignData) -> str:
    out = ['<section id="plan"><h2>Test plan and plan check</h2>']
    pc = d.plan_check
    src = d.sources("design/plan_check.parquet")
    if pc is None:
        return "".join(out) + lineage_line(src) + "</section>"
    flagged = pc[pc["flagged"].astype(bool)]
    if len(flagged):
        items = "".join(
            f'<li title="{esc(src.title(selector_of(r, ["case"]), "reasons"))}"><strong>{esc(r["case"])}</strong>: '
            f'{esc(r["reasons"])}</li>' for r in flagged.to_dict("records"))
        out.append(note(f"{len(flagged)} of {len(pc)} planned cases break a design constraint "
                        f"(a-priori check with the nominal damper data, paper Sec. 3.3):", "warn")
                   + f"<ul>{items}</ul>")
    else:
        out.append(note(f"None of the {len(pc)} planned cases breaks a design constraint.", "good"))
    cols = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
            Col("status", "status", text, False),
            Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("period_s", "T [s]"),
            Col("frequency_Hz", "f [Hz]"), Col("amplitude_m", "amplitude [mm]", scale=1e3),
            Col("G3", "G3", lambda x: fmt(x, 3)),
            Col("stroke_to_converge_m", "stroke to converge [mm]", lambda x: fmt(x, 3), scale=1e3),
            Col("window_start_stroke_m", "window start stroke [mm]", lambda x: fmt(x, 3), scale=1e3),
            Col("flagged", "flagged", yes_no, False), Col("reasons", "reasons", text, False)]
    out.append(table_html(pc, cols, src, ["case"], row_class=lambda r: "flagged" if r["flagged"] else "",
                          table_id="plan-check"))
    out.append("</section>")
    return "".join(out)


def _cases_section(d: CampaignData) -> str:
    """The cases table: status, quality and the measured motion of each case (validate)."""
    out = ['<section id="cases"><h2>Cases and measured motion</h2>']
    cases = d.cases
    src = d.sources("cases.parquet")
    if cases is None:
        return "".join(out) + lineage_line(src) + "</section>"
    cases = cases.copy()
    for column in ("motion_start_s", "delay_s", "velocity_ratio", "motion_rms_m"):
        if column not in cases:
            cases[column] = np.nan      # a cases table written before the motion was measured
    if "quality" not in cases:
        cases["quality"] = np.where(cases["status"] == "ok", "ok", "quarantined")
    out.append(note("Windows are cut where the measured piston motion is: at the <em>motion start</em> (the record "
                    "time at which the plan's t = 0 lies, from the displacement channel) plus the plan's window "
                    "times. The <em>delay</em> is the motion start after the record's first sample (actuator delay "
                    "and servo lag); the speed ratio is the mean measured |v| of the four half-periods over the "
                    "planned 4Y/T (Eq. 26); the motion rms is the displacement's rms departure from the planned "
                    "triangle (LVDT noise included)."))
    cols = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
            Col("status", "status", text, False), Col("n_samples", "samples"),
            Col("motion_start_s", "motion start [s]", lambda x: fmt(x, 5)),
            Col("delay_s", "delay [ms]", lambda x: fmt(x, 3), scale=1e3),
            Col("velocity_ratio", "speed / planned", lambda x: fmt(x, 4)),
            Col("motion_rms_m", "motion rms [&micro;m]", lambda x: fmt(x, 3), scale=1e6),
            Col("quality", "quality", text, False)]

    def row_class(r: Mapping) -> str:
        if r["status"] != "ok":
            return "flagged"
        return "warned" if isinstance(r.get("quality"), str) and r["quality"] != "ok" else ""

    out.append(table_html(cases, cols, src, ["case"], row_class=row_class, table_id="cases-table"))
    out.append("</section>")
    return "".join(out)


def _figures(d: CampaignData, figures: Sequence[tuple[str, str]], captions: Mapping[str, str]) -> str:
    return "".join(figure_html(d.sources(rel), title, captions.get(Path(rel).stem, ""), fig_id=Path(rel).stem)
                   for rel, title in figures)


def _characteristic_section(d: CampaignData, captions: Mapping[str, str]) -> str:
    out = ['<section id="characteristic"><h2>Steady characteristic</h2>']
    char = d.characteristic
    src = d.sources("characteristic.parquet")
    out.append(_figures(d, CHARACTERISTIC_FIGURES, captions))
    if char is None:
        return "".join(out) + lineage_line(src) + "</section>"
    speed = char["velocity_m_s"].abs()
    char = char.assign(_speed=speed).sort_values(["direction", "_speed", "case", "period"]).reset_index(drop=True)
    cols = [Col("case", "case", text, False), Col("direction", "dir", text, False),
            Col("period", "period"), Col("segment", "segment"),
            Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_N", "force [N]"),
            Col("force_std_N", "force std [N]", lambda x: fmt(x, 3)), Col("n_samples", "samples"),
            Col("raw_file", "raw file", lambda x: f"<code>{text(x)}</code>", False),
            Col("row_start", "rows from"), Col("row_stop", "rows to (excl.)"),
            Col("window_start_s", "window from [s]"), Col("window_end_s", "window to [s]"),
            Col("repeatability_flagged", "rep. flagged", yes_no, False)]

    def extra(r):
        return [f"raw {r.get('raw_file')} rows {r.get('row_start')}-{r.get('row_stop')} "
                f"(window {fmt_text(r.get('window_start_s'))}-{fmt_text(r.get('window_end_s'))} s, "
                f"raw sha256 {short(r.get('raw_sha256'))})"]

    out.append(f"<details><summary>All {len(char)} characteristic points (window mean force, velocity from a "
               "least-squares line through the window's displacement; raw file and row range of each)</summary>")
    out.append(table_html(char, cols, src, ["case", "segment"], row_extra=extra,
                          row_class=lambda r: "flagged" if r.get("repeatability_flagged") else "",
                          table_id="characteristic-points"))
    out.append("</details></section>")
    return "".join(out)


def _repeatability_section(d: CampaignData) -> str:
    out = ['<section id="repeatability"><h2>Repeatability (period 2 against period 1)</h2>']
    rep = d.repeatability
    src = d.sources("repeatability.parquet")
    if rep is None:
        return "".join(out) + lineage_line(src) + "</section>"
    cols = [Col("case", "case", text, False), Col("direction", "dir", text, False),
            Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_period1_N", "F period 1 [N]"),
            Col("force_period2_N", "F period 2 [N]"), Col("rel_diff", "(F2-F1)/mean", fmt_pct),
            Col("tolerance", "tolerance", fmt_pct), Col("flagged", "flagged", yes_no, False)]
    flagged = rep[rep["flagged"].astype(bool)]
    tol = rep["tolerance"].iloc[0] if len(rep) else float("nan")
    if len(rep):
        worst = rep.loc[rep["rel_diff"].abs().idxmax()]
        worst_txt = (f" Largest difference: {fmt_pct(worst['rel_diff'])} (case {esc(worst['case'])}, "
                     f"direction {esc(worst['direction'])}).")
    else:
        worst_txt = ""
    if len(flagged):
        out.append(note(f"{len(flagged)} of {len(rep)} case/direction pairs differ by more than the tolerance "
                        f"({fmt_pct(tol)}).{worst_txt}", "bad"))
        out.append("<h3>Flagged pairs</h3>")
        out.append(table_html(flagged, cols, src, ["case", "direction"], row_class=lambda r: "flagged",
                              table_id="repeatability-flagged"))
    else:
        out.append(note(f"No pair of the {len(rep)} differs by more than the tolerance ({fmt_pct(tol)}).{worst_txt}",
                        "good"))
    out.append(f"<details><summary>All {len(rep)} pairs</summary>")
    out.append(table_html(rep, cols, src, ["case", "direction"],
                          row_class=lambda r: "flagged" if r["flagged"] else "", table_id="repeatability-all"))
    out.append("</details></section>")
    return "".join(out)


MODEL_NAMES = {"wallaschek": "Wallaschek (symmetric: F = sign(v) F_C + D_L v + D_Q v|v|)",
               "surace": "Surace (one parameter set per direction)"}


def _models_section(d: CampaignData, captions: Mapping[str, str]) -> str:
    out = ['<section id="models"><h2>Model comparison</h2>', _figures(d, MODEL_FIGURES, captions)]
    models = d.models
    src = d.sources("models/models.parquet")
    if models is None or not len(models):
        out.append(note("No fitted models (too few characteristic points)." if models is not None else
                        "models.parquet was not produced.", "warn"))
        return "".join(out) + lineage_line(src) + "</section>"
    cols = [Col("direction", "dir", text, False), Col("parameter", "parameter", text, False),
            Col("estimate", "estimate"), Col("ci_low", "95 % low"), Col("ci_high", "95 % high"),
            Col("std_error", "std error", lambda x: fmt(x, 3)), Col("unit", "unit", formula, False),
            Col("description", "meaning", formula, False), Col("assumption", "assuming", formula, False)]
    for model, group in models.groupby("model", sort=False):
        first = group.iloc[0]
        scale = first.get("residual_scale")
        fit_note = (f"{int(first['n_points'])} points, {int(first['dof'])} degrees of freedom, rms residual "
                    f"{fmt(first['rms_residual_N'])} N, residual scale {fmt(scale, 3)}")
        kind = "warn" if not _missing(scale) and float(scale) > 3 else "info"
        extra = (" &mdash; far above 1: the model form does not fit the characteristic within its noise"
                 if kind == "warn" else "")
        out.append(f"<h3>{esc(MODEL_NAMES.get(model, model))}</h3>")
        fit_sel = selector_of(first, ["model", "direction", "parameter"])
        out.append(f'<p class="note {kind}" title="{esc(src.title(fit_sel, "n_points,dof,rms_residual_N,residual_scale"))}">'
                   f"{fit_note}{extra}</p>")
        fitted = group[group["kind"] == "fitted"]
        derived = group[group["kind"] != "fitted"]
        keys = ["model", "direction", "parameter"]
        out.append(table_html(fitted, cols, src, keys, caption="Fitted parameters, 95 % intervals",
                              row_extra=_fit_rows, table_id=f"models-{model}-fitted"))
        if len(derived):
            out.append(table_html(derived, cols, src, keys, row_extra=_fit_rows,
                                  caption="Physical readings (equivalent values with the nominal geometry)",
                                  table_id=f"models-{model}-derived"))
    comp = d.comparison
    csrc = d.sources("models/comparison.parquet")
    if comp is not None and len(comp):
        items = []
        for col, label in (("rel_err_nominal_plan", "nominal model through the plan"),
                           ("rel_err_nominal_eq31", "incompressible nominal (Eq. 31)"),
                           ("rel_err_wallaschek", "Wallaschek fit"), ("rel_err_surace", "Surace fit")):
            if col in comp:
                v = comp[col].to_numpy(dtype=float)
                v = v[np.isfinite(v)]
                if v.size:
                    value = math.sqrt(float(np.mean(v ** 2)))
                    items.append((esc(label), fmt_pct(value), csrc.title(
                        "", col, [f"computed by the report: rms over {v.size} points of {col}"])))
        if items:
            out.append("<h3>rms relative error against the measured characteristic</h3>" + kv_table(items)
                       + lineage_line(csrc))
    out.append("</section>")
    return "".join(out)


def _fit_rows(row: Mapping) -> list[str]:
    """Row-level lineage of a fitted parameter: the characteristic rows the fit used."""
    rows = row.get("source_rows")
    if not isinstance(rows, str) or not rows:
        return []
    shown = rows if len(rows) <= 400 else rows[:400] + "..."
    return [f"fitted on {row.get('n_points')} rows (case/segment) of {row.get('source_file') or 'characteristic.parquet'}: "
            f"{shown}"]


def _harmonic_section(d: CampaignData, captions: Mapping[str, str]) -> str:
    out = ['<section id="harmonic"><h2>Harmonic and free records</h2>', _figures(d, HARMONIC_FIGURES, captions)]
    h = d.harmonic
    src = d.sources("harmonic/harmonic.parquet")
    if h is None:
        return "".join(out) + lineage_line(src) + "</section>"
    if not len(h):
        out.append(note("The campaign has no sine or free records."))
        return "".join(out) + lineage_line(src) + "</section>"
    cols = [Col("case", "case", text, False), Col("waveform", "waveform", text, False),
            Col("kind", "kind", text, False), Col("direction", "dir", text, False),
            Col("velocity_m_s", "velocity [mm/s]", scale=1e3), Col("force_N", "force [N]"),
            Col("frequency_Hz", "f [Hz]"), Col("amplitude_m", "amplitude [mm]", scale=1e3),
            Col("lag_s", "force lag [s]", lambda x: fmt(x, 3)), Col("n_points", "points")]
    h = h.reset_index(drop=True)
    keys = ["case", "kind", "direction"]
    if h.duplicated(keys).any():  # binned points of free records: by position in the file
        h, keys = h.assign(row=h.index), ["row"]
    out.append(table_html(h, cols, src, keys, table_id="harmonic-points"))
    out.append("</section>")
    return "".join(out)


def _design_section(d: CampaignData, captions: Mapping[str, str]) -> str:
    return ('<section id="design"><h2>Test design</h2>' + _figures(d, DESIGN_FIGURES, captions) + "</section>")


def _diagnosis_section(d: CampaignData, captions: Mapping[str, str]) -> str:
    out = ['<section id="diagnosis"><h2>Sim-to-real gap diagnosis</h2>']
    diag = d.diagnosis
    src = d.sources("diagnosis.json")
    if diag is None:
        out.append(note("diagnosis.json was not produced.", "warn"))
        return "".join(out) + lineage_line(src) + _figures(d, DIAGNOSIS_FIGURES, captions) + "</section>"
    if diag.get("status", "ok") != "ok":
        out.append(note(f"Not diagnosed: {esc(diag.get('reason', diag.get('status')))}", "warn"))
        return "".join(out) + lineage_line(src) + _figures(d, DIAGNOSIS_FIGURES, captions) + "</section>"
    verdict = diag.get("verdict") or []
    explained = diag.get("explained", True)
    metric = diag.get("metric", "gap")
    if not verdict:
        out.append(note("The nominal model explains the characteristic within noise and repeatability: "
                        "no effect is added.", "good"))
    elif explained:
        out.append(note(f"<strong>Which:</strong> {esc(', '.join(verdict))} explain the gap within noise "
                        f"(fit and holdout pass the chi-squared test).", "good"))
    else:
        out.append(note(f"<strong>Not explained.</strong> Best candidate: {esc(', '.join(verdict))}. "
                        f"{esc(diag.get('unexplained_note', ''))}", "bad"))

    def t(key: str, label: str) -> str:
        return src.title(key, label)

    items = [("verdict", esc(", ".join(verdict) or "[] (nominal)"), t("verdict", "verdict")),
             ("explained", yes_no(explained), t("explained", "explained")),
             (f"gap before ({esc(metric)})", fmt(diag.get("gap_before")), t("gap_before", "gap_before")),
             (f"gap after ({esc(metric)})", fmt(diag.get("gap_after")), t("gap_after", "gap_after")),
             (f"holdout gap after ({esc(metric)})", fmt(diag.get("holdout_gap_after")),
              t("holdout_gap_after", "holdout_gap_after")),
             ("shrink (before / after)", fmt(diag.get("shrink")), t("shrink", "shrink"))]
    if "rms_rel_before" in diag:
        items.append(("rms relative error before -> after",
                      f"{fmt_pct(diag.get('rms_rel_before'))} &rarr; {fmt_pct(diag.get('rms_rel_after'))}",
                      t("rms_rel_before", "rms_rel_before (rms_rel_after: key rms_rel_after)")))
    noise = diag.get("noise") or {}
    if noise:
        items.append(("data", f"{noise.get('n_windows', '-')} windows + {noise.get('n_transient_bins', '-')} "
                              f"transient bins; between-period scatter {fmt_pct(noise.get('repeatability_rel'))}",
                      t("noise", "noise")))
    if "nominal_p_value" in diag:
        items.append(("nominal test p-value (chi-squared, instrument terms fitted)", fmt(diag.get("nominal_p_value"), 3),
                      t("nominal_p_value", "nominal_p_value")))
    out.append("<h3>How far</h3>" + kv_table(items))
    inst = diag.get("instrument") or {}
    if inst:
        def shown(key, scale=1.0, unit=""):
            value = inst.get(key)
            return "not needed" if value is None else f"{fmt(value * scale)} {unit}".strip()
        out.append("<h3>Instrument terms (the rig's own errors, never damper effects)</h3>" + kv_table([
            ("actuator delay (median over cases)", shown("delay_s", 1e3, "ms"), t("instrument.delay_s", "delay_s")),
            ("load-cell zero offset", shown("force_offset_N", 1.0, "N"), t("instrument.force_offset_N", "force_offset_N")),
            ("load-cell gain", shown("force_gain"), t("instrument.force_gain", "force_gain"))]))
        if diag.get("confounded_instrument_note"):
            out.append(note(esc(diag["confounded_instrument_note"]), "warn"))

    ident = (diag.get("identifiability") or {}).get("parameters") or {}
    params = diag.get("params") or {}
    if params:
        rows = "".join(
            f"<tr><td><code>{esc(k)}</code></td>"
            f'<td class="num" title="{esc(t(f"params.{k}", k))}">{fmt(v)}</td>'
            f'<td class="num" title="{esc(t(f"identifiability.parameters.{k}.std_error", "std_error"))}">'
            f"{fmt((ident.get(k) or {}).get('std_error'), 3)}</td>"
            f"<td>{formula(EFFECT_PARAM_UNITS.get(k, ''))}</td></tr>" for k, v in params.items())
        out.append("<h3>Fitted effect parameters of the verdict</h3>"
                   f'<div class="tablewrap"><table id="diagnosis-params"><thead><tr><th>parameter</th><th>estimate</th>'
                   f"<th>std error</th><th>unit</th></tr></thead><tbody>{rows}</tbody></table></div>")
        corr = (diag.get("identifiability") or {}).get("correlation") or {}
        if corr:
            strong = {k: v for k, v in corr.items() if abs(v) >= 0.8}
            text_ = ", ".join(f"{esc(k)} {fmt(v, 2)}" for k, v in corr.items())
            out.append(note(f"Parameter correlations: {text_}."
                            + (" Strongly correlated pairs are hard to tell apart." if strong else ""),
                            "warn" if strong else "info"))
    where = diag.get("where") or []
    out.append("<h3>Where: speed bands with |z| &gt; 3 (nominal model)</h3>")
    if where:
        wdf = pd.DataFrame(where).reset_index(drop=True)
        wdf["band"] = [f"where.{i}" for i in range(len(wdf))]
        cols = [Col("direction", "dir", text, False), Col("v_min_m_s", "from [mm/s]", scale=1e3),
                Col("v_max_m_s", "to [mm/s]", scale=1e3), Col("n_cases", "cases"),
                Col("mean_rel_error", "mean signed rel. error", fmt_pct), Col("mean_z", "mean z", lambda x: fmt(x, 3)),
                Col("significant", "significant", yes_no, False)]
        cols = [c for c in cols if c.key in wdf]
        out.append(_json_table(wdf, cols, src, "band", "where-bands", json_keys=set(pd.DataFrame(where).columns)))
        out.append(note("Negative error: the damper is weaker than the nominal model in that band."))
    else:
        out.append(note("No band: the residual stays within what noise and repeatability explain.", "good"))

    cands = diag.get("candidates") or []
    if cands:
        shown = list(range(min(8, len(cands))))
        in_verdict = [i for i, c in enumerate(cands) if set(c.get("effects") or []) == set(verdict)]
        shown += [i for i in in_verdict[:1] if i not in shown]  # the verdict's row, wherever it ranks
        top = [cands[i] for i in shown]
        cdf = pd.DataFrame({
            "rank": [i + 1 for i in shown],
            "key": [f"candidates.{i}" for i in shown],
            "effects": [", ".join(c.get("effects") or []) or "(nominal)" for c in top],
            "explained": [c.get("explained") for c in top],
            "gap_after": [c.get("gap_after") for c in top],
            "holdout_gap_after": [c.get("holdout_gap_after") for c in top],
            "score": [c.get("score") for c in top],
            "params": ["; ".join(f"{k} = {fmt_text(v)}" for k, v in (c.get("params") or {}).items()) for c in top],
        })
        cols = [Col("rank", "rank"), Col("effects", "effects", text, False),
                Col("explained", "explains", yes_no, False), Col("gap_after", "gap after"),
                Col("holdout_gap_after", "holdout gap"), Col("score", "score"),
                Col("params", "fitted parameters", text, False)]
        out.append(f"<h3>Top candidates ({len(top)} of {len(cands)}, best score first; the verdict's row "
                   "in green)</h3>")
        vset = set(verdict)
        out.append(_json_table(cdf, cols, src, "key", "candidates", json_keys={"gap_after", "holdout_gap_after", "score"},
                               row_class=lambda r: "verdict" if set(r["effects"].split(", ")) == vset else ""))
    confounded = diag.get("confounded") or []
    if confounded:
        groups = "; ".join(", ".join(g) if isinstance(g, (list, tuple)) else str(g) for g in confounded)
        out.append(note(f"<strong>Confounded:</strong> {esc(groups)} &mdash; explaining candidates of the same size "
                        f"within 10 score units; the data cannot tell them apart, the verdict holds the preferred one.",
                        "warn"))
    else:
        out.append(note("Confounded: none (no other explaining candidate of the same size scores within 10 units)."))
    out.append(lineage_line(src, "verdict"))
    sources = diag.get("sources")
    if isinstance(sources, Mapping) and sources:
        windows = [k for k in str(sources.get("windows") or "").split(",") if k]
        series = sources.get("timeseries") or {}
        listing = "".join(f"<li><code>{esc(c)}</code>: <code>{esc(v.get('timeseries_file', ''))}</code> from "
                          f"<code>{esc(v.get('raw_file', ''))}</code> (sha256 {esc(short(v.get('raw_sha256')))})</li>"
                          for c, v in series.items() if isinstance(v, Mapping))
        out.append(f"<details><summary>Observations the diagnosis used: {len(windows)} windows of "
                   f"<code>{esc(sources.get('characteristic_file', 'characteristic.parquet'))}</code> and the "
                   f"transient bins of {len(series)} time series</summary><p>windows (case/segment): "
                   f"<code>{esc(', '.join(windows))}</code></p><ul>{listing}</ul></details>")
    out.append(_figures(d, DIAGNOSIS_FIGURES, captions))
    out.append("</section>")
    return "".join(out)


def _json_path(base: str, column: str, json_keys: Iterable[str]) -> str:
    return f"{base}.{column}" if column in json_keys else base


def _json_table(df: pd.DataFrame, cols: Sequence[Col], src: Source, key: str, table_id: str,
                row_class: Callable[[Mapping], str] | None = None, json_keys: Iterable[str] = ()) -> str:
    """A table of JSON list entries: a cell's selector is its key path (``where.0.v_min_m_s``)."""
    json_keys = set(json_keys)
    head = "".join(f"<th>{c.header}</th>" for c in cols)
    body = []
    for row in df.to_dict("records"):
        cls = row_class(row) if row_class else ""
        cells = "".join(
            (f'<td class="num" title="{esc(src.title(_json_path(row[key], c.key, json_keys), c.key))}">'
             f"{c.show(_scaled(row.get(c.key), c.scale))}</td>"
             if c.number else f"<td>{c.show(_scaled(row.get(c.key), c.scale))}</td>") for c in cols)
        audit = src.audit(row[key])
        trace_attr = f' data-trace="{esc(audit)}"' if audit else ""
        body.append(f'<tr{f" class={chr(34)}{cls}{chr(34)}" if cls else ""}{trace_attr}>{cells}</tr>')
    return (f'<div class="tablewrap"><table id="{esc(table_id)}"><thead><tr>{head}</tr></thead>'
            f'<tbody>{"".join(body)}</tbody></table></div>')


def _quarantine_section(d: CampaignData) -> str:
    out = ['<section id="quarantine"><h2>Quarantined cases</h2>']
    q = d.quarantine
    src = d.sources("quarantine.parquet")
    if q is None:
        return "".join(out) + lineage_line(src) + "</section>"
    if not len(q):
        out.append(note("No case was set aside: every planned case passed validation.", "good"))
        out.append(lineage_line(src))
    else:
        cols = [Col("case", "case", text, False), Col("stage", "stage", text, False),
                Col("column", "column", text, False), Col("row", "first bad row"),
                Col("reason", "reason", text, False)]
        out.append(note(f"{q['case'].nunique()} case(s) set aside; the rest of the campaign carries on.", "bad"))
        out.append(table_html(q, cols, src, ["case", "stage"], row_class=lambda r: "flagged", table_id="quarantine"))
    out.append("</section>")
    return "".join(out)


def _lineage_section(sources: Sequence[Source]) -> str:
    rows = []
    for s in sorted(sources, key=lambda s: s.label):
        rec = s.record or {}
        inputs = rec.get("inputs") or {}
        logs = rec.get("log") or []
        inputs_html = ("<details><summary>%d inputs</summary>%s</details>" % (
            len(inputs), "<br>".join(f"<code>{esc(k)}</code> {esc(short(v, 12))}" for k, v in inputs.items()))
            if inputs else "-") + "".join(f"<div>log <code>{esc(x)}</code></div>" for x in logs)
        rows.append(f"<tr><td><code>{esc(s.label)}</code></td><td>{esc(s.rule or '?')}</td>"
                    f"<td><code>{esc(short(rec.get('git_commit'), 12))}</code>"
                    f"{' dirty' if rec.get('git_dirty') else ''}</td>"
                    f"<td><code>{esc(short(rec.get('params_sha256'), 12))}</code></td>"
                    f"<td><code>{esc(short(rec.get('config_sha256'), 12))}</code></td>"
                    f"<td>{esc(rec.get('created_utc', '-'))}</td><td>{esc(s.origin if s.record else 'not recorded')}</td>"
                    f"<td><code>{esc(short(s.sha256, 16)) if s.exists else 'missing'}</code></td><td>{inputs_html}</td></tr>")
    return ('<section id="lineage"><h2>Lineage of this page</h2>'
            "<p>Every file this page shows numbers or figures from, with the lineage record it carries "
            "(Parquet schema metadata <code>isokinetic.lineage</code>, JSON key <code>lineage</code>, or the "
            "campaign's <code>provenance.json</code>) and its sha256 as read for this page.</p>"
            '<div class="tablewrap"><table id="lineage-table"><thead><tr><th>file</th><th>rule</th><th>commit</th>'
            "<th>params sha256</th><th>config sha256</th><th>made (UTC)</th><th>record</th><th>file sha256</th>"
            f"<th>inputs</th></tr></thead><tbody>{''.join(rows)}</tbody></table></div></section>")


CAMPAIGN_NAV = [("header", "Campaign"), ("plan", "Plan check"), ("cases", "Cases"),
                ("characteristic", "Characteristic"),
                ("repeatability", "Repeatability"), ("models", "Models"), ("harmonic", "Harmonic"),
                ("design", "Design"), ("diagnosis", "Diagnosis"), ("quarantine", "Quarantine"),
                ("lineage", "Lineage")]


def render_campaign_report(campaign_root: str | os.PathLike, *, captions_dir: str | os.PathLike | None = None,
                           lineage_record: Mapping | None = None, index_href: str | None = "../index.html") -> str:
    """The HTML page of one campaign, read from ``results/<campaign>/`` (missing parts are said)."""
    d = CampaignData.read(campaign_root)
    captions = read_captions(captions_dir)
    meta = d.meta or {}
    sections = [_header_section(d), _plan_section(d), _cases_section(d), _characteristic_section(d, captions),
                _repeatability_section(d), _models_section(d, captions), _harmonic_section(d, captions),
                _design_section(d, captions), _diagnosis_section(d, captions), _quarantine_section(d)]
    sections.append(_lineage_section(d.sources.all()))
    back = f' &middot; <a href="{esc(index_href)}">all campaigns</a>' if index_href else ""
    header = (f'<header class="top"><h1>{esc(d.name)}</h1><p>{esc(meta.get("description") or "")}</p>'
              f"<p>source: {esc(meta.get('source') or '-')}{back}</p></header>")
    return page(f"isokinetic - {d.name}", header, CAMPAIGN_NAV, "".join(sections),
                _generated_footer(lineage_record, d.sources.all()), lineage_record)


def write_campaign_report(campaign_root: str | os.PathLike, out_path: str | os.PathLike, **kwargs) -> Path:
    """Write :func:`render_campaign_report` to ``out_path`` atomically."""
    return write_text(render_campaign_report(campaign_root, **kwargs), out_path)


# ----------------------------------------------------------------------------------------------
# index page
# ----------------------------------------------------------------------------------------------

def _campaign_row(results_root: Path, campaign: str) -> tuple[str, list[Source]]:
    root = results_root / campaign
    srcs = Sources(root, _read_json(root / "provenance.json"))
    meta = _read_json(root / "ingest" / "campaign.json") or {}
    cases = _read_parquet(root / "cases.parquet")
    char = _read_parquet(root / "characteristic.parquet")
    pc = _read_parquet(root / "design" / "plan_check.parquet")
    rep = _read_parquet(root / "repeatability.parquet")
    q = _read_parquet(root / "quarantine.parquet")
    models = _read_parquet(root / "models" / "models.parquet")
    diag = _read_json(root / "diagnosis.json")

    def cell(value_html: str, src: Source, selector: str, column: str, extra: Sequence[str] = ()) -> str:
        return f'<td class="num" title="{esc(src.title(selector, column, extra))}">{value_html}</td>'

    counted = ["counted by the index"]
    cells = [f'<td class="name"><a href="{esc(campaign)}/report.html"><strong>{esc(campaign)}</strong></a>'
             f'<br><small>{esc(meta.get("source") or "-")}</small></td>']
    src = srcs("cases.parquet")
    cells.append(cell(f"{int((cases['status'] == 'ok').sum())} / {len(cases)}" if cases is not None else "-",
                      src, "", "count of rows with status ok / all rows", counted))
    src = srcs("quarantine.parquet")
    cells.append(cell(str(q["case"].nunique() if q is not None and len(q) else 0) if q is not None else "-",
                      src, "", "distinct cases", counted))
    src = srcs("characteristic.parquet")
    cells.append(cell(str(len(char)) if char is not None else "-", src, "", "rows", counted))
    src = srcs("design/plan_check.parquet")
    cells.append(cell(str(int(pc["flagged"].sum())) if pc is not None else "-", src, "", "count of flagged rows",
                      counted))
    src = srcs("repeatability.parquet")
    cells.append(cell(str(int(rep["flagged"].sum())) if rep is not None else "-", src, "", "count of flagged rows",
                      counted))
    src = srcs("models/models.parquet")
    scale = None
    if models is not None and len(models) and "wallaschek" in set(models["model"]):
        scale = models.loc[models["model"] == "wallaschek", "residual_scale"].iloc[0]
    cells.append(cell(fmt(scale, 3), src, "model=wallaschek,direction=both,parameter=F_C", "residual_scale"))
    src = srcs("diagnosis.json")
    if diag and diag.get("status", "ok") == "ok":
        verdict = ", ".join(diag.get("verdict") or []) or "[] nominal"
        explained = diag.get("explained", True)
        cells.append(f'<td title="{esc(src.title("verdict", "verdict"))}">{esc(verdict)} '
                     f'{badge("explained", "good") if explained else badge("not explained", "bad")}</td>')
        cells.append(cell(fmt(diag.get("gap_before"), 4), src, "gap_before", "gap_before"))
        cells.append(cell(fmt(diag.get("gap_after"), 3), src, "gap_after", "gap_after"))
        cells.append(cell(fmt(diag.get("holdout_gap_after"), 3), src, "holdout_gap_after", "holdout_gap_after"))
        cells.append(cell(fmt(diag.get("shrink"), 3), src, "shrink", "shrink"))
    else:
        reason = (diag or {}).get("reason") or ("diagnosis.json missing" if diag is None else "not diagnosed")
        cells.append(f'<td colspan="5" title="{esc(src.title("status", "status"))}">{esc(reason)}</td>')
    report = root / "report.html"
    cells.append(f'<td><a href="{esc(campaign)}/report.html">report</a></td>' if report.is_file()
                 else "<td>report missing</td>")
    return f"<tr>{''.join(cells)}</tr>", srcs.all()


def _pass_badge(ok: bool | None) -> str:
    return badge("N/A", "warn") if ok is None else (badge("PASS", "good") if ok else badge("FAIL", "bad"))


def _blind_section(blind_dir: Path, captions: Mapping[str, str]) -> tuple[str, list[Source]]:
    srcs = Sources(blind_dir)
    summary = _read_json(blind_dir / "summary.json")
    scores = _read_parquet(blind_dir / "scores.parquet")
    out = ['<section id="blind"><h2>Blind test of the diagnosis</h2>']
    ssrc = srcs("summary.json")
    if summary is None:
        out.append(note("The blind suite has not been run (no <code>summary.json</code>).", "warn"))
        out.append("</section>")
        return "".join(out), srcs.all()
    all_pass = summary.get("all_pass")
    out.append(note(f"{summary.get('n_scenarios', '?')} scenarios ({summary.get('n_single', '?')} single effect, "
                    f"{summary.get('n_pairs', '?')} pairs, {summary.get('n_none', '?')} without effect), "
                    f"{summary.get('n_errors', 0)} failed to run; exact attribution rate "
                    f"{fmt_pct(summary.get('exact_rate'))}. Targets: "
                    + (badge("ALL PASS", "good") if all_pass else badge("NOT ALL PASS", "bad")),
                    "good" if all_pass else "bad"))
    rows = []
    for key, target in (summary.get("targets") or {}).items():
        if "claimed" in target:
            result = f"{target.get('claimed')}/{target.get('n')} claimed"
            threshold = (f"&le; alpha = {fmt(target['alpha'])}" if "alpha" in target else "0 claimed")
        elif "flagged" in target:
            result = f"{target.get('flagged')}/{target.get('n')} = {fmt_pct(target.get('rate'))}"
            threshold = f"&ge; {fmt_pct(target.get('threshold'))}"
        elif "rate" in target:
            result = f"{target.get('exact', '?')}/{target.get('n', '?')} = {fmt_pct(target.get('rate'))}"
            threshold = f"&ge; {fmt_pct(target.get('threshold'))}"
        elif "param_error_max" in target:
            result = (f"effect sizes within {fmt_pct(target.get('param_error_max'))}; delay within "
                      f"{fmt((target.get('delay_error_max_s') or 0) * 1e3, 3)} ms; offset within "
                      f"{fmt(target.get('offset_error_max_N'), 3)} N")
            threshold = "15 %; 2 ms; 2 N"
            target = {**target, "misses": sorted({*target.get("param_misses", []), *target.get("delay_misses", []),
                                                   *target.get("offset_misses", [])})}
        else:
            result = f"median {fmt(target.get('median'), 3)} over {target.get('n', '?')}"
            threshold = f"&ge; {fmt(target.get('threshold'), 3)}"
        misses = ", ".join(map(str, target.get("misses") or [])) or "-"
        rows.append(f"<tr><td><strong>{esc(key)}</strong></td><td>{esc(target.get('description', ''))}</td>"
                    f'<td class="num" title="{esc(ssrc.title(f"targets.{key}", key))}">{result}</td>'
                    f"<td>{threshold}</td><td>{_pass_badge(target.get('pass'))}</td>"
                    f"<td>{esc(misses)}</td></tr>")
    out.append('<h3>Targets</h3><div class="tablewrap"><table id="blind-targets"><thead><tr><th>target</th>'
               "<th>what</th><th>result</th><th>threshold</th><th></th><th>misses</th></tr></thead>"
               f"<tbody>{''.join(rows)}</tbody></table></div>")
    bins = summary.get("bins") or {}
    if bins:
        rows = []
        for name, b in bins.items():
            t = ssrc.title(f"bins.{name}", name)
            rows.append(f"<tr><td>{esc(name)} detection</td>"
                        f'<td class="num" title="{esc(t)}">{b.get("exact", "-")}/{b.get("n", "-")}</td>'
                        f'<td class="num" title="{esc(t)}">{fmt_pct(b.get("rate"))}</td>'
                        f'<td class="num" title="{esc(t)}">{b.get("exact_single", "-")}/{b.get("n_single", "-")}</td>'
                        f'<td class="num" title="{esc(t)}">{fmt_pct(b.get("rate_single"))}</td></tr>')
        out.append('<h3>By magnitude bin</h3><div class="tablewrap"><table id="blind-bins"><thead><tr><th>bin</th>'
                   "<th>exact</th><th>rate</th><th>exact (single effect)</th><th>rate (single effect)</th></tr></thead>"
                   f"<tbody>{''.join(rows)}</tbody></table></div>")
    scores_label = srcs("scores.parquet").label
    out.append(lineage_line(ssrc, "targets", note=f"the targets are computed from <code>{esc(scores_label)}</code>; "
                            f'audit a scenario with <code class="cmd">{esc(trace_command(scores_label, "scenario=<id>"))}'
                            "</code>"))
    rel, title = BLIND_FIGURE
    out.append(figure_html(srcs(rel), title, captions.get(Path(rel).stem, ""), fig_id=Path(rel).stem))
    if scores is not None:
        src = srcs("scores.parquet")
        cols = [Col("scenario", "scenario", text, False), Col("truth", "truth", lambda x: text(x or "(none)"), False),
                Col("verdict", "verdict", lambda x: text(x or "(none)"), False), Col("exact", "exact", yes_no, False),
                Col("magnitude_x_detection", "magnitude [x detection]", lambda x: fmt(x, 3)),
                Col("magnitude_bin", "bin", text, False), Col("gap_before", "gap before", lambda x: fmt(x, 3)),
                Col("gap_after", "gap after", lambda x: fmt(x, 3)), Col("shrink", "shrink", lambda x: fmt(x, 3)),
                Col("error", "error", text, False)]
        cols = [c for c in cols if c.key in scores]
        out.append(f"<details><summary>All {len(scores)} scenarios</summary>")
        out.append(table_html(scores, cols, src, ["scenario"], row_class=lambda r: "" if r.get("exact") else "flagged",
                              table_id="blind-scores"))
        out.append("</details>")
    out.append("</section>")
    return "".join(out), srcs.all()


def render_index(results_root: str | os.PathLike, campaigns: Sequence[str], *, blind_dir: str | os.PathLike | None = None,
                 captions_dir: str | os.PathLike | None = None, lineage_record: Mapping | None = None) -> str:
    """``results/index.html``: every campaign with its verdict and key numbers, and the blind-suite scores."""
    results_root = Path(results_root)
    captions = read_captions(captions_dir)
    rows, sources = [], []
    for c in campaigns:
        row, srcs = _campaign_row(results_root, c)
        rows.append(row)
        sources += srcs
    head = ("<th>campaign</th><th>cases ok / planned</th><th>quarantined</th><th>points</th><th>plan flagged</th>"
            "<th>repeatability flagged</th><th>Wallaschek residual scale</th><th>verdict</th><th>gap before</th>"
            "<th>gap after</th><th>holdout gap</th><th>shrink</th><th>page</th>")
    body = ['<section id="campaigns"><h2>Campaigns</h2>',
            "<p>Gap: the diagnosis metric (rms_z: rms of the residual in units of its noise and repeatability "
            "standard error; about 1 means explained). Hover a number for its source file, rule and commit.</p>",
            f'<div class="tablewrap"><table id="campaigns-table"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(rows)}</tbody></table></div>"]
    if not campaigns:
        body.append(note("No campaign.", "warn"))
    body.append("</section>")
    nav = [("campaigns", "Campaigns")]
    if blind_dir is None:
        body.append(note("The blind test of the diagnosis is not part of this build (no <code>blind</code> block "
                         "in the config)."))
    else:
        blind_html, srcs = _blind_section(Path(blind_dir), captions)
        body.append(blind_html)
        sources += srcs
        nav.append(("blind", "Blind test"))
    body.append(_lineage_section(sources))
    nav.append(("lineage", "Lineage"))
    header = ('<header class="top"><h1>isokinetic results</h1><p>Steady force-velocity characteristics of hydraulic '
              f"dampers: {len(campaigns)} campaign(s). Workflow view: Snakemake's own report "
              '<a href="report.html">report.html</a> (made by <code>snakemake --report results/report.html</code>).'
              "</p></header>")
    return page("isokinetic - results", header, nav, "".join(body), _generated_footer(lineage_record, sources),
                lineage_record)


def write_index(results_root: str | os.PathLike, out_path: str | os.PathLike, campaigns: Sequence[str],
                **kwargs) -> Path:
    """Write :func:`render_index` to ``out_path`` atomically."""
    return write_text(render_index(results_root, campaigns, **kwargs), out_path)


# ----------------------------------------------------------------------------------------------
# checks: static (no browser) and in a headless browser
# ----------------------------------------------------------------------------------------------

_EXTERNAL = re.compile(r"""(?:src|href|action|poster|data)\s*=\s*["']?\s*(?:https?:|ftp:|//)"""
                       r"""|url\(\s*["']?\s*(?!data:)[^)'"\s]|@import""", re.IGNORECASE)
_IMG = re.compile(r"<img\b[^>]*>", re.IGNORECASE)
_SRC = re.compile(r"""\bsrc\s*=\s*"([^"]*)\"""", re.IGNORECASE)
_DATA_FILE = re.compile(r"""\bdata-file\s*=\s*"([^"]*)\"""", re.IGNORECASE)


def embedded_images(page_html: str) -> list[tuple[str, str]]:
    """(data-file, src) of every <img> of a page."""
    out = []
    for tag in _IMG.findall(page_html):
        src = _SRC.search(tag)
        name = _DATA_FILE.search(tag)
        out.append((html.unescape(name.group(1)) if name else "?", html.unescape(src.group(1)) if src else ""))
    return out


def page_problems(page_html: str, expected_figures: Iterable[str] = ()) -> list[str]:
    """What makes a page not self-contained or incomplete: external references, images that are not
    decodable PNG data URIs, expected figures (file names) absent, 'figure missing' boxes."""
    problems = []
    for m in _EXTERNAL.finditer(page_html):
        problems.append(f"external reference: {page_html[max(0, m.start() - 20):m.end() + 40]!r}")
    images = embedded_images(page_html)
    for name, src in images:
        if not src.startswith("data:image/png;base64,"):
            problems.append(f"image {name} is not an embedded PNG: {src[:60]!r}")
            continue
        try:
            data = base64.b64decode(src.split(",", 1)[1], validate=True)
        except ValueError:
            problems.append(f"image {name}: invalid base64")
            continue
        if not png_ok(data):
            problems.append(f"image {name}: not a complete PNG ({len(data)} bytes)")
    names = {Path(n).name for n, _ in images}
    for fig in expected_figures:
        if Path(fig).name not in names:
            problems.append(f"figure {fig} not on the page")
    if 'class="fig missing"' in page_html:
        problems.append("page shows a 'figure missing' box")
    return problems


def find_chromium() -> str | None:
    """The headless browser: $ISOKINETIC_CHROMIUM, else chromium / chromium-browser / google-chrome on PATH."""
    env = os.environ.get("ISOKINETIC_CHROMIUM")
    if env:
        return env if Path(env).is_file() or shutil.which(env) else None
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


def chromium_args(chromium: str, user_data_dir: str | os.PathLike) -> list[str]:
    return [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-extensions",
            "--disable-dev-shm-usage", f"--user-data-dir={user_data_dir}", "--virtual-time-budget=5000"]


def check_in_browser(path: str | os.PathLike, chromium: str | None = None, timeout: float = 120) -> dict:
    """Open a page in headless Chromium and read what its load script wrote on <body>:
    ``{"loaded": int, "total": int, "broken": [files], "dom_chars": int}``. Raises RuntimeError
    when the browser fails or the script did not run."""
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("no chromium on PATH (install Debian's package 'chromium')")
    url = Path(path).resolve().as_uri()
    with tempfile.TemporaryDirectory(prefix="isokinetic-chromium-") as profile:
        proc = subprocess.run([*chromium_args(chromium, profile), "--dump-dom", url], capture_output=True,
                              text=True, timeout=timeout)
    dom = proc.stdout
    body = re.search(r"<body\b[^>]*>", dom)
    if proc.returncode != 0 or body is None:
        raise RuntimeError(f"chromium failed on {path} (exit {proc.returncode}): {proc.stderr[-2000:]}")
    attrs = dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(0)))
    if "data-images-total" not in attrs:
        raise RuntimeError(f"{path}: the page's load script did not run (no data-images-total on <body>)")
    return {"loaded": int(attrs["data-images-loaded"]), "total": int(attrs["data-images-total"]),
            "broken": [b for b in html.unescape(attrs.get("data-images-broken", "")).split(" ") if b],
            "dom_chars": len(dom)}


def screenshot(path: str | os.PathLike, out_png: str | os.PathLike, width: int = 1280, height: int = 2400,
               chromium: str | None = None, timeout: float = 120) -> Path:
    """A PNG screenshot of a page (the top ``height`` pixels) for a human look."""
    chromium = chromium or find_chromium()
    if chromium is None:
        raise RuntimeError("no chromium on PATH")
    with tempfile.TemporaryDirectory(prefix="isokinetic-chromium-") as profile:
        subprocess.run([*chromium_args(chromium, profile), "--hide-scrollbars", f"--window-size={width},{height}",
                        f"--screenshot={Path(out_png).resolve()}", Path(path).resolve().as_uri()],
                       capture_output=True, timeout=timeout, check=True)
    return Path(out_png)


def campaign_figure_files() -> list[str]:
    """File names of the figures every campaign page embeds."""
    return [Path(rel).name for rel, _ in CAMPAIGN_FIGURES]


def check_pages(results_root: str | os.PathLike, campaigns: Sequence[str], *, index: bool = True,
                blind: bool = True, browser: bool = True) -> list[str]:
    """Problems of the built pages (empty list: all good): each campaign's report.html (and, with
    ``index``, index.html, which shows Fig. 17 when ``blind``) present, non-empty, self-contained,
    every figure embedded as a PNG and, with ``browser``, decoded by headless Chromium."""
    results_root = Path(results_root)
    problems = []
    pages = [(results_root / c / "report.html", campaign_figure_files()) for c in campaigns]
    if index:
        pages.append((results_root / "index.html", [BLIND_FIGURE[0]] if blind else []))
    for path, figs in pages:
        if not path.is_file() or path.stat().st_size == 0:
            problems.append(f"{path}: missing or empty")
            continue
        problems += [f"{path}: {p}" for p in page_problems(path.read_text(encoding="utf-8"), figs)]
        if browser:
            try:
                res = check_in_browser(path)
            except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
                problems.append(f"{path}: {exc}")
                continue
            if res["loaded"] != res["total"] or res["total"] < len(figs):
                problems.append(f"{path}: {res['loaded']}/{res['total']} images decoded in the browser "
                                f"(expected {len(figs)}); broken: {res['broken']}")
    return problems
