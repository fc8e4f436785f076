"""The engine: orchestration from a procedure file to a recorded, analysed, decided run.

Package map. The shared records first (imported by the stages below the engine too), then the
orchestration (which calls :mod:`aatest.recording`, :mod:`aatest.metrology`,
:mod:`aatest.bundle`, :mod:`aatest.storage`, :mod:`aatest.early` and :mod:`aatest.parallel`):

- ``errors``          the one exception tree (``AatestError``) and the CLI exit codes
- ``steps``, ``logs`` the shared records: planned steps, raw sampled logs
- ``datasheet``       the sensor datasheet and the per-channel sensor record (every sensor
                      number and its default defined once)
- ``rig_description`` the rig's stated accuracies (``rig.yaml`` / ``dataset.yaml``)
- ``interfaces``      one ``Protocol`` per plugin kind, the rig context, the table envelope
- ``requirements``    what an analysis needs from a plan, declared by the analysis
- ``simulation``      which runs are simulations (never calibrations)
- ``registry``        installed plugins by entry-point group, validated when loaded
- ``procedure/``      procedure YAML → pydantic models (with FILE:LINE:COLUMN errors) → plan →
                      envelope check (the JSON Schema export is :mod:`aatest.schemas.export`)
- ``plan_checks``     preflight checks of a procedure and its plan
- ``run/``            rig life cycle (safe stop on any fault), step loop with resume, run state,
                      and ``session`` (what each command does end to end)
- ``analysis/``       the analysis pass over a dataset (ordered by what each analysis
                      requires) and the typed ``results.json`` (models in ``aatest.results``)

The engine never imports a plugin module: plugins are found through entry points only.
"""
