"""Stepped records become several cases: one per step of a sine sweep (written as an MTS 793 export) or of a
series of triangle ramps, and one per standstill; each slice leaves out transitions and settling cycles, and
the draft ingests cleanly and passes its own `--check`."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from isokinetic.__main__ import main
from isokinetic.contracts.manifest import load_manifest
from isokinetic.init_campaign.draft import write_draft
from isokinetic.init_campaign.steps import find_steps, is_stepped, resolution, rounded_inwards
from isokinetic.stages.ingest import ingest_campaign

from .records import Step, sine_record, stepped_record, write_table

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from rigfiles import write_mts793  # noqa: E402

SWEEP = [Step("standstill", duration_s=4.0), Step("sine", 0.5, 0.0127, 3), Step("sine", 1.0, 0.0127, 4),
         Step("sine", 2.0, 0.0127, 6), Step("sine", 5.0, 0.0127, 10), Step("sine", 5.0, 0.005, 10)]
RATE_HZ = 512.0


def test_bounds_are_rounded_inwards_to_a_hundredth_of_the_period_at_most():
    assert resolution(0.1) == 1e-3 and resolution(5.0) == 0.01 and resolution(100.0) == 0.1
    assert rounded_inwards(1.2341, 2.5679, 1e-3) == (1.235, 2.567)


def test_a_steady_record_is_not_stepped():
    rec = sine_record(2.0, 0.01, 12, 500.0)
    assert not is_stepped(find_steps(rec["time_s"], rec["displacement_m"]), rec["time_s"])


@pytest.fixture(scope="module")
def sweep(tmp_path_factory) -> tuple[Path, list[Step]]:
    """A stepped sine sweep (standstill, then steps of frequency and of amplitude, dwells between them) in an MTS
    793 export (in, lbf, Sec; blocks; CRLF) in a subfolder, the file's time axis starting at 100 s."""
    record, steps = stepped_record(SWEEP, RATE_HZ, t0_s=100.0)
    folder = tmp_path_factory.mktemp("raw") / "sweep"
    (folder / "run1").mkdir(parents=True)
    write_mts793(folder / "run1" / "sweep.txt", record["time_s"], record["displacement_m"], record["force_N"],
                 block_rows=1024)
    return folder, steps


def test_a_stepped_sweep_drafts_one_case_per_step_without_transitions(sweep, tmp_path):
    src, steps = sweep
    folder = tmp_path / "raw" / "sweep"
    (folder / "run1").mkdir(parents=True)
    (folder / "run1" / "sweep.txt").write_bytes((src / "run1" / "sweep.txt").read_bytes())
    path, _ = write_draft(folder)
    manifest = load_manifest(path)
    cases = manifest.cases
    assert manifest.csv.format == "mts793"
    assert [c.id for c in cases] == ["sweep-Z01", "sweep-S01", "sweep-S02", "sweep-S03", "sweep-S04", "sweep-S05"]
    assert {c.columns["displacement"].unit for c in cases} == {"in"} and {c.columns["force"].unit for c in cases} \
        == {"lbf"}
    for case, step in zip(cases, steps):
        assert case.file == "run1/sweep.txt" and case.plan.waveform == step.kind
        a, b = case.time_range_s
        if step.kind == "standstill":
            assert step.start_s <= a < b <= step.end_s and b - a >= 0.5 * step.duration_s
            continue
        period = 1.0 / step.frequency_Hz
        assert case.plan.frequency_Hz == pytest.approx(step.frequency_Hz, rel=1e-4)
        assert case.plan.amplitude_m == pytest.approx(step.amplitude_m, rel=2e-3)
        assert step.start_s + period - 1e-9 <= a and b <= step.end_s + 1e-9       # settling cycle, dwell left out
        assert (b - a) / period == pytest.approx(round((b - a) / period), abs=0.02) and b - a >= 2 * period - 0.01
    root = tmp_path / "out" / "sweep"
    ingest_campaign(folder, root)
    table = pd.read_parquet(root / "ingest" / "cases.parquet")
    assert (table["status"] == "ok").all()
    assert main(["init-campaign", "--check", str(folder)]) == 0


def test_triangle_ramps_at_several_speeds_become_triangle_cases_from_reversal_to_reversal(tmp_path):
    plan = [Step("triangle", 0.25, 0.02, 3), Step("triangle", 0.5, 0.02, 4), Step("triangle", 1.0, 0.02, 5)]
    record, steps = stepped_record(plan, 200.0, dwell_s=1.0)
    folder = tmp_path / "tri"
    write_table(folder / "ramps.csv", {"time_s": record["time_s"], "x_mm": record["displacement_m"] * 1e3,
                                       "F_N": record["force_N"]})
    path, _ = write_draft(folder)
    cases = load_manifest(path).cases
    assert [c.plan.waveform for c in cases] == ["triangle"] * 3
    for case, step in zip(cases, steps):
        assert case.plan.period_s == pytest.approx(1.0 / step.frequency_Hz, rel=1e-4)
        assert case.plan.amplitude_m == pytest.approx(step.amplitude_m, rel=5e-3)
        assert case.plan.phase_rad == pytest.approx(-math.pi / 2)              # starts at the lower reversal
        a, b = case.time_range_s
        assert step.start_s <= a and b <= step.end_s
        first = record["displacement_m"][np.searchsorted(record["time_s"], a)]
        within_a_sample = 4.0 * step.amplitude_m * step.frequency_Hz / 200.0
        assert first == pytest.approx(-step.amplitude_m, abs=within_a_sample)
    assert main(["init-campaign", "--check", str(folder)]) == 0


def test_a_slow_ramp_is_not_a_standstill():
    t = np.arange(0.0, 400.0, 0.1)
    y = 1e-4 * np.abs(((t / 200.0) % 2.0) - 1.0)                  # a triangle at 1 µm/s: flat in any 1 s window
    assert [s.kind for s in find_steps(t, y)] == []


def mts_style_sweep(plan, amplitude_m: float = 0.0127, rest_s: float = 1.0, rate_Hz: float = 1024.0):
    """An MTS-style stepped sweep: at rest at +Y, each step of ``plan`` (frequency, cycles) a sine from that
    reversal (phase π/2) for its cycles back to it, ``rest_s`` at rest after each; 2 µm seeded noise. Returns
    (t, y, [(start_s, end_s, frequency_Hz)])."""
    total = rest_s + sum(k / f + rest_s for f, k in plan)
    t = np.arange(int(total * rate_Hz)) / rate_Hz
    y, spans, start = np.full(t.size, amplitude_m), [], rest_s
    for f, k in plan:
        inside = (t >= start) & (t <= start + k / f)
        y[inside] = amplitude_m * np.sin(2.0 * math.pi * f * (t[inside] - start) + 0.5 * math.pi)
        spans.append((start, start + k / f, f))
        start += k / f + rest_s
    return t, y + 2e-6 * np.random.default_rng(3).standard_normal(t.size), spans


def test_a_sweep_of_two_or_three_cycles_a_step_gets_one_step_each_with_both_velocity_peaks_inside():
    """Each step, 2 or 3 cycles from a reversal between rests, is found with one settling cycle at most left out
    and at least one whole cycle kept; its slice (on to the rest) holds a peak of each velocity sign with the
    fit span of the peak method (T/20) either side."""
    plan = [(0.2, 2), (0.5, 3), (1.0, 2), (2.0, 3), (5.0, 3), (10.0, 2)]
    t, y, spans = mts_style_sweep(plan)
    found = [s for s in find_steps(t, y) if s.kind == "cycles"]
    assert len(found) == len(plan)
    for step, (start, end, f) in zip(found, spans):
        period = 1.0 / f
        assert step.period_s == pytest.approx(period, rel=0.01)
        stop = step.tail_s if math.isfinite(step.tail_s) else step.end_s
        assert start + 0.5 * period <= step.start_s and stop <= end + 0.01 * period
        assert step.cycles >= 1 and step.end_s - step.start_s >= step.cycles * period * 0.99
        # this sine's velocity peaks: + at phase 0 (t = start + (j + 3/4) T), - at phase π (start + (j + 1/4) T)
        for quarter in (0.25, 0.75):
            peaks = start + (np.arange(-1, 4) + quarter) * period
            assert any(step.start_s + 0.05 * period <= p <= stop - 0.05 * period for p in peaks), (f, quarter)
