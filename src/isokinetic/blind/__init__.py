"""The blind suite: the diagnosis tested on campaigns whose effects it is not told.

Scenarios are drawn on the independent reference rig (:mod:`isokinetic.reference`) at multiples of each
effect's detection level (:mod:`~isokinetic.blind.generate`), some with effects that hide from the steady
characteristic (:mod:`~isokinetic.blind.hidden`); a mixed triangle-and-sine campaign is built alike
(:mod:`~isokinetic.blind.mixed`); the verdicts are scored against the withheld truth
(:mod:`~isokinetic.blind.score`). The rules' runners are :mod:`isokinetic.stages.blind_generate`,
:mod:`isokinetic.stages.blind_diagnose` (which runs each scenario through the build's own chain) and
:mod:`isokinetic.stages.blind_score`. The package sits beside the diagnosis and the figures: below the stages,
above measurement, physics, contracts and the reference rig.
"""
