"""A folder of case files surveyed: each file sniffed, read, its columns given roles, units and a waveform;
then the campaign-level choices (dialect, columns, units, sample rate) that the draft writes.

Files are read only (ingest's reader). A file that cannot be used (unreadable, a dialect other than the
campaign's, no time / displacement / force column, a symlink leading out of the folder, a name the manifest
refuses) gets a ``problem``: the draft lists it commented out with that reason.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass, field
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
from isokinetic.init_campaign import channels as ch
from isokinetic.init_campaign.sniff import DELIMITER_WORDS, ColumnData, SniffError, read_columns, sniff_file
from isokinetic.init_campaign.waveform import Estimate, Waveform, detect_waveform, round_to_uncertainty
from isokinetic.stages.ingest import CaseFileError
from isokinetic.stages.validate import MIN_SAMPLES

#: File name endings taken as case files (any case).
CASE_SUFFIXES = (".csv", ".tsv")
#: Larger files are not read (listed with the reason): 256 MB.
MAX_FILE_BYTES = 256 * 1024 * 1024
#: A sample rate is rounded to the fewest digits within this fraction (validation allows 5 %).
RATE_FLOOR = 1e-4
#: Channels every case needs.
REQUIRED = ("time", "displacement", "force")
#: Correlation of force and velocity above which a role from magnitudes is likely (else a guess).
LIKELY_CORRELATION = 0.8
#: Correlation with the displacement above which another column is its command.
COMMAND_CORRELATION = 0.98


@dataclass
class FileSurvey:
    """One case file: its id, its problem (None when usable), and what was found in it."""

    file: str
    case_id: str
    id_note: str = ""
    problem: str | None = None
    sniff_note: str = ""
    dialect: CsvDialect | None = None
    comments: int = 0
    data: dict[str, ColumnData] = field(default_factory=dict)
    roles: dict[str, str] = field(default_factory=dict)       # channel -> column name
    role_how: dict[str, tuple[str, str]] = field(default_factory=dict)   # channel -> (how, sure)
    extras: list[str] = field(default_factory=list)
    time_s: np.ndarray | None = None
    rate: Estimate | None = None
    waveform: Waveform | None = None
    motion: str | None = None        # the channel the waveform was detected on
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.problem is None


@dataclass(frozen=True)
class ColumnChoice:
    """A campaign-level column: channel, CSV name, unit, and the comment (how it was found, how sure)."""

    channel: str
    name: str
    unit: str | None
    how: str
    sure: str


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

    @property
    def usable(self) -> list[FileSurvey]:
        return [f for f in self.files if f.ok]


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


def case_files(folder: Path) -> list[Path]:
    """The folder's case files (:data:`CASE_SUFFIXES`), sorted by name; symlinks included, folders not."""
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in CASE_SUFFIXES and not p.is_dir())


def file_problem(path: Path, folder: Path) -> str | None:
    """Why a file cannot be a case before it is opened (None when it can be read)."""
    if not bare_file_name(path.name):
        return f"file name {path.name!r} is not one the manifest accepts (no ':', '..', '\\\\')"
    if path.is_symlink():
        try:
            path.resolve().relative_to(folder.resolve())
        except ValueError:
            return f"a symlink to {path.resolve().as_posix()}, outside the campaign folder"
    if not path.is_file():
        return "not a regular file"
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        return f"{size / 2**20:.0f} MB, larger than the {MAX_FILE_BYTES / 2**20:.0f} MB this command reads"
    return None


def read_file(survey: FileSurvey, path: Path, folder: Path) -> None:
    """Sniff and read one file into ``survey`` (or set its problem)."""
    survey.problem = file_problem(path, folder)
    if survey.problem:
        return
    try:
        sniffed = sniff_file(path)
    except (SniffError, OSError) as exc:
        survey.problem = f"cannot read: {exc}"
        return
    dup = sorted({n for n in sniffed.header if sniffed.header.count(n) > 1})
    if dup:
        survey.problem = f"duplicate column names {dup}: a column cannot be told by its name"
        return
    survey.dialect, survey.comments, survey.sniff_note = sniffed.dialect, len(sniffed.comments), sniffed.decimal_note
    try:
        survey.data = read_columns(path, sniffed.dialect, survey.warnings)
    except CaseFileError as exc:
        survey.problem = f"ingest would refuse it: {exc.problem.message}" + (
            f" (row {exc.problem.row})" if exc.problem.row is not None else "")
        return
    rows = next(iter(survey.data.values())).rows
    if rows < MIN_SAMPLES:
        survey.problem = f"only {rows} samples, at least {MIN_SAMPLES} needed"


def _usable(data: ColumnData, role: str) -> bool:
    if role == "time":
        return data.stamps_s is not None or (data.numbers is not None and ch.increasing(data.numbers))
    return data.numbers is not None


def assign_by_name(survey: FileSurvey) -> None:
    """Roles from column names (the first column naming a role takes it)."""
    for name, data in survey.data.items():
        guess = ch.guess_from_name(name)
        if guess.role and guess.role not in survey.roles and _usable(data, guess.role):
            survey.roles[guess.role] = name
            survey.role_how[guess.role] = (guess.how, "sure")


def assign_by_magnitude(survey: FileSurvey) -> None:
    """Roles the names left open: time (the column that only increases), displacement and force (the force
    follows the displacement's velocity), command (a smoother near-copy of the displacement)."""
    taken = set(survey.roles.values())
    if "time" not in survey.roles:
        for name, data in survey.data.items():
            if name not in taken and _usable(data, "time"):
                survey.roles["time"] = name
                survey.role_how["time"] = (f"column {name!r} from magnitudes: it only increases", "likely")
                taken.add(name)
                break
    if "time" not in survey.roles:
        return
    t_data = survey.data[survey.roles["time"]]
    t = t_data.stamps_s if t_data.stamps_s is not None else t_data.numbers
    free = {n: d.numbers for n, d in survey.data.items()
            if d.numbers is not None and n not in taken and np.ptp(d.numbers[np.isfinite(d.numbers)]) > 0
            and not ch.increasing(d.numbers) and ch.guess_from_name(n).role in (None, "displacement", "force")}
    named = {c: survey.data[survey.roles[c]].numbers for c in ("displacement", "force") if c in survey.roles}
    if len(named) < 2:
        pool = {**free, **{survey.roles[c]: v for c, v in named.items()}}
        d, f, r = ch.pair_by_velocity(t, pool, survey.roles.get("displacement"), survey.roles.get("force"))
        sure = "likely" if r >= LIKELY_CORRELATION else "guess"
        for channel, name in (("displacement", d), ("force", f)):
            if channel not in survey.roles and name is not None and r > 0.3:
                survey.roles[channel] = name
                survey.role_how[channel] = (f"column {name!r} from magnitudes: the force follows the displacement's "
                                            f"velocity (correlation {r:.2f})", sure)
    assign_command(survey, free)


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


def survey_files(folder: Path) -> list[FileSurvey]:
    """Every case file of ``folder`` read, with roles; at most MAX_CASES become cases."""
    paths = case_files(folder)
    surveys = []
    for path, (case, note) in zip(paths, case_ids([p.stem for p in paths])):
        survey = FileSurvey(file=path.name, case_id=case, id_note=note)
        if sum(s.ok for s in surveys) >= MAX_CASES:
            survey.problem = f"more than the {MAX_CASES} cases a campaign may have"
        else:
            read_file(survey, path, folder)
        if survey.ok:
            assign_by_name(survey)
            assign_by_magnitude(survey)
            survey.extras = [n for n in survey.data if n not in survey.roles.values()]
        surveys.append(survey)
    return surveys


def choose_dialect(files: list[FileSurvey]) -> tuple[CsvDialect, str]:
    """The most common dialect of the readable files; files in another get a problem."""
    counts = Counter(f.dialect for f in files if f.ok)
    if not counts:
        return CsvDialect(), ""
    dialect, n = counts.most_common(1)[0]
    for f in files:
        if f.ok and f.dialect != dialect:
            f.problem = (f"written with {DELIMITER_WORDS[f.dialect.delimiter]} between fields and "
                         f"'{f.dialect.decimal}' as the decimal mark, the campaign's other files with "
                         f"{DELIMITER_WORDS[dialect.delimiter]} and '{dialect.decimal}' (the csv block is "
                         "campaign-wide)")
    words = f"{DELIMITER_WORDS[dialect.delimiter]} between fields, '{dialect.decimal}' as the decimal mark"
    return dialect, f"sniffed: {words} in {n} of {sum(counts.values())} files"


def _values(survey: FileSurvey, channel: str) -> np.ndarray | None:
    name = survey.roles.get(channel)
    return None if name is None else survey.data[name].numbers


def unit_for(channel: str, name: str, files: list[FileSurvey]) -> ch.UnitChoice:
    """The unit of column ``name`` playing ``channel``: its header's when it names one (magnitudes that
    clearly disagree are noted), else the most plausible from the magnitudes of every file that has it."""
    with_it = [f for f in files if f.ok and f.roles.get(channel) == name]
    if channel == "time" and all(f.data[name].stamps_s is not None for f in with_it):
        return ch.UnitChoice("datetime", "sure", "ISO 8601 time stamps")
    magnitudes = ch.choose_unit([ch.unit_scores(channel, f.data[name].numbers, f.time_s) for f in with_it
                                 if f.data[name].numbers is not None])
    sample = with_it[0] if with_it else None
    shown = f"{sample.file}: {ch.describe(channel, sample.data[name].numbers, sample.time_s)}" \
        if sample is not None and sample.data[name].numbers is not None else ""
    guess = ch.guess_from_name(name)
    if guess.unit is not None and guess.role is not None and ch.DIMENSION[guess.role] == ch.DIMENSION[channel]:
        if magnitudes.unit not in (None, guess.unit) and magnitudes.sure == "sure":
            return ch.UnitChoice(guess.unit, "likely", f"from header {name!r}; CHECK: the magnitudes look like "
                                                       f"{magnitudes.unit} ({shown})")
        agree = "magnitudes agree" if magnitudes.unit == guess.unit else "magnitudes unclear"
        return ch.UnitChoice(guess.unit, "sure", f"from header {name!r}; {agree} ({shown})")
    if magnitudes.unit is None:
        return magnitudes
    return ch.UnitChoice(magnitudes.unit, magnitudes.sure, f"from magnitudes ({shown}): {magnitudes.why}")


def time_in_seconds(survey: FileSurvey, unit: str | None) -> np.ndarray | None:
    data = survey.data[survey.roles["time"]]
    if data.stamps_s is not None:
        return data.stamps_s
    return None if unit is None else data.numbers * ch.FACTORS["time"][unit]


def sample_rate(t_s: np.ndarray) -> Estimate:
    """1 / the median sample interval, with a standard error from the intervals' spread [Hz]."""
    steps = np.diff(t_s)
    step = float(np.median(steps))
    spread = 1.4826 * float(np.median(np.abs(steps - step)))
    return Estimate(1.0 / step, spread / step ** 2 / math.sqrt(steps.size))


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
        return unit.why
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
        first = next(f for f in ok if f.roles.get(channel) == name)
        how, sure = first.role_how[channel]
        choice = units[(channel, name)]
        said = column_how(how, choice)
        count = f" (in {n} of {len(ok)} files)" if n < len(ok) else ""
        columns[channel] = ColumnChoice(channel, name, choice.unit, said + count,
                                        max(sure, choice.sure, key=["sure", "likely", "guess"].index))
    return columns


def measure_file(f: FileSurvey, units: dict[tuple[str, str], ch.UnitChoice]) -> None:
    """Sample rate and waveform of one usable file (the command when there is one, else the displacement)."""
    missing = [c for c in REQUIRED if c not in f.roles]
    unknown = [c for c in f.roles if c != "temperature" and units[(c, f.roles[c])].unit is None]
    if missing or unknown:
        said = (f"no {' / '.join(missing)} column found" if missing else
                f"no plausible unit for the {' / '.join(unknown)} column")
        named = [n for n, d in f.data.items() if ch.guess_from_name(n).role == "time" and "time" in missing]
        if named:
            said += f" (column {named[0]!r} is named like time but does not increase from row to row)"
        f.problem = f"{said} (header: {', '.join(f.data)})"
        return
    for name in f.roles.values():
        values = f.data[name].numbers
        if values is not None and not np.isfinite(values).all():
            row = int(np.argmax(~np.isfinite(values)))
            f.problem = f"column {name!r}, row {row}: not a finite number (ingest would set the case aside)"
            return
    f.rate = sample_rate(f.time_s)
    f.motion = "command" if "command" in f.roles else "displacement"
    factor = ch.FACTORS["length"][units[(f.motion, f.roles[f.motion])].unit]
    f.waveform = detect_waveform(f.time_s, _values(f, f.motion) * factor)
    disp, force = _values(f, "displacement"), _values(f, "force")
    if ch.velocity_correlation(f.time_s, disp, force) < -0.3:
        f.warnings.append("the force opposes the displacement's velocity: the rig's sign convention may be the "
                          "opposite of the spec's, add `invert: true` to the force (or displacement) column")


def survey_folder(folder: str | Path) -> Survey:
    """Survey a folder of case files: everything the draft needs."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: not a folder")
    campaign, note = campaign_id(folder)
    files = survey_files(folder)
    if not files:
        raise FileNotFoundError(f"{folder}: no case files ({', '.join('*' + s for s in CASE_SUFFIXES)})")
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
        rate_how = (f"median time step {1.0 / rate:.6g} s in {n} of {usable} files" +
                    (" (the others get their own)" if n < usable else ""))
    return Survey(folder, campaign, note, files, dialect, dialect_how, columns, units, rate, rate_how)
