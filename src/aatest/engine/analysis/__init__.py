"""After recording: the analysis pass and ``results.json``.

- ``plugins``  analysis plugins loaded and checked (key, requires, Options, Result), their
               procedure options parsed and validated
- ``passes``   runs the requested analyses (and what they require) in dependency order
- ``results``  builds, writes and reads the typed ``results.json``
- ``verdicts``  judges the certified results against their acceptance limits (ILAC-G8),
  after the uncertainty stage (:mod:`aatest.metrology.uncertainty`); ``verdicts_limits`` says where
  the limits come from (sensor datasheet, overridden by the procedure's ``acceptance``)
"""
