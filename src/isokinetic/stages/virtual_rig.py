"""Rule ``virtual_rig``: a config-defined campaign simulated, measured and written as an ingested campaign.

The damper physics (noise-free responses) is that of the paper "A method for the identification of
hydraulic damper characteristics from steady velocity inputs" (Titurus et al.), in
:mod:`isokinetic.physics.responses` (rigid servo) and :mod:`isokinetic.physics.servo` (finite servo
stiffness); equation numbers are the paper's. This module holds what makes it a test campaign:

Configuration
    :class:`VirtualCampaign` parses one entry of ``virtual_campaigns`` (config/config.yaml): nominal
    damper, hidden truth effects, :class:`Measurement` (sensors and servo) and the test plan.

Measurement
    The simulation and its sensor model: :mod:`isokinetic.physics.virtual_rig`.

Export
    :func:`write_campaign` writes the ingested campaign (the rule's output); :func:`export_raw_campaign`
    a raw campaign folder of the same series (the ``export-virtual`` command).
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from isokinetic.contracts import tables
from isokinetic.contracts.campaign import timeseries_relpath, write_ingested
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.campaign_meta import CampaignMeta
from isokinetic.contracts.outputs import CAMPAIGN_ID
from isokinetic.physics.damper import Damper, Effects
from isokinetic.physics.plan import CasePlan, paper_plan
from isokinetic.physics.virtual_rig import (
    Measurement,
    check_keys,
    check_mapping,
    check_number,
    simulate_cases,
)

#: CSV columns of an exported case: (column name, unit, SI per unit).
RAW_COLUMNS = {
    "time": ("time_s", "s", 1.0),
    "displacement": ("disp_mm", "mm", 1.0e-3),
    "force": ("force_kN", "kN", 1.0e3),
    "command": ("cmd_mm", "mm", 1.0e-3),
}


# --------------------------------------------------------------------------------------------
# Configuration
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class VirtualCampaign:
    """One simulated campaign: nominal damper, hidden truth effects, sensors and test plan."""

    name: str
    description: str
    seed: int
    temperature_C: float
    damper: Damper
    effects: Effects
    measurement: Measurement
    cases: tuple[CasePlan, ...]

    def case(self, case_id: str) -> CasePlan:
        for c in self.cases:
            if c.case == case_id:
                return c
        raise KeyError(f"campaign {self.name}: unknown case {case_id!r}; known: {[c.case for c in self.cases]}")

    @classmethod
    def from_config(cls, name: str, mapping: Mapping) -> VirtualCampaign:
        """Parse one entry of ``virtual_campaigns`` (config/config.yaml); mm -> m here.

        Errors (KeyError / ValueError) name the offending key as ``virtual_campaigns.<name>.<key>``.
        """
        where = f"virtual_campaigns.{name}"
        if not isinstance(name, str) or not CAMPAIGN_ID.fullmatch(name):
            raise ValueError(f"{where}: campaign name must match [a-z0-9][a-z0-9_-]*")
        mapping = check_mapping(mapping, where)
        check_keys(mapping, ("description", "seed", "temperature_C", "damper", "effects", "measurement", "plan"),
                    ("seed", "temperature_C", "damper", "plan"), where)
        seed = mapping["seed"]
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"{where}.seed: must be a non-negative integer, got {seed!r}")
        description = mapping.get("description", "") or ""
        if not isinstance(description, str):
            raise ValueError(f"{where}.description: must be a string")
        try:
            damper = Damper.from_mapping(check_mapping(mapping["damper"], f"{where}.damper"))
        except (KeyError, ValueError) as exc:
            raise type(exc)(f"{where}.{exc.args[0]}") from exc
        extra = set(check_mapping(mapping["damper"], f"{where}.damper")) - {f.name for f in dataclasses.fields(Damper)}
        if extra:
            raise KeyError(f"{where}.damper: unknown key {sorted(extra)[0]!r}")
        groups = check_mapping(mapping.get("effects") or {}, f"{where}.effects")
        for group, values in groups.items():
            for key, value in check_mapping(values or {}, f"{where}.effects.{group}").items():
                check_number(value, f"{where}.effects.{group}.{key}")
        try:
            effects = Effects.from_config(groups)
        except KeyError as exc:
            raise KeyError(f"{where}.{exc.args[0]}") from exc
        measurement = Measurement.from_config(mapping.get("measurement"), f"{where}.measurement")
        cases = _plan_from_config(check_mapping(mapping["plan"], f"{where}.plan"), f"{where}.plan")
        return cls(name=name, description=description.strip(), seed=seed,
                   temperature_C=check_number(mapping["temperature_C"], f"{where}.temperature_C"),
                   damper=damper, effects=effects, measurement=measurement, cases=tuple(cases))


def _number_list(values, key: str) -> list[float]:
    if not isinstance(values, (list, tuple)) or not values:
        raise ValueError(f"{key}: must be a non-empty list")
    return [check_number(v, f"{key}[{i}]", positive=True) for i, v in enumerate(values)]


def _plan_from_config(plan: Mapping, where: str) -> list[CasePlan]:
    """Cases of a ``plan`` block via :func:`plan.paper_plan` (mm -> m)."""
    check_keys(plan, ("triangle", "sine"), (), where)
    if not plan:
        raise KeyError(f"{where}: needs a 'triangle' and/or a 'sine' block")
    velocities, periods, tri_rate, phase, acq = [], [], 1.0, -math.pi / 2, 2.0
    if "triangle" in plan:
        w = f"{where}.triangle"
        tri = check_mapping(plan["triangle"], w)
        check_keys(tri, ("velocities_mm_s", "periods_s", "phase_rad", "acquisition_periods", "sample_rate_Hz"),
                    ("velocities_mm_s", "periods_s", "sample_rate_Hz"), w)
        velocities = [v * 1e-3 for v in _number_list(tri["velocities_mm_s"], f"{w}.velocities_mm_s")]
        periods = _number_list(tri["periods_s"], f"{w}.periods_s")
        if len(periods) != len(velocities):
            raise ValueError(f"{w}.periods_s: {len(periods)} periods for {len(velocities)} velocities")
        tri_rate = check_number(tri["sample_rate_Hz"], f"{w}.sample_rate_Hz", positive=True)
        phase = check_number(tri.get("phase_rad", phase), f"{w}.phase_rad")
        acq = check_number(tri.get("acquisition_periods", acq), f"{w}.acquisition_periods", positive=True)
    amplitudes, freq, sine_rate, sine_periods = [], 1.0, 1.0, 1.0
    if "sine" in plan:
        w = f"{where}.sine"
        sine = check_mapping(plan["sine"], w)
        check_keys(sine, ("frequency_Hz", "amplitudes_mm", "periods", "sample_rate_Hz"),
                    ("frequency_Hz", "amplitudes_mm", "periods", "sample_rate_Hz"), w)
        amplitudes = [a * 1e-3 for a in _number_list(sine["amplitudes_mm"], f"{w}.amplitudes_mm")]
        freq = check_number(sine["frequency_Hz"], f"{w}.frequency_Hz", positive=True)
        sine_rate = check_number(sine["sample_rate_Hz"], f"{w}.sample_rate_Hz", positive=True)
        sine_periods = check_number(sine["periods"], f"{w}.periods", positive=True)
    return paper_plan(velocities, periods, amplitudes, freq, tri_rate, sine_rate, sine_periods,
                      phase_rad=phase, acquisition_periods=acq)


def simulate_campaign(vc: VirtualCampaign) -> dict[str, pd.DataFrame]:
    """Every case of the campaign, in plan order: {case id: simulate_case(...)}."""
    return simulate_cases(vc.cases, vc.damper, vc.effects, vc.measurement, vc.seed)


# --------------------------------------------------------------------------------------------
# CSV / campaign export
# --------------------------------------------------------------------------------------------

def _decimals(resolution_si: float, unit_si: float) -> tuple[float, int]:
    """Resolution in the CSV unit and the decimals that print its multiples exactly."""
    r = Decimal(repr(resolution_si)) / Decimal(repr(unit_si))
    r = r.normalize()
    digits = r.as_tuple()
    if len(digits.digits) > 6:
        raise ValueError(f"resolution {resolution_si!r} is not a short decimal in the export unit")
    return float(r), max(0, -digits.exponent)


def _format_channel(values_si: np.ndarray, resolution_si: float, unit_si: float) -> list[str]:
    """Exact decimal strings of quantised values (shortest round-trip repr if unquantised)."""
    if resolution_si == 0.0:
        return [repr(v) for v in (values_si / unit_si + 0.0).tolist()]
    r, d = _decimals(resolution_si, unit_si)
    counts = np.rint(values_si / resolution_si) + 0.0
    if np.abs(counts).max(initial=0.0) * 10 ** d >= 2.0**52:
        raise ValueError("value too large for exact decimal printing")
    return [f"{v:.{d}f}" for v in (counts * r + 0.0).tolist()]


def case_csv(series: pd.DataFrame, measurement: Measurement) -> str:
    """The raw-format CSV text of a simulated case (header time_s,disp_mm,force_kN,cmd_mm)."""
    cols = [
        [repr(v) for v in series["time_s"].tolist()],
        _format_channel(series["displacement_m"].to_numpy(), measurement.displacement_resolution_m, 1e-3),
        _format_channel(series["force_N"].to_numpy(), measurement.force_resolution_N, 1e3),
        _format_channel(series["command_m"].to_numpy(), measurement.command_resolution_m, 1e-3),
    ]
    header = ",".join(RAW_COLUMNS[k][0] for k in ("time", "displacement", "force", "command"))
    return header + "\n" + "\n".join(map(",".join, zip(*cols))) + "\n"


def case_sha256(series: pd.DataFrame, measurement: Measurement) -> str:
    """raw_sha256 of a simulated case: sha256 of its exported CSV bytes (:func:`case_csv`)."""
    return hashlib.sha256(case_csv(series, measurement).encode("utf-8")).hexdigest()


def _cases_table(campaign: str, cases: Sequence[CasePlan], series: Mapping[str, pd.DataFrame],
                 measurement: Measurement, temperature_C: float) -> pd.DataFrame:
    rows = []
    for c in cases:
        rows.append({"campaign": campaign, "case": c.case, "waveform": c.waveform,
                     "sample_rate_Hz": float(c.sample_rate_Hz), "amplitude_m": float(c.amplitude_m),
                     "period_s": float(c.period_s), "frequency_Hz": float(c.frequency_Hz),
                     "phase_rad": float(c.phase_rad), "duration_s": float(c.duration_s),
                     "raw_file": f"virtual_rig:{campaign}/{c.case}",
                     "raw_sha256": case_sha256(series[c.case], measurement),
                     "timeseries_file": timeseries_relpath(c.case),
                     "n_samples": int(len(series[c.case])), "status": "ok",
                     "temperature_C": float(temperature_C), "temperature_span_C": math.nan,
                     "temperature_source": "campaign"})
    df = pd.DataFrame(rows)
    return df.astype({"n_samples": "int64"})


def write_campaign(vc: VirtualCampaign, campaign_root: str | os.PathLike) -> Path:
    """Simulate and write ``campaign_root/ingest/`` (campaign.write_ingested); returns the ingest dir.

    campaign.json carries the *nominal* damper only; raw_sha256 is the sha256 of the case CSV
    that :func:`export_raw_campaign` would write (same series, same bytes).
    """
    series = simulate_campaign(vc)
    meta = CampaignMeta(format_version=1, campaign=vc.name, source="simulation", description=vc.description,
                        temperature_C=vc.temperature_C, damper=vc.damper, manifest_file="", manifest_sha256="",
                        metadata=_generated_by(vc, [c.case for c in vc.cases], None))
    ingest = CampaignFolder.at(campaign_root).ingest_dir
    write_ingested(ingest, meta, _cases_table(vc.name, vc.cases, series, vc.measurement, vc.temperature_C),
                   tables.empty(tables.QUARANTINE), series)
    return ingest


def _generated_by(vc: VirtualCampaign, cases: list[str], sample_rate_Hz: float | None) -> dict:
    return {"generated_by": {"generator": "isokinetic.virtual_rig", "config_campaign": vc.name,
                             "seed": vc.seed, "cases": list(cases), "sample_rate_Hz": sample_rate_Hz}}


def _short(x: float) -> float:
    """Derived plan value without float noise (15 significant digits; 0.654 not 0.6540000000000001)."""
    return float(f"{x:.15g}")


def campaign_manifest(vc: VirtualCampaign, cases: Sequence[CasePlan], name: str,
                      sample_rate_Hz: float | None) -> dict:
    """campaign.yaml content (raw-campaign format v1) of an export."""
    rates = [c.sample_rate_Hz for c in cases]
    default_rate = max(rates, key=lambda r: (rates.count(r), -rates.index(r)))
    entries = []
    for c in cases:
        e = {"id": c.case, "waveform": c.waveform}
        if c.waveform == "triangle":
            e.update(period_s=float(c.period_s), amplitude_mm=_short(c.amplitude_m * 1e3),
                     phase_rad=float(c.phase_rad))
        else:
            e.update(frequency_Hz=float(c.frequency_Hz), amplitude_mm=_short(c.amplitude_m * 1e3))
        if c.sample_rate_Hz != default_rate:
            e["sample_rate_Hz"] = float(c.sample_rate_Hz)
        e["duration_s"] = _short(c.duration_s)
        e["file"] = f"{c.case}.csv"
        entries.append(e)
    return {"format_version": 1, "campaign": name, "description": vc.description, "source": "simulation",
            "temperature_C": float(vc.temperature_C), "sample_rate_Hz": float(default_rate),
            "columns": {k: {"name": v[0], "unit": v[1]} for k, v in RAW_COLUMNS.items()},
            "damper": vc.damper.to_dict(),
            **_generated_by(vc, [c.case for c in cases], sample_rate_Hz),
            "cases": entries}


def export_raw_campaign(vc: VirtualCampaign, out_dir: str | os.PathLike, cases: Sequence[str] | None = None,
                        sample_rate_Hz: float | None = None, name: str | None = None) -> Path:
    """Write a raw campaign folder (spec raw-campaign-format.md) of simulated cases; returns it.

    ``out_dir`` is the campaign folder itself (it must not exist or be empty); the spec wants the
    campaign id equal to the folder name, so ``name`` defaults to the folder name and must equal it
    when given. ``cases`` selects case ids (plan order kept); ``sample_rate_Hz`` simulates every
    selected case at that rate. Byte reproducible: same config, seed and arguments, same bytes.
    campaign.yaml carries the nominal damper and a ``generated_by`` block (config campaign, seed,
    cases, sample rate override); the truth effects are not written.
    """
    out = Path(out_dir)
    name = out.name if name is None else name
    if not CAMPAIGN_ID.fullmatch(name):
        raise ValueError(f"campaign name {name!r} must match [a-z0-9][a-z0-9_-]* (the spec's campaign id)")
    if out.name != name:
        raise ValueError(f"the campaign folder must be named like the campaign ({name!r}), got {out.name!r}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"refusing to write into existing non-empty {out}")
    if cases is None:
        selected = list(vc.cases)
    else:
        wanted = list(cases)
        if len(set(wanted)) != len(wanted) or not wanted:
            raise ValueError(f"cases: must be a non-empty list without duplicates, got {wanted}")
        for cid in wanted:
            vc.case(cid)
        selected = [c for c in vc.cases if c.case in set(wanted)]
    if sample_rate_Hz is not None:
        rate = check_number(sample_rate_Hz, "sample_rate_Hz", positive=True)
        selected = [dataclasses.replace(c, sample_rate_Hz=rate) for c in selected]
        sample_rate_Hz = rate
    manifest = campaign_manifest(vc, selected, name, sample_rate_Hz)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(dir=out.parent, prefix=f".{name}."))
    try:
        for case_id, series in simulate_cases(selected, vc.damper, vc.effects, vc.measurement, vc.seed).items():
            with open(tmp / f"{case_id}.csv", "w", encoding="utf-8", newline="\n") as fh:
                fh.write(case_csv(series, vc.measurement))
        with open(tmp / "campaign.yaml", "w", encoding="utf-8", newline="\n") as fh:
            yaml.safe_dump(manifest, fh, sort_keys=False, default_flow_style=False, allow_unicode=True, width=100)
        os.chmod(tmp, 0o755)
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out

