"""Row keys: the compact text naming the rows a result comes from (lineage of a table row).

``row_keys`` writes 'T01/1,T01/2,T02/1' (values joined by '/', rows by ','), ``parse_row_keys`` reads it
back; a contract between the stages that write ``source_rows`` columns and the audit that follows them.
"""

from __future__ import annotations

from collections.abc import Iterable


def row_keys(frame, columns: Iterable[str] = ("case", "segment")) -> str:
    """Compact explicit list of row keys: 'T01/1,T01/2,T02/1' (values joined by '/', rows by ',').

    Case ids cannot hold '/' or ',' (manifest.CASE_ID_RULE), so the text parses back unambiguously
    (:func:`parse_row_keys`). Rows keep the frame's order; duplicates are dropped.
    """
    columns = list(columns)
    seen, keys = set(), []
    for values in frame[columns].itertuples(index=False, name=None):
        key = "/".join(str(v) for v in values)
        if key not in seen:
            seen.add(key)
            keys.append(key)
    return ",".join(keys)


def parse_row_keys(text: str) -> list[tuple[str, int]]:
    """(case, segment) pairs of a :func:`row_keys` text over ('case', 'segment')."""
    out = []
    for key in filter(None, (text or "").split(",")):
        case, _, segment = key.rpartition("/")
        out.append((case, int(segment)))
    return out
