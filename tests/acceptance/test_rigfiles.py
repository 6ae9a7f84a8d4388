"""The test instruments of ``tests/rigfiles.py`` write what they claim (checked by plain parsing here)."""

from __future__ import annotations

import csv

import numpy as np
import pytest

import rigfiles as rf


def runs(indices: np.ndarray) -> list[int]:
    """Lengths of the runs of consecutive indices."""
    breaks = np.flatnonzero(np.diff(indices) != 1)
    return np.diff(np.concatenate(([0], breaks + 1, [indices.size]))).tolist()


def test_dropout_rows_drop_the_fraction_in_singles_and_bursts():
    drop = rf.dropout_rows(20_000, fraction=0.01, seed=5)
    lengths = runs(drop)
    assert drop.size == 200 and np.all(np.diff(drop) > 0)
    assert 1 in lengths and any(5 <= n <= 40 for n in lengths)
    assert all(n == 1 or 5 <= n <= 40 for n in lengths)
    assert drop.min() >= 50 and drop.max() < 20_000 - 50


def test_dropout_rows_are_seeded():
    assert np.array_equal(rf.dropout_rows(5000, seed=1), rf.dropout_rows(5000, seed=1))
    assert not np.array_equal(rf.dropout_rows(5000, seed=1), rf.dropout_rows(5000, seed=2))


def test_drop_rows_keeps_every_other_line_as_it_was(tmp_path):
    src = rf.write_csv(tmp_path / "a.csv", {"t": [str(i) for i in range(1000)], "f": [f"{i}.5" for i in range(1000)]})
    drop = rf.drop_rows(src, tmp_path / "b.csv", fraction=0.02, seed=3)
    before = src.read_text(encoding="utf-8").splitlines()
    after = (tmp_path / "b.csv").read_text(encoding="utf-8").splitlines()
    assert after == [before[0]] + [line for i, line in enumerate(before[1:]) if i not in set(drop.tolist())]


@pytest.mark.slow
def test_crank_folder_volts_are_affine_maps_of_the_scaled_columns(tmp_path):
    runs = rf.write_crank_folder(tmp_path / "crank")
    assert len(runs) == 5
    with runs[0].path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    header, data = rows[0], np.array(rows[1:], dtype=float)
    assert header == ["Timestamp", "Force (V)", "Force (N)", "Displacement (V)", "Displacement (mm)",
                      "Temperature (V)", "Temperature (C)"]
    assert np.median(np.diff(data[:, 0])) == pytest.approx(1 / 300, rel=1e-3)
    for volts, scaled in ((1, 2), (3, 4), (5, 6)):
        gain, offset = np.polyfit(data[:, scaled], data[:, volts], 1)
        residual = data[:, volts] - (gain * data[:, scaled] + offset)
        # printed with 5 decimals in volts and 2 or 3 in the scaled unit: the rounding is all that is left
        assert np.abs(residual).max() < 2e-4 and abs(gain) < 0.5, header[volts]


def test_triangle_campaign_in_cp1252_writes_the_degree_sign_as_one_byte(tmp_path):
    rf.triangle_campaign(tmp_path / "c", temperature_header="oil [°C]", encoding="cp1252",
                         cases=(("T01", 2.0, 0.01),))
    header = (tmp_path / "c" / "T01.csv").read_bytes().split(b"\n")[0]
    assert header == b"time_s,disp_mm,force_N,oil [\xb0C]"
    assert "encoding: cp1252" in (tmp_path / "c" / "campaign.yaml").read_text(encoding="utf-8")
