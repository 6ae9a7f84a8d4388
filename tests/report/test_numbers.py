"""Numbers as the pages show them."""

from __future__ import annotations

import numpy as np

from isokinetic.report import numbers


def test_numbers_are_formatted_for_reading():
    assert numbers.fmt_text(4309.893) == "4310"
    assert numbers.fmt_text(0.959494) == "0.9595"
    assert numbers.fmt_text(2.1998e-12) == "2.200e-12"
    assert numbers.fmt(2.1998e-12) == "2.200&#8239;&times;&#8239;10<sup>-12</sup>"
    assert numbers.fmt_text(float("nan")) == "-" and numbers.fmt_text(None) == "-"
    assert numbers.fmt_text(np.int64(501)) == "501" and numbers.fmt_text(True) == "yes"
    assert numbers.fmt_pct(-0.4321) == "-43.2 %"
    assert numbers.formula("A_O^2") == "A<sub>O</sub><sup>2</sup>"
