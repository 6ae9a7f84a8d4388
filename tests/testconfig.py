"""The tests' own configuration, ``.test/config/config.yaml`` (the Snakemake catalog's convention).

Tests build from it, never from the user-editable ``config/config.yaml``: a user's edit there changes no test.
"""

from pathlib import Path

import yaml

TEST_CONFIG = Path(__file__).resolve().parents[1] / ".test" / "config" / "config.yaml"


def load_test_config() -> dict:
    """The whole test configuration."""
    return yaml.safe_load(TEST_CONFIG.read_text(encoding="utf-8"))


def paper_campaign() -> dict:
    """The virtual campaign ``paper-lag-damper`` of the test configuration (the paper's damper and plan)."""
    return load_test_config()["virtual_campaigns"]["paper-lag-damper"]
