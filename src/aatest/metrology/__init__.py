"""Metrology: what a result is worth — its uncertainty, and whether it meets its limit.

Sits between the typed results of the analyses (:mod:`aatest.results`) and the report: the
engine's run calls the two stages in order and the report only presents what they wrote.

- ``uncertainty/``     the uncertainty stage: GUM budgets of every certified result (expanded
                       uncertainty, coverage factor, budget rows), :func:`apply_uncertainty`
- ``verdicts``         the verdict stage: every certified quantity judged against its limit by
                       the procedure's decision rule (ILAC-G8), the overall verdict
- ``verdicts_limits``  where the limits come from: the sensor's datasheet, overridden by the
                       procedure
- ``verdicts_missing`` not measured is never passed: ``not judged`` verdicts for what was asked
                       and not obtained

Nothing here finds or runs a plugin: the sensor datasheets are resolved by the engine
(:func:`aatest.engine.run.rig.datasheets`) and handed in.
"""
