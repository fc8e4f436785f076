"""The engine: from a procedure file to a recorded, analysed run.

Package map (data flows top to bottom):

- ``errors``       the one exception tree (``AatestError``) and the CLI exit codes
- ``steps``, ``logs``, ``dataset``  the shared records: planned steps, raw logs, analysis input
- ``datasheet``    the sensor datasheet and the per-channel sensor record (every sensor number
                   and its default defined once)
- ``interfaces``   one ``Protocol`` per plugin kind, the rig context, the table envelope
- ``registry``     installed plugins by entry-point group, validated when loaded
- ``procedure/``   procedure YAML → pydantic models (with FILE:LINE:COLUMN errors) → plan →
                   envelope check; the JSON Schema export
- ``run/``         rig life cycle (safe stop on any fault), step loop with resume, run state,
                   signatures, and ``session`` (what each command does end to end)
- ``recording/``   MCAP recording: per-step crash-safe files, the merged recording, reading back
- ``data/``        measured-data import and CSV export (the import format)
- ``analysis/``    the analysis pass over a dataset (ordered by what each analysis requires) and
                   the typed ``results.json`` (models in ``aatest.results``)

The engine never imports a plugin module: plugins are found through entry points only.
"""
