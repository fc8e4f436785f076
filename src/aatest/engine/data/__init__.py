"""Measured data in and out of aatest (the import format of ``docs/interfaces.md`` §3).

- ``importer``   an import directory (``dataset.yaml`` + CSV pairs) → ``Dataset``
- ``exporter``   a recording → an import directory
- ``csv_table``  strict CSV reading with file:line errors
"""
