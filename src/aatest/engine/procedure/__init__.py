"""Procedures: what a QA engineer writes, checked before anything moves.

- ``models``        pydantic models of the procedure YAML (the JSON Schema's source)
- ``loader``        YAML (:mod:`aatest.positioned_yaml`) → models; every problem as
                    ``FILE:LINE:COLUMN: field: message``
- ``generators``    sweeps, multi-position, temperature steps … → concrete steps
- ``planner``       the expanded plan with its lab duration
- ``envelope``      every step against the turntable's and the sensor's limits

The JSON Schema export (``aatest schema``) is :mod:`aatest.schemas.export`.
"""
