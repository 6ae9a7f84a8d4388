"""Column roles and units: from names, and from magnitudes when the names do not say."""

from __future__ import annotations

import numpy as np
import pytest

from isokinetic.init_campaign import channels as ch
from isokinetic.physics.plan import triangle_displacement


@pytest.mark.parametrize("name, role, unit", [
    ("time_s", "time", "s"), ("t[ms]", "time", "ms"), ("Time (s)", "time", "s"), ("Zeit [s]", "time", "s"),
    ("disp_mm", "displacement", "mm"), ("x_um", "displacement", "um"), ("position (mm)", "displacement", "mm"),
    ("pos / m", "displacement", "m"), ("force_kN", "force", "kN"), ("F[N]", "force", "N"),
    ("load in kN", "force", "kN"),
    ("cmd_mm", "command", "mm"), ("x_cmd_um", "command", "um"), ("oil_C", "temperature", "C"),
    ("T_C", "temperature", "C"), ("t_oil", "temperature", None), ("time", "time", None), ("x", "displacement", None),
    ("ch1", None, None), ("mm", "displacement", "mm"),
])
def test_role_and_unit_from_the_name(name, role, unit):
    guess = ch.guess_from_name(name)
    assert (guess.role, guess.unit) == (role, unit)


def test_a_unit_word_that_does_not_fit_the_role_is_left_to_the_magnitudes():
    guess = ch.guess_from_name("force_k")
    assert (guess.role, guess.unit) == ("force", None) and "does not fit" in guess.how


@pytest.mark.parametrize("unit, factor", [("s", 1.0), ("ms", 1e3)])
@pytest.mark.parametrize("rate_Hz, samples", [(100.0, 4000), (1000.0, 5714), (100.0, 48000)])
def test_time_unit_from_step_and_length(unit, factor, rate_Hz, samples):
    t = np.arange(samples) / rate_Hz * factor
    choice = ch.choose_unit([ch.unit_scores("time", t, None)])
    assert (choice.unit, choice.sure) == (unit, "sure")


def test_a_time_axis_both_units_fit_is_only_likely():
    t = np.arange(9600) / 20.0          # 20 Hz for 480 s, or 20 kHz for 0.48 s
    choice = ch.choose_unit([ch.unit_scores("time", t, None)])
    assert (choice.unit, choice.sure) == ("s", "likely")


@pytest.mark.parametrize("unit", ["m", "mm", "um"])
@pytest.mark.parametrize("amplitude_m, period_s", [(0.3e-3, 240.0), (1.22e-3, 20.0), (7.5e-3, 20.0)])
def test_displacement_unit_from_amplitude_and_speed(unit, amplitude_m, period_s):
    t = np.arange(int(2 * period_s * 100)) / 100.0
    y = triangle_displacement(t, amplitude_m, period_s) / ch.FACTORS["length"][unit]
    choice = ch.choose_unit([ch.unit_scores("displacement", y, t)])
    assert choice.unit == unit and choice.sure in ("sure", "likely")


@pytest.mark.parametrize("unit", ["N", "kN"])
@pytest.mark.parametrize("peak_N", [60.0, 800.0, 4000.0])
def test_force_unit_from_its_range(unit, peak_N):
    f = peak_N * np.sin(np.linspace(0, 20, 2000)) / ch.FACTORS["force"][unit]
    choice = ch.choose_unit([ch.unit_scores("force", f, None)])
    assert choice.unit == unit
    assert choice.sure == ("likely" if peak_N == 4000.0 and unit == "kN" else "sure")   # 4 kN, or 4 N?


def test_campaign_scores_settle_an_ambiguous_file():
    t = np.arange(4000) / 100.0
    small = triangle_displacement(t, 0.05e-3, 20.0) / 1e-6          # 50 um: alone, um or mm are both possible
    large = triangle_displacement(t, 5e-3, 20.0) / 1e-6             # 5000 um: mm would be 5 m
    alone = ch.choose_unit([ch.unit_scores("displacement", small, t)])
    together = ch.choose_unit([ch.unit_scores("displacement", small, t), ch.unit_scores("displacement", large, t)])
    assert alone.sure != "sure"
    assert (together.unit, together.sure) == ("um", "sure")


def test_force_and_displacement_are_told_apart_by_velocity():
    rng = np.random.default_rng(7)
    t = np.arange(4000) / 100.0
    y = triangle_displacement(t, 1e-3, 20.0)
    force = np.sign(np.gradient(y, t)) * 300.0 + rng.normal(0, 5, t.size)
    d, f, r = ch.pair_by_velocity(t, {"a": force, "b": y}, None, None)
    assert (d, f) == ("b", "a") and r > 0.9


def test_a_command_is_smoother_than_its_measured_displacement():
    rng = np.random.default_rng(8)
    t = np.arange(4000) / 100.0
    command = triangle_displacement(t, 1e-3, 20.0)
    assert ch.roughness(command) < ch.roughness(command + rng.normal(0, 1e-6, t.size))


def test_a_damper_force_follows_the_velocity_in_every_cycle():
    rng = np.random.default_rng(9)
    t = np.arange(5000) / 500.0
    y = 0.01 * np.sin(2 * np.pi * 1.0 * t)
    v = 0.01 * 2 * np.pi * np.cos(2 * np.pi * 1.0 * t)
    force = 2000.0 * v + rng.normal(0, 1.0, t.size)
    follows = ch.force_follows_velocity(t, y, force)
    assert follows.correlation > 0.99 and follows.opposed_cycles == 0 and not follows.problem
    assert follows.damping_N_s_m == pytest.approx(2000.0, rel=0.01) and ch.plausible_damping(follows.damping_N_s_m)
    opposed = ch.force_follows_velocity(t, y, -force)
    assert opposed.opposed_everywhere and opposed.cycles == opposed.opposed_cycles >= 8
    half = np.where(t < 5.0, force, -force)                 # the sign flips half way: no convention fits
    mixed = ch.force_follows_velocity(t, y, half)
    assert not mixed.opposed_everywhere and mixed.problem
    assert "does not follow the velocity" in ch.force_follows_velocity(t, y, rng.normal(0, 1.0, t.size)).problem


@pytest.mark.parametrize("text, expected", [("in", ("length", "in")), ("lbf", ("force", "lbf")),
                                            ("Sec", ("time", "s")), ("°C", ("temperature", "C")),
                                            ("F", ("temperature", "F")), ("kN", ("force", "kN")), ("V", None),
                                            ("", None)])
def test_a_units_row_cell_gives_dimension_and_unit(text, expected):
    assert ch.unit_from_units_row(text) == expected
