"""The contracts' own fast check (tables.passes) never passes a table that pandera's schema rejects,
passes the valid tables, and validate_table / failure_cases answer as pandera does."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pandera.pandas as pa
import pytest

from isokinetic.contracts import tables

SCHEMAS = {name: getattr(tables, name) for name in ("TIMESERIES", "CASES", "QUARANTINE", "WINDOWS", "REPEATABILITY",
                                                     "CHARACTERISTIC", "PLAN_CHECK", "MODELS", "HARMONIC")}
N_ROWS = 4


def _values(name: str, col: tables.Column) -> pd.Series:
    """N_ROWS values that meet the column's contract (distinct, increasing, >= 2, in its isin set)."""
    allowed = next((c.value for c in col.checks if c.name == "isin"), None)
    if allowed is not None:
        return pd.Series([allowed[k % len(allowed)] for k in range(N_ROWS)], dtype="object" if col.dtype == "str"
                         else col.dtype if col.dtype != "bool" else bool)
    k = np.arange(N_ROWS)
    offset = 100 if name == "row_stop" else 2
    if col.dtype == "str":
        return pd.Series([f"{name}{i}" for i in k], dtype="object")
    if col.dtype == "bool":
        return pd.Series(k % 2 == 0)
    if col.dtype == "Int64":
        return pd.Series(pd.array(k + offset, dtype="Int64"))
    return pd.Series(k + offset, dtype=col.dtype)


def valid_frame(schema: tables.Schema) -> pd.DataFrame:
    return pd.DataFrame({name: _values(name, col) for name, col in schema.columns.items()})


def _mutations(df: pd.DataFrame, schema: tables.Schema):
    """Frames that break (or may break) the contract one way each."""
    yield df.iloc[:0]
    yield df.assign(extra=1.0)
    for name, col in schema.columns.items():
        yield df.drop(columns=name)
        s = df[name]
        yield df.assign(**{name: s.astype("string")})
        yield df.assign(**{name: s.astype(object)})
        yield df.assign(**{name: pd.concat([s.iloc[:1], s.iloc[:-1]], ignore_index=True)})
        yield df.assign(**{name: s.iloc[::-1].to_numpy()})
        for bad in (np.nan, None, np.inf, -np.inf, -1, -1.5, 0, 0.0, "x", True):
            t = df.copy()
            t[name] = t[name].astype(object)
            t.loc[1, name] = bad
            yield t
            try:
                yield df.assign(**{name: t[name].astype(s.dtype)})
            except (TypeError, ValueError, OverflowError):
                pass
        if col.dtype in ("float64", "int64"):
            yield df.assign(**{name: s.astype("float64" if col.dtype == "int64" else "int64")})


def pandera_passes(df: pd.DataFrame, schema: tables.Schema) -> bool:
    try:
        tables.pandera_schema(schema).validate(df, lazy=True)
    except pa.errors.SchemaErrors:
        return False
    return True


@pytest.mark.parametrize("name", SCHEMAS)
def test_valid_tables_pass_both(name):
    schema = SCHEMAS[name]
    df = valid_frame(schema)
    assert tables.passes(df, schema)
    assert pandera_passes(df, schema)
    out = tables.validate_table(df, schema)
    assert out is not df
    pd.testing.assert_frame_equal(out, tables.pandera_schema(schema).validate(df, lazy=True))
    assert tables.failure_cases(df, schema) is None


@pytest.mark.slow
@pytest.mark.parametrize("name", SCHEMAS)
def test_fast_check_never_passes_what_pandera_rejects(name):
    schema = SCHEMAS[name]
    rejected = 0
    for df in _mutations(valid_frame(schema), schema):
        if tables.passes(df, schema):
            assert pandera_passes(df, schema), f"{name}: passes() accepted a table pandera rejects:\n{df}\n{df.dtypes}"
        else:
            rejected += 1
    assert rejected > 10


def test_failures_are_panderas_own():
    schema = tables.TIMESERIES
    df = valid_frame(schema)
    df.loc[2, "time_s"] = df.loc[1, "time_s"]
    df.loc[3, "force_N"] = np.inf
    with pytest.raises(pa.errors.SchemaErrors) as info:
        tables.pandera_schema(schema).validate(df, lazy=True)
    mine = tables.failure_cases(df, schema)
    pd.testing.assert_frame_equal(mine, info.value.failure_cases)
    assert set(mine["check"]) == {"time_increasing", "finite"}
    with pytest.raises(pa.errors.SchemaErrors):
        tables.validate_table(df, schema)


def test_empty_follows_the_contract():
    for schema in SCHEMAS.values():
        df = tables.empty(schema)
        assert list(df.columns) == [n for n, c in schema.columns.items() if c.required]
        assert tables.passes(df, schema) and pandera_passes(df, schema)
