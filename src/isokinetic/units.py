"""Units as rigs and manifests write them, read through pint (docs/raw-campaign-format.md, "Units").

:func:`parse_unit` reads a unit text (a manifest's ``unit``, a units-row cell, a header's bracket) to a
:class:`Unit`: its canonical symbol, its dimension and the factor and offset to the project's internal units
(SI: m, N, s, V, m/s; temperatures in degrees Celsius, as ``temperature_C`` is kept). Every factor comes from
pint's registry; this module adds only the spellings rigs write that pint reads otherwise or not at all
(:data:`RIG_SPELLINGS`: ``C`` and ``F`` are temperatures, not coulomb and farad; ``lb``/``lbs`` a force, not a
mass; ``ips``), strips brackets (``[mm]``, ``(N)``), and tries a capital's lower case (``Sec``, ``KN``, ``LBF``).
An unknown unit, or one of another dimension than asked for (``V`` for a force), raises :class:`UnitError`
naming the unit and the nearest known ones. :func:`unit_in_name` splits a unit off a column header.

Cost (a fresh Python, 2 shared cores): ``import pint`` about 0.15 s and the registry about 0.1 s, paid once per
process on the first parse (both lazy: importing this module costs nothing); a parse is then about 0.1 ms,
and repeated texts are cached. This module is a bottom layer: it imports nothing of isokinetic.
"""

from __future__ import annotations

import difflib
import functools
import re
from dataclasses import dataclass

import numpy as np

#: Dimensions a unit is classed in (pint's dimensionality -> name); others are named by pint's text.
DIMENSIONS = {
    "length": {"[length]": 1},
    "force": {"[length]": 1, "[mass]": 1, "[time]": -2},
    "time": {"[time]": 1},
    "temperature": {"[temperature]": 1},
    "voltage": {"[length]": 2, "[mass]": 1, "[time]": -3, "[current]": -1},
    "dimensionless": {},
    "velocity": {"[length]": 1, "[time]": -1},
    "mass": {"[mass]": 1},
    "current": {"[current]": 1},
    "pressure": {"[length]": -1, "[mass]": 1, "[time]": -2},
    "frequency": {"[time]": -1},
    "acceleration": {"[length]": 1, "[time]": -2},
}
#: Dimensions of a rig's channels: the ones :func:`unit_in_name` claims a header's suffix for.
RIG_DIMENSIONS = ("length", "force", "time", "temperature", "voltage", "velocity")
#: Spellings rigs write that pint reads as another quantity, or not at all (text after bracket stripping) ->
#: pint's. On a damper rig a ``C`` column is a temperature, never a charge; a pound is a force.
RIG_SPELLINGS = {
    "C": "degC", "°C": "degC", "ºC": "degC", "degC": "degC", "deg C": "degC", "Celsius": "degC",
    "centigrade": "degC", "F": "degF", "°F": "degF", "ºF": "degF", "deg F": "degF", "Fahrenheit": "degF",
    "degK": "K", "lb": "lbf", "lbs": "lbf", "pound": "lbf", "pounds": "lbf", "klb": "kip", "klbs": "kip",
    "ips": "inch/s", "secs": "s", "sec.": "s",
}
#: Common rig units offered as near matches besides pint's own names (prefixed units are not in its list).
NEAR_CANDIDATES = ("m", "mm", "cm", "um", "in", "inch", "ft", "N", "kN", "daN", "lbf", "kip", "kgf", "ozf", "s",
                   "ms", "min", "degC", "degF", "K", "V", "mV", "mm/s", "m/s", "in/s")
#: How alike (difflib ratio) a known unit must be to an unknown one to be named as a near match.
NEAR_RATIO = 0.5
_BRACKETS = {"(": ")", "[": "]", "{": "}", "<": ">"}
_TRAILING_BRACKET = re.compile(r"^(?P<name>.*?)\s*[\(\[\{<](?P<unit>[^\(\)\[\]\{\}<>]*)[\)\]\}>]\s*$")
_SUFFIX = re.compile(r"^(?P<name>.*[A-Za-z0-9)\]])[_\s]+(?P<unit>[A-Za-zµμ°º%][A-Za-z0-9µμ°º/^*.]*)$")
_UNIT_TOKEN = re.compile(r"[A-Za-zµμ°º%][A-Za-z0-9µμ°º/^*.·\- ]{0,15}")
#: One-letter header suffixes claimed as units (``force_N``, ``time_s``); others (``_A``, ``_d``, ``_B``) are
#: more often names than units.
SHORT_SUFFIXES = frozenset("smNVCFK")


class UnitError(ValueError):
    """A unit text that names no unit pint or the rig spellings know, or one of another dimension."""


@dataclass(frozen=True)
class Unit:
    """A parsed unit: ``text`` as written, ``symbol`` its canonical short name (``kip``, ``mm``, ``degC``,
    ``um``), ``dimension`` (:data:`DIMENSIONS`), and ``scale``/``offset`` to the internal unit: SI (m, N, s, V,
    m/s) except temperatures, which go to degrees Celsius (the project's ``temperature_C``)."""

    text: str
    symbol: str
    dimension: str
    scale: float
    offset: float = 0.0

    def to_si(self, values):
        """``values`` in the internal unit: ``values * scale + offset`` (a temperature in C)."""
        out = np.asarray(values, dtype=float) * self.scale + self.offset
        return out if out.ndim else float(out)


@functools.cache
def registry():
    """The one pint registry of the process (built on first use: pint is imported here, not at module load)."""
    import pint

    return pint.UnitRegistry(autoconvert_offset_to_baseunit=False)


def _dimension_name(dimensionality) -> str:
    found = {str(k): v for k, v in dict(dimensionality).items() if v}
    return next((name for name, dims in DIMENSIONS.items() if dims == found), str(dimensionality))


def _normalised(text: str) -> str:
    """A unit text without surrounding blanks, brackets (``[mm]``, ``(N)``) and a trailing period."""
    out = text.strip()
    while len(out) >= 2 and _BRACKETS.get(out[0]) == out[-1]:
        out = out[1:-1].strip()
    return re.sub(r"\s+", " ", out)


def _spellings(text: str) -> list[str]:
    """The texts tried in turn: the rig spelling, the text, its first letter in lower case (``Sec``, ``KN``),
    all lower case (``SEC``, ``LBF``)."""
    out = []
    for candidate in (text, text[:1].lower() + text[1:], text.lower()):
        for item in (RIG_SPELLINGS.get(candidate), candidate):
            if item is not None and item not in out:
                out.append(item)
    return out


def _pint_unit(text: str):
    """pint's unit of ``text``, or None (any parse failure: pint raises several kinds)."""
    ureg = registry()
    try:
        unit = ureg.Unit(text)
    except Exception:       # noqa: BLE001  (UndefinedUnitError, DimensionalityError, AssertionError, ...)
        return None
    return unit


def _symbol(unit) -> str:
    """pint's short symbol, spelled as manifests write it: ``°C`` -> ``degC``, ``µm`` -> ``um``, ``mm / s`` ->
    ``mm/s``."""
    text = format(unit, "~").replace("°C", "degC").replace("°F", "degF").replace("µ", "u").replace("μ", "u")
    return text.replace(" / ", "/").replace(" * ", "*").replace(" ** ", "^")


def _conversion(unit, dimension: str) -> tuple[float, float]:
    """(scale, offset) from ``unit`` to the internal unit of its dimension (temperatures: degrees Celsius)."""
    ureg = registry()
    if dimension == "temperature":
        zero = ureg.Quantity(0.0, unit).to("degC").magnitude
        one = ureg.Quantity(1.0, unit).to("degC").magnitude
        return float(one - zero), float(zero)
    return float(ureg.Quantity(1.0, unit).to_base_units().magnitude), 0.0


def _check_dimension(dimension: str | None) -> None:
    if dimension is not None and dimension not in DIMENSIONS:
        raise ValueError(f"dimension must be one of {', '.join(DIMENSIONS)}, got {dimension!r}")


@functools.lru_cache(maxsize=4096)
def _readings(cleaned: str) -> tuple[tuple[object, str], ...]:
    """(pint unit, dimension name) of each spelling of ``cleaned`` pint reads, in :func:`_spellings` order."""
    found = []
    for spelling in _spellings(cleaned):
        unit = _pint_unit(spelling)
        if unit is not None:
            found.append((unit, _dimension_name(unit.dimensionality)))
    return tuple(found)


def _pick(found, dimension: str | None):
    """The reading of ``dimension``, else (none asked for) the first in a rig dimension, else the first."""
    if dimension is not None:
        return next((f for f in found if f[1] == dimension), None)
    return next((f for f in found if f[1] in RIG_DIMENSIONS), found[0] if found else None)


@functools.lru_cache(maxsize=4096)
def parse_unit(text: str, dimension: str | None = None) -> Unit:
    """The :class:`Unit` a text names (module doc); ``dimension``: the one it must have (``force``), else the
    first reading in a rig dimension (:data:`RIG_DIMENSIONS`), else any. Raises :class:`UnitError` for an
    unknown unit (naming the nearest known ones) or a known one of another dimension."""
    _check_dimension(dimension)
    if not isinstance(text, str):
        raise UnitError(f"a unit must be text, got {text!r}")
    cleaned = _normalised(text)
    if not cleaned:
        raise UnitError(f"empty unit {text!r}")
    found = _readings(cleaned)
    pick = _pick(found, dimension)
    if pick is None and found:
        unit, said = found[0]
        raise UnitError(f"unit {text.strip()!r} is a {said} unit ({_symbol(unit)}), not a {dimension} unit"
                        + _near_text(cleaned, dimension))
    if pick is None:
        raise UnitError(f"unknown unit {text.strip()!r}" + _near_text(cleaned, dimension))
    unit, said = pick
    scale, offset = _conversion(unit, said)
    return Unit(text=text, symbol=_symbol(unit), dimension=said, scale=scale, offset=offset)


@functools.cache
def _known_names() -> tuple[str, ...]:
    """Unit names and symbols pint knows, with the rig spellings and :data:`NEAR_CANDIDATES`."""
    names = set(RIG_SPELLINGS) | set(NEAR_CANDIDATES)
    for definition in registry()._units.values():       # pint keeps no public list of its units
        names.update(n for n in (definition.name, definition.symbol, *definition.aliases) if n)
    return tuple(sorted(names))


def nearest_units(text: str, dimension: str | None = None, n: int = 3) -> list[str]:
    """Up to ``n`` known unit spellings closest to ``text`` (difflib), of ``dimension`` when one is given."""
    _check_dimension(dimension)
    cleaned = _normalised(text)
    pool = difflib.get_close_matches(cleaned, _known_names(), n=40, cutoff=NEAR_RATIO)
    pool += difflib.get_close_matches(cleaned.lower(), [k.lower() for k in NEAR_CANDIDATES], n=10, cutoff=NEAR_RATIO)
    out: list[str] = []
    symbols = set()
    for name in pool:
        pick = _pick(_readings(_normalised(name)), dimension)
        if pick is None or _symbol(pick[0]) in symbols:
            continue
        symbols.add(_symbol(pick[0]))
        out.append(name)
        if len(out) == n:
            break
    return out


def _near_text(text: str, dimension: str | None) -> str:
    near = nearest_units(text, dimension)
    kind = f"{dimension} " if dimension else ""
    return f"; nearest known {kind}units: {', '.join(near)}" if near else f"; no known {kind}unit is close"


def known_unit(text: str, dimension: str | None = None) -> bool:
    """True when :func:`parse_unit` reads ``text`` (of ``dimension`` when given)."""
    try:
        parse_unit(text, dimension)
    except UnitError:
        return False
    return True


def unit_in_name(header: str) -> tuple[str, str | None]:
    """(name words, unit text or None) of a column header: a trailing bracket (``friction force (kip)``,
    ``Disp [mm]``, ``F(N)``) is the unit when its text parses or is one unit-like word (``(kp)``: then
    :func:`parse_unit` refuses it, naming it, rather than a guess); a suffix after ``_`` or a blank
    (``force_kN``, ``time s``) only when it parses in a rig dimension (:data:`RIG_DIMENSIONS`; one-letter
    suffixes only from :data:`SHORT_SUFFIXES`)."""
    text = header.strip()
    match = _TRAILING_BRACKET.match(text)
    if match and match.group("name").strip():
        unit = match.group("unit").strip()
        if unit and (known_unit(unit) or (_UNIT_TOKEN.fullmatch(unit) and " " not in unit)):
            return match.group("name").strip(), unit
        return text, None
    match = _SUFFIX.match(text)
    if match:
        unit = match.group("unit")
        short = len(unit) > 1 or unit in SHORT_SUFFIXES
        if short and any(known_unit(unit, d) for d in RIG_DIMENSIONS):
            return match.group("name").strip(" _"), unit
    return text, None
