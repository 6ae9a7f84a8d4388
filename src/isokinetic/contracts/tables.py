"""Column contracts of every table the pipeline writes, checked as pandera schemas.

Each stage validates what it writes (``validate_table``); a schema failure there is a bug in
the pipeline, not bad input. Bad *input* is caught by :mod:`isokinetic.stages.validate` and
quarantined case by case.

The contracts are declared here as plain data (:class:`Schema` of :class:`Column` and
:class:`Check`), from which :func:`pandera_schema` builds the pandera schema. Importing pandera
costs a pipeline job about 0.3 s and its validation ~10 ms a table, so :func:`validate_table`
first runs the same contract as a strict numpy/pandas check (:func:`passes`: exact dtypes, no
nulls in a non-nullable column, every check true; a few ms a table); a table that passes it passes
pandera too, and pandera is imported and asked only for a table that does not (its errors are
then pandera's own, all failures reported at once).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cache

import numpy as np
import pandas as pd

from isokinetic.physics.plan import WAVEFORMS

STATUS = ("ok", "quarantined")
DIRECTIONS = ("+", "-")

#: Column dtypes of the contracts: pandera's dtype for each and the pandas dtype a column must have
#: exactly to pass :func:`passes` ("str": object holding Python str, as pandera's ``str``).
DTYPES = {"int64": "int64", "float64": "float64", "Int64": "Int64", "bool": bool, "str": str}


@dataclass(frozen=True)
class Check:
    """A check of a column (element-wise) or of a whole table: pandera's built-in ``ge``, ``gt`` or
    ``isin`` of ``value``, or ``fn`` under the name ``name`` (pandera's ``Check(fn, name=name)``)."""

    name: str
    value: object = None
    fn: Callable | None = field(default=None, compare=False)

    @staticmethod
    def ge(value) -> Check:
        """Every value >= ``value``."""
        return Check("greater_than_or_equal_to", value)

    @staticmethod
    def gt(value) -> Check:
        """Every value > ``value``."""
        return Check("greater_than", value)

    @staticmethod
    def isin(values) -> Check:
        """Every value one of ``values``."""
        return Check("isin", tuple(values))

    def __call__(self, data):
        """The check's boolean result on a column (element-wise) or a table."""
        if self.fn is not None:
            return self.fn(data)
        if self.name == "greater_than_or_equal_to":
            return data >= self.value
        if self.name == "greater_than":
            return data > self.value
        return data.isin(list(self.value))


@dataclass(frozen=True)
class Column:
    """One column of a contract (pandera's ``Column``: dtype, checks, nullable, required, unique)."""

    dtype: str
    checks: tuple[Check, ...] | Check = ()
    nullable: bool = False
    required: bool = True
    unique: bool = False

    def __post_init__(self):
        if self.dtype not in DTYPES:
            raise ValueError(f"unknown column dtype {self.dtype!r}, one of {sorted(DTYPES)}")
        object.__setattr__(self, "checks", (self.checks,) if isinstance(self.checks, Check) else tuple(self.checks))


@dataclass(frozen=True, eq=False)
class Schema:
    """A table contract: named columns (in table order), table-level checks, strict: no other columns."""

    columns: Mapping[str, Column]
    checks: tuple[Check, ...] = ()
    strict: bool = False
    name: str | None = None


_finite = Check("finite", fn=lambda s: pd.Series(pd.to_numeric(s, errors="coerce")).abs() < float("inf"))
#: Finite or NaN (a nullable column's missing value), never ±inf.
_not_inf = Check("not_inf", fn=lambda s: ~pd.Series(pd.to_numeric(s, errors="coerce")).abs().eq(float("inf")))


def _increasing(s: pd.Series) -> pd.Series:
    """Element-wise: each value above its predecessor (the first sample passes)."""
    return s.diff().fillna(1.0) > 0


#: Canonical time series of one case: one Parquet file per case, rows as in the raw file.
TIMESERIES = Schema(
    {
        "row": Column("int64", Check.ge(0)),
        "time_s": Column("float64", [_finite, Check("time_increasing", fn=_increasing)]),
        "displacement_m": Column("float64", _finite),
        "force_N": Column("float64", _finite),
        "command_m": Column("float64", _finite, required=False),
        # (format 1.1) the manifest's temperature channel, in C
        "temperature_C": Column("float64", _finite, required=False),
    },
    strict=False,
    name="timeseries",
)

#: One row per planned case of a campaign, with its source and status.
CASES = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str", unique=True),
        "waveform": Column("str", Check.isin(WAVEFORMS)),
        "sample_rate_Hz": Column("float64", Check.gt(0)),
        "amplitude_m": Column("float64", nullable=True),
        "period_s": Column("float64", nullable=True),
        "frequency_Hz": Column("float64", nullable=True),
        "phase_rad": Column("float64", nullable=True),
        "duration_s": Column("float64", nullable=True),
        "raw_file": Column("str"),
        "raw_sha256": Column("str"),
        "timeseries_file": Column("str"),
        "n_samples": Column("int64", Check.ge(0)),
        "status": Column("str", Check.isin(STATUS)),
        # 'ok', 'quarantined', or the flagged-but-usable warnings ('; '-joined); absent in
        # ingest tables written before the column existed (validation then fills 'ok')
        "quality": Column("str", nullable=True, required=False),
        # measured motion of a triangle case (validate, motion.estimate_motion); NaN for sine and
        # free cases and cases set aside before the motion check; absent in ingest tables:
        # record time [s] at which the plan's t = 0 lies (windows: motion start + plan times)
        "motion_start_s": Column("float64", _not_inf, nullable=True, required=False),
        # motion_start_s - the first time stamp: command-to-piston delay (actuator delay + servo lag) [s]
        "delay_s": Column("float64", _not_inf, nullable=True, required=False),
        # mean measured |v| of the four half-periods / planned W = 4Y/T (Eq. 26)
        "velocity_ratio": Column("float64", Check.ge(0), nullable=True, required=False),
        # rms departure of the measured displacement from the planned triangle at the motion start [m]
        "motion_rms_m": Column("float64", Check.ge(0), nullable=True, required=False),
        # the case's temperature [C]: the mean of its temperature channel, else the case's temperature_C,
        # else the campaign's (temperature_source: channel | case | campaign; NaN and '' when none is known);
        # temperature_span_C: max - min of the channel over the record (NaN without a channel)
        "temperature_C": Column("float64", _not_inf, nullable=True, required=False),
        "temperature_span_C": Column("float64", Check.ge(0), nullable=True, required=False),
        "temperature_source": Column("str", Check.isin(("channel", "case", "campaign", "")), nullable=True,
                                     required=False),
        # dropped samples (validate, measurement.sampling; NaN/NA for cases set aside before the check):
        # samples missing from the record's grid, their fraction of the grid, the longest interval
        # without a sample [s] (0 when none is missing)
        "missing_samples": Column("Int64", Check.ge(0), nullable=True, required=False),
        "missing_fraction": Column("float64", Check.ge(0), nullable=True, required=False),
        "longest_gap_s": Column("float64", Check.ge(0), nullable=True, required=False),
        # (ingest, manifest 1.2) a case sliced from its file (time_range_s / rows): the slice's first time on the
        # file's own time axis [s] and its data rows [row_start, row_stop) (whole numbers, float64 so that a
        # whole-file case has NaN, as trace compares them); NaN for a whole-file case
        "slice_start_s": Column("float64", _not_inf, nullable=True, required=False),
        "row_start": Column("float64", Check.ge(0), nullable=True, required=False),
        "row_stop": Column("float64", Check.ge(0), nullable=True, required=False),
        # (ingest) the gas force subtracted from the case's force samples [N] (case's, else campaign's); NaN: none
        "gas_force_N": Column("float64", _not_inf, nullable=True, required=False),
    },
    strict=False,
    name="cases",
)

#: Cases set aside, each with the reason naming campaign, case, column and first bad row.
QUARANTINE = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str"),
        "stage": Column("str"),
        "column": Column("str"),
        "row": Column("Int64", nullable=True),
        "reason": Column("str"),
    },
    strict=True,
    name="quarantine",
)

_WINDOW_COLUMNS = {
    "campaign": Column("str"),
    "case": Column("str"),
    "segment": Column("int64", Check.isin([1, 2, 3, 4])),
    "direction": Column("str", Check.isin(DIRECTIONS)),
    "period": Column("int64", Check.isin([1, 2])),
    "planned_velocity_m_s": Column("float64"),
    "velocity_m_s": Column("float64", _finite),
    "force_N": Column("float64", _finite),
    "force_std_N": Column("float64", Check.ge(0)),
    "n_samples": Column("int64", Check.ge(2)),
    "window_start_s": Column("float64"),
    "window_end_s": Column("float64"),
    "row_start": Column("int64", Check.ge(0)),
    "row_stop": Column("int64", Check.ge(0)),
    "raw_file": Column("str"),
    "raw_sha256": Column("str"),
    # 'ok' or the case's flagged-but-usable warnings (e.g. samples missing outside the windows)
    "quality": Column("str", nullable=True, required=False),
}

#: One row per constant-velocity window (item 7): four per triangle case.
WINDOWS = Schema(
    {**_WINDOW_COLUMNS,
     # samples of the record's grid inside the window that the logger dropped (validate sets a case
     # aside beyond validation.max_missing_fraction); absent in windows written before it existed
     "missing_samples": Column("Int64", Check.ge(0), nullable=True, required=False),
     # (issue 34) force samples left out of the window's statistics as spikes (measurement.spikes); absent in
     # windows written before it existed
     "spikes_excluded": Column("Int64", Check.ge(0), nullable=True, required=False)},
    checks=(Check("row_range", fn=lambda df: df["row_stop"] > df["row_start"]),),
    strict=False,
    name="windows",
)

#: Period 1 against period 2 for each case and direction (item 8).
REPEATABILITY = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str"),
        "direction": Column("str", Check.isin(DIRECTIONS)),
        "velocity_m_s": Column("float64"),
        "force_period1_N": Column("float64"),
        "force_period2_N": Column("float64"),
        "rel_diff": Column("float64"),
        "tolerance": Column("float64", Check.gt(0)),
        "flagged": Column("bool"),
    },
    strict=False,
    name="repeatability",
)

#: How a characteristic point was measured (stages.characteristic, docs/method.md): a triangle case's
#: constant-velocity window; the force at the peaks of the measured velocity of any periodic record (sine,
#: distorted sine, crank; cycles averaged, half the steady cycles a period); a quasi-static free record's
#: velocity bin.
CHARACTERISTIC_METHODS = ("triangle_window", "sine_peak", "free_bin")

#: The steady characteristic (item 9): the windows with their repeatability flag, and (issue 19) the
#: periodic records' peak-velocity points and the quasi-static free records' bins (``method``;
#: stages.characteristic). ``segment`` of a peak point: 1 (+) and 2 (-) of period 1, 3 and 4 of period 2; of a
#: free bin: its 1-based number in the case. ``n_samples`` of a peak point counts cycles (force_std_N is their
#: scatter; for one cycle, the force noise of its fit). ``force_se_N`` (issue 33): the standard error of the
#: point's force, force_std_N / sqrt(n_samples), NaN for a peak point resting on one cycle.
CHARACTERISTIC = Schema(
    {**_WINDOW_COLUMNS, "segment": Column("int64", Check.ge(1)), "n_samples": Column("int64", Check.ge(1)),
     "repeatability_flagged": Column("bool"),
     "method": Column("str", Check.isin(CHARACTERISTIC_METHODS), required=False),
     "force_se_N": Column("float64", Check.ge(0), nullable=True, required=False),
     # (issue 34) force samples left out of the point as spikes (measurement.spikes): of its window, of its cycles'
     # speed windows, of its bin; absent in tables written before it existed
     "spikes_excluded": Column("Int64", Check.ge(0), nullable=True, required=False)},
    strict=False,
    name="characteristic",
)

#: Energy dissipated per cycle of each sine case (closed integral of F dx, steady cycles; stages.characteristic).
ENERGY = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str"),
        "frequency_Hz": Column("float64", Check.gt(0)),
        "displacement_amplitude_m": Column("float64", Check.ge(0)),
        "velocity_amplitude_m_s": Column("float64", Check.ge(0)),
        "energy_J": Column("float64", _finite),
        "energy_std_J": Column("float64", Check.ge(0), nullable=True),
        "energy_se_J": Column("float64", Check.ge(0), nullable=True),
        "n_cycles": Column("int64", Check.ge(1)),
        "equivalent_damping_N_s_m": Column("float64", _not_inf, nullable=True),
        "row_start": Column("int64", Check.ge(0)),
        "row_stop": Column("int64", Check.ge(0)),
    },
    strict=False,
    name="energy",
)


#: Test design per planned case (issue: G-numbers Eq. 19-22, stroke to converge Eq. 28-29).
PLAN_CHECK = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str"),
        "waveform": Column("str", Check.isin(WAVEFORMS)),
        "velocity_m_s": Column("float64", nullable=True),
        "period_s": Column("float64", nullable=True),
        "amplitude_m": Column("float64", nullable=True),
        "G1": Column("float64", nullable=True),
        "G2": Column("float64", nullable=True),
        "G3": Column("float64", nullable=True),
        "stroke_to_converge_m": Column("float64", nullable=True),
        "window_start_stroke_m": Column("float64", nullable=True),
        "flagged": Column("bool"),
        "reasons": Column("str"),
    },
    strict=False,
    name="plan_check",
)

#: Fitted model parameters (Wallaschek symmetric, Surace asymmetric) with 95 % intervals.
MODELS = Schema(
    {
        "campaign": Column("str"),
        "model": Column("str", Check.isin(["wallaschek", "surace"])),
        "direction": Column("str", Check.isin(["both", "+", "-"])),
        "parameter": Column("str"),
        # NaN: not fitted (e.g. fewer characteristic points than parameters)
        "estimate": Column("float64", nullable=True),
        "ci_low": Column("float64", nullable=True),
        "ci_high": Column("float64", nullable=True),
        # physical range check (stages.models): the range ('' when none), false only when the whole
        # interval lies outside it, and the reason ('' when inside; 'not excluded: ...' when it straddles)
        "physical_range": Column("str"),
        "plausible": Column("bool"),
        "plausibility": Column("str"),
    },
    strict=False,
    name="models",
)

#: The static force at v -> 0 (gas force, load-cell zero) of a campaign: one row (stages.static_force).
STATIC_FORCE = Schema(
    {
        "campaign": Column("str"),
        # NaN: not estimated (no speed with both directions; note says why)
        "static_force_N": Column("float64", _not_inf, nullable=True),
        "std_error_N": Column("float64", Check.ge(0), nullable=True),
        "ci_low_N": Column("float64", _not_inf, nullable=True),
        "ci_high_N": Column("float64", _not_inf, nullable=True),
        "confidence": Column("float64", Check.gt(0)),
        "source": Column("str", Check.isin(["characteristic", "harmonic_binned", "standstill", "none"])),
        "method": Column("str", Check.isin(["linear_fit", "two_speeds", "lowest_speed", "standstill_mean", "none"])),
        "n_speeds": Column("int64", Check.ge(0)),
        "n_matched": Column("int64", Check.ge(0)),
        "v_min_m_s": Column("float64", nullable=True),
        "v_max_m_s": Column("float64", nullable=True),
        # the declared gas force ingest subtracted (manifest gas_force_N); NaN: none declared
        "gas_force_N": Column("float64", nullable=True),
        "significant": Column("bool"),
        "note": Column("str"),
        # (manifest 1.2) ok standstill cases; the declared gas forces checked against what is left after
        # subtracting them (agrees | disagrees | not_checked) and one line per check (stages.static_force)
        "n_standstill": Column("int64", Check.ge(0), required=False),
        "gas_force_check": Column("str", Check.isin(["agrees", "disagrees", "not_checked"]), required=False),
        "gas_force_cases": Column("str", required=False),
    },
    checks=(Check("one_row", fn=lambda df: pd.Series([len(df) == 1])),),
    strict=False,
    name="static_force",
)

#: Harmonic and free-waveform summary points (peak-to-peak, peak-velocity, velocity-binned).
HARMONIC = Schema(
    {
        "campaign": Column("str"),
        "case": Column("str"),
        "waveform": Column("str", Check.isin(["sine", "free"])),
        "kind": Column("str", Check.isin(["peak_to_peak", "peak_velocity", "binned"])),
        "direction": Column("str", Check.isin(DIRECTIONS)),
        "velocity_m_s": Column("float64"),
        "force_N": Column("float64"),
        # (issue 33) the case's record passes the quasi-static test (measurement.quasi_static): only then are a
        # free record's bins characteristic points (in characteristic.parquet); else they are its loop's view
        "quasi_static": Column("bool", required=False),
    },
    strict=False,
    name="harmonic",
)

#: Campaigns compared point by point (stages.compare): one row per campaign (against the reference),
#: direction and velocity; basis 'measured' (matched points) or 'model:<name>' (both through their fit).
_BASIS = Check("measured_or_model", fn=lambda s: s.eq("measured") | s.str.startswith("model:"))
COMPARE = Schema(
    {
        "comparison": Column("str"),
        "reference": Column("str"),
        "campaign": Column("str"),
        "direction": Column("str", Check.isin(DIRECTIONS)),
        "velocity_m_s": Column("float64", _finite),
        "basis": Column("str", _BASIS),
        # each side: the case whose point the row uses ('' on a model row for the side it did not come from),
        # its measured velocity, force (the campaign's moved to the reference's velocity) and standard error;
        # the noise and repeatability parts of a measured point's SE (NaN on a model row)
        **{f"{side}_{name}": col for side in ("reference", "campaign") for name, col in (
            ("case", Column("str")), ("velocity_m_s", Column("float64", _finite)),
            ("force_N", Column("float64", _finite)), ("se_N", Column("float64", Check.ge(0))),
            ("noise_se_N", Column("float64", Check.ge(0), nullable=True)),
            ("repeatability_se_N", Column("float64", Check.ge(0), nullable=True)))},
        "velocity_shift_N": Column("float64", _finite),
        "difference_N": Column("float64", _finite),
        "difference_se_N": Column("float64", Check.gt(0)),
        "z": Column("float64", _finite),
        "p_value": Column("float64", [Check.ge(0), Check("at_most_1", fn=lambda s: s <= 1)]),
        "alpha": Column("float64", Check.gt(0)),
        "significant": Column("bool"),
        "test": Column("str"),
    },
    strict=True,
    name="compare",
)


def _column_passes(s: pd.Series, col: Column) -> bool:
    """The column has exactly the contract's dtype, no null unless nullable, no duplicate if unique,
    and every check true (on the non-null values, as pandera applies a check)."""
    if col.dtype == "str":
        if s.dtype != object or pd.api.types.infer_dtype(s, skipna=True) not in ("string", "empty"):
            return False
    elif col.dtype == "Int64":
        if not isinstance(s.dtype, pd.Int64Dtype):
            return False
    elif s.dtype != np.dtype(col.dtype):
        return False
    if col.unique and s.duplicated().any():
        return False
    nulls = s.isna()
    if nulls.any():
        if not col.nullable:
            return False
        s = s[~nulls]
    return all(bool(np.all(check(s))) for check in col.checks)


def passes(df: pd.DataFrame, schema: Schema) -> bool:
    """True when ``df`` meets the contract by a strict check of its own (no pandera): then pandera's
    schema passes too. False means "not decided here": ask :func:`pandera_schema`."""
    if not isinstance(df, pd.DataFrame) or not df.columns.is_unique:
        return False
    names = set(df.columns)
    if schema.strict and not names <= set(schema.columns):
        return False
    for name, col in schema.columns.items():
        if name not in names:
            if col.required:
                return False
            continue
        if not _column_passes(df[name], col):
            return False
    return all(bool(np.all(check(df))) for check in schema.checks)


def _pandera_check(check: Check):
    from pandera import Check as PanderaCheck

    if check.fn is not None:
        return PanderaCheck(check.fn, name=check.name)
    builtin = {"greater_than_or_equal_to": PanderaCheck.ge, "greater_than": PanderaCheck.gt,
               "isin": lambda v: PanderaCheck.isin(list(v))}
    return builtin[check.name](check.value)


@cache
def pandera_schema(schema: Schema):
    """The pandera ``DataFrameSchema`` of a contract (pandera imported here, on first use)."""
    import pandera.pandas as pa

    columns = {name: pa.Column(DTYPES[col.dtype], [_pandera_check(c) for c in col.checks], nullable=col.nullable,
                               required=col.required, unique=col.unique)
               for name, col in schema.columns.items()}
    return pa.DataFrameSchema(columns, checks=[_pandera_check(c) for c in schema.checks], strict=schema.strict,
                              name=schema.name)


def validate_table(df: pd.DataFrame, schema: Schema) -> pd.DataFrame:
    """Validate a table the pipeline is about to write (all failures reported at once): a copy of
    ``df`` when it passes, as pandera returns it; pandera's ``SchemaErrors`` when it does not."""
    if passes(df, schema):
        return df.copy()
    return pandera_schema(schema).validate(df, lazy=True)


def failure_cases(df: pd.DataFrame, schema: Schema) -> pd.DataFrame | None:
    """None when ``df`` passes the contract, else pandera's failure cases (one row per failure:
    ``check``, ``column``, ``index``, ``failure_case``, ...)."""
    if passes(df, schema):
        return None
    import pandera.pandas as pa

    try:
        pandera_schema(schema).validate(df, lazy=True)
    except pa.errors.SchemaErrors as exc:
        return exc.failure_cases
    return None


def empty(schema: Schema) -> pd.DataFrame:
    """An empty frame with the schema's required columns and dtypes."""
    cols = {name: pd.Series(dtype="object" if col.dtype == "str" else col.dtype)
            for name, col in schema.columns.items() if col.required}
    return pd.DataFrame(cols)
