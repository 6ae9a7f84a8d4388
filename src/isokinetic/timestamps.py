"""Time columns written as clock times, stamps or spreadsheet dates (docs/raw-campaign-format.md, "1.5
additions"), read as seconds from the record's first sample. A bottom layer: imports nothing of isokinetic.

Time units that are no pint unit (:data:`TIME_TEXT_UNITS`):

* ``datetime``: ISO 8601 stamps. With an offset (``Z``, ``+02:00``) they are absolute. Without one they are the
  logger's local time: with a declared ``timezone`` (an IANA name, the csv block's) they are converted to UTC,
  the hour a daylight-saving fall-back repeats resolved by the rows' order; without one, a step back of
  :data:`DST_STEP_S` (a fall-back) is refused naming the jump and the key to set, never read as time running
  backwards.
* ``hms``: clock times ``HH:MM:SS.fff`` (or ``MM:SS.fff``; a decimal comma in the seconds read too). A step back
  of more than half a day is midnight: the next day.
* ``excel_serial``: Excel's serial dates, days since 1899-12-30 (the fraction is the time of day): seconds =
  (days - first) x 86400; float64 days resolve about 1 us.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:       # pandas is imported where a column is read: the manifest's readers load no pandas (issue 23)
    import pandas as pd

TIME_STAMPS = "datetime"
TIME_TEXT_UNITS = (TIME_STAMPS, "hms", "excel_serial")
SECONDS_PER_DAY = 86400.0
#: Serial dates of 1954 to 2119: what a logger's Excel export holds (a plain seconds column never starts there
#: with steps of 1e-4 days or less).
EXCEL_SERIAL_RANGE = (20000.0, 80000.0)
#: Largest step of an Excel-serial time column [days] (1e-3 days = 86 s: slower than any damper record's sampling).
MAX_EXCEL_STEP_DAYS = 1e-3
#: A step back of local stamps this long [s] is a daylight-saving fall-back (20 min to 3 h: every zone's is 30 min
#: to 2 h); anything else stepping back is left to the time check (a row out of order).
DST_STEP_S = (1200.0, 10800.0)
_HMS = re.compile(r"^\s*(?:(\d{1,3}):)?(\d{1,2}):(\d{1,2}(?:[.,]\d*)?)\s*$")
_OFFSET = re.compile(r"(?:[zZ]|[+-]\d{2}:?\d{2})\s*$")


def hms_seconds(cells: pd.Series) -> np.ndarray:
    """Clock times (``HH:MM:SS.fff``, ``MM:SS.fff``) as seconds from the first one (NaN where a cell is none);
    a step back of more than half a day starts the next day."""
    import pandas as pd

    parts = cells.astype(object).where(cells.map(lambda v: isinstance(v, str)), "").astype(str).str.extract(_HMS)
    hours = pd.to_numeric(parts[0], errors="coerce").fillna(0.0).to_numpy(float)
    minutes = pd.to_numeric(parts[1], errors="coerce").to_numpy(float)
    secs = pd.to_numeric(parts[2].str.replace(",", ".", regex=False), errors="coerce").to_numpy(float)
    clock = hours * 3600.0 + minutes * 60.0 + secs
    clock[(minutes >= 60) | (secs >= 61)] = np.nan
    return _from_first(_unwrapped(clock, SECONDS_PER_DAY))


def _unwrapped(clock: np.ndarray, period: float) -> np.ndarray:
    """``clock`` with ``period`` added after every step back of more than half a period (midnight)."""
    finite = np.flatnonzero(np.isfinite(clock))
    if finite.size < 2:
        return clock
    wraps = np.diff(clock[finite]) < -period / 2
    out = clock.copy()
    out[finite[1:]] += period * np.cumsum(wraps)
    return out


def _from_first(seconds: np.ndarray) -> np.ndarray:
    finite = np.flatnonzero(np.isfinite(seconds))
    return seconds - seconds[finite[0]] if finite.size else seconds


def excel_seconds(days) -> np.ndarray:
    """Excel serial dates (days) as seconds from the first."""
    return _from_first(np.asarray(days, dtype=float)) * SECONDS_PER_DAY


def looks_excel_serial(numbers: np.ndarray | None) -> bool:
    """True for a time column of Excel serial dates: every value in :data:`EXCEL_SERIAL_RANGE`, increasing in
    steps of at most :data:`MAX_EXCEL_STEP_DAYS`."""
    if numbers is None:
        return False
    x = np.asarray(numbers, dtype=float)
    x = x[np.isfinite(x)]
    if x.size < 2 or x.min() < EXCEL_SERIAL_RANGE[0] or x.max() > EXCEL_SERIAL_RANGE[1]:
        return False
    steps = np.diff(x)
    return bool(np.median(steps) > 0 and np.median(steps) <= MAX_EXCEL_STEP_DAYS)


def looks_hms(cells: pd.Series) -> bool:
    """True for a column whose every filled cell is a clock time (``HH:MM:SS.fff``)."""
    filled = cells.dropna().astype(str)
    return bool(len(filled)) and bool(filled.str.match(_HMS).all())


def iso_seconds(cells: pd.Series, timezone: str | None = None) -> tuple[np.ndarray, tuple[int, str] | None]:
    """ISO 8601 stamps (a decimal comma in the seconds already '.') as seconds from the first (NaN where a cell is
    none), and the (row, reason) of a daylight-saving step back of local stamps when no ``timezone`` is declared
    (or of a fall-back the declared zone cannot place)."""
    import pandas as pd

    text = cells.astype(object)
    first = next((str(v) for v in text if isinstance(v, str) and v.strip()), "")
    local = bool(first) and not _OFFSET.search(first)
    if not local:
        stamps = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
    else:
        stamps = pd.to_datetime(text, format="ISO8601", errors="coerce")
        if timezone is not None:
            try:
                stamps = stamps.dt.tz_localize(timezone, ambiguous="infer", nonexistent="NaT")
            except (ValueError, TypeError) as exc:      # pytz.AmbiguousTimeError is a ValueError
                return np.full(len(cells), np.nan), (0, f"local time stamps cannot be placed in {timezone}: "
                                                        f"{str(exc)[:100]}")
    ns = stamps.dt.tz_convert("UTC").dt.tz_localize(None) if stamps.dt.tz is not None else stamps
    seconds = (ns - ns.dropna().iloc[0]).dt.total_seconds().to_numpy(float) if ns.notna().any() \
        else np.full(len(cells), np.nan)
    if local and timezone is None:
        jump = dst_jump(seconds)
        if jump is not None:
            i, back = jump
            return seconds, (i, f"local time stamps step back {back / 3600:.4g} h ({_cell(text, i - 1)} -> "
                                f"{_cell(text, i)}): a daylight-saving fall-back; declare the logger's zone in the "
                                "manifest's csv block (`timezone: Europe/Berlin`, say) or export UTC stamps")
    return seconds, None


def _cell(text: pd.Series, i: int) -> str:
    return str(text.iloc[i]).strip()[:32]


def dst_jump(seconds: np.ndarray) -> tuple[int, float] | None:
    """(row, seconds back) of the first step back of :data:`DST_STEP_S`, None when there is none."""
    finite = np.flatnonzero(np.isfinite(seconds))
    if finite.size < 2:
        return None
    steps = np.diff(seconds[finite])
    back = np.flatnonzero((-steps >= DST_STEP_S[0]) & (-steps <= DST_STEP_S[1]))
    return None if not back.size else (int(finite[back[0] + 1]), float(-steps[back[0]]))


def time_seconds(cells: pd.Series, unit: str, timezone: str | None = None
                 ) -> tuple[np.ndarray, tuple[int, str] | None]:
    """A time column in one of :data:`TIME_TEXT_UNITS` as seconds from its first sample (NaN where a cell is not
    one), with the (row, reason) of a problem the cells alone show (a daylight-saving jump)."""
    import pandas as pd

    if unit == "hms":
        return hms_seconds(cells), None
    if unit == "excel_serial":
        return excel_seconds(pd.to_numeric(cells, errors="coerce")), None
    return iso_seconds(cells, timezone)
