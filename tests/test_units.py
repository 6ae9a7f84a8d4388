"""units.py: units as rigs and manifests write them, read through pint; factors checked against their
definitions (NIST SP 811: 1 lbf = 4.4482216152605 N, 1 in = 0.0254 m, 1 kip = 1000 lbf)."""

from __future__ import annotations

import numpy as np
import pytest

from fresh_imports import modules_loaded
from isokinetic.units import Unit, UnitError, nearest_units, parse_unit, unit_in_name

LBF_N = 4.4482216152605


@pytest.mark.parametrize("text, symbol, dimension, scale", [
    ("kip", "kip", "force", 1000 * LBF_N), ("cm", "cm", "length", 0.01), ("daN", "daN", "force", 10.0),
    ("ozf", "ozf", "force", LBF_N / 16), ("ms", "ms", "time", 1e-3), ("in", "in", "length", 0.0254),
    ("inch", "in", "length", 0.0254), ("mm/s", "mm/s", "velocity", 1e-3), ("kgf", "kgf", "force", 9.80665),
    ("lbf", "lbf", "force", LBF_N), ("kN", "kN", "force", 1e3), ("V", "V", "voltage", 1.0),
])
def test_a_unit_pint_knows_converts_to_si_by_its_definition(text, symbol, dimension, scale):
    unit = parse_unit(text)
    assert (unit.symbol, unit.dimension) == (symbol, dimension)
    assert unit.scale == pytest.approx(scale, rel=1e-12) and unit.offset == 0.0


@pytest.mark.parametrize("text, symbol", [
    ("Sec", "s"), ("SEC", "s"), ("lbs", "lbf"), ("lb", "lbf"), ("[mm]", "mm"), ("(N)", "N"), ("µm", "um"),
    ("μm", "um"), ("um", "um"), ("KN", "kN"), ("LBF", "lbf"), ("Kip", "kip"), ("ips", "in/s"),
])
def test_rig_spellings_read_as_the_unit_they_mean(text, symbol):
    assert parse_unit(text).symbol == symbol


@pytest.mark.parametrize("text", ["degC", "°C", "ºC", "C", "deg C", "Celsius"])
def test_celsius_spellings_are_a_temperature_kept_in_celsius(text):
    unit = parse_unit(text)
    assert (unit.symbol, unit.dimension, unit.scale, unit.offset) == ("degC", "temperature", 1.0, 0.0)


def test_fahrenheit_and_kelvin_go_to_celsius():
    assert parse_unit("F").to_si(np.array([32.0, 212.0])) == pytest.approx([0.0, 100.0])
    assert parse_unit("K").to_si(273.15) == pytest.approx(0.0)


def test_to_si_scales_an_array_and_a_scalar():
    assert np.allclose(parse_unit("kip").to_si(np.array([1.0, -2.0])), [1000 * LBF_N, -2000 * LBF_N])
    assert isinstance(parse_unit("mm").to_si(3), float)


def test_an_unknown_unit_is_refused_with_the_nearest_known_ones():
    with pytest.raises(UnitError, match=r"unknown unit 'kp'; nearest known force units: kip"):
        parse_unit("kp", "force")


def test_a_unit_of_another_dimension_is_refused_naming_both():
    with pytest.raises(UnitError, match="'V' is a voltage unit .*not a force unit"):
        parse_unit("V", "force")


def test_a_unit_error_is_a_value_error():
    assert issubclass(UnitError, ValueError)


def test_an_empty_unit_is_refused():
    with pytest.raises(UnitError, match="empty unit"):
        parse_unit(" [ ] ")


def test_the_dimension_asked_for_picks_among_readings():
    assert parse_unit("C", "temperature").dimension == "temperature"
    assert parse_unit("Sec", "time").scale == 1.0


def test_nearest_units_keep_to_the_dimension():
    near = nearest_units("kNn", "force")
    assert near and all(parse_unit(n).dimension == "force" for n in near)


@pytest.mark.parametrize("header, expected", [
    ("friction force (kip)", ("friction force", "kip")), ("Disp [mm]", ("Disp", "mm")), ("F(N)", ("F", "N")),
    ("force_kN", ("force", "kN")), ("time_s", ("time", "s")), ("Temp_C", ("Temp", "C")),
    ("Time (Sec)", ("Time", "Sec")), ("Velocity (mm/s)", ("Velocity", "mm/s")), ("x (kp)", ("x", "kp")),
])
def test_unit_in_name_splits_the_unit_off_a_header(header, expected):
    assert unit_in_name(header) == expected


@pytest.mark.parametrize("header", ["channel_A", "stroke_d", "force_1", "Force (load cell 2)", "Position", "Y"])
def test_unit_in_name_claims_no_unit_that_is_a_name(header):
    assert unit_in_name(header) == (header, None)


def test_a_unit_is_a_frozen_value():
    with pytest.raises(AttributeError):
        parse_unit("mm").scale = 1.0      # type: ignore[misc]
    assert Unit("x", "mm", "length", 1e-3) == Unit("x", "mm", "length", 1e-3, 0.0)


def test_importing_units_loads_no_pint():
    assert "pint" not in modules_loaded("import isokinetic.units", "pint")
