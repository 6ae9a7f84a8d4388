"""The raw evidence of a traced number (:mod:`isokinetic.audit.trace`): where a processed campaign
came from, re-processed into a scratch folder with every raw hash checked first.

A raw campaign (``cases.raw_file`` a path) is the manifest named in ``ingest/campaign.json`` and
its case CSVs, re-read with :func:`isokinetic.stages.ingest.ingest_case`. A simulated campaign
(``raw_file`` = ``virtual_rig:<campaign>/<case>``) is the virtual-rig spec, from the lineage
params of ``ingest/cases.parquet`` when present, else ``virtual_campaigns.<campaign>`` of the
config; its cases are re-simulated and their exported CSV
(:func:`isokinetic.stages.virtual_rig.case_csv`) hashed.
A hash that differs from the recorded one stops the trace (:class:`RawFileChanged`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pandas as pd

from isokinetic.audit.provenance import VIRTUAL_PREFIX
from isokinetic.audit.trace_core import Context, MissingFile, RawFileChanged, TraceStop, read_lineage, sha_text
from isokinetic.contracts import tables
from isokinetic.contracts.campaign import timeseries_relpath
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.contracts.manifest import MANIFEST_NAME, load_manifest, si_conversion
from isokinetic.contracts.outputs import STAGE_OUTPUTS, ingest_path
from isokinetic.contracts.settings import Settings
from isokinetic.io import sha256_file, write_parquet
from isokinetic.stages.chain import run_step
from isokinetic.stages.ingest import CANONICAL
from isokinetic.stages.validate import write_validated
from isokinetic.stages.virtual_rig import RAW_COLUMNS, VirtualCampaign, case_csv, write_campaign


@dataclass
class RawSource:
    """Where a processed campaign's numbers came from: a raw folder or a virtual-rig spec."""

    name: str
    kind: str                           # "raw" | "virtual"
    recorded: pd.DataFrame | None       # the processed cases table (recorded hashes), None if unknown
    recorded_path: Path | None
    vc: object = None                   # VirtualCampaign
    spec_where: str = ""
    manifest: object = None             # Manifest
    manifest_path: Path | None = None
    manifest_recorded: str = ""         # manifest_file as the pipeline recorded it
    campaign_dir: Path | None = None
    extra: dict = field(default_factory=dict)

    @property
    def damper(self):
        return self.vc.damper if self.kind == "virtual" else self.manifest.damper

    def case_ids(self) -> list[str]:
        if self.recorded is not None:
            return [str(c) for c in self.recorded["case"]]
        if self.kind == "virtual":
            return [c.case for c in self.vc.cases]
        return [s.id for s in self.manifest.cases]

    def recorded_row(self, case: str) -> pd.Series | None:
        if self.recorded is None:
            return None
        hit = self.recorded[self.recorded["case"].astype(str) == case]
        return None if hit.empty else hit.iloc[0]


def _recorded_cases(root: Path) -> tuple[pd.DataFrame, Path]:
    folder = CampaignFolder.at(root)
    paths = (folder.path("validate", "cases"), folder.ingest_path("cases"))
    for p in paths:
        if p.is_file():
            return pd.read_parquet(p), p
    names = f"{STAGE_OUTPUTS['validate']['cases']} or {ingest_path('cases')}"
    raise MissingFile(f"{root}: no {names} to take the recorded raw files from")


def open_source(ctx: Context, root: Path) -> RawSource:
    """The raw evidence of the processed campaign folder ``root`` (results/<campaign>)."""
    recorded, recorded_path = _recorded_cases(root)
    raw_files = recorded["raw_file"].astype(str)
    if len(recorded) and raw_files.str.startswith(VIRTUAL_PREFIX).all():
        name = raw_files.iloc[0][len(VIRTUAL_PREFIX):].split("/")[0]
        return _virtual_source(ctx, root, name, recorded, recorded_path)
    results = CampaignFolder.at(root)
    meta = results.meta if results.has_meta() else None
    manifest_file = (meta and meta.manifest_file) or ""
    if not manifest_file:
        ing = read_lineage(results.ingest_path("cases")) or {}
        folder = (ing.get("params") or {}).get("campaign_dir")
        if folder:
            manifest_file = f"{folder}/{MANIFEST_NAME}"
        else:
            with_file = [f for f in raw_files if f]
            if not with_file:
                raise TraceStop(f"{ctx.rel(root)}: no raw file recorded for any case")
            manifest_file = (Path(with_file[0]).parent / MANIFEST_NAME).as_posix()
    return raw_source(ctx, ctx.resolve(manifest_file), manifest_file, (meta and meta.manifest_sha256) or "",
                       recorded, recorded_path, where=ctx.rel(results.ingest_path("meta")) if meta else "")


def _virtual_source(ctx: Context, root: Path, name: str, recorded, recorded_path) -> RawSource:
    ing = CampaignFolder.at(root).ingest_path("cases")
    rec = read_lineage(ing) if ing.is_file() else None
    spec = ((rec or {}).get("params") or {}).get("spec")
    if isinstance(spec, Mapping):
        where = f"lineage params of {ctx.rel(ing)} (rule {rec.get('rule')})"
    else:
        cfg = ctx.config() or {}
        spec = (cfg.get("virtual_campaigns") or {}).get(name)
        if spec is None:
            where = ctx.rel(ctx.config_path) if ctx.config_path else "no config found"
            raise TraceStop(f"campaign {name} was simulated, but {ctx.rel(ing)} has no lineage record and "
                            f"{where} has no virtual_campaigns.{name}: nothing to re-simulate from (pass --config)")
        where = f"{ctx.rel(ctx.config_path)} virtual_campaigns.{name} (no lineage record in {ctx.rel(ing)})"
    vc = VirtualCampaign.from_config(name, spec)
    return RawSource(name=name, kind="virtual", recorded=recorded, recorded_path=recorded_path, vc=vc,
                     spec_where=where)


def raw_source(ctx: Context, manifest_path: Path, manifest_recorded: str, manifest_sha: str, recorded,
                recorded_path, where: str = "") -> RawSource:
    if not manifest_path.is_file():
        raise MissingFile(f"manifest {manifest_recorded or manifest_path} not found (looked in {ctx.root})")
    sha = sha256_file(manifest_path)
    if manifest_sha and sha != manifest_sha:
        raise RawFileChanged(f"manifest {ctx.rel(manifest_path)}: sha256 is now {sha_text(sha)}, recorded "
                             f"{sha_text(manifest_sha)} in {where or ingest_path('meta')}: it changed after processing")
    manifest = load_manifest(manifest_path)
    src = RawSource(name=manifest.campaign, kind="raw", recorded=recorded, recorded_path=recorded_path,
                    manifest=manifest, manifest_path=manifest_path, manifest_recorded=manifest_recorded or
                    manifest_path.as_posix(), campaign_dir=manifest_path.parent)
    src.extra["manifest_sha"] = sha
    src.extra["manifest_sha_recorded"] = manifest_sha
    return src


def describe_source(ctx: Context, src: RawSource) -> None:
    if src.kind == "virtual":
        vc = src.vc
        effects = ", ".join(vc.effects.active()) or "none"
        ctx.report.step(f"Raw source: simulated campaign {src.name!r} (virtual rig)",
                        f"spec from {src.spec_where}",
                        f"seed {vc.seed}, {len(vc.cases)} planned cases, hidden effects: {effects}; "
                        f"noise: force {vc.measurement.force_noise_N:g} N + {vc.measurement.force_noise_rel:g}|F|, "
                        f"LVDT {vc.measurement.displacement_noise_m:g} m",
                        "raw_sha256 of a simulated case = sha256 of its exported CSV (virtual_rig.case_csv)")
    else:
        rec = src.extra.get("manifest_sha_recorded")
        check = (f"= recorded {sha_text(rec)} (campaign.json) - unchanged" if rec else "(no recorded hash to check)")
        ctx.report.step(f"Raw source: campaign folder {ctx.rel(src.campaign_dir)}",
                        f"manifest {ctx.rel(src.manifest_path)}: sha256 {sha_text(src.extra['manifest_sha'])} {check}",
                        f"campaign {src.name!r}, {len(src.manifest.cases)} cases in the manifest")


def rebuild(ctx: Context, src: RawSource, cases: Sequence[str] | None = None,
            expected: Mapping[str, str] | None = None, validate: bool = True,
            settings: Settings | None = None) -> Path:
    """Re-process ``cases`` (default: every recorded case) from the raw evidence into a scratch
    campaign folder (ingest/ and, with ``validate``, cases.parquet) with the ``settings`` the traced files were
    made with (ingest's file-size limit; what validate accepted: the sample rate's tolerance and the dropped
    samples'; :func:`isokinetic.audit.trace_core.recorded_settings`); raw hashes checked first."""
    if settings is None:
        raise ValueError("rebuild: needs the settings the traced files were made with")
    wanted = list(cases) if cases is not None else src.case_ids()
    scratch = ctx.new_scratch(src.name)
    if src.kind == "virtual":
        known = {c.case: c for c in src.vc.cases}
        missing = [c for c in wanted if c not in known]
        if missing:
            raise RawFileChanged(f"case(s) {', '.join(missing)} are not in the virtual-rig spec ({src.spec_where}): "
                                 "the spec changed after processing")
        write_campaign(dataclasses.replace(src.vc, cases=tuple(known[c] for c in wanted)), scratch)
    else:
        known = {s.id for s in src.manifest.cases}
        for case in wanted:
            if case not in known:
                raise RawFileChanged(f"case {case} is no longer in {ctx.rel(src.manifest_path)}")
        run_step("ingest", scratch, settings, raw_dir=src.campaign_dir, cases=wanted)   # the build's own step
        name_as_recorded(ctx, src, CampaignFolder.at(scratch))
    check_hashes(ctx, src, CampaignFolder.at(scratch).ingested_cases(), expected or {})
    if validate:
        write_validated(scratch, sample_rate_tolerance=settings.sample_rate_tolerance, gap_tolerance=settings.gap)
    return scratch


def name_as_recorded(ctx: Context, src: RawSource, folder: CampaignFolder) -> None:
    """Re-ingested cases' raw files named as the pipeline named them (:func:`recorded_name`), in the scratch
    folder's ingest table: what the re-derived rows carry is then compared with the stored rows as it is."""
    cases = folder.ingested_cases()
    cases["raw_file"] = [recorded_name(ctx, str(f), src.recorded_row(str(c)))
                         for c, f in zip(cases["case"], cases["raw_file"], strict=True)]
    write_parquet(tables.validate_table(cases, tables.CASES), folder.ingest_path("cases"))


def recorded_name(ctx: Context, raw_file: str, recorded_row) -> str:
    """A re-ingested case's raw file named as the pipeline named it (the recorded row's ``raw_file``) where both
    are the same file, else as re-ingest names it."""
    recorded = "" if recorded_row is None else str(recorded_row["raw_file"] or "")
    if recorded and raw_file and ctx.resolve(recorded).resolve() == Path(raw_file).resolve():
        return recorded
    return raw_file


def check_hashes(ctx: Context, src: RawSource, new_cases: pd.DataFrame, expected: Mapping[str, str]) -> None:
    """Every re-derived raw hash against the recorded ones; RawFileChanged / MissingFile on a difference."""
    lines, changed, files = [], [], []
    for row in new_cases.itertuples(index=False):
        case, sha = str(row.case), str(row.raw_sha256)
        rec = src.recorded_row(case)
        label = str(row.raw_file) if src.kind == "raw" else f"{VIRTUAL_PREFIX}{src.name}/{case} (re-simulated CSV)"
        records = []
        if rec is not None:
            records.append((str(rec["raw_sha256"]), ctx.rel(src.recorded_path)))
        if case in expected:
            records.append((str(expected[case]), f"the traced row ({ctx.rel(ctx.table)})"))
        if src.kind == "raw" and not sha and any(r for r, _ in records):
            raise MissingFile(f"case {case}: raw file {label} not found (recorded sha256 "
                              f"{sha_text(records[0][0])} in {records[0][1]})")
        for want, where in records:
            if want != sha:
                changed.append(f"case {case}: {label} has sha256 {sha_text(sha)} now, {sha_text(want)} "
                               f"recorded in {where}")
                if label not in files:
                    files.append(label)
        if records:
            lines.append(f"{case}: {label}  sha256 {sha_text(sha)} = recorded ({', '.join(w for _, w in records)})")
        else:
            lines.append(f"{case}: {label}  sha256 {sha_text(sha)} (nothing recorded to check against)")
    verb = "Re-read" if src.kind == "raw" else "Re-simulated"
    if changed:
        ctx.report.step(f"{verb} {len(new_cases)} case(s): raw sha256 DIFFERS from the record", *changed)
        if src.kind == "raw":
            what = f"{', '.join(files)} changed after processing"
        else:
            what = (f"the re-simulated CSV of {', '.join(files)} differs from the recorded one: the virtual-rig spec "
                    f"({src.spec_where}) or the simulator changed after processing")
        raise RawFileChanged(f"{what}; nothing was recomputed from the changed data")
    if len(lines) > 3:
        lines = lines[:2] + [f"... {len(lines) - 2} more case file(s), every hash equal to the recorded one"]
    ctx.report.step(f"{verb} {len(new_cases)} case(s) and checked their raw sha256", *lines)


# ----------------------------------------------------------------------------------------------
# raw text lines (for the audit trail)
# ----------------------------------------------------------------------------------------------

class RawText:
    """The raw CSV text of a case (the file, or the exported CSV of a simulated case)."""

    def __init__(self, ctx: Context, src: RawSource, scratch: Path, case: str):
        if src.kind == "virtual":
            series = pd.read_parquet(scratch / timeseries_relpath(case))
            self.lines = case_csv(series, src.vc.measurement).splitlines()
            self.label = f"exported CSV of {VIRTUAL_PREFIX}{src.name}/{case}"
        else:
            cases = CampaignFolder.at(scratch).ingested_cases().set_index("case")
            path = ctx.resolve(str(cases.loc[case, "raw_file"]))
            self.lines = path.read_text(encoding="utf-8-sig").splitlines()
            self.label = ctx.rel(path)
        self.header = 0
        while self.header < len(self.lines) and (not self.lines[self.header].strip()
                                                 or self.lines[self.header].startswith("#")):
            self.header += 1

    def line(self, row: int) -> str:
        i = self.header + 1 + int(row)
        text = self.lines[i] if i < len(self.lines) else "(beyond the end)"
        return f"line {i + 1}: {text}"

    def header_text(self) -> str:
        return f"line {self.header + 1}: {self.lines[self.header] if self.header < len(self.lines) else ''}"


def column_mapping(src: RawSource, case: str) -> list[str]:
    """How each CSV column becomes a canonical SI column."""
    if src.kind == "virtual":
        lines = [f"{name} [{unit}] x {factor:g} -> {CANONICAL[ch]}" for ch, (name, unit, factor) in RAW_COLUMNS.items()]
        return lines + ["(the pipeline used the simulated SI series; the CSV holds the same quantised values)"]
    spec = next(s for s in src.manifest.cases if s.id == case)
    out = []
    if spec.csv is not None:
        out.append(f"read with {spec.csv.delimiter!r} between fields and {spec.csv.decimal!r} as the decimal mark "
                   "(manifest csv block)")
    for ch, col in spec.columns.items():
        conversion = si_conversion(ch, col)
        factor, offset = conversion if conversion is not None else (None, 0.0)
        how = "ISO 8601 -> seconds from the first sample" if factor is None else f"x {factor:g}"
        how += f" {offset:+g}" if offset else ""
        invert = " x (-1) (invert)" if col.invert and ch != "temperature" else ""
        out.append(f"{col.name} [{col.unit}] {how}{invert} -> {CANONICAL[ch]}")
    return out

