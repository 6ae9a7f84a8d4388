"""The mixed campaign of the reference rig (slow triangles plus a sine matrix, friction and entrained air)."""

import pytest
import yaml

from isokinetic.blind import mixed as bm
from isokinetic.blind.mixed import write_mixed_campaign
from isokinetic.physics.damper import TABLE_1


def test_mixed_campaign_has_slow_triangles_and_a_sine_matrix_with_friction_and_air(tmp_path):
    truth = write_mixed_campaign(tmp_path / "mixed-friction-air", seed=4)
    manifest = yaml.safe_load((tmp_path / "mixed-friction-air" / "campaign.yaml").read_text(encoding="utf-8"))
    waves = [c["waveform"] for c in manifest["cases"]]
    assert waves.count("triangle") == len(bm.MIXED_TRIANGLE_SPEEDS_MM_S)
    assert waves.count("sine") == len(bm.MIXED_SINE_FREQUENCIES_HZ) * len(bm.MIXED_SINE_AMPLITUDES_MM)
    assert truth["truth"] == ["friction", "air"] and manifest["damper"]["charge_pressure_Pa"] == 5.0e6
    assert truth["params"]["coulomb_force_N"] == pytest.approx(3.0 * truth["detection_level"]["friction"])
    # the air sits at the triangles' detection level; the sines see it far beyond their noise
    assert truth["air_rms_z_triangles"] == pytest.approx(3.0, rel=1e-3)
    assert truth["air_rms_z_sines"] > 30.0
    assert TABLE_1.to_dict() == {k: manifest["damper"][k] for k in TABLE_1.to_dict()}
