"""``aatest batch`` and ``aatest records impact``: many recordings re-analysed on Dask.

- :mod:`.selection`  which recordings: records from the store, or a URL/directory prefix
- :mod:`.method`     what a re-analysis means, and its hash (the idempotency key)
- :mod:`.correction` a reference standard's correction, undone on the data as it is read
- :mod:`.task`       one recording analysed or diagnosed on a worker (writes nothing)
- :mod:`.runner`     the Dask coordinator: submit, store each result as it arrives
- :mod:`.ledger`     the ``reanalyses`` table, hash-chained, never touching a certificate
- :mod:`.impact`     reverse traceability: certificates of a reference, and what changes
- :mod:`.commands`   the CLI (docs/batch.md)
"""
