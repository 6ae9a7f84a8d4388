"""What real labs do to good raw campaigns (issue 34), for :mod:`stages.test_realities_fuzz`.

Two good campaigns are written by the test instruments of ``tests/rigfiles.py`` (never by the package's writers):

- ``tri``: three triangle cases of the virtual rig's shock absorber (:func:`rigfiles.triangle_record`, 250 Hz,
  the three velocities of :data:`rigfiles.TRIANGLE_CASES`), time in s, temperature in C, displacement in mm and the
  load cell in kN (its last column: the field a crash cuts short);
- ``crank``: a crank dyno's folder (:func:`rigfiles.write_crank_folder`, 1, 2 and 4 Hz, nine cycles, 1000 Hz),
  its force column moved last, with a manifest of sine cases.

Both dampers carry a one-sided valve (the - branch 30 % stiffer) and a little entrained air, so that the force lags
the motion visibly and a record played backwards with its load cell upside down gives different points (a
symmetric damper without lag reads the same either way, and no check could tell).

A campaign is held as text: its manifest (a dict) and each case file as header cells, rows of cells, delimiter and
line end, exactly as the writers wrote them. Each damage edits that text (seeded: which case, which window, which
row and cell) and says which data rows of the good file it touched, so a test can tell the windows it left intact.
"""

from __future__ import annotations

import copy
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

import rigfiles as rf
from isokinetic.physics.damper import Effects
from isokinetic.physics.plan import triangle_displacement

#: The dampers' effects: seal friction, a one-sided valve, entrained air (a lag of about 10 ms at low speed).
EFFECTS = Effects(coulomb_force_N=25.0, path_asymmetry=0.3, air_volume_fraction=0.003)
TRI_RATE_HZ = 250.0
CRANK_RATE_HZ = 1000.0
CRANK_FREQUENCIES_HZ = (1.0, 2.0, 4.0)
CRANK_CYCLES = 9
CRANK_AMPLITUDE_MM = 25.0
#: One 10 kN spike sample (issue 34).
SPIKE_N = 1.0e4

#: Manifest keys of format 1.5 a damage declares (csv.thousands in contracts/manifest_csv.py, the time units of
#: isokinetic/timestamps.py).
THOUSANDS_KEY = "thousands"          # csv.thousands: the thousands separator (issue 34, part 4)
CLOCK_TIME_UNIT = "hms"              # time unit of HH:MM:SS.fff stamps
EXCEL_TIME_UNIT = "excel_serial"     # time unit of Excel serial dates (days since 1899-12-30)


@dataclass
class CaseFile:
    """A delimited case file as text: preamble lines, header cells, rows of cells, delimiter, line end."""

    header: list[str]
    rows: list[list[str]]
    delimiter: str = ","
    newline: str = "\n"
    preamble: list[str] = field(default_factory=list)
    final_newline: bool = True

    @classmethod
    def parse(cls, data: bytes) -> CaseFile:
        text = data.decode("utf-8")
        newline = "\r\n" if "\r\n" in text else "\n"
        lines = text.split(newline)
        if lines[-1] == "":
            lines = lines[:-1]
        return cls(lines[0].split(","), [line.split(",") for line in lines[1:]], newline=newline)

    def to_bytes(self) -> bytes:
        lines = self.preamble + [self.delimiter.join(self.header)] + [self.delimiter.join(r) for r in self.rows]
        return (self.newline.join(lines) + (self.newline if self.final_newline else "")).encode("utf-8")

    def col(self, name: str) -> int:
        return self.header.index(name)


@dataclass
class Campaign:
    """A raw campaign as text: its manifest and its case files by file name; ``channels`` maps each channel to
    its column name in the files (``time``, ``displacement``, ``force``, ``temperature``)."""

    base: str
    manifest: dict
    files: dict[str, CaseFile]
    channels: dict[str, str]
    rate_Hz: float

    def copy(self) -> Campaign:
        return copy.deepcopy(self)

    def cases(self) -> list[str]:
        return [str(c["id"]) for c in self.manifest["cases"]]

    def entry(self, case: str) -> dict:
        return next(c for c in self.manifest["cases"] if str(c["id"]) == case)

    def file(self, case: str) -> CaseFile:
        return self.files[self.entry(case)["file"]]

    def write(self, folder: Path, name: str) -> Path:
        """The campaign as ``folder/name`` (manifest with ``campaign: name``); returns the folder."""
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        for file_name, case_file in self.files.items():
            (folder / file_name).write_bytes(case_file.to_bytes())
        rf.write_manifest(folder, {**self.manifest, "campaign": name})
        return folder


# --------------------------------------------------------------------------------------------
# the two good campaigns
# --------------------------------------------------------------------------------------------

def triangle_base() -> Campaign:
    """The good triangle campaign (module docstring): T01-T03, 8 s periods, 5, 10 and 20 mm/s."""
    files, entries = {}, []
    for i, (case, period, velocity) in enumerate(rf.TRIANGLE_CASES):
        rec = rf.triangle_record(period, velocity, TRI_RATE_HZ, effects=EFFECTS, seed=11 + i)
        columns = {"time_s": rf.fixed(rec["time_s"], 3), "oil_C": rf.fixed(rec["temperature_C"], 2),
                   "disp_mm": rf.fixed(rec["displacement_m"] * 1e3, 5),
                   "force_kN": rf.fixed(rec["force_N"] / 1e3, 5)}
        files[f"{case}.csv"] = CaseFile(list(columns), [list(r) for r in zip(*columns.values())])
        entries.append({"id": case, "waveform": "triangle", "period_s": period,
                        "amplitude_mm": round(velocity * period / 4.0 * 1e3, 9), "file": f"{case}.csv"})
    manifest = {"format_version": 1, "campaign": "tri", "description": "triangle campaign (issue 34 fuzz)",
                "source": "rig", "temperature_C": 40.0, "sample_rate_Hz": TRI_RATE_HZ,
                "columns": {"time": {"name": "time_s", "unit": "s"}, "displacement": {"name": "disp_mm", "unit": "mm"},
                            "force": {"name": "force_kN", "unit": "kN"},
                            "temperature": {"name": "oil_C", "unit": "C"}},
                "damper": {k: float(v) for k, v in rf.SHOCK_ABSORBER.to_dict().items()},
                "cases": entries}
    channels = {"time": "time_s", "displacement": "disp_mm", "force": "force_kN", "temperature": "oil_C"}
    return Campaign("tri", manifest, files, channels, TRI_RATE_HZ)


def crank_base(scratch: Path) -> Campaign:
    """The good sine campaign: the crank dyno's folder written in ``scratch`` (module docstring), read back as
    text, the force column moved last, and its manifest."""
    rf.write_crank_folder(scratch, frequencies_Hz=CRANK_FREQUENCIES_HZ, stroke_amplitude_m=CRANK_AMPLITUDE_MM * 1e-3,
                          cycles=CRANK_CYCLES, sample_rate_Hz=CRANK_RATE_HZ, effects=EFFECTS)
    files, entries = {}, []
    for i, f in enumerate(CRANK_FREQUENCIES_HZ, start=1):
        parsed = CaseFile.parse((scratch / f"run_{i}.csv").read_bytes())
        j = parsed.col("Force (N)")
        order = [k for k in range(len(parsed.header)) if k != j] + [j]
        parsed.header = [parsed.header[k] for k in order]
        parsed.rows = [[r[k] for k in order] for r in parsed.rows]
        files[f"run_{i}.csv"] = parsed
        entries.append({"id": f"S0{i}", "waveform": "sine", "frequency_Hz": f, "amplitude_mm": CRANK_AMPLITUDE_MM,
                        "file": f"run_{i}.csv"})
    channels = {"time": "Timestamp", "displacement": "Displacement (mm)", "force": "Force (N)",
                "temperature": "Temperature (C)"}
    manifest = {"format_version": 1, "campaign": "crank", "description": "crank dyno (issue 34 fuzz)",
                "source": "rig", "temperature_C": 32.0, "sample_rate_Hz": CRANK_RATE_HZ,
                "columns": {"time": {"name": channels["time"], "unit": "s"},
                            "displacement": {"name": channels["displacement"], "unit": "mm"},
                            "force": {"name": channels["force"], "unit": "N"},
                            "temperature": {"name": channels["temperature"], "unit": "C"}},
                "cases": entries}
    return Campaign("crank", manifest, files, channels, CRANK_RATE_HZ)


# --------------------------------------------------------------------------------------------
# damages
# --------------------------------------------------------------------------------------------

@dataclass
class Damage:
    """What a damage did: the data rows (of the good file) it touched per case and the cases it damaged whole
    (no window of them is good: they must be set aside or give the good points)."""

    touched: dict[str, set[int]] = field(default_factory=dict)
    whole: set[str] = field(default_factory=set)
    temperature: bool = False     # the temperature channel is damaged: check cases.parquet's temperature_C
    #: the damaged cases are a faithful record of the mirrored damper (played backwards, load cell upside down):
    #: where the force has too little memory for any check to tell (docs/real-world-input.md, causality), their
    #: points may be the mirrored twin's, each the negated point of the other direction
    mirrored: bool = False


@dataclass(frozen=True)
class Windows:
    """The good twin's windows: {case: [(row_start, row_stop), ...]} and the velocity-peak rows of a sine case."""

    spans: dict[str, list[tuple[int, int]]]

    def pick(self, case: str, rng: np.random.Generator) -> tuple[int, int]:
        spans = self.spans[case]
        return spans[int(rng.integers(len(spans)))]


def peak_rows(campaign: Campaign, case: str, start: int, stop: int) -> list[int]:
    """Rows in [start, stop) where the speed is at its peak: a sine's y = A sin(2 pi f t) peaks at t = k / (2 f);
    a triangle's window holds its constant velocity throughout."""
    entry = campaign.entry(case)
    if entry["waveform"] != "sine":
        return list(range(start, stop))
    f = float(entry["frequency_Hz"])
    k = np.arange(0, int(2 * f * stop / campaign.rate_Hz) + 2)
    rows = np.round(k * campaign.rate_Hz / (2 * f)).astype(int)
    return [int(r) for r in rows if start <= r < stop] or list(range(start, stop))


def _row_in_window(c: Campaign, w: Windows, rng, peak: bool = False) -> tuple[str, int]:
    case = c.cases()[int(rng.integers(len(c.cases())))]
    start, stop = w.pick(case, rng)
    rows = peak_rows(c, case, start, stop) if peak else list(range(start, stop))
    return case, rows[int(rng.integers(len(rows)))]


def kn_as_n(c: Campaign, w: Windows, rng) -> Damage:
    """Force in kN declared as N, in a campaign without a damper block (every file, the header without a unit)."""
    c.manifest.pop("damper", None)
    name = c.channels["force"]
    for case_file in c.files.values():
        j = case_file.col(name)
        if c.base == "tri":                       # the values are kN already: the header loses its unit
            case_file.header[j] = "load"
        else:                                     # the logger wrote kN under the header "Force (N)"
            for r in case_file.rows:
                r[j] = f"{float(r[j]) / 1e3:.5f}"
    c.manifest["columns"]["force"] = {"name": "load" if c.base == "tri" else name, "unit": "N"}
    return Damage(whole=set(c.cases()))


def reversed_upside_down(c: Campaign, w: Windows, rng) -> Damage:
    """One case played backwards (rows in reverse order, the time column left ascending), the load cell upside
    down (force negated). For a damper without memory this is, sample for sample, the record of the mirrored
    damper F'(v) = -F(-v) (the time reversal negates the velocity, the load cell the force): no check of the file
    can tell it from a real one, only the force's lag can (causality). The case is set aside, or its points are
    the mirrored twin's."""
    case = c.cases()[int(rng.integers(len(c.cases())))]
    f = c.file(case)
    t, j = f.col(c.channels["time"]), f.col(c.channels["force"])
    times = [r[t] for r in f.rows]
    f.rows = [list(r) for r in reversed(f.rows)]
    for r, stamp in zip(f.rows, times):
        r[t] = stamp
        r[j] = r[j][1:] if r[j].startswith("-") else "-" + r[j]
    return Damage(whole={case}, mirrored=True)


def spike(c: Campaign, w: Windows, rng) -> Damage:
    """One 10 kN spike sample inside a window (at a velocity peak of a sine), either sign."""
    case, row = _row_in_window(c, w, rng, peak=True)
    f = c.file(case)
    j = f.col(c.channels["force"])
    scale = 1e3 if c.base == "tri" else 1.0
    value = float(f.rows[row][j]) + float(rng.choice([-1.0, 1.0])) * SPIKE_N / scale
    f.rows[row][j] = f"{value:.5f}" if c.base == "tri" else f"{value:.2f}"
    return Damage(touched={case: {row}})


def _crash_at(c: Campaign, w: Windows, rng) -> tuple[str, CaseFile, set[int]]:
    """A rig that crashed while writing: the file ends at a row inside a window; rows after it are gone.
    Returns (case, file, the rows touched: the last one written and every one lost)."""
    case, row = _row_in_window(c, w, rng)
    f = c.file(case)
    touched = set(range(row, len(f.rows)))
    f.rows = f.rows[:row + 1]
    f.final_newline = False
    return case, f, touched


def cut_short(c: Campaign, w: Windows, rng) -> Damage:
    """The file ends inside a window with its last number cut short (``-1.`` for ``-1.22``)."""
    case, f, touched = _crash_at(c, w, rng)
    last = f.rows[-1][-1]
    prefixes = [last[:k] for k in range(1, len(last))
                if any(ch.isdigit() for ch in last[:k]) and float(last[:k]) != float(last)]
    f.rows[-1][-1] = prefixes[int(rng.integers(len(prefixes)))] if prefixes else last[:-1]
    return Damage(touched={case: touched})


def truncated_row(c: Campaign, w: Windows, rng) -> Damage:
    """The file ends inside a window in a row cut off before its last field (with or without the delimiter)."""
    case, f, touched = _crash_at(c, w, rng)
    f.rows[-1] = f.rows[-1][:-1] + ([""] if rng.random() < 0.5 else [])
    return Damage(touched={case: touched})


def blank_cell(c: Campaign, w: Windows, rng) -> Damage:
    """One blank cell (time, displacement, force or temperature) in a row inside a window."""
    case, row = _row_in_window(c, w, rng)
    f = c.file(case)
    channel = ["time", "displacement", "force", "temperature"][int(rng.integers(4))]
    f.rows[row][f.col(c.channels[channel])] = ""
    return Damage(touched={case: {row}})


def duplicated_time(c: Campaign, w: Windows, rng) -> Damage:
    """One duplicated time stamp: a row inside a window carries the previous row's time."""
    case, row = _row_in_window(c, w, rng)
    f = c.file(case)
    t = f.col(c.channels["time"])
    f.rows[row][t] = f.rows[row - 1][t]
    return Damage(touched={case: {row - 1, row}})


def second_header(c: Campaign, w: Windows, rng) -> Damage:
    """A second header line in the middle of the data (inside a window); no sample is lost."""
    case, row = _row_in_window(c, w, rng)
    f = c.file(case)
    f.rows.insert(row, list(f.header))
    return Damage()


def lone_cr(c: Campaign, w: Windows, rng) -> Damage:
    """Lone-CR line endings (classic Mac OS, some loggers) in one case file."""
    case = c.cases()[int(rng.integers(len(c.cases())))]
    c.file(case).newline = "\r"
    return Damage()


def _thousands(value: str, decimals: int) -> str:
    """``1234.5`` as ``1.234,5``: '.' groups thousands, ',' marks the decimals."""
    return f"{float(value):,.{decimals}f}".replace(",", "_").replace(".", ",").replace("_", ".")


def thousands_separators(c: Campaign, w: Windows, rng) -> Damage:
    """Every file as a German spreadsheet writes it: ';' between fields, ',' for decimals, '.' between thousands
    (``1.234,5``), declared in the manifest. The triangle's times are written in ms so that they reach thousands."""
    if c.base == "tri":
        _time_column(c, lambda t_s: f"{t_s * 1e3:.0f}", header="time_ms")
        c.manifest["columns"]["time"]["unit"] = "ms"
    for case_file in c.files.values():
        for r in case_file.rows:
            r[:] = [_thousands(cell, len(cell.split(".")[1]) if "." in cell else 0) for cell in r]
        case_file.delimiter = ";"
    c.manifest["csv"] = {"delimiter": ";", "decimal": ","}
    c.manifest["csv"][THOUSANDS_KEY] = "."
    return Damage()


def _time_column(c: Campaign, render: Callable[[float], str], header: str = "time") -> None:
    """Every file's time column rendered anew, its header without a unit (``time_s`` would say seconds)."""
    name = c.channels["time"]
    for case_file in c.files.values():
        t = case_file.col(name)
        for r in case_file.rows:
            r[t] = render(float(r[t]))
        if name == "time_s":
            case_file.header[t] = header
    if name == "time_s":
        c.manifest["columns"]["time"]["name"] = header


def clock_times(c: Campaign, w: Windows, rng) -> Damage:
    """``HH:MM:SS.fff`` time stamps from a seeded start of day (no midnight inside a record)."""
    start_ms = int(rng.integers(0, 22 * 3600 * 1000))

    def render(t_s: float) -> str:
        ms = start_ms + int(round(t_s * 1e3))
        return f"{ms // 3_600_000:02d}:{ms // 60_000 % 60:02d}:{ms // 1000 % 60:02d}.{ms % 1000:03d}"

    _time_column(c, render)
    c.manifest["columns"]["time"]["unit"] = CLOCK_TIME_UNIT
    return Damage()


def excel_serial_dates(c: Campaign, w: Windows, rng) -> Damage:
    """Excel serial dates (days since 1899-12-30, 10 decimals: 9 microseconds) from a seeded day and time."""
    start_day = 45_000 + int(rng.integers(0, 1000)) + float(rng.integers(0, 20 * 3600)) / 86_400
    _time_column(c, lambda t_s: f"{start_day + t_s / 86_400:.10f}")
    c.manifest["columns"]["time"]["unit"] = EXCEL_TIME_UNIT
    return Damage()


def excel_sep_line(c: Campaign, w: Windows, rng) -> Damage:
    """Every file ';'-separated with Excel's ``sep=;`` first line, the delimiter declared."""
    for case_file in c.files.values():
        case_file.delimiter = ";"
        case_file.preamble = ["sep=;"]
    c.manifest["csv"] = {"delimiter": ";"}
    return Damage()


def command_as_temperature(c: Campaign, w: Windows, rng) -> Damage:
    """A command channel under the short header ``c`` declared as the temperature in C; the real temperature
    column stays in the files under a name the manifest does not use."""
    for case_id in c.cases():
        f, entry = c.file(case_id), c.entry(case_id)
        t = np.array([float(r[f.col(c.channels["time"])]) for r in f.rows])
        amplitude_m = float(entry["amplitude_mm"]) * 1e-3
        if entry["waveform"] == "triangle":
            command = triangle_displacement(t, amplitude_m, float(entry["period_s"]))
        else:
            command = amplitude_m * np.sin(2 * math.pi * float(entry["frequency_Hz"]) * t)
        f.header.append("c")
        for r, value in zip(f.rows, rf.fixed(command * 1e3, 4)):
            r.append(value)
    c.manifest["columns"]["temperature"] = {"name": "c", "unit": "C"}
    return Damage(whole=set(c.cases()), temperature=True)


def velocity_as_displacement(c: Campaign, w: Windows, rng) -> Damage:
    """One case's displacement column names a velocity channel (mm/s, the displacement's derivative)."""
    case = c.cases()[int(rng.integers(len(c.cases())))]
    f = c.file(case)
    t = np.array([float(r[f.col(c.channels["time"])]) for r in f.rows])
    x = np.array([float(r[f.col(c.channels["displacement"])]) for r in f.rows])
    f.header.append("vel")
    for r, value in zip(f.rows, rf.fixed(np.gradient(x, t), 4)):
        r.append(value)
    c.entry(case)["columns"] = {"displacement": {"name": "vel", "unit": "mm"}}
    return Damage(whole={case})


def dropped_row(c: Campaign, w: Windows, rng) -> Damage:
    """Control: one row inside a window missing (a logger's dropout, which format 1.2 already keeps)."""
    case, row = _row_in_window(c, w, rng)
    del c.file(case).rows[row]
    return Damage(touched={case: {row}})


#: The realities of issue 34, by name (the test's ids), and the control.
DAMAGES: dict[str, Callable[[Campaign, Windows, np.random.Generator], Damage]] = {
    "kN_declared_as_N": kn_as_n,
    "reversed_upside_down": reversed_upside_down,
    "spike_10kN": spike,
    "last_number_cut_short": cut_short,
    "truncated_last_row": truncated_row,
    "blank_cell": blank_cell,
    "duplicated_time_stamp": duplicated_time,
    "second_header": second_header,
    "lone_cr": lone_cr,
    "thousands_separators": thousands_separators,
    "clock_times": clock_times,
    "excel_serial_dates": excel_serial_dates,
    "excel_sep_line": excel_sep_line,
    "command_as_temperature": command_as_temperature,
    "velocity_as_displacement": velocity_as_displacement,
    "control_dropped_row": dropped_row,
}


def windows_of(characteristic: pd.DataFrame) -> Windows:
    """The good twin's windows by case (the row ranges of its characteristic points)."""
    spans: dict[str, list[tuple[int, int]]] = {}
    for r in characteristic.sort_values(["case", "segment"]).itertuples():
        spans.setdefault(str(r.case), []).append((int(r.row_start), int(r.row_stop)))
    return Windows(spans)


def load_yaml(path: Path) -> dict:
    return yaml.safe_load(path.read_text(encoding="utf-8"))
