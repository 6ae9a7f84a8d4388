"""Tables of a page as data: rows of already-formatted cells, laid out by the ``table`` macro.

:func:`table_view` turns a DataFrame into a :class:`Table` whose every number cell's ``title``
names its row's file, rule, commit and audit command (:meth:`isokinetic.report.sources.Source.title`);
:func:`json_table_view` does the same for entries of a JSON list (a cell's selector is its key
path, ``where.0.v_min_m_s``); :func:`kv_table` is a two-column table of labelled values.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from markupsafe import Markup

from isokinetic.report.numbers import esc, fmt, missing
from isokinetic.report.sources import Lineage, Source, lineage_of, selector_of


@dataclass(frozen=True)
class Col:
    """A column of an HTML table: the DataFrame column, its header, how to show a value."""

    key: str
    header: str
    show: Callable[[object], str] = fmt
    number: bool = True
    scale: float = 1.0     # displayed value = value * scale (e.g. m/s -> mm/s)


@dataclass(frozen=True)
class Cell:
    """One cell: its HTML, its title (hover text, escaped by the template) and its class."""

    html: str
    title: str | None = None
    cls: str = ""
    tag: str = "td"
    colspan: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "html", Markup(self.html))


@dataclass(frozen=True)
class Row:
    """A table row: its cells, its class (flagged, warned, verdict) and its audit command."""

    cells: Sequence[Cell]
    cls: str = ""
    trace: str | None = None


@dataclass(frozen=True)
class Table:
    """A table as the ``table`` macro lays it out, with the lineage line that follows it."""

    headers: Sequence[str]
    rows: Sequence[Row]
    id: str = ""
    cls: str = ""
    caption: str = ""
    lineage: Lineage | None = None
    heads: Sequence[Markup] = field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "heads", [Markup(h) for h in self.headers])
        object.__setattr__(self, "caption", Markup(self.caption))


def badge(text: str, kind: str) -> str:
    """A coloured label (good, bad, warn) as HTML."""
    return f'<span class="badge {kind}">{esc(text)}</span>'


def number_cell(html: str, title: str) -> Cell:
    """A number with its lineage in the title."""
    return Cell(html, title, "num")


def _scaled(value, scale: float):
    if scale == 1.0 or missing(value) or isinstance(value, (bool, np.bool_, str)):
        return value
    return float(value) * scale


def _shown(col: Col, row: Mapping) -> str:
    return col.show(_scaled(row.get(col.key), col.scale))


def table_view(df: pd.DataFrame, cols: Sequence[Col], src: Source, keys: Sequence[str],
               row_class: Callable[[Mapping], str] | None = None,
               row_extra: Callable[[Mapping], list[str]] | None = None, table_id: str = "",
               caption: str = "") -> Table:
    """A table whose every number cell's title gives its row's lineage and audit command."""
    rows = []
    for row in df.to_dict("records"):
        selector = selector_of(row, keys)
        extra = row_extra(row) if row_extra else []
        cells = [number_cell(_shown(c, row), src.title(selector, c.key, extra)) if c.number else Cell(_shown(c, row))
                 for c in cols]
        rows.append(Row(cells, row_class(row) if row_class else "", src.audit(selector)))
    first = selector_of(df.iloc[0].to_dict(), keys) if len(df) else ""
    return Table([c.header for c in cols], rows, id=table_id, caption=caption, lineage=lineage_of(src, first))


def _json_path(base: str, column: str, json_keys: Iterable[str]) -> str:
    return f"{base}.{column}" if column in json_keys else base


def json_table_view(df: pd.DataFrame, cols: Sequence[Col], src: Source, key: str, table_id: str,
                    row_class: Callable[[Mapping], str] | None = None, json_keys: Iterable[str] = ()) -> Table:
    """A table of JSON list entries: a cell's selector is its key path (``where.0.v_min_m_s``)."""
    json_keys = set(json_keys)
    rows = []
    for row in df.to_dict("records"):
        cells = [number_cell(_shown(c, row), src.title(_json_path(row[key], c.key, json_keys), c.key))
                 if c.number else Cell(_shown(c, row)) for c in cols]
        rows.append(Row(cells, row_class(row) if row_class else "", src.audit(row[key])))
    return Table([c.header for c in cols], rows, id=table_id)


def kv_table(items: Sequence[tuple[str, str, str]]) -> Table:
    """A two-column table of (label html, value html, title)."""
    return Table([], [Row([Cell(label, tag="th"), number_cell(value, title)]) for label, value, title in items],
                 cls="kv")
