"""Example vendor plugins for aatest (see ``docs/vendor-plugins.md``).

* ``acme-single-axis`` (group ``aatest.turntables``): a single-axis rate table that declares its
  own envelope (no outer axis, its own rate/acceleration limits and terminal frequency) and, having
  no hardware here, moves by wrapping aatest's simulated turntable loaded through the registry.
* ``acme-mems-aa`` (group ``aatest.sensors``): a MEMS angular accelerometer datasheet.
* ``asymmetric_scale`` (group ``aatest.effects``): an effect model for ``aatest diagnose`` and
  the twin — a scale factor that differs for α > 0 and α < 0.
* ``acme-summary`` (group ``aatest.reports``): a one-page calibration summary written from the
  typed results (``aatest.results.RunResults``), quantities named by ``aatest.results.quantities``.

Only aatest's public plugin API is imported: ``aatest.engine.interfaces``, ``.errors``,
``.steps``, ``.logs`` and ``.registry``, ``aatest.effects``, and the typed results
(``aatest.results``, ``aatest.results.quantities``).
"""

__version__ = "0.1.0"
