"""Each column's role (time, displacement, force, command, temperature) and unit, from its name and magnitudes.

Names first: ``time_s``, ``t[ms]``, ``disp_mm``, ``x_um``, ``force_kN``, ``F [N]``, ``cmd_mm``, ``oil_C`` are split
into words and a unit (the last word, or what stands in brackets, after ``/`` or ``in``); the words name
the role (:data:`ROLE_WORDS`), the unit its dimension.

Magnitudes next, for what the names leave open. A unit is chosen by how plausible each candidate makes the
record (:func:`unit_scores`): the sample interval and length of a numeric time axis (s or ms), the amplitude
and speed of a displacement (m, mm or um: a damper moves micrometres to decimetres, at micrometres per
second to metres per second), the force range (N or kN: a damper's forces are tens to thousands of
newtons). Scores are decades away from a typical rig's values, infinite outside physical bounds; a
campaign sums them over its files. Roles without a name: the time is the column that only increases, the
displacement and force the pair in which the force follows the displacement's velocity (force resists
velocity, raw-campaign spec), the command a smoother near-copy of the displacement.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from isokinetic.contracts.manifest import unit_from_text
from isokinetic.init_campaign.steps import upward_crossings
from isokinetic.measurement.motion import noise_level

#: Channels in the order the manifest lists them.
CHANNELS = ("time", "displacement", "force", "command", "temperature")
#: Words naming each role, checked in this order (``x_cmd`` is a command, ``t_oil`` a temperature).
ROLE_WORDS = {
    "command": {"cmd", "command", "commanded", "demand", "dem", "setpoint", "sp", "set", "target", "ref",
                "reference", "soll", "desired"},
    "temperature": {"temp", "temperature", "oil", "theta", "thermo", "thermocouple", "celsius", "tmp"},
    "force": {"force", "f", "load", "lc", "loadcell", "kraft", "fz", "fx", "fy"},
    "time": {"time", "t", "zeit", "timestamp", "stamp", "elapsed", "date", "datetime", "clock", "sec"},
    "displacement": {"disp", "displacement", "x", "pos", "position", "stroke", "lvdt", "travel", "y", "z", "weg",
                     "piston", "extension", "ext", "deflection", "dx"},
}
#: One-letter role words that a unit of another dimension overrules (``T_C`` is a temperature).
WEAK_WORDS = {"t", "x", "y", "z", "f"}
#: Unit words (lowercase) -> (dimension, manifest unit).
UNIT_WORDS = {
    **dict.fromkeys(("s", "sec", "secs", "second", "seconds"), ("time", "s")),
    **dict.fromkeys(("ms", "msec", "millisecond", "milliseconds"), ("time", "ms")),
    **dict.fromkeys(("m", "meter", "metre", "meters", "metres"), ("length", "m")),
    **dict.fromkeys(("mm", "millimeter", "millimetre", "millimeters", "millimetres"), ("length", "mm")),
    **dict.fromkeys(("um", "µm", "μm", "micron", "microns", "micrometer", "micrometre", "mum"), ("length", "um")),
    **dict.fromkeys(("n", "newton", "newtons"), ("force", "N")),
    **dict.fromkeys(("kn", "kilonewton", "kilonewtons"), ("force", "kN")),
    **dict.fromkeys(("c", "degc", "°c", "celsius", "gradc"), ("temperature", "C")),
    **dict.fromkeys(("k", "kelvin"), ("temperature", "K")),
    **dict.fromkeys(("in", "inch", "inches"), ("length", "in")),
    **dict.fromkeys(("lbf", "lbs", "lb"), ("force", "lbf")),
    **dict.fromkeys(("kgf", "kp"), ("force", "kgf")),
    **dict.fromkeys(("degf", "°f", "fahrenheit"), ("temperature", "F")),
}
#: Words (a column name's last word, or its bracketed unit, or a units row's text) saying a column is in volts.
VOLT_WORDS = {"v", "mv", "volt", "volts", "voltage", "millivolt", "millivolts", "vdc", "uv", "µv"}
#: The dimension of each channel's unit.
DIMENSION = {"time": "time", "displacement": "length", "command": "length", "force": "force",
             "temperature": "temperature"}
#: Units of each dimension and their factor to SI (temperature: offset to kelvin is not needed here).
FACTORS = {"time": {"s": 1.0, "ms": 1e-3}, "length": {"m": 1.0, "mm": 1e-3, "um": 1e-6, "in": 0.0254},
           "force": {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605, "kgf": 9.80665},
           "temperature": {"C": 1.0, "K": 1.0, "F": 1.0}}
#: The dimension of each manifest unit.
UNIT_DIMENSION = {unit: dimension for dimension, units in FACTORS.items() for unit in units}
#: Units the magnitudes choose between (inches, pounds and kilograms-force only from a name or a units row).
SCORED = {"time": ("s", "ms"), "length": ("m", "mm", "um"), "force": ("N", "kN"), "temperature": ("C", "K")}
#: Typical values of a damper rig (decades away from them cost score) and physical bounds (outside: implausible).
TYPICAL = {"rate_Hz": 300.0, "duration_s": 60.0, "amplitude_m": 1e-3, "speed_m_s": 1e-3, "force_N": 300.0}
BOUNDS = {"rate_Hz": (5.0, 1e6), "duration_s": (0.05, 1e6), "amplitude_m": (1e-6, 1.0), "speed_m_s": (1e-8, 50.0),
          "force_N": (0.5, 2e6), "C": (-60.0, 250.0), "K": (200.0, 550.0)}
#: Margin (decades per file) between the best and the next unit above which a guess is sure / likely.
SURE_MARGIN, LIKELY_MARGIN = 1.5, 0.75

_BRACKETS = re.compile(r"^(.*?)\s*[\[({]\s*([^\])}]*?)\s*[\])}]\s*$")
_SLASH = re.compile(r"^(.*?)\s*/\s*([^/]+?)\s*$")
_IN = re.compile(r"^(.*?)\s+in\s+(\S+)\s*$", re.IGNORECASE)
_SPLIT = re.compile(r"[^a-z0-9µμ°]+")


@dataclass(frozen=True)
class NameGuess:
    """What a column name says: its role (None when it does not say), its unit, and how that was read."""

    role: str | None
    unit: str | None
    how: str


def name_words(name: str) -> tuple[tuple[str, ...], str | None]:
    """(words, unit word or None) of a column name: ``'F [kN]'`` -> (('f',), 'kn'), ``disp_mm`` -> (('disp',), 'mm')."""
    text = name.strip().lower()
    for pattern in (_BRACKETS, _SLASH, _IN):
        match = pattern.match(text)
        if match and match.group(2).replace(" ", "") in UNIT_WORDS:
            return tuple(w for w in _SPLIT.split(match.group(1)) if w), match.group(2).replace(" ", "")
    words = [w for w in _SPLIT.split(text) if w]
    if words and words[-1] in UNIT_WORDS:
        return tuple(words[:-1]), words[-1]
    return tuple(words), None


def says_volts(name: str, unit_text: str | None = None) -> bool:
    """Whether a column name (``Force (V)``, ``disp_V``, ``Load [mV]``, ``LVDT volts``) or its units-row text says
    the column holds a transducer's voltage rather than engineering units."""
    if unit_text is not None and unit_text.strip().lower() in VOLT_WORDS:
        return True
    text = name.strip().lower()
    for pattern in (_BRACKETS, _SLASH, _IN):
        match = pattern.match(text)
        if match and match.group(2).replace(" ", "") in VOLT_WORDS:
            return True
    words = [w for w in _SPLIT.split(text) if w]
    return bool(words) and (words[-1] in VOLT_WORDS or any(w.startswith("volt") for w in words))


def unit_from_units_row(text: str | None) -> tuple[str, str] | None:
    """(dimension, manifest unit) of a units row's cell (``in``, ``lbf``, ``Sec``, ``mm``, ``kN``, ``°C``, ``F``),
    read as ingest reads it (:func:`isokinetic.contracts.manifest.unit_from_text`); None when it names no
    unit the format knows."""
    unit = unit_from_text(text) if text and text.strip() else None
    return None if unit is None else (UNIT_DIMENSION[unit], unit)


def role_of(words: tuple[str, ...]) -> str | None:
    """The first role (in :data:`ROLE_WORDS` order) one of ``words`` names."""
    for role, vocabulary in ROLE_WORDS.items():
        if any(w in vocabulary for w in words):
            return role
    return None


def guess_from_name(name: str, unit_text: str | None = None) -> NameGuess:
    """Role and unit of a column from its name and its cell of a units row (the row's unit wins: ingest checks
    the manifest's unit against it); either may be None."""
    words, unit_word = name_words(name)
    role = role_of(words)
    row_unit = unit_from_units_row(unit_text)          # what ingest checks the manifest's unit against
    if unit_word is None and row_unit is None:
        return NameGuess(role, None, f"from header {name!r}" if role else "")
    if row_unit is not None:
        dimension, unit = row_unit
        name_said = f"{name!r} [{unit_text.strip()}]"
        if unit_word is not None and UNIT_WORDS[unit_word] != row_unit:
            name_said += f" (the units row's unit; CHECK: the name says {unit_word!r})"
    else:
        dimension, unit = UNIT_WORDS[unit_word]
        name_said = repr(name)
    name = name_said
    if role is None or DIMENSION[role] == dimension:
        role = role or {"time": "time", "length": "displacement", "force": "force",
                        "temperature": "temperature"}[dimension]
        return NameGuess(role, unit, f"from header {name}")
    if all(w in WEAK_WORDS for w in words if role_of((w,)) == role):
        role = {"time": "time", "length": "displacement", "force": "force", "temperature": "temperature"}[dimension]
        return NameGuess(role, unit, f"from header {name} (its unit)")
    return NameGuess(role, None, f"from header {name} (its unit {unit!r} does not fit a {role}: "
                                 "unit from magnitudes)")


# --- magnitudes ------------------------------------------------------------------------------------

def _decades(value: float, typical: float, bounds: tuple[float, float]) -> float:
    if not (math.isfinite(value) and bounds[0] <= value <= bounds[1]):
        return math.inf
    return abs(math.log10(value / typical))


def robust_range(y: np.ndarray) -> float:
    """Peak-to-peak of a record without its outliers (1st to 99th percentile, widened to the full span)."""
    lo, hi = np.percentile(y, [1.0, 99.0])
    return float((hi - lo) / 0.98)


def typical_speed(t: np.ndarray, y: np.ndarray) -> float:
    """Median |dy/dt| over steps of about 1/200 of the record (noise averaged out), in y's units per t's."""
    k = max(1, t.size // 200)
    dt = t[k:] - t[:-k]
    ok = dt > 0
    return float(np.median(np.abs(y[k:] - y[:-k])[ok] / dt[ok])) if ok.any() else math.nan


def time_scores(t: np.ndarray) -> dict[str, float]:
    """Score of s and ms for a numeric time axis: its sample rate and length against a rig's."""
    steps = np.diff(t)
    step = float(np.median(steps)) if steps.size else math.nan
    span = float(t[-1] - t[0]) if t.size else math.nan
    out = {}
    for unit, factor in FACTORS["time"].items():
        rate, duration = 1.0 / (step * factor) if step > 0 else math.nan, span * factor
        out[unit] = 0.5 * (_decades(rate, TYPICAL["rate_Hz"], BOUNDS["rate_Hz"])
                           + _decades(duration, TYPICAL["duration_s"], BOUNDS["duration_s"]))
    return out


def length_scores(y: np.ndarray, t_s: np.ndarray) -> dict[str, float]:
    """Score of m, mm and um for a displacement: its amplitude and its speed against a damper's."""
    amplitude, speed = robust_range(y) / 2.0, typical_speed(t_s, y)
    return {unit: _decades(amplitude * f, TYPICAL["amplitude_m"], BOUNDS["amplitude_m"])
            + 0.5 * _decades(speed * f, TYPICAL["speed_m_s"], BOUNDS["speed_m_s"])
            for unit, f in FACTORS["length"].items() if unit in SCORED["length"]}


def force_scores(f: np.ndarray) -> dict[str, float]:
    """Score of N and kN for a force: its 99th percentile of |F| against a damper's tens to thousands of N."""
    peak = float(np.percentile(np.abs(f), 99.0))
    return {unit: _decades(peak * factor, TYPICAL["force_N"], BOUNDS["force_N"])
            for unit, factor in FACTORS["force"].items() if unit in SCORED["force"]}


def temperature_scores(values: np.ndarray) -> dict[str, float]:
    """Score of C and K for a temperature: its median inside the plausible range of each."""
    median = float(np.median(values))
    return {unit: (0.0 if BOUNDS[unit][0] <= median <= BOUNDS[unit][1] else math.inf) + (0.5 if unit == "K" else 0.0)
            for unit in ("C", "K")}


def describe(channel: str, values: np.ndarray, t_s: np.ndarray | None) -> str:
    """The magnitudes a unit guess rests on, in the column's own numbers."""
    if channel == "time":
        steps = np.diff(values)
        return f"step {np.median(steps):.4g}, span {values[-1] - values[0]:.6g}" if steps.size else "one sample"
    if channel in ("displacement", "command"):
        speed = typical_speed(t_s, values) if t_s is not None else math.nan
        return f"amplitude {robust_range(values) / 2:.4g}, speed {speed:.3g}/s"
    if channel == "force":
        return f"99th percentile |F| {np.percentile(np.abs(values), 99.0):.4g}"
    return f"median {np.median(values):.4g}"


def unit_scores(channel: str, values: np.ndarray, t_s: np.ndarray | None) -> dict[str, float]:
    """Scores (lower is more plausible, inf implausible) of each unit of ``channel`` for one record."""
    finite = np.isfinite(values)
    if channel in ("displacement", "command"):
        if t_s is None or t_s.size != values.size:
            return {}
        finite &= np.isfinite(t_s)
        return length_scores(values[finite], t_s[finite]) if finite.sum() >= 2 else {}
    values = values[finite]
    if values.size < 2:
        return {}
    if channel == "time":
        return time_scores(values)
    if channel == "force":
        return force_scores(values)
    return temperature_scores(values)


@dataclass(frozen=True)
class UnitChoice:
    """A unit chosen from summed scores: the unit, how sure (sure / likely / guess), and why."""

    unit: str | None
    sure: str
    why: str


def choose_unit(per_file: list[dict[str, float]]) -> UnitChoice:
    """The most plausible unit over the records of a campaign (scores summed), and how clearly it wins: sure when
    every other unit is implausible somewhere, when it wins by :data:`SURE_MARGIN` decades per record on average,
    or when one record alone shows that and none prefers another unit (a campaign's files share their units:
    one file's magnitudes may fit two units, a whole campaign's rarely do)."""
    per_file = [s for s in per_file if s]
    summed: dict[str, float] = {}
    for scores in per_file:
        for unit, score in scores.items():
            summed[unit] = summed.get(unit, 0.0) + score
    finite = sorted((s, u) for u, s in summed.items() if math.isfinite(s))
    if not finite:
        return UnitChoice(None, "guess", "no unit gives plausible magnitudes")
    unit = finite[0][1]
    if len(finite) == 1:
        others = [u for u in summed if u != unit]
        return UnitChoice(unit, "sure", f"{', '.join(others)} implausible" if others else "")
    second = finite[1][1]
    margins = [s[second] - s[unit] for s in per_file]
    mean, best, worst = (finite[1][0] - finite[0][0]) / len(per_file), max(margins), min(margins)
    sure = ("sure" if mean >= SURE_MARGIN or (best >= SURE_MARGIN and worst >= 0) else
            "likely" if mean >= LIKELY_MARGIN or (best >= LIKELY_MARGIN and worst >= 0) else "guess")
    spread = f", {best:.1f} in the clearest file" if len(per_file) > 1 else ""
    return UnitChoice(unit, sure, f"{second} {mean:.1f} decades less plausible{spread}")


# --- roles from magnitudes ---------------------------------------------------------------------------

def increasing(values: np.ndarray | None) -> bool:
    return values is not None and values.size >= 2 and bool(np.all(np.diff(values) > 0))


def velocity_correlation(t: np.ndarray, displacement: np.ndarray, force: np.ndarray) -> float:
    """Correlation of a force with a displacement's velocity (a damper's force follows its velocity)."""
    k = max(1, t.size // 500)
    v = (displacement[2 * k:] - displacement[:-2 * k]) / (t[2 * k:] - t[:-2 * k])
    f = force[k:-k]
    ok = np.isfinite(v) & np.isfinite(f)
    if ok.sum() < 3 or np.std(v[ok]) == 0 or np.std(f[ok]) == 0:
        return 0.0
    return float(np.corrcoef(v[ok], f[ok])[0, 1])


def velocity(t: np.ndarray, y: np.ndarray, k: int) -> np.ndarray:
    """Central differences over ±k samples, at samples k .. n-k-1 (noise averaged over 2k samples)."""
    return (y[2 * k:] - y[:-2 * k]) / (t[2 * k:] - t[:-2 * k])


def temperature_C(values: np.ndarray, unit: str) -> np.ndarray:
    """A temperature column in degrees Celsius from C, K or F."""
    if unit == "K":
        return values - 273.15
    if unit == "F":
        return (values - 32.0) * 5.0 / 9.0
    return values


@dataclass(frozen=True)
class ForceVerdict:
    """How a force follows the displacement's velocity: overall correlation, per-cycle correlations' signs,
    the damping (least-squares slope of force over velocity, N s/m), and what is wrong ("" when nothing)."""

    correlation: float
    cycles: int
    opposed_cycles: int
    damping_N_s_m: float
    problem: str = ""

    @property
    def opposed_everywhere(self) -> bool:
        return self.cycles >= 1 and self.opposed_cycles == self.cycles and self.correlation < -WEAK_FOLLOW


#: |correlation| of force and velocity under which a force does not follow the velocity as a damper's does.
WEAK_FOLLOW = 0.3
#: Plausible damping of a damper, force over velocity [N s/m]: a bicycle's shock at speed to a friction-dominated
#: helicopter lag damper creeping at 0.05 mm/s (1e7 and more); outside, the force or the velocity is off by orders
#: of magnitude (a wrong column, or units).
DAMPING_RANGE_N_S_M = (1.0, 1.0e9)


def plausible_damping(damping_N_s_m: float) -> bool:
    return DAMPING_RANGE_N_S_M[0] <= abs(damping_N_s_m) <= DAMPING_RANGE_N_S_M[1]


def cycle_bounds(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sample indices of the upward mid-stroke crossings of a displacement (the cycles between them)."""
    lo, hi = np.percentile(y, [1.0, 99.0])
    crossings = upward_crossings(t, y, 0.5 * (lo + hi), max(5.0 * noise_level(y), 0.02 * (hi - lo)))
    return np.searchsorted(t, crossings)


def force_follows_velocity(t: np.ndarray, displacement_m: np.ndarray, force_N: np.ndarray) -> ForceVerdict:
    """A damper's force follows its velocity (force resists velocity, raw-campaign spec): the correlation of
    force and velocity, overall and in each cycle, and the damping (slope of force over velocity)."""
    k = max(1, t.size // 2000)
    v, f = velocity(t, displacement_m, k), force_N[k:-k]
    ok = np.isfinite(v) & np.isfinite(f)
    v, f, tc = v[ok], f[ok], t[k:-k][ok]
    if v.size < 3 or np.std(v) == 0 or np.std(f) == 0:
        return ForceVerdict(0.0, 0, 0, math.nan, "the force or the velocity is constant")
    r = float(np.corrcoef(v, f)[0, 1])
    damping = float(np.cov(v, f)[0, 1] / np.var(v))
    signs = []
    bounds = np.searchsorted(tc, t[cycle_bounds(t, displacement_m).clip(0, t.size - 1)])
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= 8 and np.std(v[a:b]) > 0 and np.std(f[a:b]) > 0:
            signs.append(float(np.corrcoef(v[a:b], f[a:b])[0, 1]))
    opposed = sum(c < 0 for c in signs)
    problem = ""
    if abs(r) < WEAK_FOLLOW:
        problem = (f"the force does not follow the velocity as a damper's does (correlation {r:.2f}): is it the "
                   "force, and the other the displacement?")
    elif r < 0:
        problem = (f"the force opposes the velocity overall (correlation {r:.2f}) but not in every cycle ({opposed} "
                   f"of {len(signs)}): the sign convention is unclear, check it by hand (`invert: true`?)")
    return ForceVerdict(r, len(signs), opposed, damping, problem)


def roughness(values: np.ndarray) -> float:
    """Noise (1 sigma, second differences) over range: low for a command, higher for a measured channel."""
    span = robust_range(values)
    return noise_level(values) / span if span > 0 else math.inf


def pair_by_velocity(t: np.ndarray, candidates: dict[str, np.ndarray], displacement: str | None,
                     force: str | None) -> tuple[str | None, str | None, float]:
    """(displacement, force, correlation): the pair of candidate columns (a given one kept) in which the force
    follows the displacement's velocity best."""
    best = (displacement, force, 0.0)
    for a in ([displacement] if displacement else candidates):
        for b in ([force] if force else candidates):
            if a == b or a not in candidates or b not in candidates:
                continue
            r = velocity_correlation(t, candidates[a], candidates[b])
            if r > best[2]:
                best = (a, b, r)
    return best
