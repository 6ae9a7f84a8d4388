"""Case files of an exported campaign rewritten in other layouts: units, column names and order, with or
without the command column, comment lines, delimiter and decimal mark."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

#: SI factor of each unit a layout may write.
FACTOR = {"s": 1.0, "ms": 1e-3, "m": 1.0, "mm": 1e-3, "um": 1e-6, "N": 1.0, "kN": 1e3, "C": 1.0}
#: The exported files' columns: channel -> (name, unit).
EXPORTED = {"time": ("time_s", "s"), "displacement": ("disp_mm", "mm"), "force": ("force_kN", "kN"),
            "command": ("cmd_mm", "mm")}


@dataclass(frozen=True)
class Layout:
    """How a rig might write the same records: (channel, column name, unit) in column order, comment lines
    before the header, delimiter and decimal mark. Channel ``temperature`` adds a constant oil temperature."""

    name: str
    columns: tuple[tuple[str, str, str], ...]
    comments: tuple[str, ...] = ()
    delimiter: str = ","
    decimal: str = "."


LAYOUTS = (
    Layout("exported", (("time", "time_s", "s"), ("displacement", "disp_mm", "mm"), ("force", "force_kN", "kN"),
                        ("command", "cmd_mm", "mm"))),
    Layout("ms-m-N-renamed-reordered-no-command", (("force", "F[N]", "N"), ("time", "t[ms]", "ms"),
                                                   ("displacement", "x_m", "m")),
           comments=("# rig: bench 2", "# operator: test")),
    Layout("um-kN-command-first-temperature", (("command", "cmd_um", "um"), ("displacement", "x_um", "um"),
                                               ("time", "time_s", "s"), ("force", "load_kN", "kN"),
                                               ("temperature", "oil_C", "C"))),
    Layout("spreadsheet-semicolon-decimal-comma", (("time", "Zeit [s]", "s"), ("displacement", "Weg [mm]", "mm"),
                                                   ("force", "Kraft [kN]", "kN"), ("command", "Soll [mm]", "mm")),
           comments=("# Prüfstand 3; exportiert",), delimiter=";", decimal=","),
    Layout("tab-ms-N-no-command", (("time", "time [ms]", "ms"), ("displacement", "position (mm)", "mm"),
                                   ("force", "force (N)", "N")), delimiter="\t"),
    Layout("iso-stamps-N-mm", (("time", "timestamp", "datetime"), ("displacement", "disp_mm", "mm"),
                               ("force", "force_N", "N"), ("command", "cmd_mm", "mm"))),
    Layout("unnamed-channels", (("time", "ch0", "s"), ("force", "ch1", "N"), ("displacement", "ch2", "mm"),
                                ("command", "ch3", "mm"))),
)


def si_columns(csv_path: Path) -> dict[str, np.ndarray]:
    """An exported case file's channels in SI."""
    table = pd.read_csv(csv_path)
    return {channel: table[name].to_numpy(float) * FACTOR[unit] for channel, (name, unit) in EXPORTED.items()}


def layout_text(si: dict[str, np.ndarray], layout: Layout) -> str:
    """The case file text of ``si`` channels in ``layout`` (12 significant digits: the exported decimals exactly)."""
    cells = []
    for channel, _name, unit in layout.columns:
        if unit == "datetime":
            stamps = pd.Timestamp("2024-05-01T10:00:00") + pd.to_timedelta(np.rint(si["time"] * 1e6), unit="us")
            cells.append([s.isoformat(timespec="microseconds") for s in stamps])
            continue
        values = np.full(si["time"].size, 40.0) if channel == "temperature" else si[channel] / FACTOR[unit]
        text = [f"{v:.12g}" for v in values.tolist()]
        cells.append([t.replace(".", layout.decimal) for t in text])
    header = layout.delimiter.join(name for _, name, _ in layout.columns)
    rows = [layout.delimiter.join(row) for row in zip(*cells)]
    return "\n".join([*layout.comments, header, *rows]) + "\n"


def rewrite_campaign(exported: Path, out: Path, layout: Layout | dict[str, Layout]) -> Path:
    """The exported campaign's case files in folder ``out`` (no campaign.yaml), in ``layout`` or, given a mapping,
    each case in its own."""
    out.mkdir(parents=True)
    for path in sorted(exported.glob("*.csv")):
        own = layout[path.stem] if isinstance(layout, dict) else layout
        (out / path.name).write_text(layout_text(si_columns(path), own), encoding="utf-8")
    return out
