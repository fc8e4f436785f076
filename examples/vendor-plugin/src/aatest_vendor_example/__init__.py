"""Example vendor plugins for aatest (see ``docs/vendor-plugins.md``).

* ``acme-single-axis`` (group ``aatest.turntables``): a single-axis rate table that declares its
  own envelope (no outer axis, its own rate/acceleration limits and terminal frequency).
* ``acme-mems-aa`` (group ``aatest.sensors``): a MEMS angular accelerometer datasheet.
"""

__version__ = "0.1.0"
