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


def calibration_proposal(groups: Sequence[tuple[str, Sequence]], declared: tuple[float, float] | None
                         ) -> tuple[list[dict], dict[str, float], dict[str, str]]:
    """(the ``calibrations`` entries, {group: the calibration's Δχ² credited before the cases are chosen},
    {gain group: why no calibration is proposed for it}) of the groups (name, readings). One calibration of
    CALIBRATION_UNCERTAINTY_REL serves every group holding ``force_gain``; proposed where it separates one by at least
    RESOLVES_MIN_SE, unless the campaign ``declared`` one at least as tight."""
    gain_groups = [(name, rs) for name, rs in groups
                   if "force_gain" in name.split("+") and "displacement_scale" not in name.split("+")]
    if not gain_groups:
        return [], {}, {}
    if declared is not None and declared[1] <= CALIBRATION_UNCERTAINTY_REL:
        why = (f"the campaign's declared load-cell calibration (±{declared[1] * 100:.2g} %) holds the gain: a further "
               "calibration would not separate it")
        return [], {}, {name: why for name, _ in gain_groups}
    centre = 1.0 if declared is None else declared[0]
    se = {name: calibration_se(rs, centre) for name, rs in gain_groups}
    resolves = [g for g, s in se.items() if s >= RESOLVES_MIN_SE]
    if not resolves:
        why = (f"its readings' load-cell gains differ by less than {CALIBRATION_UNCERTAINTY_REL * 100:.2g} %: "
               "a calibration of the load cell would not separate them either")
        return [], {}, dict.fromkeys(se, why)
    entry = {"check": CHECK, "channel": "force", "uncertainty_rel": CALIBRATION_UNCERTAINTY_REL,
             "rig_time_s": CALIBRATION_RIG_TIME_S, "resolves": resolves, "separation_se": max(se.values()),
             "separation_se_by_group": se, "how": HOW}
    return [entry], {g: s * s for g, s in se.items()}, {}


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
    """(the LVDT calibration's entries, {group: its Δχ² credited before the cases are chosen}, {scale group: why none
    is proposed}) of the groups (name, readings; a family no case separates as its two readings). One calibration of
    LVDT_UNCERTAINTY_REL serves every group holding ``displacement_scale`` and resolves each (a declared one makes the
    scale measured), unless the campaign ``declared`` one at least as tight."""
    scale_groups = [(name, rs) for name, rs in groups if "displacement_scale" in name.split("+")]
    if not scale_groups:
        return [], {}, {}
    if declared is not None and declared[1] <= LVDT_UNCERTAINTY_REL:
        why = (f"the campaign's declared LVDT calibration (±{declared[1] * 100:.2g} %) holds the scale: a further "
               "calibration would not separate it")
        return [], {}, {name: why for name, _ in scale_groups}
    centre = 1.0 if declared is None else declared[0]
    se = {name: least_separated([reading_scale(r, centre) for r in rs], LVDT_UNCERTAINTY_REL)
          for name, rs in scale_groups}
    entry = {"check": LVDT_CHECK, "channel": "displacement", "uncertainty_rel": LVDT_UNCERTAINTY_REL,
             "rig_time_s": LVDT_RIG_TIME_S, "resolves": list(se), "separation_se": max(se.values()),
             "separation_se_by_group": se, "how": LVDT_HOW}
    return [entry], {g: s * s for g, s in se.items()}, {}


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
