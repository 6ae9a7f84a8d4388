"""The virtual rig: the damper model of :mod:`isokinetic.physics.responses` (rigid servo) and
:mod:`isokinetic.physics.servo` (finite servo stiffness) measured by a sensor model, one record per case
(the paper "A method for the identification of hydraulic damper characteristics from steady velocity
inputs", Titurus et al.; equation numbers are the paper's).

Measurement
    Seeded Gaussian noise, independent per case (``SeedSequence([seed, crc32(case)])``): LVDT noise
    on the actuator position (the command for a rigid servo), additive plus |F|-proportional noise
    on the force (Fig. 12). Every channel is then quantised to a stated resolution (ADC step), so
    an exported CSV prints exact decimals and reading it back reproduces the simulated series to
    float rounding.

The rule ``virtual_rig`` (:mod:`isokinetic.stages.virtual_rig`) reads the config, runs this and writes
the ingested campaign.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from isokinetic.physics.damper import Damper, Effects
from isokinetic.physics.plan import CasePlan
from isokinetic.physics.responses import true_response, true_responses
from isokinetic.physics.servo import check_stiffness

# --------------------------------------------------------------------------------------------
# Configuration values
# --------------------------------------------------------------------------------------------

def check_number(value, key: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    """A finite float from config, else ValueError naming ``key``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{key}: must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise ValueError(f"{key}: must be > 0, got {value!r}")
    if nonnegative and value < 0:
        raise ValueError(f"{key}: must be >= 0, got {value!r}")
    return float(value)


def check_mapping(value, key: str) -> Mapping:
    """The value if it is a mapping, else ValueError naming ``key``."""
    if not isinstance(value, Mapping):
        raise ValueError(f"{key}: must be a mapping, got {type(value).__name__}")
    return value


def check_keys(values: Mapping, allowed: Iterable[str], required: Iterable[str], where: str) -> None:
    """KeyError naming ``where`` and the key for a key of ``values`` not allowed or a required one absent."""
    allowed = set(allowed)
    for key in values:
        if key not in allowed:
            raise KeyError(f"{where}: unknown key {key!r}; allowed: {sorted(allowed)}")
    for key in required:
        if key not in values:
            raise KeyError(f"{where}: missing key {key!r}")


@dataclass(frozen=True)
class Measurement:
    """Sensor and servo model of the rig (1σ noise levels, ADC resolutions, servo stiffness, SI).

    Resolutions quantise the *measured* channels (and the command) to integer multiples of the
    step; 0 disables quantisation. A resolution must be a short decimal in the export unit
    (e.g. 0.1 N = 1e-4 kN) so that the CSV prints it exactly.

    ``servo_stiffness_N_m`` k: the displacement-controlled actuator lags its command under load,
    x = command - F/k, and the LVDT measures x (:func:`servo.servo_response`). inf (the default) is a
    rigid servo: x = command exactly, the fast paths of :func:`responses.true_responses`.
    """

    force_noise_N: float = 0.0
    force_noise_rel: float = 0.0
    displacement_noise_m: float = 0.0
    force_resolution_N: float = 0.1
    displacement_resolution_m: float = 1.0e-7
    command_resolution_m: float = 1.0e-9
    servo_stiffness_N_m: float = math.inf

    def __post_init__(self):
        for f in dataclasses.fields(self):
            if f.name == "servo_stiffness_N_m":
                check_stiffness(self.servo_stiffness_N_m, f"measurement.{f.name}")
            else:
                check_number(getattr(self, f.name), f"measurement.{f.name}", nonnegative=True)

    @classmethod
    def ideal(cls) -> Measurement:
        """The measurement without noise or quantisation (for physics checks)."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_config(cls, values: Mapping | None, where: str = "measurement") -> Measurement:
        """The measurement of the config block; unknown keys raise KeyError naming the key."""
        values = check_mapping(values or {}, where)
        names = [f.name for f in dataclasses.fields(cls)]
        check_keys(values, names, (), where)
        return cls(**{k: (check_stiffness(v, f"{where}.{k}") if k == "servo_stiffness_N_m"
                          else check_number(v, f"{where}.{k}", nonnegative=True)) for k, v in values.items()})



# --------------------------------------------------------------------------------------------
# Measurement and cases
# --------------------------------------------------------------------------------------------

def quantise(x, resolution: float) -> np.ndarray:
    """The nearest integer multiple of ``resolution`` (x's unit; 0: unchanged); never -0.0."""
    x = np.asarray(x, dtype=float)
    if resolution == 0.0:
        return x + 0.0
    return np.rint(x / resolution) * resolution + 0.0


def case_rng(seed: int, case_id: str) -> np.random.Generator:
    """The independent, reproducible noise stream of one case: SeedSequence([seed, crc32(case)])."""
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(case_id.encode("utf-8"))]))


def simulate_case(case: CasePlan, damper: Damper, effects: Effects, measurement: Measurement,
                  seed: int) -> pd.DataFrame:
    """The measured record of one case (tables.TIMESERIES): row, time_s, displacement_m, force_N, command_m.

    displacement = LVDT on the actuator (the command for a rigid servo, command - F/k otherwise;
    plus noise), force = transmitted force (Eq. 8 in contact) + additive and |F|-proportional
    noise; both then quantised (``measurement`` resolutions).
    """
    return measure(case, true_response(case, damper, effects, servo_stiffness_N_m=measurement.servo_stiffness_N_m),
                   measurement, seed)


def measure(case: CasePlan, truth: pd.DataFrame, measurement: Measurement, seed: int) -> pd.DataFrame:
    """The measured record (as :func:`simulate_case`): the sensor model applied to a noise-free record
    (:func:`true_response`) of ``case``.

    Draws, in this order from ``case_rng(seed, case.case)``: LVDT noise, additive force noise,
    relative force noise (standard normals of the record length).
    """
    n = len(truth)
    rng = case_rng(seed, case.case)
    z_disp = rng.standard_normal(n)
    z_add = rng.standard_normal(n)
    z_rel = rng.standard_normal(n)
    f = truth["force_N"].to_numpy()
    cmd = truth["command_m"].to_numpy()
    lvdt = truth["actuator_m"].to_numpy() if "actuator_m" in truth else cmd
    force = f + measurement.force_noise_N * z_add + measurement.force_noise_rel * np.abs(f) * z_rel
    disp = lvdt + measurement.displacement_noise_m * z_disp
    return pd.DataFrame({
        "row": np.arange(n, dtype=np.int64),
        "time_s": truth["time_s"].to_numpy(),
        "displacement_m": quantise(disp, measurement.displacement_resolution_m),
        "force_N": quantise(force, measurement.force_resolution_N),
        "command_m": quantise(cmd, measurement.command_resolution_m),
    })


def simulate_cases(cases: Sequence[CasePlan], damper: Damper, effects: Effects, measurement: Measurement,
                   seed: int) -> dict[str, pd.DataFrame]:
    """:func:`simulate_case` of many cases, physics batched; {case id: record}, in the given order."""
    truths = true_responses(cases, damper, effects, servo_stiffness_N_m=measurement.servo_stiffness_N_m)
    return {c.case: measure(c, truth, measurement, seed) for c, truth in zip(cases, truths)}
