"""After recording: the analysis pass and ``results.json``.

- ``plugins``  analysis plugins loaded and checked (key, requires, Options, Result), their
               procedure options parsed and validated
- ``passes``   runs the requested analyses (and what they require) in dependency order
- ``results``  builds, writes and reads the typed ``results.json``
"""
