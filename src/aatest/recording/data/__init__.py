"""Measured data in and out of aatest (the import format of ``docs/interfaces.md`` §3).

- ``importer``   an import directory (``dataset.yaml`` + CSV pairs) → ``Dataset``
- ``exporter``   a recording → an import directory
- ``csv_table``  strict CSV reading with file:line errors
- ``plausible``  physically possible values (positions, rates, volts, temperatures)
- ``mapping``         ``mapping.yaml``: which TDMS/MF4 channel is which, units and scaling
- ``logger_files``    npTDMS/asammdf behind one small reader interface
- ``logger_import``   ``mapping.yaml`` + TDMS/MF4 files → ``Dataset`` (steps read lazily)
- ``logger_export``   a recording → a TDMS or MF4 file + ``mapping.yaml``, piece by piece
"""
