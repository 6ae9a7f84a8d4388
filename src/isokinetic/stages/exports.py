"""Stage ``exports``: a campaign's characteristic and fitted models as CSV files for spreadsheets.

``characteristic.csv`` (from ``characteristic.parquet``) and ``models/models.csv`` (from
``models/models.parquet``), in SI units as the tables hold them:

- row 1: the column names; row 2: each column's unit (:func:`units_row`); then one row per table row;
- ',' between fields, '.' as decimal mark, UTF-8, '\\n' line ends, fields quoted only when they hold a
  ',' or a quote (``source_rows``, the plausibility text);
- floats in their shortest round-trip form (Python's ``repr``): parsed exactly, they give back the
  very same float64. pandas' default parser is not exact (it misses by one unit in the last place
  for about a third of the values); ``pandas.read_csv(path, skiprows=[1], float_precision="round_trip")``
  reads the file back bit for bit;
- booleans as ``true``/``false``, a missing value (NaN, not fitted) as an empty field.

The unit rule. A column's unit is read from the end of its name, the longest suffix of
:data:`UNIT_SUFFIXES` that matches winning (``velocity_m_s`` -> m/s, ``window_start_s`` -> s,
``ci_low_N`` -> N). A name that ends in none of them - a count, a flag, a text, a ratio such as
``rel_diff``, ``confidence`` or ``residual_scale`` - has an empty unit field. In the models table
the value columns (:data:`MODELS_ROW_UNIT_COLUMNS`: estimate, its interval and its standard error)
take each row's own ``unit`` (N, N s/m, Pa s, ...; '-' for a pure number): their unit field says
:data:`ROW_UNIT`.

A CSV file has no place for the lineage record the Parquet, JSON and PNG outputs carry
(:mod:`isokinetic.io`); each export is a view of its Parquet source, written by the same job as
``models.parquet``, and that source carries the record.
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import pandas as pd

from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.io import write_text

#: Name suffix -> unit (the house convention of units in names); the longest matching suffix wins.
UNIT_SUFFIXES = {
    "_m3_s_Pa": "m^3/(s Pa)",
    "_kg_m3": "kg/m^3",
    "_N_s_m": "N s/m",
    "_Pa_s": "Pa s",
    "_1_Pa": "1/Pa",
    "_m_s2": "m/s^2",
    "_m_s": "m/s",
    "_rad": "rad",
    "_Hz": "Hz",
    "_Pa": "Pa",
    "_m2": "m^2",
    "_m3": "m^3",
    "_N": "N",
    "_m": "m",
    "_s": "s",
    "_K": "K",
    "_C": "degC",
}
_SUFFIXES_LONGEST_FIRST = sorted(UNIT_SUFFIXES, key=len, reverse=True)
#: The unit field of a column whose unit is given per row by the table's ``unit`` column.
ROW_UNIT = "see unit column"
#: The models table's columns in the unit of their row.
MODELS_ROW_UNIT_COLUMNS = ("estimate", "ci_low", "ci_high", "std_error")
#: Export name -> (Parquet source, CSV file, columns in their row's unit); paths relative to the campaign's folder.
EXPORTS = {
    "characteristic_csv": (STAGE_OUTPUTS["characteristic"]["characteristic"],
                           STAGE_OUTPUTS["exports"]["characteristic_csv"], ()),
    "models_csv": (STAGE_OUTPUTS["models"]["models"], STAGE_OUTPUTS["exports"]["models_csv"],
                   MODELS_ROW_UNIT_COLUMNS),
}


def unit_of(name: str) -> str:
    """The unit of a column from its name's suffix (module doc); '' when the name carries none."""
    suffix = next((s for s in _SUFFIXES_LONGEST_FIRST if name.endswith(s) and len(name) > len(s)), None)
    return "" if suffix is None else UNIT_SUFFIXES[suffix]


def units_row(columns: Iterable[str], row_unit: Sequence[str] = ()) -> list[str]:
    """The units row of a table's columns: :data:`ROW_UNIT` for those in ``row_unit``, else :func:`unit_of`."""
    return [ROW_UNIT if c in row_unit else unit_of(str(c)) for c in columns]


def csv_text(table: pd.DataFrame, row_unit: Sequence[str] = ()) -> str:
    """A table as CSV text: names, units, then the rows (module doc: format, floats, booleans).

    ``row_unit``: the columns whose unit is the row's own ``unit`` column (the table must have one).
    """
    if any(c in table.columns for c in row_unit) and "unit" not in table.columns:
        raise ValueError("columns in their row's unit need a 'unit' column")
    head = io.StringIO()
    writer = csv.writer(head, lineterminator="\n")
    writer.writerow([str(c) for c in table.columns])
    writer.writerow(units_row(table.columns, row_unit))
    body = table.copy(deep=False)
    for col in table.columns:
        if pd.api.types.is_bool_dtype(table[col]):
            body[col] = table[col].astype(object).map({True: "true", False: "false"})
    return head.getvalue() + body.to_csv(index=False, header=False, lineterminator="\n", na_rep="",
                                         quoting=csv.QUOTE_MINIMAL)


def write_exports(campaign_root: str | os.PathLike) -> list[Path]:
    """``characteristic.csv`` and ``models/models.csv`` of a campaign folder from their Parquet tables
    (:data:`EXPORTS`); returns the written paths."""
    root = Path(campaign_root)
    return [write_text(csv_text(pd.read_parquet(root / source), row_unit), root / target)
            for source, target, row_unit in EXPORTS.values()]
