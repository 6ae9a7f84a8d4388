"""Numbers and short texts as the report pages show them.

The one place the pages format a value: :func:`fmt_text` (plain text, significant digits),
:func:`fmt` (the same as HTML, exponents as x10<sup>n</sup>), :func:`fmt_pct`, :func:`short`
(a hash cut for display), :func:`formula` (units and symbols such as ``A_O^2``), and the HTML
escape :func:`esc` of the few cell fragments the Python side builds. Functions named for HTML
return HTML as ``str``; the page views mark it safe where they hand it to a template.
"""

from __future__ import annotations

import html
import math
import re

import numpy as np
import pandas as pd

_GREEK = {"pi": "&pi;", "rho": "&rho;", "mu": "&mu;", "alpha": "&alpha;", "beta": "&beta;"}


def esc(value) -> str:
    """``value`` as HTML text (quotes escaped too, for attributes)."""
    return html.escape(str(value), quote=True)


def missing(x) -> bool:
    """Whether a value is absent: None, pandas' NA, NaN or infinite."""
    if x is None or x is pd.NA:
        return True
    try:
        return isinstance(x, (float, np.floating)) and not math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def fmt_text(x, digits: int = 4) -> str:
    """A number as plain text: ``digits`` significant digits, ``1.235e+05`` beyond 1e-3..1e5."""
    if missing(x):
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
    """A fraction as a percentage: ``-0.4321`` -> ``-43.2 %``."""
    return "-" if missing(x) else f"{fmt_text(100 * float(x), digits)} %"


def short(sha: str | None, n: int = 12) -> str:
    """The first ``n`` characters of a hash (or commit), ``-`` when there is none."""
    return (sha or "")[:n] or "-"


def text(x) -> str:
    """A value as HTML text, ``-`` when absent."""
    return "-" if missing(x) else esc(x)


def yes_no(x) -> str:
    """A flag as ``yes`` / ``no``, ``-`` when absent."""
    return "-" if missing(x) else ("yes" if bool(x) else "no")


def formula(x) -> str:
    """Units and short formulas as HTML: ``A_O^2`` -> A<sub>O</sub><sup>2</sup>, ``rho`` -> &rho;."""
    if missing(x):
        return "-"
    out = esc(x)
    out = re.sub(r"\b([A-Za-z])_([A-Za-z0-9]{1,2})\b", r"\1<sub>\2</sub>", out)
    out = re.sub(r"\^(-?\d+)", r"<sup>\1</sup>", out)
    return re.sub(r"\b(" + "|".join(_GREEK) + r")\b", lambda m: _GREEK[m.group(1)], out)
