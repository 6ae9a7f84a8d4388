"""The next test of a sensor (issue 37): a calibration of the load cell against a reference force, or of the LVDT
against a reference displacement, proposed beside the cases of :mod:`isokinetic.diagnosis.next_tests` where a
confounded group holds the load cell's gain, or the LVDT's scale without a command channel.

Why a calibration and not a case: a gain g scales every force the load cell reads, as a discharge coefficient with
a viscosity together do; the two readings of such a group differ only in the compressibility transients, which the
fitted force-channel lag takes up in part, so no case within the rig's limits separates them (on the reference
rig's campaign built for it, 1.5 SE now and 2.2 SE with two cases). A calibration measures g itself: the group's
readings predict it at g_A and g_B (a reading with the gain held: the campaign's declared centre, else 1), so a
calibration of relative standard uncertainty u tells them apart by |g_A − g_B|/u standard errors
(:func:`calibration_se`). It is independent of the campaign's records: its χ² adds to the cases'
(:func:`calibration_proposal`'s credits).

Not for a group holding the LVDT's scale (``displacement_scale``, no command channel): there the diagnosis lists
the scale's confounding whatever it measures, for its model has no scale term to hold a calibrated load cell
against (its gain 1/k is the LVDT's only inside the next test's readings); the LVDT's calibration
(:func:`lvdt_proposal`) or a command channel decides. A calibration proposed there would promise a separation no
re-diagnosis delivers (on the reference rig's LVDT 1.2 % long without a command channel: 12.9 SE expected, still
listed).

The LVDT's scale (issue 37): a group holding ``displacement_scale`` (no command channel) gets a calibration of the
LVDT against a reference displacement instead (:func:`lvdt_proposal`). Its readings predict the LVDT's scale at
k_A and k_B (the verdict's reading: the scale its model was driven at, the declared one, else 1; the scale reading:
its k, :func:`reading_scale`; of the family no case separates, where no readings are built, 1/g of the verdict's
fitted gain g), so a calibration of relative standard uncertainty u separates them by |k_A − k_B|/u SE, credited to
the group as the load cell's. Whatever that separation, it resolves the group's listing: a declared LVDT
calibration makes the scale measured, and the diagnosis then lists no scale group.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

#: Relative standard uncertainty (1 σ) of the proposed calibration (stated, not measured here): a reference load cell
#: of ISO 376 class 00 or 0.5 (reproducibility 0.05-0.1 %) mounted in series, read over load steps each way, gives
#: the working cell's gain to about 0.1 %; the groups' gains differ by about a per cent (the gain error the verdict
#: cannot tell from discharge with viscosity), so 0.1 % separates them by some ten standard errors.
CALIBRATION_UNCERTAINTY_REL = 1e-3
#: Rig time of the calibration [s]: the reference cell mounted in series with the load cell, load steps each way
#: over the campaign's force range, held until both read steadily, and the reference removed (half an hour).
CALIBRATION_RIG_TIME_S = 1800.0
CHECK = "load_cell_gain"
HOW = ("mount a reference load cell (ISO 376 class 00 or 0.5) in series with the rig's load cell; apply load steps "
       "each way over the campaign's force range; fit the rig's reading against the reference force: its slope is "
       "the gain (the load cell's reading per unit true force)")
#: A calibration "resolves" a group where it separates its readings by at least this [standard errors].
RESOLVES_MIN_SE = 1.0
#: Relative standard uncertainty (1 σ) of the proposed LVDT calibration (stated, not measured here): a micrometer
#: calibrator or gauge blocks (±1-2 µm) against the actuator's rod, read at steps over a stroke of some tens of mm
#: each way, give the LVDT's slope to about 0.1 % (its non-linearity, 0.1-0.25 % of full scale, spread over the
#: steps); the scale error no command channel can tell from a gain with discharge is about a per cent (the reference
#: rig's confounded kind: 1.2 %), so 0.1 % separates them by some ten standard errors.
LVDT_UNCERTAINTY_REL = 1e-3
#: Rig time of the LVDT calibration [s]: the damper or its rod end unpinned, the reference fixture mounted against
#: the rod, some ten steps each way over the campaign's stroke held until the LVDT reads steadily, the fixture
#: removed and the damper refitted (half an hour).
LVDT_RIG_TIME_S = 1800.0
LVDT_CHECK = "lvdt_scale"
LVDT_HOW = ("mount a reference displacement (a micrometer calibrator or gauge blocks, ±1-2 µm) against the actuator's "
            "rod; step the rod each way over the campaign's stroke; fit the LVDT's reading against the reference "
            "displacement: its slope is the scale (the LVDT's reading per unit true displacement)")
#: The calibrations' names in the plan's note, by ``check``.
NAMES = {CHECK: "a load-cell calibration against a reference force",
         LVDT_CHECK: "an LVDT calibration against a reference displacement"}


def reading_gain(reading, centre: float) -> float:
    """The load cell's gain g a reading predicts a calibration to find: its fitted gain where free, else the
    ``centre`` it was held at; an LVDT scale's reading (``scale``: its model gain 1/k is the LVDT's) the centre."""
    c = reading.candidate
    if getattr(reading, "scale", False) or "force_gain" not in c.instrument:
        return float(centre)
    return float(c.gain)


def calibration_se(readings: Sequence, centre: float = 1.0,
                   uncertainty_rel: float = CALIBRATION_UNCERTAINTY_REL) -> float:
    """The calibration's expected separation of a group's readings [SE]: its least separated pair,
    |g_A − g_B|/u."""
    return least_separated([reading_gain(r, centre) for r in readings], uncertainty_rel)


def least_separated(values: Sequence[float], uncertainty_rel: float) -> float:
    """The least separated pair of the values a group's readings predict a calibration to find [SE]:
    min |v_A − v_B|/u (0 of a single value)."""
    return min(abs(a - b) for a, b in itertools.combinations(values, 2)) / uncertainty_rel if len(values) > 1 else 0.0


def declared_calibration(obs) -> tuple[float, float] | None:
    """The campaign's declared calibration (gain, uncertainty_rel) (:attr:`Observations.force_calibration`), or
    None."""
    cal = obs.force_calibration
    return None if cal is None else (float(cal[0]), float(cal[1]))


@dataclass(frozen=True)
class SensorCheck:
    """A sensor calibration the next test can propose for the groups holding ``holds``: its ``check`` and
    ``channel`` (the ``calibrations`` entry's), its stated uncertainty and rig time, what to do (``how``), the
    words of its notes, and whether it resolves a group whatever its separation (``resolves_always``: a declared
    one makes the listing go, as an LVDT's calibration makes the scale measured) or where it separates it by
    RESOLVES_MIN_SE."""

    check: str
    channel: str
    holds: str
    uncertainty_rel: float
    rig_time_s: float
    how: str
    device: str
    quantity: str
    resolves_always: bool


LOAD_CELL = SensorCheck(CHECK, "force", "force_gain", CALIBRATION_UNCERTAINTY_REL, CALIBRATION_RIG_TIME_S, HOW,
                        "load cell", "gain", False)
LVDT = SensorCheck(LVDT_CHECK, "displacement", "displacement_scale", LVDT_UNCERTAINTY_REL, LVDT_RIG_TIME_S, LVDT_HOW,
                   "LVDT", "scale", True)


def proposal(spec: SensorCheck, groups: Sequence[tuple[str, Sequence]], declared: tuple[float, float] | None,
             value) -> tuple[list[dict], dict[str, float], dict[str, str]]:
    """(the ``calibrations`` entries of ``spec``, {group: its Δχ² credited before the cases are chosen}, {group: why
    none is proposed}) of the groups (name, readings) it decides: one calibration serves them all, its separation
    of each the least separated pair of the values its readings predict it to find (``value(reading, centre)``,
    the centre the declared value, else 1), over its uncertainty; none where the campaign ``declared`` one at least
    as tight."""
    if not groups:
        return [], {}, {}
    sensor = spec.device.replace(" ", "-")
    if declared is not None and declared[1] <= spec.uncertainty_rel:
        why = (f"the campaign's declared {sensor} calibration (±{declared[1] * 100:.2g} %) holds the {spec.quantity}: "
               "a further calibration would not separate it")
        return [], {}, {name: why for name, _ in groups}
    centre = 1.0 if declared is None else declared[0]
    se = {name: least_separated([value(r, centre) for r in rs], spec.uncertainty_rel) for name, rs in groups}
    resolves = list(se) if spec.resolves_always else [g for g, v in se.items() if v >= RESOLVES_MIN_SE]
    if not resolves:
        why = (f"its readings' {sensor} {spec.quantity}s differ by less than {spec.uncertainty_rel * 100:.2g} %: "
               f"a calibration of the {spec.device} would not separate them either")
        return [], {}, dict.fromkeys(se, why)
    entry = {"check": spec.check, "channel": spec.channel, "uncertainty_rel": spec.uncertainty_rel,
             "rig_time_s": spec.rig_time_s, "resolves": resolves, "separation_se": max(se.values()),
             "separation_se_by_group": se, "how": spec.how}
    return [entry], {g: v * v for g, v in se.items()}, {}


def calibration_proposal(groups: Sequence[tuple[str, Sequence]], declared: tuple[float, float] | None
                         ) -> tuple[list[dict], dict[str, float], dict[str, str]]:
    """The load cell's :func:`proposal` (:data:`LOAD_CELL`): every group holding ``force_gain`` but not the LVDT's
    scale (module doc), where it separates one by at least RESOLVES_MIN_SE."""
    return proposal(LOAD_CELL, [(name, rs) for name, rs in groups if "force_gain" in name.split("+")
                                and "displacement_scale" not in name.split("+")], declared, reading_gain)


def reading_scale(reading, centre: float = 1.0) -> float:
    """The LVDT's scale k a reading predicts a calibration to find: an LVDT-scale reading's (``scale``) k, its model
    gain being 1/k (:func:`isokinetic.diagnosis.next_tests.fit_scale`) on drives at the ``centre`` (the declared
    scale, else 1); every other reading the ``centre`` its model was driven at."""
    return float(centre) / float(reading.candidate.gain) if getattr(reading, "scale", False) else float(centre)


def declared_lvdt(result: Mapping) -> tuple[float, float] | None:
    """The campaign's declared LVDT calibration (scale, uncertainty_rel) as the diagnosis used it
    (``instrument_tests.displacement_scale`` with ``source`` "calibration"), or None."""
    scale = (result.get("instrument_tests") or {}).get("displacement_scale") or {}
    if scale.get("source") != "calibration" or scale.get("uncertainty_rel") is None:
        return None
    return float(scale.get("estimate") or 1.0), float(scale["uncertainty_rel"])


def lvdt_proposal(groups: Sequence[tuple[str, Sequence]], declared: tuple[float, float] | None
                  ) -> tuple[list[dict], dict[str, float], dict[str, str]]:
    """The LVDT's :func:`proposal` (:data:`LVDT`): every group holding ``displacement_scale`` (a family no case
    separates as its two readings), each resolved whatever its separation (a declared one makes the scale
    measured)."""
    return proposal(LVDT, [(name, rs) for name, rs in groups if "displacement_scale" in name.split("+")], declared,
                    reading_scale)


def proposals(groups: Sequence[tuple[str, Sequence]], family: Sequence[tuple[str, Sequence]],
              force_declared: tuple[float, float] | None, lvdt_declared: tuple[float, float] | None
              ) -> tuple[list[dict], dict[str, float], dict[str, str]]:
    """Both calibrations (entries, credits, why none) of the groups with readings and the LVDT-scale ``family`` no
    case separates: the load cell's (:func:`calibration_proposal`, not for scale groups), the LVDT's
    (:func:`lvdt_proposal`)."""
    cell, cell_credit, cell_why = calibration_proposal(groups, force_declared)
    lvdt, lvdt_credit, lvdt_why = lvdt_proposal([*groups, *family], lvdt_declared)
    credits = {g: cell_credit.get(g, 0.0) + lvdt_credit.get(g, 0.0) for g in (*cell_credit, *lvdt_credit)}
    return [*cell, *lvdt], credits, {**cell_why, **lvdt_why}


def calibration_text(entry: Mapping) -> str:
    """A calibration entry in one clause of the plan's note (an LVDT's says it resolves the listing)."""
    text = (f"{NAMES[entry['check']]} (±{entry['uncertainty_rel'] * 100:.2g} %, "
            f"{entry['rig_time_s'] / 60.0:.0f} min of rig time) separates "
            + ", ".join(f"{g} by {entry['separation_se_by_group'][g]:.1f} SE" for g in entry["resolves"]))
    if entry["check"] == LVDT_CHECK:
        text += " and, declared, resolves its listing (a calibrated LVDT's scale is measured)"
    return text
