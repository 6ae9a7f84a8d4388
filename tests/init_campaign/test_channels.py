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
    ("cmd_mm", "command", "mm"), ("x_cmd_um", "command", "um"), ("oil_C", "temperature", "degC"),
    ("T_C", "temperature", "degC"), ("t_oil", "temperature", None), ("time", "time", None), ("x", "displacement", None),
    ("ch1", None, None), ("mm", "displacement", "mm"),
])
def test_role_and_unit_from_the_name(name, role, unit):
    guess = ch.guess_from_name(name)
    assert (guess.role, guess.unit) == (role, unit)


def test_a_unit_word_that_does_not_fit_the_role_is_left_to_the_magnitudes():
    guess = ch.guess_from_name("force_ms")
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
    y = triangle_displacement(t, amplitude_m, period_s) / ch.factor(unit)
    choice = ch.choose_unit([ch.unit_scores("displacement", y, t)])
    assert choice.unit == unit and choice.sure in ("sure", "likely")


@pytest.mark.parametrize("unit", ["N", "kN"])
@pytest.mark.parametrize("peak_N", [60.0, 800.0, 4000.0])
def test_force_unit_from_its_range(unit, peak_N):
    f = peak_N * np.sin(np.linspace(0, 20, 2000)) / ch.factor(unit)
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
                                            ("Sec", ("time", "s")), ("°C", ("temperature", "degC")),
                                            ("F", ("temperature", "degF")), ("kN", ("force", "kN")),
                                            ("kip", ("force", "kip")), ("[cm]", ("length", "cm")),
                                            ("V", ("voltage", "V")), ("blorps", None), ("", None)])
def test_a_units_row_cell_gives_dimension_and_unit(text, expected):
    assert ch.unit_from_units_row(text) == expected


def mr_like_record(seed: int = 4) -> dict[str, np.ndarray]:
    """A ramped 5 Hz sine of an MR damper at 200 Hz as a preprocessor writes it: t [s], x [mm], v [mm/s] by backward
    differences of x, and a force [N] with the hysteresis of a Bingham-like damper (a loop: it leads the velocity)."""
    rng = np.random.default_rng(seed)
    t = np.arange(450) * 0.005
    envelope = np.clip(np.minimum(t / 0.4, (t[-1] - t) / 0.4), 0.0, 1.0)
    x = 2.0 * envelope * np.sin(2 * np.pi * 5.0 * t) + 0.002 * rng.standard_normal(t.size)
    v = np.r_[0.0, np.diff(x) / 0.005]
    lead = np.r_[v[3:], v[-3:]]                   # the force's loop: it follows the velocity 15 ms ahead
    force = 0.8 * v + 80.0 * np.tanh(lead / 10.0) + 2.0 * rng.standard_normal(t.size)
    return {"t": t, "x": x, "v": v, "F": force}


def test_a_column_equal_to_the_displacements_derivative_is_a_velocity_and_the_force_is_not():
    r = mr_like_record()
    velocity_fit = ch.derivative_fit(r["t"], r["x"], r["v"])
    assert velocity_fit.is_velocity and velocity_fit.unit_ratio == 1.0 and velocity_fit.quotient == "backward"
    assert not ch.derivative_fit(r["t"], r["x"], r["F"]).is_velocity
    found = ch.velocity_columns(r["t"], {"x": r["x"], "v": r["v"], "F": r["F"]})
    assert set(found) == {"v"} and found["v"][0] == "x"


def test_a_velocity_in_other_units_is_found_by_its_unit_ratio():
    r = mr_like_record()
    fit = ch.derivative_fit(r["t"], r["x"] / 25.4, r["v"] * 1e-3)        # x in inches, v in m/s
    assert fit.is_velocity and fit.unit_ratio == pytest.approx(0.0254)


def test_a_switching_control_voltage_has_levels_and_a_moving_channel_has_none():
    rng = np.random.default_rng(12)
    voltage = np.repeat(rng.choice([0.0, 1.0, 2.0, 2.5], 60), 80) + 0.01 * rng.standard_normal(4800)
    t = np.arange(4800) / 400.0
    assert ch.switched_levels(voltage) == 4
    assert ch.switched_levels(np.sin(2 * np.pi * t)) == 0
    assert ch.switched_levels(rng.standard_normal(4800)) == 0
    assert ch.switched_levels(np.round(0.002 * rng.standard_normal(4800), 3)) == 0     # a quantised standstill


@pytest.mark.parametrize("name, role, unit", [("friction force (kip)", "force", "kip"),
                                              ("disp [cm]", "displacement", "cm"), ("Load (daN)", "force", "daN"),
                                              ("stroke_in", "displacement", "in")])
def test_units_in_headers_are_read_by_the_units_library(name, role, unit):
    guess = ch.guess_from_name(name)
    assert (guess.role, guess.unit) == (role, unit)
    assert ch.factor("kip") == pytest.approx(4448.2216, rel=1e-6) and ch.factor("cm") == pytest.approx(0.01)


def test_a_header_in_a_unit_of_velocity_is_never_the_force():
    assert ch.guess_from_name("v [mm/s]").role == "velocity"
