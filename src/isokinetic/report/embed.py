"""Figures embedded in a page: PNG files as base64 ``data:`` URIs, with their captions and lineage.

Which figures a page shows, their titles and files come from the figure registry
(:data:`isokinetic.contracts.outputs.FIGURES`); the captions are those of Snakemake's report
(``workflow/report/<figure>.rst``), read as plain text.
"""

from __future__ import annotations

import base64
import os
import re
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from isokinetic.contracts.outputs import Figure
from isokinetic.io import VECTOR_FORMATS
from isokinetic.report.sources import Lineage, Source, Sources, lineage_of

#: The first eight bytes of every PNG file (PNG specification, section 5.2).
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


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


def rst_to_text(text: str) -> str:
    """A figure caption from workflow/report/*.rst as plain text (literal and emphasis marks dropped)."""
    text = re.sub(r"\{\{.*?\}\}", "", text)
    text = text.replace("``", "").replace("**", "")
    return " ".join(text.split())


def read_captions(captions_dir: str | os.PathLike | None) -> dict[str, str]:
    """Figure captions by figure name from the Snakemake report's caption files (:attr:`Figure.caption`)."""
    out: dict[str, str] = {}
    if captions_dir is None or not Path(captions_dir).is_dir():
        return out
    for p in sorted(Path(captions_dir).glob("*.rst")):
        out[p.stem] = rst_to_text(p.read_text(encoding="utf-8"))
    return out


@dataclass(frozen=True)
class FigureView:
    """A figure as the ``figure`` macro lays it out; ``uri`` None: missing or not a PNG."""

    id: str
    title: str
    caption: str
    uri: str | None
    label: str
    facts: str
    lineage: Lineage
    vectors: tuple[tuple[str, str], ...] = ()   # (format, page-relative link) of its SVG/PDF copies


def vector_links(src: Source, href: str) -> tuple[tuple[str, str], ...]:
    """(format, link) of each vector copy written beside a figure's PNG (config ``figures.vector_format``);
    ``href`` is the PNG's path relative to the page."""
    return tuple((fmt.upper(), str(Path(href).with_suffix(f".{fmt}"))) for fmt in VECTOR_FORMATS
                 if src.path.with_suffix(f".{fmt}").is_file())


def figure_view(src: Source, fig: Figure, caption: str = "", href_prefix: str = "") -> FigureView:
    """The figure ``fig`` read from ``src``, embedded; ``href_prefix`` leads from the page to ``src``'s folder."""
    return FigureView(id=fig.name, title=fig.title, caption=caption, uri=png_data_uri(src.path), label=src.label,
                      facts=" | ".join(src.facts()), lineage=lineage_of(src),
                      vectors=vector_links(src, href_prefix + fig.path))


@dataclass(frozen=True)
class LeftOut:
    """A figure that does not apply to the campaign: the ``figures`` macro says so in one line instead."""

    id: str
    title: str
    reason: str


def figure_views(sources: Sources, figures: tuple[Figure, ...], captions: Mapping[str, str],
                 applies: Callable[[str], str | None] | None = None) -> list[FigureView | LeftOut]:
    """The figures of a page section, each with its caption and lineage; with ``applies`` (figure name ->
    None, or why it does not apply), a figure that does not apply is a :class:`LeftOut` line instead."""
    out: list[FigureView | LeftOut] = []
    for fig in figures:
        reason = applies(fig.name) if applies is not None else None
        out.append(LeftOut(fig.name, fig.title, reason) if reason else
                   figure_view(sources(fig.path), fig, captions.get(fig.name, "")))
    return out
