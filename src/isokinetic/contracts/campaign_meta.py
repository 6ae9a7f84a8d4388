"""A campaign's metadata record, ``results/<campaign>/ingest/campaign.json``, typed.

:class:`CampaignMeta` is built from the file (:meth:`CampaignMeta.from_mapping`) and written back to it
(:meth:`CampaignMeta.to_mapping`); both check the mapping against the JSON schema
``campaign.schema.json`` (package data of :mod:`isokinetic.contracts`, the one description of the keys).
The keys readers use are typed fields; a key the schema does not name (a newer writer's, a hand-added
one) is kept in :attr:`CampaignMeta.extra` and written back unchanged, so old and new folders both read.
The optional keys raw ingest adds (``viscosity_law``, ``gas_force_N``, ``csv``, ``warnings``,
``force_calibration``, ``displacement_calibration``) are written back only when the record was built with them (a
simulated campaign's file has none).

The schema uses only ``type``, ``required``, ``properties`` and ``items``, checked here by
:func:`schema_problems` without importing jsonschema (0.1 s a job); the tests check that jsonschema agrees.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from typing import Any

from isokinetic.physics.damper import Damper
from isokinetic.physics.viscosity import ViscosityLaw, law_from_mapping

SCHEMA_RESOURCE = "campaign.schema.json"
#: The optional keys raw ingest writes (the virtual rig does not).
RAW_INGEST_KEYS = ("viscosity_law", "gas_force_N", "csv", "warnings", "force_calibration",
                   "displacement_calibration")
#: The declared calibrations (format 1.6): campaign.json key -> the two numbers it holds.
CALIBRATION_NUMBERS = {"force_calibration": ("gain", "uncertainty_rel"),
                       "displacement_calibration": ("scale", "uncertainty_rel")}
#: Optional keys of the record: raw ingest's and the writing job's lineage record.
OPTIONAL_KEYS = (*RAW_INGEST_KEYS, "lineage")
#: JSON type name -> the Python types json.loads gives for it.
JSON_TYPES = {"string": (str,), "integer": (int,), "number": (int, float), "object": (dict,),
              "array": (list, tuple), "null": (type(None),), "boolean": (bool,)}


@functools.cache
def campaign_schema() -> dict:
    """The JSON schema of campaign.json (package data)."""
    text = resources.files("isokinetic.contracts").joinpath(SCHEMA_RESOURCE).read_text(encoding="utf-8")
    return json.loads(text)


#: The keys every campaign.json holds (the schema's ``required``).
CAMPAIGN_KEYS = tuple(campaign_schema()["required"])


def _type_ok(value, types: str | list[str]) -> bool:
    names = [types] if isinstance(types, str) else types
    if isinstance(value, bool):                     # a bool is an int to Python, not to JSON
        return "boolean" in names
    return any(isinstance(value, JSON_TYPES[n]) for n in names)


def schema_problems(mapping: Mapping[str, Any], schema: Mapping | None = None) -> list[str]:
    """What in a campaign.json mapping breaks its schema (``required``, ``type``, ``items``), [] when
    nothing does."""
    schema = campaign_schema() if schema is None else schema
    if not isinstance(mapping, Mapping):
        return [f"expected an object, got {type(mapping).__name__}"]
    problems = [f"missing key {k!r}" for k in schema.get("required", ()) if k not in mapping]
    for key, spec in schema.get("properties", {}).items():
        if key not in mapping:
            continue
        value = mapping[key]
        if "type" in spec and not _type_ok(value, spec["type"]):
            problems.append(f"key {key!r} must be {spec['type']}, got {value!r}")
        elif "items" in spec and isinstance(value, (list, tuple)):
            problems += [f"key {key!r} item {i} must be {spec['items']['type']}, got {v!r}"
                         for i, v in enumerate(value) if not _type_ok(v, spec["items"]["type"])]
    return problems


class CampaignMetaError(ValueError):
    """A campaign.json that breaks its schema; the message names the file (or campaign) and the key."""


@dataclass(frozen=True)
class CampaignMeta:
    """A campaign's metadata (campaign.json): the campaign, its source, its nominal damper (SI) and what
    raw ingest recorded about its manifest."""

    format_version: int
    campaign: str
    source: str | None
    description: str | None
    temperature_C: float | None
    damper: Damper | None
    manifest_file: str
    manifest_sha256: str
    metadata: Mapping[str, Any]
    viscosity_law_block: Mapping[str, Any] | None = None
    gas_force_N: float | None = None
    csv: Mapping[str, Any] | None = None
    warnings: tuple[str, ...] = ()
    lineage: Mapping[str, Any] | None = None
    #: the load cell's declared calibration {"gain", "uncertainty_rel"} (manifest columns.force.calibration, 1.6)
    force_calibration: Mapping[str, float] | None = None
    #: the LVDT's declared calibration {"scale", "uncertainty_rel"} (manifest columns.displacement.calibration, 1.6)
    displacement_calibration: Mapping[str, float] | None = None
    #: keys the schema does not name, kept as they were read
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: the optional keys (OPTIONAL_KEYS) the record carries, written back by to_mapping
    present: frozenset[str] = frozenset()

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], where: str = "campaign.json") -> CampaignMeta:
        """The record of a campaign.json mapping; :class:`CampaignMetaError` naming ``where`` and the key
        when it breaks the schema or its damper block is not a damper's data."""
        problems = schema_problems(mapping)
        if problems:
            raise CampaignMetaError(f"{where}: {'; '.join(problems)}")
        try:
            damper = None if mapping["damper"] is None else Damper.from_mapping(mapping["damper"])
        except (KeyError, ValueError) as exc:
            raise CampaignMetaError(f"{where}: {exc}") from None
        for key, numbers in CALIBRATION_NUMBERS.items():
            calibration = mapping.get(key)
            if calibration is not None and not all(_type_ok(calibration.get(k), "number") for k in numbers):
                raise CampaignMetaError(f"{where}: key {key!r} must hold the numbers {' and '.join(numbers)}, "
                                        f"got {calibration!r}")
        known = set(CAMPAIGN_KEYS) | set(OPTIONAL_KEYS)
        return cls(format_version=mapping["format_version"], campaign=mapping["campaign"], source=mapping["source"],
                   description=mapping["description"],
                   temperature_C=mapping["temperature_C"],
                   damper=damper, manifest_file=mapping["manifest_file"],
                   manifest_sha256=mapping["manifest_sha256"], metadata=dict(mapping["metadata"]),
                   viscosity_law_block=mapping.get("viscosity_law"),
                   gas_force_N=mapping.get("gas_force_N"), csv=mapping.get("csv"),
                   warnings=tuple(mapping.get("warnings", ())), lineage=mapping.get("lineage"),
                   force_calibration=mapping.get("force_calibration"),
                   displacement_calibration=mapping.get("displacement_calibration"),
                   extra={k: v for k, v in mapping.items() if k not in known},
                   present=frozenset(k for k in OPTIONAL_KEYS if k in mapping))

    def to_mapping(self) -> dict[str, Any]:
        """The campaign.json mapping of the record (the inverse of :meth:`from_mapping`)."""
        out = dict(self.extra)
        out.update({"format_version": self.format_version, "campaign": self.campaign, "source": self.source,
                    "description": self.description, "temperature_C": self.temperature_C,
                    "damper": None if self.damper is None else self.damper.to_dict(),
                    "manifest_file": self.manifest_file, "manifest_sha256": self.manifest_sha256,
                    "metadata": dict(self.metadata)})
        optional = {"viscosity_law": self.viscosity_law_block, "gas_force_N": self.gas_force_N, "csv": self.csv,
                    "warnings": list(self.warnings), "lineage": self.lineage,
                    **{key: None if getattr(self, key) is None else dict(getattr(self, key))
                       for key in CALIBRATION_NUMBERS}}
        out.update({k: v for k, v in optional.items() if k in self.present})
        problems = schema_problems(out)
        if problems:
            raise CampaignMetaError(f"campaign {self.campaign!r}: {'; '.join(problems)}")
        return out

    @property
    def generated_by(self) -> Mapping[str, Any] | None:
        """The virtual rig's record of a simulated campaign (``metadata.generated_by``), None for a raw one."""
        return self.metadata.get("generated_by")

    @property
    def calibration(self) -> tuple[float, float] | None:
        """(gain, uncertainty_rel) of the load cell's declared calibration (``force_calibration``), None without."""
        cal = self.force_calibration
        return None if cal is None else (float(cal["gain"]), float(cal["uncertainty_rel"]))

    @property
    def lvdt_calibration(self) -> tuple[float, float] | None:
        """(scale, uncertainty_rel) of the LVDT's declared calibration (``displacement_calibration``), None
        without."""
        cal = self.displacement_calibration
        return None if cal is None else (float(cal["scale"]), float(cal["uncertainty_rel"]))

    def viscosity_law(self) -> ViscosityLaw | None:
        """The oil's viscosity-temperature law (``viscosity_law``, format 1.1), None without one or without a
        damper block (the law's kinematic form needs the damper's density)."""
        if not self.viscosity_law_block or self.damper is None:
            return None
        return law_from_mapping(self.viscosity_law_block, float(self.damper.density_kg_m3))
