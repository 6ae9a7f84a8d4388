"""Shared figure helpers of every plot module: canvas, units, messages, log ticks and the PNG writer.

The figures reproduce those of the paper "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (Titurus et al.). They are drawn on a bare
:class:`matplotlib.figure.Figure` (Agg canvas, no pyplot state, nothing to close) and written by
:func:`save_figure`: atomically, with no software stamp, so identical figures give identical bytes.
"""

from __future__ import annotations

import os
import textwrap
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from isokinetic.io import current_vector_format, write_png, write_vector

if TYPE_CHECKING:  # matplotlib is imported where a figure is made: a job that only asks which figures apply
    from matplotlib.figure import Figure  # (the campaign report) does not pay for it (issue 23)

#: Resolution of every PNG [dots per inch].
DPI = 120
#: PNG metadata: no software/version stamp, so identical inputs give identical bytes.
PNG_METADATA = {"Software": None}
#: m -> mm, m/s -> mm/s: SI inside, mm at the plot edge.
MM = 1e3

_MISSING_STYLE = {"ha": "center", "va": "center", "fontsize": 10, "color": "tab:red", "wrap": True}


def new_figure(width_in: float, height_in: float) -> Figure:
    """An empty figure of that size [inches] with the constrained layout."""
    from matplotlib.figure import Figure  # used directly: no pyplot state, Agg canvas when saving

    return Figure(figsize=(width_in, height_in), layout="constrained")


def force_unit(values) -> tuple[float, str]:
    """(divisor, unit) of the forces [N] of a figure: always newtons, the unit of every table and page, so
    a number read off a figure is compared with the tables without a conversion (``values`` is accepted
    for the callers' sake and must be numeric)."""
    np.asarray(values, dtype=float)
    return 1.0, "N"


def say_missing(ax, text: str) -> None:
    """Write a 'missing data' message in red in the middle of an axes."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, **_MISSING_STYLE)


def footnote(fig: Figure, text: str, *, width: int | None = None, fontsize: float = 7.5) -> None:
    """A small grey note under the axes (the figure's supxlabel, so the layout reserves room).

    Wrapped at ``width`` characters: by default about half the figure width at 7.5 pt, ``0`` for a
    single line. Nothing is drawn for an empty text.
    """
    if not text:
        return
    if width is None:
        width = max(40, int(fig.get_figwidth() * 10))
    fig.supxlabel(textwrap.fill(text, width) if width else text, x=0.01, ha="left", fontsize=fontsize, color="0.3")


def plain_log_ticks(ax) -> None:
    """Label the log-scaled axes of ``ax`` 0.01, 0.1, 1 rather than 10^-2 ..., without minor labels."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    for axis in (ax.xaxis, ax.yaxis):
        if axis.get_scale() == "log":
            axis.set_major_formatter(FuncFormatter(lambda x, _pos: f"{x:g}"))
            axis.set_minor_formatter(NullFormatter())


def lay_out(fig: Figure, dpi: float) -> None:
    """Run the figure's layout once, at the resolution it is saved with, and keep the result.

    ``savefig`` of a figure with a layout engine draws it twice: a pass without output whose only
    product is the layout, then the real one. Laying out here (on an Agg canvas at the saving dpi) and
    saving without the engine skips that pass's drawing. Two cuts make the layout itself about 30 % cheaper
    (issue 23; an axes moves by at most about 1.5 % of the figure against matplotlib's own layout,
    ``tests/plots/test_style.py``): the axes' spines are left out of it (they
    lie on the axes' edges and their tick marks under the tick labels, but each asks its axis for its
    ticks again), and the constrained layout makes one pass of its algorithm, not two
    (:func:`constrained_layout_once`). A figure whose engine cannot be dropped (rcParams that choose one
    for every figure) keeps it and is drawn twice.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    engine = fig.get_layout_engine()
    if engine is None or not fig.axes:
        return
    if not isinstance(fig.canvas, FigureCanvasAgg):
        FigureCanvasAgg(fig)
    for ax in fig.axes:
        for spine in ax.spines.values():
            spine.set_in_layout(False)
    saved_dpi = fig.dpi
    fig.dpi = dpi
    try:
        if not constrained_layout_once(fig, engine):
            engine.execute(fig)
    except ValueError:  # as Figure.draw: a layout that cannot be applied is left out
        pass
    finally:
        fig.dpi = saved_dpi
    fig.set_layout_engine(None)
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine(engine)


#: What :func:`constrained_layout_once` uses of matplotlib's constrained layout (``matplotlib._constrained_layout``).
_CL_STEPS = ("make_layoutgrids", "make_layout_margins", "make_margin_suptitles", "match_submerged_margins",
             "check_no_collapsed_axes", "reposition_axes", "reset_margins")


def constrained_layout_once(fig: Figure, engine) -> bool:
    """One pass of the constrained layout of ``fig`` (``engine``: its ConstrainedLayoutEngine); True when done.

    matplotlib's ``do_constrained_layout`` runs its algorithm twice, because tick labels may change size once
    the axes have moved; on this package's figures the second pass moves an axes by at most about 1 % of the
    figure and costs about a third of the layout. False, with nothing changed, when the engine is another
    one, compresses, the algorithm's steps are not found (another matplotlib), or the axes would collapse
    (the caller then runs the engine itself, which warns as matplotlib does).
    """
    from matplotlib import _constrained_layout as cl
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    if type(engine) is not ConstrainedLayoutEngine or getattr(engine, "_compress", True) \
            or not all(hasattr(cl, step) for step in _CL_STEPS):
        return False
    try:
        return _constrained_layout_pass(fig, engine, cl)
    except (TypeError, AttributeError, KeyError):   # another matplotlib's private steps: its own engine lays out
        return False


def _constrained_layout_pass(fig: Figure, engine, cl) -> bool:
    """The steps of matplotlib's ``do_constrained_layout``, once (see :func:`constrained_layout_once`)."""
    params = engine.get()
    width_in, height_in = fig.get_size_inches()
    pads = {"h_pad": params["h_pad"] / height_in, "w_pad": params["w_pad"] / width_in}
    spaces = {"hspace": params["hspace"], "wspace": params["wspace"]}
    renderer = fig._get_renderer()
    grids = cl.make_layoutgrids(fig, None, rect=params["rect"])
    if not grids["hasgrids"]:
        return False
    cl.make_layout_margins(grids, fig, renderer, **pads, **spaces)
    cl.make_margin_suptitles(grids, fig, renderer, **pads)
    cl.match_submerged_margins(grids, fig)
    grids[fig].update_variables()
    if not cl.check_no_collapsed_axes(grids, fig):
        cl.reset_margins(grids, fig)
        return False
    cl.reposition_axes(grids, fig, renderer, **pads, **spaces)
    suptitle = fig._suptitle
    if suptitle is not None and suptitle.get_in_layout() and suptitle._autopos:  # as matplotlib places it
        suptitle.set_position((suptitle.get_position()[0], grids[fig].get_inner_bbox().y1 + pads["h_pad"]))
        suptitle.set_verticalalignment("bottom")
    cl.reset_margins(grids, fig)
    return True


def save_figure(fig: Figure, path: str | os.PathLike, dpi: int = DPI,
                metadata: Mapping[str, str] | None = None) -> Path:
    """Write a PNG atomically; ``metadata`` becomes PNG text chunks (matplotlib's ``savefig``), and
    so does a pipeline job's lineage record (:func:`isokinetic.io.write_png`). Inside a
    :func:`isokinetic.io.vector_figures` block the figure is also written as SVG or PDF beside the PNG
    (same name, that suffix: :func:`isokinetic.io.write_vector`).

    The layout is done once (:func:`lay_out`). The software stamp is left out
    (:data:`PNG_METADATA`), so identical figures and metadata give identical bytes.
    """
    lay_out(fig, dpi)
    out = write_png(fig, path, dpi=dpi, metadata={**PNG_METADATA, **(metadata or {})})
    vector = current_vector_format()
    if vector is not None:
        write_vector(fig, Path(path).with_suffix(f".{vector}"), vector)
    return out


__all__ = ["DPI", "MM", "PNG_METADATA", "constrained_layout_once", "footnote", "force_unit", "lay_out", "new_figure",
           "plain_log_ticks", "save_figure", "say_missing"]
