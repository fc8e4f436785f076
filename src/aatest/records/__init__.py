"""Calibration records: every unit's history in a real database (SQLite or PostgreSQL).

Package map:

- ``url``, ``engine``   which database (``--records``/``AATEST_RECORDS``/default file), connecting
- ``tables``, ``schema``, ``migrations/``   the schema and its Alembic migrations
- ``numbering``         gap-free certificate numbers per lab prefix and year
- ``models``, ``store`` typed records and the store API (register, query, history)
- ``extract``           what a record keeps from ``results.json``
- ``lab``               the lab profile (name, certificate prefix, calibration interval)
- ``hook``              registration from ``run``/``analyze``/``report``/``diagnose``
- ``history``, ``trend``, ``export``, ``verify``   what the CLI shows and checks
"""

from aatest.records.errors import RecordsError, RecordsUnavailable
from aatest.records.lab import LabProfile, load_lab
from aatest.records.models import CalibrationRecord, RecordFilter, Registration
from aatest.records.store import RecordStore

__all__ = [
    "CalibrationRecord",
    "LabProfile",
    "RecordFilter",
    "RecordStore",
    "RecordsError",
    "RecordsUnavailable",
    "Registration",
    "load_lab",
]
