"""Raw ingest of case files in a declared dialect (manifest ``csv`` block, format 1.1): a spreadsheet
export with ';' between fields and decimal commas (or tabs, or '|') gives the same SI series as the
same data written with ',' and '.', and every hostile-input check still names its row and column."""

from __future__ import annotations

import codecs
import csv
import shutil
from pathlib import Path

import pandas as pd
import pytest
import yaml

from conftest import CAMPAIGN, CASE_IDS, assert_quarantine, assert_rest_unchanged, data_line
from isokinetic.contracts.campaign_folder import CampaignFolder
from isokinetic.stages.ingest import ingest_campaign
from isokinetic.stages.virtual_rig import VirtualCampaign, export_raw_campaign
from testconfig import TEST_CONFIG as CONFIG

EXPORTED_CASES = ("T22", "H01")
W = "campaign demo, case"
HINT = ": set `encoding:` in the manifest's csv block (for example cp1252)"


def respell(text: str, delimiter: str, decimal: str) -> str:
    """A ',' and '.' CSV text in another dialect: fields joined by ``delimiter``, '.' in the data rows
    replaced by ``decimal``; comment lines, blank lines and the header's names kept."""
    out, header_seen = [], False
    for line in text.split("\n"):
        if not line.strip() or line.startswith("#"):
            out.append(line)
            continue
        fields = next(csv.reader([line]))
        if header_seen:
            fields = [f.replace(".", decimal) for f in fields]
        header_seen = True
        out.append(delimiter.join(fields))
    return "\n".join(out)


def respell_campaign(raw_dir: Path, delimiter: str, decimal: str, cases=None, declare: bool = True) -> None:
    """Rewrite the case files of a raw campaign (``cases``: default every CSV) in a dialect and, with
    ``declare``, add the manifest's csv block."""
    for path in sorted(raw_dir.glob("*.csv")):
        if cases is None or path.stem in cases:
            path.write_text(respell(path.read_text(encoding="utf-8"), delimiter, decimal), encoding="utf-8")
    if declare:
        manifest_file = raw_dir / "campaign.yaml"
        manifest = yaml.safe_load(manifest_file.read_text(encoding="utf-8"))
        manifest["csv"] = {"delimiter": delimiter, "decimal": decimal}
        manifest_file.write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")


# --- a campaign exported by the virtual rig -------------------------------------------------------

@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """Two cases of the paper campaign (a triangle and a sine) exported at 50 Hz, ',' and '.'."""
    spec = yaml.safe_load(CONFIG.read_text(encoding="utf-8"))["virtual_campaigns"]["paper-lag-damper"]
    vc = VirtualCampaign.from_config("paper-lag-damper", spec)
    return export_raw_campaign(vc, tmp_path_factory.mktemp("export") / "lag", cases=list(EXPORTED_CASES),
                               sample_rate_Hz=50.0)


@pytest.fixture(scope="module")
def exported_ingested(exported, tmp_path_factory):
    root = tmp_path_factory.mktemp("exported") / "lag"
    ingest_campaign(exported, root)
    return CampaignFolder.at(root)


@pytest.mark.parametrize("delimiter, decimal", [(";", ","), ("\t", "."), ("\t", ","), ("|", ",")],
                         ids=["semicolon-decimal-comma", "tab", "tab-decimal-comma", "pipe-decimal-comma"])
def test_exported_campaign_in_another_dialect_gives_the_same_si_series(exported, exported_ingested, tmp_path,
                                                                       delimiter, decimal):
    raw_dir = tmp_path / "raw" / "lag"
    shutil.copytree(exported, raw_dir)
    respell_campaign(raw_dir, delimiter, decimal)
    first = (raw_dir / "T22.csv").read_text(encoding="utf-8").split("\n")[:2]
    assert first[0] == delimiter.join(["time_s", "disp_mm", "force_kN", "cmd_mm"])
    assert first[1].count(delimiter) == 3 and ("." in first[1]) == (decimal == ".")   # really respelled
    ingest_campaign(raw_dir, tmp_path / "results")
    got = CampaignFolder.at(tmp_path / "results")
    assert got.ingested_quarantine().empty and (got.ingested_cases()["status"] == "ok").all()
    for case in EXPORTED_CASES:
        pd.testing.assert_frame_equal(got.timeseries(case), exported_ingested.timeseries(case), check_exact=True)
    raw = ["raw_file", "raw_sha256"]
    pd.testing.assert_frame_equal(got.ingested_cases().drop(columns=raw),
                                  exported_ingested.ingested_cases().drop(columns=raw))
    assert got.meta.csv == {"format": "delimited", "delimiter": delimiter, "decimal": decimal, "encoding": "utf-8",
                               "units_row": False}
    assert exported_ingested.meta.csv is None


# --- the fixture campaign as a ';' and ',' spreadsheet export ---------------------------------------

def check(campaign, baseline, cases, quarantine, case, column, row, reason):
    """Exactly one quarantine row (stage ingest) with this reason; every other case, read in the declared
    dialect, identical to the ',' and '.' baseline."""
    assert_quarantine(campaign, cases, quarantine, [(CAMPAIGN, case, "ingest", column, row)])
    assert quarantine["reason"].tolist() == [reason]
    assert_rest_unchanged(campaign, cases, baseline, {case})


def test_semicolon_decimal_comma_campaign_matches_the_baseline(raw_campaign, baseline):
    """Every fixture case (comment lines, reversed columns in T02, an inverted force in T03, a sine,
    a free record) respelled with ';' and ','; F01 with a UTF-8 byte-order mark as well."""
    respell_campaign(raw_campaign.raw_dir, ";", ",")
    f01 = raw_campaign.raw_dir / "F01.csv"
    f01.write_bytes(codecs.BOM_UTF8 + f01.read_bytes())
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty
    assert_rest_unchanged(raw_campaign, cases, baseline, set())
    assert CampaignFolder.at(raw_campaign.root).meta.csv == {"format": "delimited", "delimiter": ";", "decimal": ",",
                                                            "encoding": "utf-8", "units_row": False}


def test_spreadsheet_export_without_csv_block_keeps_the_format_message(raw_campaign):
    respell_campaign(raw_campaign.raw_dir, ";", ",", declare=False)
    cases, quarantine = raw_campaign.run()
    assert_quarantine(raw_campaign, cases, quarantine, [(CAMPAIGN, case, "ingest", "file", None) for case in CASE_IDS])
    header = "'time_s;disp_mm;force_kN;cmd_mm;temp_C'"           # T01's
    assert quarantine["reason"].iloc[0] == (
        f"{W} T01, key 'file': fields are separated by ';', not ',' (header {header}): the format needs ',' "
        "between fields and '.' as the decimal mark")
    assert CampaignFolder.at(raw_campaign.root).meta.csv is None


def _edit_row(case: str, row: int, edit):
    """A byte edit of data row ``row`` of a ';' fixture file: ``edit(fields) -> fields``."""
    def apply(data: bytes) -> bytes:
        lines = data.split(b"\n")
        i = data_line(data, row)
        lines[i] = b";".join(edit(lines[i].split(b";")))
        return b"\n".join(lines)
    return case, apply


def _set_field(index: int, value: bytes):
    def edit(fields):
        fields[index] = value
        return fields
    return edit


def _edit_rows(case: str, rows, edit):
    """:func:`_edit_row` on every row of ``rows`` (more than a partial record's damage: refused, naming the first)."""
    def apply(data: bytes) -> bytes:
        for row in rows:
            data = _edit_row(case, row, edit)[1](data)
        return data
    return case, apply


DOT_NOTE = (": the manifest's csv block declares ',' as the decimal mark, and a '.' is not read (a thousands "
            "separator? declare `thousands: '.'` in the csv block; a file written with '.' decimals?)")


@pytest.mark.parametrize("edit, case, column, row, message", [
    (_edit_row("T01", 7, lambda f: f[:-1]), "T01", "temp_C", 7, "row ends after 4 of 5 fields: a ragged row"),
    (_edit_row("T01", 7, lambda f: f + [b"1"]), "T01", "file", 7, "row has 6 fields, the header 5"),
    (_edit_rows("H01", range(3, 13), _set_field(1, b"0.25")), "H01", "disp_mm", 3,
     "non-numeric value '0.25'" + DOT_NOTE),
    (_edit_rows("H01", range(3, 13), _set_field(1, b"0,2,5")), "H01", "disp_mm", 3, "non-numeric value '0,2,5'"),
    (_edit_row("T02", 30, _set_field(2, b"0,5\xb5")), "T02", "force_kN", 30,
     "not UTF-8: byte 0xb5 in b'0,5\\xb5'" + HINT),
], ids=["ragged", "extra-field", "dot-decimal", "two-commas", "not-utf8"])
def test_damage_in_a_semicolon_file_names_row_and_column(raw_campaign, baseline, edit, case, column, row, message):
    respell_campaign(raw_campaign.raw_dir, ";", ",")
    name, apply = edit
    path = raw_campaign.raw_dir / f"{name}.csv"
    path.write_bytes(apply(path.read_bytes()))
    cases, quarantine = raw_campaign.run()
    where = f"{W} {case}, " + (f"key {column!r}" if column == "file" else f"column {column!r}")
    check(raw_campaign, baseline, cases, quarantine, case, column, row, f"{where}, row {row}: {message}")


def test_file_not_in_the_declared_dialect_is_set_aside(raw_campaign, baseline):
    respell_campaign(raw_campaign.raw_dir, ";", ",", cases=set(CASE_IDS) - {"H01"})   # H01 left as ',' and '.'
    cases, quarantine = raw_campaign.run()
    check(raw_campaign, baseline, cases, quarantine, "H01", "file", None,
          f"{W} H01, key 'file': fields are separated by ',', not ';' as the manifest's csv block declares "
          "(header 'time_s,disp_mm,force_kN,cmd_mm,temp_C')")


def _stamp_campaign(name: str, text: str, csv_block: dict | None) -> Path:
    """A one-case free campaign at ``data/raw/<name>`` with ISO 8601 time stamps."""
    raw_dir = Path("data", "raw", name)
    raw_dir.mkdir(parents=True)
    manifest = {"format_version": 1, "campaign": name, "sample_rate_Hz": 100.0,
                "columns": {"time": {"name": "stamp", "unit": "datetime"},
                            "displacement": {"name": "disp_mm", "unit": "mm"},
                            "force": {"name": "force_kN", "unit": "kN"}},
                "cases": [{"id": "C1", "waveform": "free", "file": "C1.csv"}]}
    if csv_block is not None:
        manifest["csv"] = csv_block
    (raw_dir / "campaign.yaml").write_text(yaml.safe_dump(manifest), encoding="utf-8")
    (raw_dir / "C1.csv").write_text(text, encoding="utf-8")
    return raw_dir


def test_time_stamps_with_decimal_comma_seconds(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    stamps = pd.date_range("2025-03-01T10:59:59.95", periods=12, freq="10ms")
    text = "stamp,disp_mm,force_kN\n" + "".join(f"{s.isoformat()}Z,{k * 0.1:.1f},{k * 0.25:.2f}\n"
                                                 for k, s in enumerate(stamps))
    ingest_campaign(_stamp_campaign("dots", text, None), "results/dots")
    spelled = respell(text, ";", ",")
    assert "10:59:59,960000Z;0,1;0,25" in spelled                 # ISO 8601's decimal comma in the seconds
    ingest_campaign(_stamp_campaign("commas", spelled, {"delimiter": ";", "decimal": ","}), "results/commas")
    dots, commas = CampaignFolder.at("results/dots"), CampaignFolder.at("results/commas")
    assert dots.ingested_quarantine().empty and commas.ingested_quarantine().empty
    pd.testing.assert_frame_equal(commas.timeseries("C1"), dots.timeseries("C1"), check_exact=True)
    assert commas.timeseries("C1")["time_s"].iloc[-1] == pytest.approx(0.11)


def _grouped(value: float, decimals: int) -> str:
    """``value`` written as a German spreadsheet does: '.' between thousands, ',' as the decimal mark."""
    return f"{value:,.{decimals}f}".replace(",", "_").replace(".", ",").replace("_", ".")


def _force_in_mN(raw_campaign, decimals: int, csv_block: dict) -> None:
    """Every case's force column rewritten in mN with thousands separators (``273.239,531``), ';' and ','."""
    respell_campaign(raw_campaign.raw_dir, ";", ",")
    for path in sorted(raw_campaign.raw_dir.glob("*.csv")):
        lines = path.read_text(encoding="utf-8").split("\n")
        k = next(i for i, line in enumerate(lines) if line and not line.startswith("#"))
        names = lines[k].split(";")
        force = next(i for i, n in enumerate(names) if n.startswith("force"))
        names[force] = names[force].replace("_kN", "_mN")
        lines[k] = ";".join(names)
        for i in range(k + 1, len(lines)):
            if lines[i]:
                fields = lines[i].split(";")
                fields[force] = _grouped(float(fields[force].replace(",", ".")) * 1e6, decimals)
                lines[i] = ";".join(fields)
        path.write_text("\n".join(lines), encoding="utf-8")

    def edit(m):
        m["csv"] = csv_block
        m["columns"]["force"] = {"name": "force_mN", "unit": "mN"}
        raw_campaign.case_entry(m, "T03")["columns"]["force"]["name"] = "force_inv_mN"
    raw_campaign.edit_manifest(edit)


def _same_forces(raw_campaign, baseline) -> None:
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    for row in cases.itertuples():
        series = pd.read_parquet(raw_campaign.root / row.timeseries_file)
        pd.testing.assert_frame_equal(series, baseline[row.case], check_exact=False, rtol=1e-9)


def test_thousands_separators_are_read_where_unambiguous(raw_campaign, baseline):
    """``273.239,5310000`` under a decimal comma: a '.' before three digits and a decimal part can only group thousands
    (before: "non-numeric value", the case set aside)."""
    _force_in_mN(raw_campaign, 7, {"delimiter": ";", "decimal": ","})
    assert "." in (raw_campaign.raw_dir / "T01.csv").read_text(encoding="utf-8").split("\n")[4].split(";")[2]
    _same_forces(raw_campaign, baseline)


def test_declared_thousands_separator_reads_whole_numbers(raw_campaign, baseline):
    """``273.240`` (whole mN) under a decimal comma is ambiguous: read as 273240 only with `thousands: '.'`."""
    _force_in_mN(raw_campaign, 0, {"delimiter": ";", "decimal": ","})
    cases, quarantine = raw_campaign.run()
    assert set(quarantine["case"]) == {"T01", "T02", "T03", "H01", "F01"}
    assert "declare `thousands: '.'` in the csv block" in quarantine["reason"].iloc[0]
    raw_campaign.edit_manifest(lambda m: m["csv"].update(thousands="."))
    cases, quarantine = raw_campaign.run()
    assert quarantine.empty, quarantine["reason"].tolist()
    for row in cases.itertuples():           # whole mN: within half a mN of the baseline's force
        series = pd.read_parquet(raw_campaign.root / row.timeseries_file)
        assert (series["force_N"] - baseline[row.case]["force_N"]).abs().max() <= 5.0001e-4
