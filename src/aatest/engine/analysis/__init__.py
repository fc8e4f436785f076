"""After recording: the analysis pass and ``results.json``.

- ``passes``   runs the requested analysis plugins over a ``Dataset``
- ``results``  builds, writes and reads ``results.json``
"""
