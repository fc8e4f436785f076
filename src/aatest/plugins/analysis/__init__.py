"""Analysis plugins: turn synchronised recordings into the numbers a calibration lab signs.

Every plugin reads only the :class:`~aatest.recording.dataset.Dataset` and the outputs of the
analyses it ``requires`` (the synchronised steps come from ``sync``'s output), and returns its
typed result (:mod:`aatest.results`) whose fields are the keys of ``results.json``
(docs/interfaces.md §1).
"""
