"""Checks of the built pages: self-contained and complete without a browser, figures decoded in one.

:func:`page_problems` reads a page's HTML (external references, images that are not complete
embedded PNGs, expected figures absent); :func:`check_in_browser` opens it in headless Chromium
and reads what the page's load script (``image_check.js``) wrote on ``<body>``
(``data-images-loaded`` / ``data-images-total`` / ``data-images-broken``). :func:`check_pages`
runs both over a build's campaign pages and index, for the rule ``campaign_report`` and CI.
"""

from __future__ import annotations

import base64
import html
import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

import pandas as pd

from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.outputs import FIGURES, STAGE_OUTPUTS, comparison_folder, figure, figures_in
from isokinetic.report.embed import png_ok

#: Report sections of a campaign page that show figures (the blind suite's are on the index).
CAMPAIGN_SECTIONS = ("cases", "characteristic", "models", "harmonic", "design", "diagnosis")

_EXTERNAL = re.compile(r"""(?:src|href|action|poster|data)\s*=\s*["']?\s*(?:https?:|ftp:|//)"""
                       r"""|url\(\s*["']?\s*(?!data:)[^)'"\s]|@import""", re.IGNORECASE)
#: The base64 text of an embedded image: no reference fits in its alphabet, so the scan for external
#: references skips it (ten times faster on a campaign page of 2 MB, issue 23).
_PAYLOAD = re.compile(r"(?<=;base64,)[A-Za-z0-9+/=]+")
_IMG = re.compile(r"<img\b[^>]*>", re.IGNORECASE)
_SRC = re.compile(r"""\bsrc\s*=\s*"([^"]*)\"""", re.IGNORECASE)
_DATA_FILE = re.compile(r"""\bdata-file\s*=\s*"([^"]*)\"""", re.IGNORECASE)


def campaign_figure_paths() -> list[str]:
    """The figures every campaign page embeds, relative to ``results/<campaign>/``, in page order."""
    return [f.path for f in FIGURES if f.section in CAMPAIGN_SECTIONS]


def campaign_figure_files(cases: pd.DataFrame | None = None) -> list[str]:
    """File names of the figures a campaign page embeds: all of them, or, given its cases table, those that
    apply to it (:func:`isokinetic.plots.figures.applies`; the page says why it leaves out the others)."""
    from isokinetic.plots.figures import applies  # matplotlib only when a cases table is given

    return [Path(f.path).name for f in FIGURES if f.section in CAMPAIGN_SECTIONS
            and (cases is None or applies(f.name, cases) is None)]


def _cases_of(campaign_root: Path) -> pd.DataFrame | None:
    try:
        return CampaignFolder.at(campaign_root).validated_cases()
    except (OSError, ValueError):
        return None


def embedded_images(page_html: str) -> list[tuple[str, str]]:
    """(data-file, src) of every <img> of a page."""
    out = []
    for tag in _IMG.findall(page_html):
        src = _SRC.search(tag)
        name = _DATA_FILE.search(tag)
        out.append((html.unescape(name.group(1)) if name else "?", html.unescape(src.group(1)) if src else ""))
    return out


def _image_problem(name: str, src: str) -> str | None:
    if not src.startswith("data:image/png;base64,"):
        return f"image {name} is not an embedded PNG: {src[:60]!r}"
    try:
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
    except ValueError:
        return f"image {name}: invalid base64"
    return None if png_ok(data) else f"image {name}: not a complete PNG ({len(data)} bytes)"


def page_problems(page_html: str, expected_figures: Iterable[str] = ()) -> list[str]:
    """What makes a page not self-contained or incomplete: external references, images that are not
    decodable PNG data URIs, expected figures (file names) absent, 'figure missing' boxes."""
    text = _PAYLOAD.sub("", page_html)
    problems = [f"external reference: {text[max(0, m.start() - 20):m.end() + 40]!r}"
                for m in _EXTERNAL.finditer(text)]
    images = embedded_images(page_html)
    problems += [p for p in (_image_problem(name, src) for name, src in images) if p]
    names = {Path(n).name for n, _ in images}
    problems += [f"figure {fig} not on the page" for fig in expected_figures if Path(fig).name not in names]
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


def _browser_problems(path: Path, n_figures: int) -> list[str]:
    try:
        res = check_in_browser(path)
    except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
        return [f"{path}: {exc}"]
    if res["loaded"] != res["total"] or res["total"] < n_figures:
        return [f"{path}: {res['loaded']}/{res['total']} images decoded in the browser "
                f"(expected {n_figures}); broken: {res['broken']}"]
    return []


def check_pages(results_root: str | os.PathLike, campaigns: Sequence[str], *, index: bool = True,
                blind: bool = True, browser: bool = True, comparisons: Sequence[str] = ()) -> list[str]:
    """Problems of the built pages (empty list: all good): each campaign's report.html, each comparison's
    (``results/compare/<name>/report.html``, Fig. 18-19) and, with ``index``, index.html (which shows
    Fig. 17 when ``blind``) present, non-empty, self-contained, every figure embedded as a PNG and, with
    ``browser``, decoded by headless Chromium."""
    results_root = Path(results_root)
    problems = []
    pages = [(CampaignFolder.at(results_root / c).path("campaign_report", "page"),
              campaign_figure_files(_cases_of(results_root / c))) for c in campaigns]
    pages += [(results_root / comparison_folder(name) / STAGE_OUTPUTS["compare_report"]["page"],
               [Path(f.path).name for f in figures_in("compare")])
              for name in comparisons]
    if index:
        pages.append((results_root / "index.html", [figure("fig17_blind_confusion").path] if blind else []))
    for path, figs in pages:
        if not path.is_file() or path.stat().st_size == 0:
            problems.append(f"{path}: missing or empty")
            continue
        problems += [f"{path}: {p}" for p in page_problems(path.read_text(encoding="utf-8"), figs)]
        if browser:
            problems += _browser_problems(path, len(figs))
    return problems
