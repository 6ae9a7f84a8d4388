"""Blind scenarios built to be confounded (issue 37): what the diagnosis should say it cannot tell apart.

Each kind (:data:`KINDS`) is one record: the catalogue truth, the rig terms set over the drawn nuisances, the
plan's speed range, whether the export keeps its command channel, and the ``confounded`` group the diagnosis is
expected to list (:attr:`ConfoundedKind.expected`):

gain_discharge
    A load-cell gain error of 1.5 % beside a discharge coefficient: a gain scales the turbulent and laminar parts
    alike, as C_D and viscosity together do (``force_gain`` + ``discharge`` [+ ``viscosity``]).
lag_air
    A second-order anti-alias low-pass at 3 Hz on the force channel (75 ms group delay) beside entrained air:
    compressibility lags the force after a reversal as a low-pass does (``air`` + ``force_lag``).
scale_no_command
    An LVDT reading 1.2 % long beside a discharge coefficient, exported without its command channel: inside the
    model a displacement scale k is a load-cell gain 1/k plus C_D·√k (``displacement_scale`` + ``force_gain`` +
    ``discharge``).
leakage_turbulent
    Leakage beside a discharge coefficient on a plan of turbulent speeds only (0.3-1.5 mm/s, where the orifice's
    quadratic term dominates): a laminar bypass flow and a larger C_D both lower the force (``leakage`` +
    ``discharge``).

A kind's scenario is drawn as a suite's scenario is (:func:`isokinetic.blind.generate.make_scenario`: the damper,
plan, nuisances, sensor chain and magnitudes in detection levels) from a stream of its own,
``SeedSequence([seed, CONFOUNDED_STREAM, k])`` for the k-th kind, so the suite's scenarios (streams ``[seed, k]``)
are the same with or without them; the kind's rig terms then replace the drawn ones (the detection levels are
those of the drawn rig: the gain, the low-pass and the LVDT scale change the noise of a mean very little). The
truth record is the suite's, plus ``confounding``: the kind, its expected group and whether the export has a
command channel.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from isokinetic.blind.generate import (
    HIGH_END_MM_S,
    LOW_END_MM_S,
    N_VELOCITIES,
    Scenario,
    export_scenario,
    make_scenario,
)
from isokinetic.blind.next_tests import drop_csv_column, read_manifest, write_manifest
from isokinetic.contracts.settings import DEFAULTS
from isokinetic.io import write_json
from isokinetic.measurement.windows import WindowSpec

#: The spawn key's middle entry of the kinds' streams (apart from the suite's ``[seed, k]``).
CONFOUNDED_STREAM = 0xC0F
#: Scenario names: this prefix and the kind's name with '-' for '_'.
NAME_PREFIX = "blind-c-"


@dataclass(frozen=True)
class ConfoundedKind:
    """One kind of scenario built to be confounded (module doc)."""

    name: str
    truth: tuple[str, ...]
    expected: tuple[str, ...]                       # the confounded group expected (its members)
    rig: Mapping[str, float] = field(default_factory=dict)     # RigImperfections fields over the drawn ones
    multiples: Mapping[str, float] = field(default_factory=dict)   # fixed detection multiples (else drawn)
    command_channel: bool = True
    low_end_mm_s: tuple[float, float] = LOW_END_MM_S
    high_end_mm_s: tuple[float, float] = HIGH_END_MM_S

    @property
    def scenario_name(self) -> str:
        return NAME_PREFIX + self.name.replace("_", "-")


KINDS = (
    ConfoundedKind("gain_discharge", ("discharge",), ("force_gain", "discharge"), {"force_gain": 1.015}),
    ConfoundedKind("lag_air", ("air",), ("air", "force_lag"), {"force_filter_Hz": 2.0, "force_filter_order": 2},
                   {"air": 1.0}),
    ConfoundedKind("scale_no_command", ("discharge",), ("displacement_scale", "force_gain", "discharge"),
                   {"displacement_gain": 1.012}, command_channel=False),
    ConfoundedKind("leakage_turbulent", ("leakage", "discharge"), ("leakage", "discharge"),
                   low_end_mm_s=(0.3, 0.4), high_end_mm_s=(1.2, 1.5)),
)
BY_NAME = {k.name: k for k in KINDS}


def make_confounded(kind: ConfoundedKind, seed: int, index: int,
                    spec: WindowSpec = DEFAULTS.window) -> Scenario:
    """The scenario of ``kind``, the ``index``-th of the kinds, for the suite's ``seed`` (module doc)."""
    drawn = make_scenario(kind.scenario_name, kind.truth,
                          np.random.SeedSequence([int(seed), CONFOUNDED_STREAM, int(index)]), kind.multiples, spec,
                          n_velocities=N_VELOCITIES, low_end_mm_s=kind.low_end_mm_s,
                          high_end_mm_s=kind.high_end_mm_s)
    return dataclasses.replace(drawn, rig=dataclasses.replace(drawn.rig, **kind.rig))


def generate_confounded(seed: int, names: Sequence[str] | None = None,
                        spec: WindowSpec = DEFAULTS.window) -> list[tuple[ConfoundedKind, Scenario]]:
    """(kind, scenario) of every kind of KINDS (or those named), in KINDS order."""
    unknown = set(names or ()) - set(BY_NAME)
    if unknown:
        raise ValueError(f"unknown confounded kinds {sorted(unknown)}; known: {sorted(BY_NAME)}")
    return [(k, make_confounded(k, seed, i, spec)) for i, k in enumerate(KINDS) if names is None or k.name in names]


def truth_record(kind: ConfoundedKind, scenario: Scenario) -> dict:
    """The suite's truth record of the scenario, plus its ``confounding`` (module doc)."""
    return {**scenario.truth_record(), "confounding": {"kind": kind.name, "expected": list(kind.expected),
                                                        "command_channel": kind.command_channel}}


def drop_command_channel(folder: str | os.PathLike) -> None:
    """Remove the command channel from a raw campaign the reference rig wrote: its column in every case file and
    its entry in the manifest's columns."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    name = manifest["columns"].pop("command")["name"]
    for entry in manifest["cases"]:
        path = folder / entry["file"]
        path.write_text(drop_csv_column(path.read_text(encoding="utf-8"), name), encoding="utf-8", newline="\n")
    write_manifest(folder, manifest)


def export_confounded(kind: ConfoundedKind, scenario: Scenario, raw_root: str | os.PathLike,
                      truth_root: str | os.PathLike) -> Path:
    """The raw campaign ``raw_root/<name>/`` as the suite exports its scenarios
    (:func:`isokinetic.blind.generate.export_scenario`), without its command channel where the kind says so, and
    the truth ``truth_root/<name>.json`` (:func:`truth_record`)."""
    out = export_scenario(scenario, raw_root, truth_root)
    if not kind.command_channel:
        drop_command_channel(out)
    write_json(truth_record(kind, scenario), Path(truth_root) / f"{scenario.name}.json")
    return out
