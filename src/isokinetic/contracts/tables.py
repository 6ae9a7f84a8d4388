"""Column contracts of every table the pipeline writes, as pandera schemas.

Each stage validates what it writes (``validate_table``); a schema failure there is a bug in
the pipeline, not bad input. Bad *input* is caught by :mod:`isokinetic.stages.validate` and
quarantined case by case.
"""

from __future__ import annotations

import pandas as pd
import pandera.pandas as pa
from pandera import Check

from isokinetic.physics.plan import WAVEFORMS

STATUS = ("ok", "quarantined")
DIRECTIONS = ("+", "-")

_finite = Check(lambda s: pd.Series(pd.to_numeric(s, errors="coerce")).abs() < float("inf"), name="finite")
#: Finite or NaN (a nullable column's missing value), never ±inf.
_not_inf = Check(lambda s: ~pd.Series(pd.to_numeric(s, errors="coerce")).abs().eq(float("inf")), name="not_inf")


def _increasing(s: pd.Series) -> pd.Series:
    """Element-wise: each value above its predecessor (the first sample passes)."""
    return s.diff().fillna(1.0) > 0


#: Canonical time series of one case: one Parquet file per case, rows as in the raw file.
TIMESERIES = pa.DataFrameSchema(
    {
        "row": pa.Column("int64", Check.ge(0)),
        "time_s": pa.Column("float64", [_finite, Check(_increasing, name="time_increasing")]),
        "displacement_m": pa.Column("float64", _finite),
        "force_N": pa.Column("float64", _finite),
        "command_m": pa.Column("float64", _finite, required=False),
    },
    strict=False,
    name="timeseries",
)

#: One row per planned case of a campaign, with its source and status.
CASES = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "case": pa.Column(str, unique=True),
        "waveform": pa.Column(str, Check.isin(WAVEFORMS)),
        "sample_rate_Hz": pa.Column("float64", Check.gt(0)),
        "amplitude_m": pa.Column("float64", nullable=True),
        "period_s": pa.Column("float64", nullable=True),
        "frequency_Hz": pa.Column("float64", nullable=True),
        "phase_rad": pa.Column("float64", nullable=True),
        "duration_s": pa.Column("float64", nullable=True),
        "raw_file": pa.Column(str),
        "raw_sha256": pa.Column(str),
        "timeseries_file": pa.Column(str),
        "n_samples": pa.Column("int64", Check.ge(0)),
        "status": pa.Column(str, Check.isin(STATUS)),
        # 'ok', 'quarantined', or the flagged-but-usable warnings ('; '-joined); absent in
        # ingest tables written before the column existed (validation then fills 'ok')
        "quality": pa.Column(str, nullable=True, required=False),
        # measured motion of a triangle case (validate, motion.estimate_motion); NaN for sine and
        # free cases and cases set aside before the motion check; absent in ingest tables:
        # record time [s] at which the plan's t = 0 lies (windows: motion start + plan times)
        "motion_start_s": pa.Column("float64", _not_inf, nullable=True, required=False),
        # motion_start_s - the first time stamp: command-to-piston delay (actuator delay + servo lag) [s]
        "delay_s": pa.Column("float64", _not_inf, nullable=True, required=False),
        # mean measured |v| of the four half-periods / planned W = 4Y/T (Eq. 26)
        "velocity_ratio": pa.Column("float64", Check.ge(0), nullable=True, required=False),
        # rms departure of the measured displacement from the planned triangle at the motion start [m]
        "motion_rms_m": pa.Column("float64", Check.ge(0), nullable=True, required=False),
    },
    strict=False,
    name="cases",
)

#: Cases set aside, each with the reason naming campaign, case, column and first bad row.
QUARANTINE = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "case": pa.Column(str),
        "stage": pa.Column(str),
        "column": pa.Column(str),
        "row": pa.Column("Int64", nullable=True),
        "reason": pa.Column(str),
    },
    strict=True,
    name="quarantine",
)

_WINDOW_COLUMNS = {
    "campaign": pa.Column(str),
    "case": pa.Column(str),
    "segment": pa.Column("int64", Check.isin([1, 2, 3, 4])),
    "direction": pa.Column(str, Check.isin(DIRECTIONS)),
    "period": pa.Column("int64", Check.isin([1, 2])),
    "planned_velocity_m_s": pa.Column("float64"),
    "velocity_m_s": pa.Column("float64", _finite),
    "force_N": pa.Column("float64", _finite),
    "force_std_N": pa.Column("float64", Check.ge(0)),
    "n_samples": pa.Column("int64", Check.ge(2)),
    "window_start_s": pa.Column("float64"),
    "window_end_s": pa.Column("float64"),
    "row_start": pa.Column("int64", Check.ge(0)),
    "row_stop": pa.Column("int64", Check.ge(0)),
    "raw_file": pa.Column(str),
    "raw_sha256": pa.Column(str),
    # 'ok' or the case's flagged-but-usable warnings (e.g. samples missing outside the windows)
    "quality": pa.Column(str, nullable=True, required=False),
}

#: One row per constant-velocity window (item 7): four per triangle case.
WINDOWS = pa.DataFrameSchema(
    _WINDOW_COLUMNS,
    checks=[Check(lambda df: df["row_stop"] > df["row_start"], name="row_range")],
    strict=False,
    name="windows",
)

#: Period 1 against period 2 for each case and direction (item 8).
REPEATABILITY = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "case": pa.Column(str),
        "direction": pa.Column(str, Check.isin(DIRECTIONS)),
        "velocity_m_s": pa.Column("float64"),
        "force_period1_N": pa.Column("float64"),
        "force_period2_N": pa.Column("float64"),
        "rel_diff": pa.Column("float64"),
        "tolerance": pa.Column("float64", Check.gt(0)),
        "flagged": pa.Column(bool),
    },
    strict=False,
    name="repeatability",
)

#: The steady characteristic (item 9): the windows with their repeatability flag.
CHARACTERISTIC = pa.DataFrameSchema(
    {**_WINDOW_COLUMNS, "repeatability_flagged": pa.Column(bool)},
    strict=False,
    name="characteristic",
)


def validate_table(df: pd.DataFrame, schema: pa.DataFrameSchema) -> pd.DataFrame:
    """Validate a table the pipeline is about to write (all failures reported at once)."""
    return schema.validate(df, lazy=True)


def empty(schema: pa.DataFrameSchema) -> pd.DataFrame:
    """An empty frame with the schema's required columns and dtypes."""
    cols = {name: pd.Series(dtype=("object" if col.dtype is None or str(col.dtype) == "str" else str(col.dtype)))
            for name, col in schema.columns.items() if col.required}
    return pd.DataFrame(cols)


#: Test design per planned case (issue: G-numbers Eq. 19-22, stroke to converge Eq. 28-29).
PLAN_CHECK = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "case": pa.Column(str),
        "waveform": pa.Column(str, Check.isin(WAVEFORMS)),
        "velocity_m_s": pa.Column("float64", nullable=True),
        "period_s": pa.Column("float64", nullable=True),
        "amplitude_m": pa.Column("float64", nullable=True),
        "G1": pa.Column("float64", nullable=True),
        "G2": pa.Column("float64", nullable=True),
        "G3": pa.Column("float64", nullable=True),
        "stroke_to_converge_m": pa.Column("float64", nullable=True),
        "window_start_stroke_m": pa.Column("float64", nullable=True),
        "flagged": pa.Column(bool),
        "reasons": pa.Column(str),
    },
    strict=False,
    name="plan_check",
)

#: Fitted model parameters (Wallaschek symmetric, Surace asymmetric) with 95 % intervals.
MODELS = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "model": pa.Column(str, Check.isin(["wallaschek", "surace"])),
        "direction": pa.Column(str, Check.isin(["both", "+", "-"])),
        "parameter": pa.Column(str),
        # NaN: not fitted (e.g. fewer characteristic points than parameters)
        "estimate": pa.Column("float64", nullable=True),
        "ci_low": pa.Column("float64", nullable=True),
        "ci_high": pa.Column("float64", nullable=True),
    },
    strict=False,
    name="models",
)

#: Harmonic and free-waveform summary points (peak-to-peak, peak-velocity, velocity-binned).
HARMONIC = pa.DataFrameSchema(
    {
        "campaign": pa.Column(str),
        "case": pa.Column(str),
        "waveform": pa.Column(str, Check.isin(["sine", "free"])),
        "kind": pa.Column(str, Check.isin(["peak_to_peak", "peak_velocity", "binned"])),
        "direction": pa.Column(str, Check.isin(DIRECTIONS)),
        "velocity_m_s": pa.Column("float64"),
        "force_N": pa.Column("float64"),
    },
    strict=False,
    name="harmonic",
)
