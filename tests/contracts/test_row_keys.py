"""Row keys of the lineage columns (isokinetic.contracts.row_keys)."""

import pandas as pd

from isokinetic.contracts.row_keys import parse_row_keys, row_keys


def test_row_keys_round_trip():
    df = pd.DataFrame({"case": ["T01", "T01", "T2.b", "T01"], "segment": [1, 3, 2, 1]})
    text = row_keys(df)
    assert text == "T01/1,T01/3,T2.b/2"
    assert parse_row_keys(text) == [("T01", 1), ("T01", 3), ("T2.b", 2)]
    assert parse_row_keys("") == []
