"""How results reach a person at the terminal: the end-of-run summary and its tables.

Numbers are rounded by :mod:`aatest.results.rounding` and named by the quantity registry
(:mod:`aatest.results.quantities`), as in the certificate, ``history`` and ``records list``.
"""
