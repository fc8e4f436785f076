"""After recording: the analysis pass and ``results.json``.

- ``plugins``       analysis plugins loaded and checked (key, requires, Options, Result), their
                    procedure options parsed and validated
- ``coverage``      before anything moves: does the plan hold what each listed analysis needs?
- ``passes``        runs the requested analyses (and what they require) in dependency order
- ``results_file``  builds, writes and reads the typed ``results.json`` (the models are
                    :mod:`aatest.results`; uncertainty and verdicts are :mod:`aatest.metrology`)
"""
