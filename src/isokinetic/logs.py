"""Logging for pipeline jobs: one log file per rule and campaign."""

from __future__ import annotations

import logging
import sys

LOGGER_NAME = "isokinetic"


def log_to_file(path: str) -> logging.Logger:
    """Send the package's log records to ``path`` (and warnings to stderr) for one job."""
    logger = logging.getLogger(LOGGER_NAME)
    logger.setLevel(logging.INFO)
    for handler in list(logger.handlers):
        logger.removeHandler(handler)
    fmt = logging.Formatter("%(asctime)s %(levelname)s %(message)s")
    to_file = logging.FileHandler(path, mode="w", encoding="utf-8")
    to_file.setFormatter(fmt)
    to_stderr = logging.StreamHandler(sys.stderr)
    to_stderr.setLevel(logging.WARNING)
    to_stderr.setFormatter(fmt)
    logger.addHandler(to_file)
    logger.addHandler(to_stderr)
    logging.captureWarnings(True)
    return logger
