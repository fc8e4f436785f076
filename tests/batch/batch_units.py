"""The shared archive's units (a named module: ``from conftest import`` collides across
test folders)."""

from __future__ import annotations

from aatest.batch.archive import TwinUnit

#: the shared archive: eight units on two rigs (the serials' digit is the seed)
RIGS = {"rig-c": ("ENC-2", "LOG-9"), "rig-d": ("ENC-2", "LOG-10")}
ARCHIVE_UNITS = tuple(
    TwinUnit(f"B{i}", 0.2 * (i - 4), "rig-c" if i % 2 else "rig-d",
             RIGS["rig-c" if i % 2 else "rig-d"], seed=i) for i in range(1, 9))
