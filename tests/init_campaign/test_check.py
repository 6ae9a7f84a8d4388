"""``init-campaign --check``: a folder against its manifest, case by case; exit status 1 on any disagreement."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import yaml

from isokinetic.__main__ import main
from isokinetic.init_campaign.check import check_folder


def edit_manifest(folder: Path, edit) -> None:
    path = folder / "campaign.yaml"
    manifest = yaml.safe_load(path.read_text(encoding="utf-8"))
    edit(manifest)
    path.write_text(yaml.safe_dump(manifest, sort_keys=False), encoding="utf-8")


def case(manifest: dict, case_id: str) -> dict:
    return next(c for c in manifest["cases"] if c["id"] == case_id)


def findings(folder: Path) -> dict[str, list[str]]:
    checks, _ = check_folder(folder)
    return {c.case: [f.key for f in c.findings] for c in checks}


def test_check_agrees_with_the_exported_campaign(campaign_copy, capsys):
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 0
    out = capsys.readouterr().out
    assert "T16 (T16.csv): agrees: triangle, period 20 s, amplitude 1.22 mm, 100 Hz" in out
    assert "H01 (H01.csv): agrees: sine, 1.75 Hz, amplitude 0.23 mm, 1000 Hz" in out
    assert "3 of 3 cases agree" in out


def test_check_reports_a_wrong_period(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: case(m, "T16").update(period_s=20.1))
    assert findings(campaign_copy) == {"T16": ["period_s"], "T22": [], "H01": []}
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    assert "  period_s: planned 20.1, detected 20 ± " in capsys.readouterr().out


def test_check_reports_a_unit_the_magnitudes_contradict(campaign_copy, capsys):
    edit_manifest(campaign_copy, lambda m: m["columns"]["force"].update(unit="N"))
    assert findings(campaign_copy) == {"T16": ["columns.force"], "T22": ["columns.force"], "H01": ["columns.force"]}
    assert main(["init-campaign", "--check", str(campaign_copy)]) == 1
    assert "columns.force: declared 'force_kN' in N, detected magnitudes that look like kN" in capsys.readouterr().out


def test_check_reports_a_displacement_declared_in_m_that_looks_like_mm(campaign_copy):
    edit_manifest(campaign_copy, lambda m: m["columns"]["displacement"].update(unit="m"))
    assert all("columns.displacement" in keys for keys in findings(campaign_copy).values())


def test_check_reports_a_wrong_waveform_amplitude_and_sample_rate(campaign_copy):
    def edit(m):
        h01 = case(m, "H01")
        h01.update(waveform="triangle", period_s=0.5714)
        del h01["frequency_Hz"]
        case(m, "T22").update(amplitude_mm=6.0)
        m["sample_rate_Hz"] = 50.0
    edit_manifest(campaign_copy, edit)
    assert findings(campaign_copy) == {"T16": ["sample_rate_Hz"], "T22": ["sample_rate_Hz", "amplitude_mm"],
                                       "H01": ["waveform"]}


def test_check_reports_a_file_ingest_would_refuse(campaign_copy):
    (campaign_copy / "T22.csv").write_text("time_s;disp_mm\n0;1\n", encoding="utf-8")
    assert findings(campaign_copy)["T22"] == ["file"]


def test_check_piped_into_a_reader_that_stops_early_ends_quietly(campaign_copy):
    # `init-campaign FOLDER --check | head -1`: the read end is closed before the command prints
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        proc = subprocess.run([sys.executable, "-m", "isokinetic", "init-campaign", str(campaign_copy), "--check"],
                              stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 1


def test_check_reports_columns_other_than_the_role_choice_takes(campaign_copy):
    def swap(m):
        m["columns"]["displacement"], m["columns"]["command"] = m["columns"]["command"], m["columns"]["displacement"]
    edit_manifest(campaign_copy, swap)
    for keys in findings(campaign_copy).values():
        assert {"columns.displacement", "columns.command"} <= set(keys)
