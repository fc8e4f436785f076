"""Analysis plugins: turn synchronised recordings into the numbers a calibration lab signs.

Every plugin reads only the :class:`~aatest.engine.dataset.Dataset` (via the shared ``sync``
cache) and returns the contract keys of ``results.json`` (docs/interfaces.md §1).
"""

#: procedure analysis names that are computed inside another plugin (engine resolves them)
ALIASES: dict[str, str] = {"thd": "frf", "snr": "frf"}

__all__ = ["ALIASES"]
