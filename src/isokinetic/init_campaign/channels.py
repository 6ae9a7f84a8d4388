"""Each column's role (time, displacement, force, command, temperature) and unit, from its name and magnitudes.

Names first: ``time_s``, ``t[ms]``, ``disp_mm``, ``x_um``, ``force_kN``, ``F [N]``, ``cmd_mm``, ``oil_C``,
``friction force (kip)`` are split into words and a unit (:func:`isokinetic.units.unit_in_name`: a bracket,
a suffix, or after ``/``), read by the units library (:func:`isokinetic.units.parse_unit`, pint: any
length, force, time or temperature unit); the words name the role (:data:`ROLE_WORDS`), the unit its
dimension. A column in a unit of velocity, or equal to the displacement's derivative (:func:`derivative_fit`),
is a velocity and never the force; a column switching between a few levels (:func:`switched_levels`) is
never the displacement or the force.

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

from isokinetic.init_campaign.steps import upward_crossings
from isokinetic.measurement.motion import noise_level
from isokinetic.measurement.plausibility import DAMPING_RANGE_N_S_M, FORCE_BOUNDS_N, SURE_MARGIN, TYPICAL_FORCE_N

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
#: Words in a column name saying it holds a voltage (besides a unit of voltage: ``(V)``, ``_mV``).
VOLT_WORDS = {"volt", "volts", "voltage", "vdc"}
#: The dimension of each channel's unit (:mod:`isokinetic.units`).
DIMENSION = {"time": "time", "displacement": "length", "command": "length", "force": "force",
             "temperature": "temperature"}
#: The role a unit's dimension names when the words name none.
ROLE_OF_DIMENSION = {"time": "time", "length": "displacement", "force": "force", "temperature": "temperature"}
#: Units the magnitudes choose between (others, inches, kips and pounds, only from a name or a units row).
SCORED = {"time": ("s", "ms"), "length": ("m", "mm", "um"), "force": ("N", "kN"), "temperature": ("degC", "K")}
#: Typical values of a damper rig (decades away from them cost score) and physical bounds (outside: implausible);
#: the force's, and the margin of a sure unit, are the build's too (isokinetic.measurement.plausibility).
TYPICAL = {"rate_Hz": 300.0, "duration_s": 60.0, "amplitude_m": 1e-3, "speed_m_s": 1e-3, "force_N": TYPICAL_FORCE_N}
BOUNDS = {"rate_Hz": (5.0, 1e6), "duration_s": (0.05, 1e6), "amplitude_m": (1e-6, 1.0), "speed_m_s": (1e-8, 50.0),
          "force_N": FORCE_BOUNDS_N, "degC": (-60.0, 250.0), "K": (200.0, 550.0)}
#: Margin (decades per file) between the best and the next unit above which a guess is sure (SURE_MARGIN, from
#: isokinetic.measurement.plausibility) / likely.
LIKELY_MARGIN = 0.75

_SLASH = re.compile(r"^(.*?[^/\s])\s*/\s*([^/]+?)\s*$")
_SPLIT = re.compile(r"[^a-z0-9µμ°]+")


def read_unit(text: str | None, dimension: str | None = None):
    """The :class:`isokinetic.units.Unit` a text names (of ``dimension`` when given), None when it names none."""
    from isokinetic.units import UnitError, parse_unit

    if not text or not text.strip():
        return None
    try:
        return parse_unit(text, dimension)
    except UnitError:
        return None


def unit_error(text: str) -> str:
    """Why the units library refuses ``text`` (the nearest known units named), "" when it reads it."""
    from isokinetic.units import UnitError, parse_unit

    try:
        parse_unit(text)
    except UnitError as exc:
        return str(exc)
    return ""


def factor(unit: str) -> float:
    """The factor from ``unit`` (a symbol the draft writes) to SI."""
    return read_unit(unit).scale


def to_si(values: np.ndarray, unit: str) -> np.ndarray:
    """``values`` in SI (temperatures in degrees Celsius) from ``unit``."""
    return read_unit(unit).to_si(values)


@dataclass(frozen=True)
class NameGuess:
    """What a column name says: its role (None when it does not say), its unit, and how that was read."""

    role: str | None
    unit: str | None
    how: str


def split_name(name: str) -> tuple[tuple[str, ...], str | None]:
    """(words, unit text or None) of a column name by :func:`isokinetic.units.unit_in_name` (``'F [kN]'`` ->
    (('f',), 'kN'), ``disp_mm`` -> (('disp',), 'mm'), ``friction force (kip)`` -> (('friction', 'force'),
    'kip')), or a unit after a slash (``x/mm``), or a header of two letters or more that is only a unit (``mm``)."""
    from isokinetic.units import unit_in_name

    text, unit = unit_in_name(name)
    if unit is None:
        match = _SLASH.match(name.strip())
        slashed = read_unit(match.group(2)) if match else None
        whole = read_unit(name) if len(name.strip()) > 1 and role_of((name.strip().lower(),)) is None else None
        if slashed is not None and slashed.dimension in DIMENSION.values():
            text, unit = match.group(1), match.group(2)
        elif whole is not None and whole.dimension in DIMENSION.values():
            text, unit = "", name.strip()          # a header that is only a unit (``mm``)
    return tuple(w for w in _SPLIT.split(text.lower()) if w), unit


def name_words(name: str) -> tuple[tuple[str, ...], str | None]:
    """(words, the unit's symbol or None) of a column name (:func:`split_name`; a unit text no library knows: None)."""
    words, text = split_name(name)
    unit = read_unit(text)
    return words, None if unit is None else unit.symbol


def says_volts(name: str, unit_text: str | None = None) -> bool:
    """Whether a column name (``Force (V)``, ``disp_V``, ``Load [mV]``, ``LVDT volts``) or its units-row text says
    the column holds a transducer's voltage rather than engineering units."""
    for text in (unit_text, split_name(name)[1]):
        unit = read_unit(text)
        if unit is not None and unit.dimension == "voltage":
            return True
    words = [w for w in _SPLIT.split(name.strip().lower()) if w]
    return bool(words) and (words[-1] in VOLT_WORDS or words[-1] in ("v", "mv") or
                            any(w.startswith("volt") for w in words))


def unit_from_units_row(text: str | None) -> tuple[str, str] | None:
    """(dimension, unit symbol) of a units row's cell (``in``, ``lbf``, ``Sec``, ``mm``, ``kN``, ``°C``, ``kip``),
    read as ingest reads it (:func:`isokinetic.units.parse_unit`); None when it names no unit."""
    unit = read_unit(text)
    return None if unit is None else (unit.dimension, unit.symbol)


def role_of(words: tuple[str, ...]) -> str | None:
    """The first role (in :data:`ROLE_WORDS` order) one of ``words`` names."""
    for role, vocabulary in ROLE_WORDS.items():
        if any(w in vocabulary for w in words):
            return role
    return None


def guess_from_name(name: str, unit_text: str | None = None) -> NameGuess:
    """Role and unit of a column from its name and its cell of a units row (the row's unit wins: ingest checks
    the manifest's unit against it); either may be None. A unit of velocity makes the role ``velocity`` (not a
    channel: such a column is never the force); a unit no library knows is said, and left to the magnitudes."""
    words, unit_word = split_name(name)
    role = role_of(words)
    named, row = read_unit(unit_word), read_unit(unit_text)
    if unit_word is not None and named is None and row is None:
        return NameGuess(role, None, f"from header {name!r} (its unit {unit_word!r} is not one the units library "
                                     "knows: unit from magnitudes)" if role else "")
    if named is None and row is None:
        return NameGuess(role, None, f"from header {name!r}" if role else "")
    unit = row if row is not None else named
    said = repr(name)
    if row is not None:
        said = f"{name!r} [{unit_text.strip()}]"
        if named is not None and (named.symbol, named.dimension) != (row.symbol, row.dimension):
            said += f" (the units row's unit; CHECK: the name says {unit_word!r})"
    if unit.dimension == "velocity":
        return NameGuess("velocity", unit.symbol, f"from header {said} (a velocity)")
    if unit.dimension not in ROLE_OF_DIMENSION:
        return NameGuess(role, None, f"from header {said} (its unit {unit.symbol!r} is a {unit.dimension}: unit "
                                     "from magnitudes)" if role else "")
    if role is None or DIMENSION[role] == unit.dimension:
        return NameGuess(role or ROLE_OF_DIMENSION[unit.dimension], unit.symbol, f"from header {said}")
    if all(w in WEAK_WORDS for w in words if role_of((w,)) == role):
        return NameGuess(ROLE_OF_DIMENSION[unit.dimension], unit.symbol, f"from header {said} (its unit)")
    return NameGuess(role, None, f"from header {said} (its unit {unit.symbol!r} does not fit a {role}: "
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
    for unit in SCORED["time"]:
        f = factor(unit)
        rate, duration = 1.0 / (step * f) if step > 0 else math.nan, span * f
        out[unit] = 0.5 * (_decades(rate, TYPICAL["rate_Hz"], BOUNDS["rate_Hz"])
                           + _decades(duration, TYPICAL["duration_s"], BOUNDS["duration_s"]))
    return out


def length_scores(y: np.ndarray, t_s: np.ndarray) -> dict[str, float]:
    """Score of m, mm and um for a displacement: its amplitude and its speed against a damper's."""
    amplitude, speed = robust_range(y) / 2.0, typical_speed(t_s, y)
    return {unit: _decades(amplitude * factor(unit), TYPICAL["amplitude_m"], BOUNDS["amplitude_m"])
            + 0.5 * _decades(speed * factor(unit), TYPICAL["speed_m_s"], BOUNDS["speed_m_s"])
            for unit in SCORED["length"]}


def force_scores(f: np.ndarray) -> dict[str, float]:
    """Score of N and kN for a force: its 99th percentile of |F| against a damper's tens to thousands of N."""
    peak = float(np.percentile(np.abs(f), 99.0))
    return {unit: _decades(peak * factor(unit), TYPICAL["force_N"], BOUNDS["force_N"]) for unit in SCORED["force"]}


def temperature_scores(values: np.ndarray) -> dict[str, float]:
    """Score of degC and K for a temperature: its median inside the plausible range of each."""
    median = float(np.median(values))
    return {unit: (0.0 if BOUNDS[unit][0] <= median <= BOUNDS[unit][1] else math.inf) + (0.5 if unit == "K" else 0.0)
            for unit in SCORED["temperature"]}


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
    """A temperature column in degrees Celsius from any temperature unit (degC, K, degF)."""
    return to_si(values, unit)


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


#: Factors between a velocity column and the displacement's derivative that units make: powers of ten (m, mm, um;
#: s, ms) and the inch's 25.4 mm.
UNIT_RATIOS = np.array(sorted({f * 10.0 ** k for k in range(-6, 7) for f in (1.0, 25.4, 1.0 / 25.4)}))
#: A column within this relative rms of a unit ratio times the displacement's derivative is its velocity: a derived
#: velocity matches one of the difference quotients exactly (the MR damper's preprocessed files: backward
#: differences, 0 % rms), a calibrated velocity transducer to its noise; a damper's force, with its hysteresis (a
#: loop, not a curve) and noise, lies percents to tens of percent off any function of the velocity alone (a
#: simulated shock absorber at 5 Hz: 3 %, the MR damper: 25 %).
DERIVATIVE_RESIDUAL = 0.02
#: ... with a least-squares factor within this fraction of a unit ratio (a force over velocity rarely falls this
#: close to a power of ten by chance; when it does, and the force has no hysteresis, the draft says CHECK).
UNIT_RATIO_TOLERANCE = 0.005


@dataclass(frozen=True)
class DerivativeFit:
    """How a column fits the displacement's derivative: the least-squares factor, the relative rms residual, the
    unit ratio the factor is (None: none within :data:`UNIT_RATIO_TOLERANCE`) and the difference quotient that fits."""

    factor: float
    residual: float
    unit_ratio: float | None
    quotient: str

    @property
    def is_velocity(self) -> bool:
        return self.unit_ratio is not None and self.residual < DERIVATIVE_RESIDUAL


def difference_quotients(t: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
    """The derivative of ``y`` by the quotients a preprocessor uses: backward, forward, central, and central over
    ±k samples (noise averaged), all on the samples of ``y`` (NaN where undefined)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.diff(y) / np.diff(t)
        k = max(2, t.size // 500)
        wide = np.full(t.size, np.nan)
        wide[k:-k] = velocity(t, y, k)
        return {"backward": np.r_[np.nan, step], "forward": np.r_[step, np.nan],
                "central": np.gradient(y, t), f"central over ±{k} samples": wide}


def nearest_unit_ratio(factor: float) -> float | None:
    """The unit ratio (:data:`UNIT_RATIOS`) within :data:`UNIT_RATIO_TOLERANCE` of ``factor``, or None."""
    if not (math.isfinite(factor) and factor > 0):
        return None
    ratio = float(UNIT_RATIOS[np.argmin(np.abs(np.log(UNIT_RATIOS / factor)))])
    return ratio if abs(factor / ratio - 1.0) <= UNIT_RATIO_TOLERANCE else None


def derivative_fit(t: np.ndarray, displacement: np.ndarray, column: np.ndarray) -> DerivativeFit:
    """The best fit ``column`` ≈ c·dy/dt over the :func:`difference_quotients` of the displacement (any units: c
    takes them up)."""
    best = DerivativeFit(math.nan, math.inf, None, "")
    for name, dydt in difference_quotients(t, displacement).items():
        ok = np.isfinite(dydt) & np.isfinite(column)
        norm = float(column[ok] @ column[ok]) if ok.sum() >= 8 else 0.0
        gram = float(dydt[ok] @ dydt[ok]) if ok.sum() >= 8 else 0.0
        if norm <= 0 or gram <= 0:
            continue
        c = float(column[ok] @ dydt[ok]) / gram
        r = column[ok] - c * dydt[ok]
        residual = math.sqrt(float(r @ r) / norm)
        if residual < best.residual:
            best = DerivativeFit(c, residual, nearest_unit_ratio(c), name)
    return best


def velocity_columns(t: np.ndarray, candidates: dict[str, np.ndarray]) -> dict[str, tuple[str, DerivativeFit]]:
    """{column: (the column it is the derivative of, the fit)}: each candidate that equals another's derivative
    times a unit ratio (:meth:`DerivativeFit.is_velocity`), the best fitting of them."""
    out: dict[str, tuple[str, DerivativeFit]] = {}
    for b, column in candidates.items():
        for a, displacement in candidates.items():
            if a == b:
                continue
            fit = derivative_fit(t, displacement, column)
            if fit.is_velocity and (b not in out or fit.residual < out[b][1].residual):
                out[b] = (a, fit)
    return out


def velocity_note(fit: DerivativeFit, of: str) -> str:
    """What a derivative fit shows, in words."""
    return (f"equals the derivative of {of} ({fit.quotient} differences) times {fit.unit_ratio:g} to "
            f"{fit.residual:.1%} rms: a velocity")


#: A switched signal (a control voltage, a current, a valve state) spends at least LEVEL_SHARE of its samples on
#: 2 to MAX_LEVELS levels, found in at most MAX_LEVEL_BINS bins of LEVEL_WIDTH of its range, and stays on a level
#: MIN_RUN samples on average. A displacement or force moves through its range; an ADC-quantised standstill
#: flickers between its levels from sample to sample.
LEVEL_WIDTH, LEVEL_SHARE, MAX_LEVELS, MAX_LEVEL_BINS, MIN_RUN = 0.02, 0.95, 8, 10, 20


def switched_levels(values: np.ndarray) -> int:
    """How many levels a switched signal switches between; 0 when ``values`` is not one."""
    v = values[np.isfinite(values)]
    span = float(np.ptp(v)) if v.size else 0.0
    if span <= 0:
        return 0
    nbins = int(round(1.0 / LEVEL_WIDTH))
    bins = np.minimum(((v - v.min()) / span * nbins).astype(int), nbins - 1)
    counts = np.bincount(bins, minlength=nbins)
    order = np.argsort(counts)[::-1]
    k = int(np.searchsorted(np.cumsum(counts[order]), LEVEL_SHARE * v.size)) + 1
    if k > MAX_LEVEL_BINS:
        return 0
    top = np.zeros(nbins, dtype=bool)
    top[order[:k]] = True
    edges = np.diff(np.r_[0, top.astype(int), 0])
    level_of_bin = np.cumsum(edges[:-1] == 1)          # adjacent populated bins are one level
    labels = level_of_bin[bins][top[bins]]
    levels = int((edges == 1).sum())
    mean_run = labels.size / (np.count_nonzero(np.diff(labels)) + 1)
    return levels if 2 <= levels <= MAX_LEVELS and mean_run >= MIN_RUN else 0


def roughness(values: np.ndarray) -> float:
    """Noise (1 sigma, second differences) over range: low for a command, higher for a measured channel."""
    span = robust_range(values)
    return noise_level(values) / span if span > 0 else math.inf


def pair_by_velocity(t: np.ndarray, candidates: dict[str, np.ndarray], displacement: str | None,
                     force: str | None, never_displacement: set[str] = frozenset()
                     ) -> tuple[str | None, str | None, float]:
    """(displacement, force, correlation): the pair of candidate columns (a given one kept) in which the force
    follows the displacement's velocity best; ``never_displacement``: columns that cannot be it (switched ones)."""
    best = (displacement, force, 0.0)
    for a in ([displacement] if displacement else [c for c in candidates if c not in never_displacement]):
        for b in ([force] if force else candidates):
            if a == b or a not in candidates or b not in candidates:
                continue
            r = velocity_correlation(t, candidates[a], candidates[b])
            if r > best[2]:
                best = (a, b, r)
    return best
