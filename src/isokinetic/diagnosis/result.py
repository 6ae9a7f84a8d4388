"""The diagnosis.json document: its versions, the document of a campaign not diagnosed, JSON-safe
values, validation against the schema shipped with the package, and its row-level sources.

Contract ``docs/diagnosis-output.md``, version 1.8 (1.1 and 1.2 readers keep working: 1.2 and 1.3 only add keys,
1.4 makes the within-window structure test decide, 1.5 adds ``next_tests``, the plan of extra cases, 1.6 its
``calibrations``, the load-cell calibration proposed beside them, 1.7 ``calibration_note``, a declared calibration
the campaign's data contradict, 1.8 the drift tests as a mixed model of the cases, the orifice's area one of their
parameters);
schema ``diagnosis.schema.json``, package data of :mod:`isokinetic.contracts`
(read through ``importlib.resources``, so a regular, non-editable install validates too).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping
from importlib import resources

import numpy as np
import pandas as pd

from isokinetic.contracts.outputs import STAGE_OUTPUTS
from isokinetic.contracts.row_keys import row_keys
from isokinetic.diagnosis.observations import Observations
from isokinetic.physics.sine_drive import SineDrive

FORMAT_VERSION = 1
CONTRACT_VERSION = "1.8"
#: The ``next_tests`` note of a campaign that was not diagnosed (contract 1.5).
NOT_DIAGNOSED_NOTE = "not diagnosed: no further test proposed"
METRIC = "rms_z"
#: The diagnosis.json schema, package data of isokinetic.contracts.
SCHEMA_PACKAGE = "isokinetic.contracts"
SCHEMA_RESOURCE = "diagnosis.schema.json"
#: Inputs of a diagnosis, relative to results/<campaign>/ (named in its ``sources`` key).
CHARACTERISTIC_FILE = STAGE_OUTPUTS["characteristic"]["characteristic"]
CASES_FILE = STAGE_OUTPUTS["validate"]["cases"]


def json_number(x: float) -> float | None:
    """A finite float, else None."""
    return float(x) if x is not None and math.isfinite(float(x)) else None


def json_safe(obj):
    """JSON-safe: NaN/inf to None, numpy scalars to Python."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return json_number(obj)
    return obj


def no_model(campaign: str, reason: str, status: str = "not_diagnosed") -> dict:
    """The diagnosis of a campaign that cannot be diagnosed (no damper data, no triangle or sine case), or
    whose diagnosis failed (``status`` 'failed', with the reason)."""
    return {"format_version": FORMAT_VERSION, "contract_version": CONTRACT_VERSION, "campaign": campaign,
            "status": status, "reason": reason, "metric": METRIC, "gap_before": None, "where": [],
            "candidates": [], "verdict": [], "explained": False,
            "instrument": {"delay_s": None, "force_offset_N": None, "force_gain": None, "force_lag_s": None,
                           "displacement_scale": None, "force_drift_N_s": None},
            "gap_after": None, "holdout_gap_after": None, "shrink": None,
            "next_tests": {"needed": False, "note": NOT_DIAGNOSED_NOTE, "plan": []}}


def diagnosis_schema() -> dict:
    """The diagnosis.json schema (package data, so a regular install validates too)."""
    return json.loads(resources.files(SCHEMA_PACKAGE).joinpath(SCHEMA_RESOURCE).read_text(encoding="utf-8"))


def validate_diagnosis(result: Mapping) -> None:
    """Validate a diagnosis dict against the diagnosis.json schema (raises ValidationError, the most relevant
    error first, as ``jsonschema.validate`` raises it)."""
    import jsonschema  # ~0.1 s: only where a diagnosis is validated

    error = jsonschema.exceptions.best_match(_validator().iter_errors(result))
    if error is not None:
        raise error


@functools.cache
def _validator():
    """The schema's validator, built once per process. The schema itself is package data, checked against its
    metaschema by the tests (``jsonschema.validate`` checked it at every call: 0.05 s a diagnosis job)."""
    import jsonschema

    schema = diagnosis_schema()
    return jsonschema.validators.validator_for(schema)(schema)


def observation_sources(obs: Observations | None, cases: pd.DataFrame | None) -> dict:
    """Row-level lineage of a diagnosis (its ``sources`` key; paths relative to results/<campaign>/).

    ``windows``: the characteristic rows used as window observations, as (case, segment) keys
    'T01/1,T01/2,...' (:func:`isokinetic.contracts.row_keys.row_keys`); ``transient_bins``: 'case/segment:n'
    per half-period with n transient bins taken from that case's time series (both of triangle cases);
    ``sine_bins``: 'case:n' per sine case with n phase bins (windows and transient bins of its steady cycles,
    :mod:`isokinetic.diagnosis.sine_observations`) taken from its time series; ``sine_harmonics``: 'case/k:h'
    per harmonic k of a sine case's measured motion that drove its model, h its amplitude over the fundamental's
    (4 significant digits); ``timeseries``: for
    each case used, its time series file and raw file with sha256 (from ``cases.parquet``).
    """
    out = {"characteristic_file": CHARACTERISTIC_FILE, "cases_file": CASES_FILE, "windows": "",
           "transient_bins": "", "sine_bins": "", "sine_harmonics": "", "timeseries": {}}
    if obs is None or len(obs) == 0:
        return out
    sine = np.array([obs.plans[i].waveform == "sine" for i in obs.case_index], dtype=bool)
    frame = pd.DataFrame({"case": obs.case, "segment": obs.segment, "kind": obs.kind})
    triangle = frame[~sine]
    out["windows"] = row_keys(triangle[triangle["kind"] == "window"])
    bins = triangle[triangle["kind"] == "transient"].groupby(["case", "segment"], sort=False).size()
    out["transient_bins"] = ",".join(f"{c}/{k}:{n}" for (c, k), n in bins.items())
    out["sine_bins"] = ",".join(f"{c}:{n}" for c, n in frame[sine].groupby("case", sort=False).size().items())
    out["sine_harmonics"] = ",".join(f"{plan.case}/{k}:{a_k / drive.amplitude_m:.4g}"
                                     for plan, drive in zip(obs.plans, obs.drives, strict=False)
                                     if isinstance(drive, SineDrive) for k, a_k, _theta in drive.harmonics)
    used = list(dict.fromkeys(obs.case.tolist()))
    if cases is not None and len(cases):
        by_case = cases.set_index("case")
        for c in used:
            if c in by_case.index:
                row = by_case.loc[c]
                out["timeseries"][c] = {k: str(row[k]) for k in ("timeseries_file", "raw_file", "raw_sha256")
                                        if k in row}
    return out
