"""What the campaign page says about temperature (format 1.1): the cases' temperatures and their use by the
models, and the diagnosis' viscosity deviation read as a temperature offset."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from isokinetic.physics.viscosity import ViscosityLaw
from isokinetic.report.campaign_report import temperature_summary
from isokinetic.report.diagnosis_section import viscosity_as_temperature
from isokinetic.report.numbers import fmt

LAW = ViscosityLaw("walther", ((40.0, 0.030), (100.0, 0.006)), 815.0)


def _cases(temps, source="channel"):
    return pd.DataFrame({"case": [f"T{i}" for i in range(len(temps))], "temperature_C": temps,
                         "temperature_source": source})


def test_summary_states_the_range_and_the_viscosities_the_models_take():
    text = temperature_summary(LAW, _cases([38.0, 52.0]))
    assert f"{fmt(38.0, 4)} to {fmt(52.0, 4)} &deg;C (from channel)" in text
    mu = 1e3 * LAW.viscosity_Pa_s([52.0, 38.0])
    assert f"{fmt(mu[0], 3)} to {fmt(mu[1], 3)} mPa s" in text


def test_summary_without_a_law_says_the_damper_viscosity_holds_for_every_case():
    text = temperature_summary(None, _cases([40.0], "campaign"))
    assert "gives no viscosity law" in text and "for every case" in text
    assert "No temperature is known" in temperature_summary(LAW, _cases([math.nan], ""))


def test_a_fitted_viscosity_reads_as_the_temperature_offset_the_law_gives():
    diag = {"params": {"viscosity_Pa_s": 0.033},
            "identifiability": {"parameters": {"viscosity_Pa_s": {"std_error": 0.0006}}}}
    text = viscosity_as_temperature(diag, LAW, 50.0, 0.030)
    dt = float(LAW.temperature_C(1.1 * LAW.viscosity_Pa_s(50.0))) - 50.0
    assert dt == pytest.approx(-2.8, abs=0.3)   # ln(1.1) at about 3.4 % per K near 50 C
    assert f"{fmt(abs(dt), 3)} K colder" in text and f"&Delta;T = {fmt(dt, 3)} K at {fmt(50.0, 4)} &deg;C" in text
    lo = float(LAW.temperature_C((1.1 + 1.96 * 0.02) * LAW.viscosity_Pa_s(50.0))) - 50.0
    assert f"95 % interval {fmt(lo, 3)} to" in text


def test_no_fitted_viscosity_no_note_and_no_law_a_hint():
    assert viscosity_as_temperature({"params": {"coulomb_force_N": 5.0}}, LAW, 50.0, 0.030) is None
    hint = viscosity_as_temperature({"params": {"viscosity_Pa_s": 0.033}}, None, 50.0, 0.030)
    assert f"{fmt(1.1, 3)} &times; the nominal" in hint and "damper.viscosity_law" in hint
