"""Stage exports: tables as CSV for spreadsheets, a units row under the names, floats that read back exactly."""

from __future__ import annotations

import io

import numpy as np
import pandas as pd
import pytest

from isokinetic.stages.exports import ROW_UNIT, csv_text, unit_of, units_row, write_exports


def read_back(text: str) -> pd.DataFrame:
    """A CSV export read as a spreadsheet user's script would: the units row skipped, floats parsed exactly."""
    return pd.read_csv(io.StringIO(text), skiprows=[1], float_precision="round_trip")


def test_units_row_is_derived_from_the_column_names():
    names = ["force_N", "velocity_m_s", "window_start_s", "amplitude_m", "sample_rate_Hz", "piston_area_m2",
             "chamber_volume_1_m3", "leakage_m3_s_Pa", "pressure_Pa", "viscosity_Pa_s", "temperature_C", "phase_rad"]
    units = ["N", "m/s", "s", "m", "Hz", "m^2", "m^3", "m^3/(s Pa)", "Pa", "Pa s", "degC", "rad"]
    assert units_row(names) == units
    table = pd.DataFrame({n: [1.0] for n in names})
    assert csv_text(table).split("\n")[1] == ",".join(units)


def test_a_column_without_a_unit_gets_an_empty_unit():
    names = ["case", "n_samples", "repeatability_flagged", "rel_diff", "confidence", "G1"]
    assert [unit_of(n) for n in names] == [""] * len(names)
    table = pd.DataFrame({n: [1] for n in names})
    assert csv_text(table).split("\n")[1] == "," * (len(names) - 1)


def test_columns_in_their_rows_unit_say_so_and_need_a_unit_column():
    models = pd.DataFrame({"parameter": ["F_C", "D_L"], "estimate": [78.0, 2.27e6], "ci_low": [74.0, 2.2e6],
                           "unit": ["N", "N s/m"], "rms_residual_N": [186.5, 186.5]})
    assert csv_text(models, ["estimate", "ci_low"]).split("\n")[1] == f",{ROW_UNIT},{ROW_UNIT},,N"
    with pytest.raises(ValueError, match="unit"):
        csv_text(models.drop(columns="unit"), ["estimate"])


def test_floats_read_back_bit_identical():
    rng = np.random.default_rng(12)
    values = np.concatenate([rng.normal(size=2000) * 10.0 ** rng.integers(-300, 300, 2000),
                             [0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, 0.1, 1 / 3,
                              np.nan, np.inf, -np.inf]])
    table = pd.DataFrame({"force_N": values, "velocity_m_s": values[::-1].copy()})
    back = read_back(csv_text(table))
    for col in table.columns:
        assert np.array_equal(back[col].to_numpy().view(np.uint64), table[col].to_numpy().view(np.uint64)), col


def test_rows_are_plain_spreadsheet_csv():
    table = pd.DataFrame({"case": ["T01", 'a "b", c'], "flagged": [True, False], "force_N": [1.5, np.nan],
                          "n_samples": [501, 3]})
    text = csv_text(table)
    assert text == ('case,flagged,force_N,n_samples\n,,N,\nT01,true,1.5,501\n"a ""b"", c",false,,3\n')
    pd.testing.assert_frame_equal(read_back(text), table)


def test_write_exports_writes_both_tables_of_a_campaign(tmp_path):
    (tmp_path / "models").mkdir()
    char = pd.DataFrame({"case": ["T01"], "velocity_m_s": [1e-3], "force_N": [-7192.080838123]})
    models = pd.DataFrame({"parameter": ["F_C"], "estimate": [77.96], "ci_low": [74.3], "ci_high": [81.6],
                           "std_error": [1.8], "unit": ["N"]})
    char.to_parquet(tmp_path / "characteristic.parquet")
    models.to_parquet(tmp_path / "models" / "models.parquet")
    written = write_exports(tmp_path)
    assert written == [tmp_path / "characteristic.csv", tmp_path / "models" / "models.csv"]
    pd.testing.assert_frame_equal(read_back(written[0].read_text(encoding="utf-8")), char)
    assert written[1].read_text(encoding="utf-8").split("\n")[1] == "," + ",".join([ROW_UNIT] * 4) + ","
