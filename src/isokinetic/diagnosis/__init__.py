"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect causes it, how far it shrinks.

The identified steady characteristic of a campaign (the method of "A method for the identification
of hydraulic damper characteristics from steady velocity inputs", Titurus et al.) is compared with
the nominal damper model of its manifest, and the difference is attributed to a catalogue of damper
effects or declared to lie outside it. The rule ``diagnosis`` (:mod:`isokinetic.stages.diagnosis`)
runs it on a processed campaign and writes ``diagnosis.json`` (contract version 1.1, schema
``isokinetic/contracts/diagnosis.schema.json``).

Modules, in the order the method uses them:

- :mod:`~isokinetic.diagnosis.observations`: the measured window and transient-bin means, in plan
  time, with their standard errors (noise model, between-period scatter);
- :mod:`~isokinetic.diagnosis.model`: the damper model's means over the same samples
  (:class:`~isokinetic.diagnosis.model.Evaluator`), unsteady windows, the drive speed's error;
- :mod:`~isokinetic.diagnosis.parametrisation`: each effect's optimiser units and bounds;
- :mod:`~isokinetic.diagnosis.instrument`: load-cell gain and offset and Coulomb friction profiled
  in closed form, the measured actuator delay;
- :mod:`~isokinetic.diagnosis.candidate`: a fitted candidate, the gap metric and the χ² tests;
- :mod:`~isokinetic.diagnosis.search`: fitting and the candidate search;
- :mod:`~isokinetic.diagnosis.identifiability`: standard errors and correlations of the verdict;
- :mod:`~isokinetic.diagnosis.gap`: where (in speed and direction) the gap lies;
- :mod:`~isokinetic.diagnosis.verdict`: the verdict, its instrument terms and confoundings, the
  diagnosis dict;
- :mod:`~isokinetic.diagnosis.result`: the diagnosis.json document: versions, the not-diagnosed
  document, JSON-safe values, schema validation, row-level sources;
- :mod:`~isokinetic.diagnosis.next_tests`: the extra cases that would separate what the verdict cannot tell
  apart, and their rig time (:mod:`~isokinetic.diagnosis.plan_text`: the plan as a manifest fragment and lines).

The noise model the standard errors rest on is :mod:`isokinetic.measurement.noise`.
"""
