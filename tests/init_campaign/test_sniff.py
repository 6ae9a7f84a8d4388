"""A case file's columns as numbers or seconds from ISO 8601 stamps (init_campaign.sniff.parse_column)."""

from __future__ import annotations

import pandas as pd

from isokinetic.init_campaign.sniff import parse_column


def test_columns_are_read_as_numbers_in_the_files_decimal_mark():
    column = parse_column("disp_mm", pd.Series(["-1,2200", "-1,2195", "-1,2190"]), ",")
    assert column.numbers.tolist() == [-1.22, -1.2195, -1.219] and column.stamps_s is None


def test_iso_stamps_are_read_as_seconds():
    stamps = parse_column("stamp", pd.Series(["2024-05-01T10:00:00.00", "2024-05-01T10:00:00.25"]), ".")
    assert stamps.numbers is None and stamps.stamps_s.tolist() == [0.0, 0.25]
