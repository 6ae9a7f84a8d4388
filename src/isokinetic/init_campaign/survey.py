"""A folder of case files surveyed: each file sniffed, read, its columns given roles, units and a waveform;
then the campaign-level choices (file format, columns, units, sample rate) that the draft writes.

Files are found in the folder and its subfolders (:data:`MAX_DEPTH` deep, hidden ones skipped; every file
passed over is listed with why) and read only, by the format's reader (:mod:`isokinetic.rawfile`: delimited
text with or without a units row, MTS 793 exports, any encoding). A file that cannot be used (unreadable,
a format other than the campaign's, no time / displacement / force column, a symlink leading out of the
folder, a name the manifest refuses) gets a ``problem``: the draft lists it commented out with that reason.

Columns are never silently wrong: a column whose name or unit says volts is never a force, displacement,
command or temperature while a scaled twin exists, nor without one (the role is refused, and said so); a
role is ``sure`` only when no other column competes for it; and the roles are checked by physics
(:func:`physics_checks`): the force follows the velocity as a damper's does (a force opposing it in every
cycle is drafted with ``invert: true``), the temperature is plausible for oil, the displacement's range is
the command's. A record holding several tests (a stepped sweep, standstills) becomes one case per step
(:mod:`.steps`).
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from isokinetic.contracts.manifest import (
    CAMPAIGN_PATTERN,
    CAMPAIGN_RULE,
    CASE_ID_PATTERN,
    MAX_CASE_ID_LENGTH,
    MAX_CASES,
    CsvDialect,
    bare_file_name,
)
from isokinetic.contracts.settings import DEFAULTS, Settings
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign import steps as st
from isokinetic.init_campaign.sniff import ColumnData, parse_column, xlsx_format
from isokinetic.init_campaign.waveform import Estimate, Waveform, detect_waveform, round_to_uncertainty
from isokinetic.measurement.sampling import SPAN_STEPS, sample_interval_error_s, sample_interval_s
from isokinetic.rawfile import DELIMITERS, FileFormat, RawFileError, read_raw_table, sniff_format
from isokinetic.stages.ingest import MAX_DAMAGED_FRACTION
from isokinetic.stages.validate import MIN_SAMPLES
from isokinetic.timestamps import excel_seconds, looks_excel_serial

#: File name endings taken as case files (any case).
CASE_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".xlsx")
#: Subfolders searched below the campaign folder (its own files are depth 0).
MAX_DEPTH = 3
#: Files that are never case files and are passed over without a word.
QUIET_FILES = ("campaign.yaml",)
#: A sample rate is rounded to the fewest digits within this fraction (validation allows 5 %).
RATE_FLOOR = 1e-4
#: Channels every case needs.
REQUIRED = ("time", "displacement", "force")
#: Correlation of force and velocity above which a role from magnitudes is likely (else a guess).
LIKELY_CORRELATION = 0.8
#: Correlation with the displacement above which another column is its command.
COMMAND_CORRELATION = 0.98
#: Plausible oil temperatures of a damper test [C].
OIL_RANGE_C = (-40.0, 200.0)
#: The displacement's range may differ from the command's by this fraction (servo error, compliance).
RANGE_TOLERANCE = 0.2
#: How sure, best first.
SURENESS = ("sure", "likely", "guess")


@dataclass
class FileSurvey:
    """One case file: its id, its problem (None when usable), and what was found in it."""

    file: str
    case_id: str
    id_note: str = ""
    problem: str | None = None
    sniff_note: str = ""
    dialect: CsvDialect | None = None
    ascii: bool = True
    units_row: dict[str, str] = field(default_factory=dict)
    data: dict[str, ColumnData] = field(default_factory=dict)
    roles: dict[str, str] = field(default_factory=dict)       # channel -> column name
    role_how: dict[str, tuple[str, str]] = field(default_factory=dict)   # channel -> (how, sure)
    extras: list[str] = field(default_factory=list)
    time_s: np.ndarray | None = None
    rate: Estimate | None = None
    waveform: Waveform | None = None
    motion: str | None = None        # the channel the waveform was detected on
    warnings: list[str] = field(default_factory=list)
    volts: dict[str, str | None] = field(default_factory=dict)   # volts column -> the role its name says
    refused: dict[str, str] = field(default_factory=dict)    # channel -> why no column was taken for it
    invert: str = ""                 # why the force is drafted with `invert: true` ("" when it is not)
    unused: dict[str, str] = field(default_factory=dict)     # column -> why it takes no role (a velocity, a switch)
    steps: list[StepCase] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.problem is None

    @property
    def cases(self) -> int:
        """How many cases the file drafts: one per step of a stepped record, else one."""
        return len(self.steps) if self.steps else 1


@dataclass(frozen=True)
class StepCase:
    """One case cut from a stepped record: its id, its slice [start_s, end_s) of the file's own time axis,
    its waveform measured on that slice, and how the step was found."""

    case_id: str
    start_s: float
    end_s: float
    waveform: Waveform
    how: str


@dataclass(frozen=True)
class ColumnChoice:
    """A campaign-level column: channel, CSV name, unit, the comment (how it was found, how sure), and whether
    (and why) it is inverted."""

    channel: str
    name: str
    unit: str | None
    how: str
    sure: str
    invert: bool = False
    invert_why: str = ""


@dataclass
class Survey:
    """A surveyed folder: campaign id (and why it is not the folder name), every file, the campaign's dialect,
    columns, units and sample rate, each with how it was found."""

    folder: Path
    campaign: str
    campaign_note: str
    files: list[FileSurvey]
    dialect: CsvDialect
    dialect_how: str
    columns: dict[str, ColumnChoice]
    units: dict[tuple[str, str], ch.UnitChoice]
    sample_rate_Hz: float | None
    rate_how: str
    skipped: list[tuple[str, str]] = field(default_factory=list)     # (relative path, why not a case file)

    @property
    def usable(self) -> list[FileSurvey]:
        return [f for f in self.files if f.ok]

    def case_kinds(self) -> list[str]:
        """The waveform of every drafted case (a stepped record's steps one by one)."""
        return [c.waveform.kind for f in self.usable for c in f.steps] + \
            [f.waveform.kind for f in self.usable if not f.steps]


def campaign_id(folder: Path) -> tuple[str, str]:
    """(campaign id, note): the folder name, lowercased and sanitised to the campaign-id rule when it must be."""
    name = folder.absolute().name
    if CAMPAIGN_PATTERN.fullmatch(name):
        return name, ""
    clean = re.sub(r"[^a-z0-9_-]+", "-", name.lower()).strip("-_") or "campaign"
    clean = re.sub(r"^[^a-z0-9]+", "", clean) or "campaign"
    return clean, (f"the folder name {name!r} is not a valid campaign id ({CAMPAIGN_RULE}): rename the folder to "
                   f"{clean!r}, the pipeline requires the id to equal the folder name")


def case_ids(stems: list[str]) -> list[tuple[str, str]]:
    """(case id, note) per file stem: sanitised to the case-id rule, at most 64 characters, unique."""
    out, seen = [], set()
    for stem in stems:
        clean = re.sub(r"[^A-Za-z0-9_.-]+", "_", stem)
        clean = re.sub(r"^[^A-Za-z0-9]+", "", clean)[:MAX_CASE_ID_LENGTH] or "case"
        base, n = clean, 2
        while clean in seen:
            suffix = f"_{n}"
            clean, n = base[:MAX_CASE_ID_LENGTH - len(suffix)] + suffix, n + 1
        seen.add(clean)
        note = "" if clean == stem and CASE_ID_PATTERN.fullmatch(stem) else f"file stem {stem!r} made a valid case id"
        out.append((clean, note))
    return out


def walk_folder(folder: Path) -> tuple[list[Path], list[tuple[str, str]]]:
    """(case files, [(relative path, why not)]) of ``folder`` and its subfolders up to :data:`MAX_DEPTH` deep,
    sorted by relative path: files with a :data:`CASE_SUFFIXES` ending (symlinks included); hidden files and
    folders, symlinked folders, deeper folders and other files are listed as passed over."""
    found, skipped = [], []

    def walk(here: Path, depth: int) -> None:
        for p in sorted(here.iterdir(), key=lambda q: q.name):
            rel = p.relative_to(folder).as_posix()
            if p.name.startswith("."):
                skipped.append((rel, "hidden " + ("folder" if p.is_dir() else "file")))
            elif p.is_dir() and p.is_symlink():
                skipped.append((rel, "a symlinked folder: not followed"))
            elif p.is_dir():
                if depth >= MAX_DEPTH:
                    skipped.append((rel, f"a folder more than {MAX_DEPTH} levels deep: not searched"))
                else:
                    walk(p, depth + 1)
            elif p.suffix.lower() in CASE_SUFFIXES:
                found.append(p)
            elif not (depth == 0 and p.name in QUIET_FILES):
                skipped.append((rel, f"not a case file ({', '.join(CASE_SUFFIXES)})"))

    walk(folder, 0)
    return sorted(found, key=lambda p: p.relative_to(folder).as_posix()), skipped


def case_files(folder: Path) -> list[Path]:
    """The folder's case files (:func:`walk_folder`), sorted by relative path."""
    return walk_folder(folder)[0]


def relative_name(path: Path, folder: Path) -> str:
    """A case file's ``file:`` entry: its path relative to the campaign folder, with '/'."""
    return path.relative_to(folder).as_posix()


def file_problem(path: Path, folder: Path, max_file_MB: float = DEFAULTS.max_case_file_MB) -> str | None:
    """Why a file cannot be a case before it is opened (None when it can be read): a file above ``max_file_MB``
    (ingest's limit, the config's ``ingest.max_case_file_MB``) is not read."""
    rel = relative_name(path, folder)
    if not all(bare_file_name(part) for part in rel.split("/")):
        return f"file name {rel!r} is not one the manifest accepts (no ':', '..', '\\\\')"
    if path.is_symlink():
        try:
            path.resolve().relative_to(folder.resolve())
        except ValueError:
            return f"a symlink to {path.resolve().as_posix()}, outside the campaign folder"
    if not path.is_file():
        return "not a regular file"
    size = path.stat().st_size
    if size > max_file_MB * 1e6:
        return f"{size / 1e6:.4g} MB, larger than the {max_file_MB:g} MB ingest reads (config ingest.max_case_file_MB)"
    return None


def read_file(survey: FileSurvey, path: Path, folder: Path, max_file_MB: float = DEFAULTS.max_case_file_MB) -> None:
    """Sniff the file's format (:func:`isokinetic.rawfile.sniff_format`) and read it with the format's reader
    into ``survey`` (or set its problem; a file above ``max_file_MB`` is not read)."""
    survey.problem = file_problem(path, folder, max_file_MB)
    if survey.problem:
        return
    notes: list[str] = []
    try:
        fmt = xlsx_format(path, notes) if path.suffix.lower() == ".xlsx" else sniff_format(path, notes)
        table = read_raw_table(path, fmt)
        survey.ascii = fmt.format == "xlsx" or path.read_bytes().isascii()       # a workbook has no encoding
    except RawFileError as exc:
        where = [f"column {exc.column!r}" if exc.kind != "key" else "", f"row {exc.row}" if exc.row is not None else ""]
        survey.problem = f"cannot read: {exc.reason}" + (f" ({', '.join(w for w in where if w)})" if any(where) else "")
        return
    except (OSError, UnicodeError, LookupError) as exc:
        survey.problem = f"cannot read: {exc}"
        return
    survey.dialect = fmt
    survey.sniff_note = "; ".join(n.split(": ", 1)[-1] for n in notes)
    survey.units_row = {name: unit for name, unit in table.units.items() if unit}
    survey.warnings += table.warnings
    survey.data = {str(name): parse_column(str(name), table.frame[name], table.decimal) for name in table.frame.columns}
    keep, note = partial_rows(survey.data)
    if note:                            # a partial record: read without its damaged rows, as ingest reads it
        frame = table.frame[keep].reset_index(drop=True)
        survey.data = {str(name): parse_column(str(name), frame[name], table.decimal) for name in frame.columns}
        survey.warnings.append(note)
    broken = next(((name, d.problem) for name, d in survey.data.items() if d.problem), None)
    if broken is not None:
        survey.problem = f"cannot use column {broken[0]!r} as time: {broken[1]}"
        return
    rows = len(table.frame)
    if rows < MIN_SAMPLES:
        survey.problem = f"only {rows} samples, at least {MIN_SAMPLES} needed"


def partial_rows(data: dict[str, ColumnData]) -> tuple[np.ndarray, str]:
    """(rows to keep, the note) of a partial record, as ingest leaves its damaged rows out
    (:func:`isokinetic.stages.ingest.partial_record`): rows with a missing value in a column of numbers or stamps,
    and rows repeating the value before in a time column that otherwise increases (a repeated stamp), when they are
    at most MAX_DAMAGED_FRACTION of the rows; all rows and "" otherwise."""
    columns = [d.numbers if d.numbers is not None else d.stamps_s for d in data.values()]
    columns = [c for c in columns if c is not None]
    n = len(columns[0]) if columns else 0
    damaged = np.zeros(n, dtype=bool)
    for values in columns:
        damaged |= ~np.isfinite(values)
    timelike = [d.stamps_s if d.stamps_s is not None else d.numbers for name, d in data.items()
                if d.stamps_s is not None or (d.numbers is not None and ch.guess_from_name(name, None).role == "time")]
    for values in timelike:
        finite = np.flatnonzero(np.isfinite(values))
        steps = np.diff(values[finite])
        if steps.size and np.all(steps >= 0) and 0 < np.sum(steps == 0) <= MAX_DAMAGED_FRACTION * n:
            damaged[finite[1:][steps == 0]] = True
    if not damaged.any() or damaged.sum() > MAX_DAMAGED_FRACTION * n:
        return np.ones(n, dtype=bool), ""
    return ~damaged, (f"{int(damaged.sum())} row(s) with a missing or unreadable value or a repeated time stamp left "
                      f"out (data rows {', '.join(map(str, np.flatnonzero(damaged)[:8].tolist()))}), as ingest does")


def _usable(data: ColumnData, role: str) -> bool:
    if role == "time":
        return data.stamps_s is not None or (data.numbers is not None and ch.increasing(data.numbers))
    return data.numbers is not None


def assign_by_name(survey: FileSurvey) -> None:
    """Roles from column names (and a units row's units). A column in volts (:func:`channels.says_volts`) takes no
    role but time: its scaled twin does, and without one the role is refused (said in ``refused``). The first
    column naming a role takes it: ``sure`` when no other column competes for it, else ``guess``, with the
    competitors named."""
    candidates: dict[str, list[tuple[str, ch.NameGuess]]] = {}
    for name, data in survey.data.items():
        guess = ch.guess_from_name(name, survey.units_row.get(name))
        if guess.role != "time" and ch.says_volts(name, survey.units_row.get(name)):
            survey.volts[name] = guess.role          # no role from magnitudes either
            continue
        if guess.role == "velocity":
            survey.unused[name] = f"a velocity by its unit ({guess.unit}): never the force"
            continue
        if guess.role is None or not _usable(data, guess.role):
            continue
        if guess.role in ("displacement", "command") and switch_note(survey, name, guess.role):
            continue
        candidates.setdefault(guess.role, []).append((name, guess))
    for role, found in candidates.items():
        if role in survey.roles:
            continue
        name, guess = found[0]
        how = guess.how
        twins = [v for v, r in survey.volts.items() if r == role]
        if twins:
            how += f"; {', '.join(repr(v) for v in twins)} in volts, not taken"
        if len(found) > 1:
            others = ", ".join(repr(n) for n, _ in found[1:])
            survey.role_how[role] = (f"{how}; CHECK: {others} also named like a {role} (the first is taken)", "guess")
        else:
            survey.role_how[role] = (how, "sure")
        survey.roles[role] = name
    for name, role in survey.volts.items():
        if role is not None and role not in candidates and role not in survey.refused:
            survey.refused[role] = (f"column {name!r} is in volts and has no scaled twin: not taken as the {role} "
                                    f"(a {role} in engineering units is needed; scale it, or name the scaled column)")


def switch_note(survey: FileSurvey, name: str, role: str | None) -> bool:
    """Whether column ``name`` is a switched signal (:func:`channels.switched_levels`): then it is noted as unused
    and is never the displacement (a displacement moves through its range, a control voltage switches)."""
    values = survey.data[name].numbers
    levels = ch.switched_levels(values) if values is not None else 0
    if levels:
        named = f" (named like a {role})" if role else ""
        survey.unused[name] = (f"switches between {levels} levels{named}: a control voltage, a current or a valve "
                               "state, never the displacement, and not the force: it does not follow the velocity")
    return bool(levels)


def assign_by_magnitude(survey: FileSurvey) -> None:
    """Roles the names left open: time (the column that only increases), displacement and force (the force
    follows the displacement's velocity), command (a smoother near-copy of the displacement). A column that is
    another's derivative (:func:`channels.velocity_columns`) is a velocity and never the force; it shows which
    column is the displacement. A switched column takes no role."""
    taken = set(survey.roles.values())
    if "time" not in survey.roles:
        for name, data in survey.data.items():
            if name not in taken and name not in survey.volts and _usable(data, "time"):
                survey.roles["time"] = name
                survey.role_how["time"] = (f"column {name!r} from magnitudes: it only increases", "likely")
                taken.add(name)
                break
    if "time" not in survey.roles:
        return
    t_data = survey.data[survey.roles["time"]]
    t = t_data.stamps_s if t_data.stamps_s is not None else t_data.numbers
    free = {n: d.numbers for n, d in survey.data.items()
            if d.numbers is not None and n not in taken and n not in survey.volts and n not in survey.unused
            and np.ptp(d.numbers[np.isfinite(d.numbers)]) > 0
            and not ch.increasing(d.numbers) and ch.guess_from_name(n).role in (None, "displacement", "force")}
    switched = {n for n in free if switch_note(survey, n, None)}
    named = {c: survey.data[survey.roles[c]].numbers for c in ("displacement", "force") if c in survey.roles}
    if len(named) < 2:
        pool = {**free, **{survey.roles[c]: v for c, v in named.items()}}
        derived = velocity_roles(survey, t, pool)
        pool = {n: v for n, v in pool.items() if n not in derived}
        d, f, r = ch.pair_by_velocity(t, pool, survey.roles.get("displacement"), survey.roles.get("force"), switched)
        if f in switched and r < LIKELY_CORRELATION:      # a switch that happens to correlate a little: no force
            d, f, r = d if "displacement" in survey.roles else None, None, 0.0
        survey.unused.pop(f, None)       # a force switching with the velocity's sign (a triangle's): a force
        sure = "likely" if r >= LIKELY_CORRELATION else "guess"
        for channel, name in (("displacement", d), ("force", f)):
            if channel not in survey.roles and channel not in survey.refused and name is not None and r > 0.3:
                survey.roles[channel] = name
                survey.role_how[channel] = (f"column {name!r} from magnitudes: the force follows the displacement's "
                                            f"velocity (correlation {r:.2f})", sure)
        if "force" not in survey.roles and derived and "force" not in survey.refused:
            survey.refused["force"] = (f"{', '.join(repr(n) for n in derived)} "
                                       f"{'is' if len(derived) == 1 else 'are'} the displacement's derivative (a "
                                       "velocity, not a force) and no other column follows the velocity as a damper's "
                                       "force does: name the force column")
        free = {n: v for n, v in free.items() if n not in derived}
    assign_command(survey, {n: v for n, v in free.items() if n not in switched})


def velocity_roles(survey: FileSurvey, t: np.ndarray, pool: dict[str, np.ndarray]) -> dict[str, str]:
    """{column: why}: the columns of ``pool`` that are another's derivative (:func:`channels.velocity_columns`),
    noted as unused velocities; the displacement, when no name gives it, is the column they are the derivative
    of (``likely``: physics, not a name)."""
    found = ch.velocity_columns(t, pool)
    derived = {}
    for name, (of, fit) in sorted(found.items(), key=lambda item: item[1][1].residual):
        if of in found:                       # the derivative of a velocity: an acceleration
            derived[name] = f"equals the derivative of {of!r}, a velocity: an acceleration, not a force"
            continue
        derived[name] = f"{ch.velocity_note(fit, repr(of))}, not a force"
        if "displacement" not in survey.roles and "displacement" not in survey.refused:
            survey.roles["displacement"] = of
            survey.role_how["displacement"] = (f"column {of!r} from magnitudes: column {name!r} equals its "
                                               f"derivative times {fit.unit_ratio:g} ({fit.residual:.1%} rms)",
                                               "likely")
    survey.unused.update(derived)
    return derived


def assign_command(survey: FileSurvey, free: dict[str, np.ndarray]) -> None:
    """A column that is a near-copy of the displacement, without a name that says so, is its command; of the
    two, the smoother is the command (the ideal waveform, raw-campaign spec)."""
    if "command" in survey.roles or "displacement" not in survey.roles:
        return
    disp_name = survey.roles["displacement"]
    disp = survey.data[disp_name].numbers
    for name, values in free.items():
        if name in survey.roles.values():
            continue
        ok = np.isfinite(values) & np.isfinite(disp)
        r = float(np.corrcoef(values[ok], disp[ok])[0, 1]) if ok.sum() > 2 and np.std(values[ok]) > 0 else 0.0
        if not r >= COMMAND_CORRELATION:
            continue
        if survey.role_how["displacement"][1] != "sure" and ch.roughness(values) > ch.roughness(disp):
            survey.roles["displacement"], name = name, disp_name
            how, sure = survey.role_how["displacement"]
            survey.role_how["displacement"] = (how.replace(repr(disp_name), repr(survey.roles["displacement"])), sure)
        survey.roles["command"] = name
        survey.role_how["command"] = (f"column {name!r} from magnitudes: a smooth copy of the displacement "
                                      f"(correlation {r:.4f})", "likely")
        return


def survey_files(folder: Path, max_file_MB: float = DEFAULTS.max_case_file_MB
                 ) -> tuple[list[FileSurvey], list[tuple[str, str]]]:
    """Every case file of ``folder`` (and its subfolders) read, with roles, at most MAX_CASES of them (none above
    ``max_file_MB``); and the files passed over, with why."""
    paths, skipped = walk_folder(folder)
    surveys = []
    for path, (case, note) in zip(paths, case_ids([p.stem for p in paths])):
        survey = FileSurvey(file=relative_name(path, folder), case_id=case, id_note=note)
        if sum(s.ok for s in surveys) >= MAX_CASES:
            survey.problem = f"more than the {MAX_CASES} cases a campaign may have"
        else:
            read_file(survey, path, folder, max_file_MB)
        if survey.ok:
            assign_by_name(survey)
            assign_by_magnitude(survey)
            survey.extras = [n for n in survey.data if n not in survey.roles.values()]
        surveys.append(survey)
    return surveys, skipped


def format_words(fmt: FileFormat) -> str:
    """A file format in words: ``tabs between fields, '.' as the decimal mark, a units row, cp1252``."""
    if fmt.format == "mts793":
        words = f"an MTS 793 export ({DELIMITERS.get(fmt.delimiter, fmt.delimiter)}, '{fmt.decimal}')"
    elif fmt.format == "xlsx":
        return (f"an .xlsx workbook, worksheet {repr(fmt.sheet) if fmt.sheet else '(the first)'}" +
                (", a units row under the header" if fmt.units_row else "") +
                (", no header" if fmt.header == "none" else ""))
    else:
        words = (f"{DELIMITERS.get(fmt.delimiter, fmt.delimiter)} between fields, '{fmt.decimal}' as the "
                 "decimal mark" + (", a units row under the header" if fmt.units_row else ""))
    return words + ("" if fmt.encoding == "utf-8" else f", encoding {fmt.encoding}")


def choose_dialect(files: list[FileSurvey]) -> tuple[CsvDialect, str]:
    """The most common file format of the readable files (a file of ASCII bytes only fits any encoding); files
    in another get a problem (the csv block is campaign-wide)."""
    ok = [f for f in files if f.ok]
    counts = Counter(replace(f.dialect, encoding="utf-8") for f in ok)
    if not counts:
        return CsvDialect(), ""
    layout, n = counts.most_common(1)[0]
    encodings = Counter(f.dialect.encoding for f in ok
                        if not f.ascii and replace(f.dialect, encoding="utf-8") == layout)
    dialect = replace(layout, encoding=encodings.most_common(1)[0][0] if encodings else "utf-8")
    for f in ok:
        if replace(f.dialect, encoding="utf-8") != layout or (not f.ascii and f.dialect.encoding != dialect.encoding):
            f.problem = (f"written as {format_words(f.dialect)}, the campaign's other files as "
                         f"{format_words(dialect)} (the csv block is campaign-wide)")
    how = f"sniffed: {format_words(dialect)} in {n} of {len(ok)} files"
    if dialect.encoding == "cp1252":
        how += " (the bytes are not UTF-8: cp1252 assumed, the Windows default; check it)"
    return dialect, how


def _values(survey: FileSurvey, channel: str) -> np.ndarray | None:
    name = survey.roles.get(channel)
    return None if name is None else survey.data[name].numbers


def unit_for(channel: str, name: str, files: list[FileSurvey]) -> ch.UnitChoice:
    """The unit of column ``name`` playing ``channel``: its header's when it names one (magnitudes that
    clearly disagree are noted), else the most plausible from the magnitudes of every file that has it."""
    with_it = [f for f in files if f.ok and f.roles.get(channel) == name]
    if channel == "time" and all(f.data[name].stamps_s is not None for f in with_it):
        units = {f.data[name].time_unit for f in with_it}
        unit = units.pop() if len(units) == 1 else "datetime"
        return ch.UnitChoice(unit, "sure", "clock times HH:MM:SS.fff" if unit == "hms" else "ISO 8601 time stamps")
    if channel == "time" and with_it and all(looks_excel_serial(f.data[name].numbers) for f in with_it):
        return ch.UnitChoice("excel_serial", "sure", "Excel serial dates (days since 1899-12-30, steps under "
                                                     "a second)")
    magnitudes = ch.choose_unit([ch.unit_scores(channel, f.data[name].numbers, f.time_s) for f in with_it
                                 if f.data[name].numbers is not None])
    sample = with_it[0] if with_it else None
    shown = f"{sample.file}: {ch.describe(channel, sample.data[name].numbers, sample.time_s)}" \
        if sample is not None and sample.data[name].numbers is not None else ""
    guess = ch.guess_from_name(name, sample.units_row.get(name) if sample is not None else None)
    if guess.unit is not None and guess.role in ch.DIMENSION and ch.DIMENSION[guess.role] == ch.DIMENSION[channel]:
        said = guess.how.split(" (its unit)")[0]
        scored = guess.unit in ch.SCORED[ch.DIMENSION[channel]]
        if scored and magnitudes.unit not in (None, guess.unit) and magnitudes.sure == "sure":
            return ch.UnitChoice(guess.unit, "likely", f"{said}; CHECK: the magnitudes look like "
                                                       f"{magnitudes.unit} ({shown})")
        agree = ("magnitudes agree" if magnitudes.unit == guess.unit else "magnitudes unclear" if scored
                 else "magnitudes not scored in this unit")
        return ch.UnitChoice(guess.unit, "likely" if "CHECK" in said else "sure", f"{said}; {agree} ({shown})")
    if magnitudes.unit is None:
        return magnitudes
    return ch.UnitChoice(magnitudes.unit, magnitudes.sure, f"from magnitudes ({shown}): {magnitudes.why}")


def time_in_seconds(survey: FileSurvey, unit: str | None) -> np.ndarray | None:
    data = survey.data[survey.roles["time"]]
    if data.stamps_s is not None:
        return data.stamps_s
    if unit == "excel_serial":
        return excel_seconds(data.numbers)
    return None if unit is None else ch.to_si(data.numbers, unit)


def sample_rate(t_s: np.ndarray) -> Estimate:
    """1 / the record's sample interval by ingest's own rule (:func:`isokinetic.measurement.sampling.
    sample_interval_s`: the median over long spans of their mean step, so that dropped samples and rounded time
    stamps leave it unchanged), with its standard error [Hz]."""
    step, se = sample_interval_s(t_s), sample_interval_error_s(t_s)
    return Estimate(1.0 / step, se / step ** 2)


def choose_units(files: list[FileSurvey]) -> dict[tuple[str, str], ch.UnitChoice]:
    """The unit of every (channel, column name) of the usable files; their time axes in seconds."""
    ok = [f for f in files if f.ok]
    units: dict[tuple[str, str], ch.UnitChoice] = {}
    for name in {f.roles["time"] for f in ok if "time" in f.roles}:
        units[("time", name)] = unit_for("time", name, ok)
    for f in ok:
        if "time" in f.roles:
            f.time_s = time_in_seconds(f, units[("time", f.roles["time"])].unit)
    for channel in ch.CHANNELS[1:]:
        for name in {f.roles[channel] for f in ok if channel in f.roles}:
            units[(channel, name)] = unit_for(channel, name, ok)
    return units


def column_how(role_how: str, unit: ch.UnitChoice) -> str:
    """How a column's role and unit were found, in one comment."""
    if role_how.startswith("from header") and unit.why.startswith("from header"):
        extra = role_how.split("; ", 1)[1] if "; " in role_how else ""
        return unit.why + (f"; {extra}" if extra else "")
    return f"{role_how}; unit {unit.why}" if role_how else unit.why


def campaign_columns(files: list[FileSurvey], units: dict[tuple[str, str], ch.UnitChoice]) -> dict[str, ColumnChoice]:
    """Campaign-level columns: for each channel, the name most usable files give it, with its unit."""
    ok = [f for f in files if f.ok]
    columns = {}
    for channel in ch.CHANNELS:
        names = Counter(f.roles[channel] for f in ok if channel in f.roles)
        if not names:
            continue
        name, n = names.most_common(1)[0]
        if channel not in REQUIRED and 2 * sum(names.values()) < len(ok):
            continue            # an optional channel most files lack: declared by the cases that have it
        having = [f for f in ok if f.roles.get(channel) == name]
        first = max(having, key=lambda f: SURENESS.index(f.role_how[channel][1]))     # the least sure file's why
        how, sure = first.role_how[channel]
        choice = units[(channel, name)]
        said = column_how(how, choice)
        count = f" (in {n} of {len(ok)} files)" if n < len(ok) else ""
        invert = channel == "force" and all(f.invert for f in having)
        columns[channel] = ColumnChoice(channel, name, choice.unit, said + count,
                                        max(sure, choice.sure, key=SURENESS.index), invert,
                                        having[0].invert if invert else "")
    return columns


def measure_file(f: FileSurvey, units: dict[tuple[str, str], ch.UnitChoice]) -> None:
    """Sample rate and waveform of one usable file (the command when there is one, else the displacement)."""
    missing = [c for c in REQUIRED if c not in f.roles]
    unknown = [c for c in f.roles if c != "temperature" and units[(c, f.roles[c])].unit is None]
    if missing or unknown:
        said = (f"no {' / '.join(missing)} column found" if missing else
                f"no plausible unit for the {' / '.join(unknown)} column")
        said += "".join(f"; {f.refused[c]}" for c in missing if c in f.refused)
        named = [n for n, d in f.data.items() if ch.guess_from_name(n).role == "time" and "time" in missing]
        if named:
            said += f" (column {named[0]!r} is named like time but does not increase from row to row)"
        f.problem = f"{said} (header: {', '.join(f.data)})"
        return
    for name in f.roles.values():
        text = f.units_row.get(name, "")
        if text and ch.unit_from_units_row(text) is None and f.data[name].stamps_s is None:
            f.problem = (f"column {name!r}: the units row says {text!r}: {ch.unit_error(text)} (ingest would set "
                         "the case aside)")
            return
        values = f.data[name].numbers
        if values is not None and not np.isfinite(values).all():
            row = int(np.argmax(~np.isfinite(values)))
            f.problem = f"column {name!r}, row {row}: not a finite number (ingest would set the case aside)"
            return
    f.rate = sample_rate(f.time_s)
    f.motion = "command" if "command" in f.roles else "displacement"
    motion_m = si_values(f, f.motion, units)
    f.waveform = detect_waveform(f.time_s, motion_m)
    physics_checks(f, units)
    found = st.find_steps(f.time_s, motion_m)
    if st.is_stepped(found, f.time_s):
        f.steps = step_cases(f, found, motion_m)
    elif f.waveform.kind == "free" and (steady := st.steady_part(found, f.time_s)) is not None:
        cut = step_cases(f, [steady], motion_m)
        if cut and cut[0].waveform.kind in ("sine", "triangle"):     # ramps around steady cycles: the steady part
            f.steps = [replace(cut[0], case_id=f.case_id, how=cut[0].how.replace("a step:", "the steady part:")
                               .replace("settling or transition", "ramp, settling or transition"))]


def si_values(f: FileSurvey, channel: str, units: dict[tuple[str, str], ch.UnitChoice]) -> np.ndarray:
    """A channel of a file in SI (temperature in C), by its chosen unit."""
    unit = units[(channel, f.roles[channel])].unit
    values = _values(f, channel)
    if channel == "temperature":
        return ch.temperature_C(values, unit)
    return ch.to_si(values, unit)


def _doubt(f: FileSurvey, channel: str, why: str) -> None:
    """Mark a role a guess, saying why (the draft writes it beside the column)."""
    how, _ = f.role_how.get(channel, ("", "guess"))
    f.role_how[channel] = (f"{how}; CHECK: {why}" if how else f"CHECK: {why}", "guess")
    f.warnings.append(f"{channel} column {f.roles[channel]!r}: {why}")


def physics_checks(f: FileSurvey, units: dict[tuple[str, str], ch.UnitChoice]) -> None:
    """The roles checked by physics: the force follows the velocity as a damper's does (sign in every cycle,
    a plausible damping), the temperature is plausible for oil, the displacement's range is the command's.
    A force opposing the velocity in every cycle sets ``invert``; other doubts make the role a guess."""
    t, disp, force = f.time_s, si_values(f, "displacement", units), si_values(f, "force", units)
    verdict = ch.force_follows_velocity(t, disp, force)
    derivative = ch.derivative_fit(t, _values(f, "displacement"), _values(f, "force"))
    if derivative.is_velocity:
        _doubt(f, "force", f"it {ch.velocity_note(derivative, 'the displacement')}, not a force (a damper's force "
                           "is no function of the velocity alone): name the force column")
    elif verdict.opposed_everywhere:
        f.invert = (f"the force opposes the displacement's velocity in all {verdict.cycles} cycles (correlation "
                    f"{verdict.correlation:.2f}): the rig's sign is the opposite of the spec's (force positive "
                    "resisting positive velocity), so the force is inverted")
    elif verdict.problem:
        _doubt(f, "force", verdict.problem)
    elif not ch.plausible_damping(verdict.damping_N_s_m):
        _doubt(f, "force", f"force over velocity {verdict.damping_N_s_m:.3g} N s/m, outside a damper's "
                           f"{ch.DAMPING_RANGE_N_S_M[0]:g} to {ch.DAMPING_RANGE_N_S_M[1]:g} N s/m: check the force and "
                           "displacement columns and their units")
    if "temperature" in f.roles and units[("temperature", f.roles["temperature"])].unit is not None:
        median = float(np.nanmedian(si_values(f, "temperature", units)))
        if not OIL_RANGE_C[0] <= median <= OIL_RANGE_C[1]:
            name = f.roles.pop("temperature")
            f.role_how.pop("temperature", None)
            f.refused["temperature"] = (f"column {name!r} read as a temperature gives a median of {median:.4g} C, "
                                        f"not plausible for oil ({OIL_RANGE_C[0]:g} to {OIL_RANGE_C[1]:g} C): not "
                                        "used")
            f.warnings.append(f.refused["temperature"])
            f.extras = [n for n in f.data if n not in f.roles.values()]
    if "command" in f.roles:
        ratio = ch.robust_range(disp) / ch.robust_range(si_values(f, "command", units))
        if abs(ratio - 1.0) > RANGE_TOLERANCE:
            _doubt(f, "displacement", f"its range is {ratio:.3g} times the command's: check the columns and units")


def step_cases(f: FileSurvey, found: list[st.Step], motion_m: np.ndarray) -> list[StepCase]:
    """One case per step of a stepped record (``<id>-S01`` ... for motion, ``<id>-Z01`` ... for standstills): its
    slice rounded inwards, its waveform measured on the slice as ingest will cut it."""
    t, out, counts = f.time_s, [], {"S": 0, "Z": 0}
    for step in found:
        if step.kind == "standstill":
            a, b = step.start_s, step.end_s
            sel = (t >= a) & (t < b)
            spread = float(np.ptp(motion_m[sel])) * 1e3 if sel.any() else math.nan
            w = Waveform("standstill", f"the {f.motion} stays within {spread:.3g} mm for {b - a:.4g} s", "sure")
            how = "a standstill: the zero and static force"
        else:
            a, b = step.start_s, step.end_s
            sel = (t >= a) & (t < b)
            rounding = st.resolution(step.period_s)
            if detect_waveform(t[sel], motion_m[sel]).kind == "triangle":
                a, b = a - step.period_s / 4.0, b - step.period_s / 4.0     # from reversal to reversal
                rounding = st.resolution(step.period_s / 10.0)                # the reversal within 0.1 % of T
            elif math.isfinite(step.tail_s):
                b = step.tail_s                 # on to the rest: the velocity peak at the last crossing inside
            a, b = st.rounded_inwards(a, b, rounding)
            sel = (t >= a) & (t < b)
            w = detect_waveform(t[sel], motion_m[sel]) if sel.sum() >= MIN_SAMPLES else None
            how = (f"a step: {step.cycles} steady cycle{'s' if step.cycles != 1 else ''} of "
                   f"{1.0 / step.period_s:.4g} Hz kept, the {step.settling} settling or transition "
                   f"cycle{'s' if step.settling != 1 else ''} before them left out" +
                   (", the run into the rest after them kept" if b > step.end_s else ""))
        if int(((t >= a) & (t < b)).sum()) < MIN_SAMPLES or w is None:
            f.warnings.append(f"a stretch [{a:g}, {b:g}) s has fewer than {MIN_SAMPLES} samples: not drafted")
            continue
        letter = "Z" if step.kind == "standstill" else "S"
        counts[letter] += 1
        case = f"{f.case_id[:MAX_CASE_ID_LENGTH - 4]}-{letter}{counts[letter]:02d}"
        out.append(StepCase(case, a, b, w, how))
    return out


def survey_folder(folder: str | Path, settings: Settings = DEFAULTS) -> Survey:
    """Survey a folder of case files: everything the draft needs (``settings``: the project's, for ingest's
    file-size limit)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: not a folder")
    campaign, note = campaign_id(folder)
    files, skipped = survey_files(folder, settings.max_case_file_MB)
    if not files:
        said = "; ".join(f"{name}: {why}" for name, why in skipped[:5])
        raise FileNotFoundError(f"{folder}: no case files ({', '.join('*' + s for s in CASE_SUFFIXES)}, up to "
                                f"{MAX_DEPTH} subfolders deep)" + (f"; passed over: {said}" if said else ""))
    dialect, dialect_how = choose_dialect(files)
    units = choose_units(files)
    for f in files:
        if f.ok:
            measure_file(f, units)
    columns = campaign_columns(files, units)
    rates = Counter(round_to_uncertainty(f.rate.value, f.rate.se, floor=RATE_FLOOR) for f in files if f.ok)
    rate, rate_how = None, ""
    if rates:
        rate, n = rates.most_common(1)[0]
        usable = sum(rates.values())
        rate_how = (f"time step {1.0 / rate:.6g} s (median over spans of {SPAN_STEPS} steps) in {n} of {usable} files" +
                    (" (the others get their own)" if n < usable else ""))
    return Survey(folder, campaign, note, files, dialect, dialect_how, columns, units, rate, rate_how, skipped)
