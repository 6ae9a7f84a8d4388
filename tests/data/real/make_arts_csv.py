"""How the ARTS-Laboratory friction-damper CSVs of this folder were made (run by hand, never by the tests).

Usage: ``python make_arts_csv.py <dataset json> <stop time s> <out csv>``, e.g. from a clone of
https://github.com/ARTS-Laboratory/Dataset-Friction-Damper-with-Backlash at commit
0e09aa9d950760277e31c08cd93fd01f39a5af09::

    python make_arts_csv.py "<clone>/data/dataset-3/characterization tests/2Hz30lbtension0.5amplitude.json" 2.5 \
        arts-friction-damper/2Hz30lbtension0.5amplitude.csv

The JSON's ``data`` matrix (columns per the data set's data/README.md) is written as CSV, its rows from the
first up to and including the last whose time is <= the stop time (a contiguous span from the start: the
ramp-in and the first steady cycles; no sample dropped, none resampled). Header: the data set's own column
names and units. Values are not rescaled (inches, kip, in/s, lb as in the JSON); time is written exactly
(multiples of 1/1024 s), the other values with 7 significant digits, far finer than each channel's
quantisation step (displacement 5.9e-5 in, friction force 8.0e-4 kip, actuator forces 0.32 lb).
"""

import json
import sys
from pathlib import Path

HEADER = ("time (s)", "displacement (in)", "friction force (kip)", "velocity (in/s)", "actuator force 1 (lb)",
          "actuator force 2 (lb)")


def rows_until(data: list[list[float]], stop_s: float) -> list[list[float]]:
    """The rows from the first up to the last whose time is <= ``stop_s``."""
    out = []
    for row in data:
        if row[0] > stop_s:
            break
        out.append(row)
    return out


def main(source: str, stop_s: str, out: str) -> None:
    data = json.loads(Path(source).read_text(encoding="utf-8"))["data"]
    lines = [",".join(HEADER)]
    for row in rows_until(data, float(stop_s)):
        if len(row) != len(HEADER):
            raise ValueError(f"row of {len(row)} values, expected {len(HEADER)}")
        lines.append(",".join([repr(float(row[0]))] + [f"{v:.7g}" for v in row[1:]]))
    Path(out).write_bytes(("\n".join(lines) + "\n").encode("ascii"))


if __name__ == "__main__":
    main(*sys.argv[1:])
