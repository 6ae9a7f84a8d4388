"""The diagnosis on reference-rig campaigns whose damper has an effect outside the catalogue that a catalogue
effect absorbs on average (issue 35): the verdict must not be `explained`, and `where` must name the axis the
effect lies on. The rig (isokinetic.reference.rig) shares no code with the diagnosis' model."""

import numpy as np
import pytest

from isokinetic.blind.hidden import hidden_fields
from isokinetic.physics.damper import TABLE_1
from isokinetic.reference import rig as rr
from stages.test_diagnosis_rig import diagnose_rig

#: Triangle cases (speed [mm/s], period [s]): strokes of 0.2-6 mm, so that a groove of ±1 mm at mid-stroke is
#: open through some windows and through part of others.
STROKES = [(0.01, 80.0), (0.04, 80.0), (0.1, 80.0), (0.15, 20.0), (0.3, 20.0), (0.5, 20.0), (0.8, 20.0), (1.2, 20.0)]


def shuffled_campaign(seed: int = 7) -> list[tuple[float, float]]:
    """16 cases, five speeds at two periods in a shuffled run order and six of them repeated at the end, as a
    campaign that interleaves its speeds."""
    plan = [(v, t) for v in (0.01, 0.04, 0.15, 0.5, 1.2) for t in (20.0, 80.0)]
    plan = [plan[i] for i in np.random.default_rng(seed).permutation(len(plan))]
    return plan + plan[:6]


def test_a_bypass_groove_at_mid_stroke_is_not_explained_and_is_located_in_position(tmp_path):
    # a groove open within 1 mm of mid-stroke, 30 % of the orifice's area: on the windows' means it looks like a
    # larger discharge coefficient; inside the windows the force drops as the piston passes it
    effects = rr.TrueEffects(**hidden_fields("bypass", 0.3, TABLE_1))
    result = diagnose_rig(tmp_path, "groove", effects, plan=STROKES)
    assert result["explained"] is False
    assert "position" in result["structure"]["axes"]
    groove = [e for e in result["where"] if e.get("axis") == "position" and e["z"] < 0]
    assert groove, result["where"]
    for run in groove:   # the damper weaker there than the verdict, inside the groove (1 mm and its taper)
        assert -1.5e-3 < run["range"][0] <= run["range"][1] < 1.5e-3 and run["mean_rel"] < 0
    # located out to its edges on both sides (the parts nearest mid-stroke, of strokes that lie wholly inside the
    # groove, carry no contrast within their windows and may fall below the runs' |z|)
    assert min(r["range"][0] for r in groove) < -0.8e-3 and max(r["range"][1] for r in groove) > 0.8e-3


def test_orifice_wear_over_the_campaign_is_not_explained_and_is_located_in_time(tmp_path):
    # the orifice's area grows 10 % over the campaign, in shuffled run order: no catalogue effect reproduces a
    # force that falls with the campaign's time whatever the speed
    effects = rr.TrueEffects(**hidden_fields("wear", 0.1, TABLE_1))
    result = diagnose_rig(tmp_path, "wear", effects, plan=shuffled_campaign())
    assert result["explained"] is False
    assert "time" in result["structure"]["axes"]
    test = next(t for t in result["structure"]["tests"] if t["axis"] == "time" and "test" not in t)
    assert test["trend_rel_t"] < 0    # weaker and weaker as the campaign goes on
    drift = next(t for t in result["structure"]["tests"] if t.get("parameter") == "orifice_area")
    assert drift["significant"] and drift["change_rel"] > 0   # the orifice passes more and more
    # at its size: 10 % over the campaign, a little less between the first and the last case's middles
    assert 0.07 < drift["change_rel"] < 0.105


def test_an_unlogged_warm_up_is_not_explained_and_is_a_viscosity_falling_in_time(tmp_path):
    # the oil 8 K warmer at the campaign's end than at its start, no temperature channel
    effects = rr.TrueEffects(**hidden_fields("warmup", 8.0, TABLE_1))
    result = diagnose_rig(tmp_path, "warm", effects, plan=shuffled_campaign(5))
    assert result["explained"] is False
    drift = next(t for t in result["structure"]["tests"] if t.get("parameter") == "viscosity_Pa_s")
    assert drift["significant"] and drift["change_rel"] < 0
    assert any(e.get("parameter") == "viscosity_Pa_s" for e in result["where"])


@pytest.mark.parametrize("seed", [3, 11])
def test_the_same_campaigns_without_the_effects_show_no_structure(tmp_path, seed):
    for name, plan in (("strokes", STROKES), ("shuffled", shuffled_campaign())):
        result = diagnose_rig(tmp_path, f"{name}-{seed}", seed=seed, plan=plan)
        assert result["structure"]["axes"] == [], (name, result["structure"]["tests"])
