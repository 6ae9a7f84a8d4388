"""refused: a campaign whose outputs cannot be replaced, or whose raw folder leads out, is refused alone."""

from __future__ import annotations

import os
import subprocess

import pytest

from isokinetic.audit.refused import CampaignRefused, refusal, refuse, unwritable_paths


def write_protect(path):
    """Make ``path`` unwritable for this process: chattr +i as root (root ignores modes), else chmod a-w."""
    if os.geteuid() == 0:
        if subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode != 0:
            pytest.skip("chattr +i is not available here")
    else:
        path.chmod(0o555 if path.is_dir() else 0o444)


def release(path):
    if os.geteuid() == 0:
        subprocess.run(["chattr", "-i", str(path)], capture_output=True)
    path.chmod(0o755 if path.is_dir() else 0o644)


@pytest.fixture
def outputs(tmp_path):
    """results/c/ and logs/c/ with a few files; every protection undone afterwards."""
    for rel in ("results/c/cases.parquet", "results/c/ingest/campaign.json", "logs/c/ingest.log"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("x", encoding="utf-8")
    protected = []
    yield tmp_path, protected
    for path in protected:
        release(path)


def test_writable_outputs_are_no_reason_to_refuse(outputs):
    work, _ = outputs
    assert unwritable_paths([work / "results/c", work / "logs/c", work / "results/absent"]) == []
    assert refusal("c", None, work / "results", work / "logs") is None


def test_a_write_protected_output_file_or_folder_refuses_the_campaign(outputs):
    work, protected = outputs
    for rel in ("results/c/cases.parquet", "logs/c"):
        protected.append(work / rel)
        write_protect(work / rel)
    assert unwritable_paths([work / "results/c", work / "logs/c"]) == [
        (work / "logs/c").as_posix(), (work / "results/c/cases.parquet").as_posix()]
    reason = refusal("c", None, work / "results", work / "logs")
    assert reason.startswith("2 existing output(s) cannot be replaced (write-protected): ")
    assert "results/c/cases.parquet" in reason and "chmod -R u+w" in reason


def test_a_refused_campaign_job_raises_naming_campaign_and_reason():
    with pytest.raises(CampaignRefused, match="^campaign c refused: because$"):
        refuse("c", "because")
