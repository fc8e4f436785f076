"""After recording: the analysis pass and ``results.json``.

- ``passes``   runs the requested analysis plugins over a ``Dataset``
- ``results``  builds, writes and reads ``results.json``
- ``verdicts``  judges the certified results against their acceptance limits (ILAC-G8),
  after the uncertainty stage (:mod:`aatest.uncertainty`); ``verdicts_limits`` says where
  the limits come from (sensor datasheet, overridden by the procedure's ``acceptance``)
"""
