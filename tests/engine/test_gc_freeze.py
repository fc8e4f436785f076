"""The freeze that keeps long-lived objects out of the collector's scans is always undone."""

from __future__ import annotations

import gc

from aatest.engine.gc_freeze import older_objects_frozen


def test_gc_freeze_is_undone_and_a_callers_freeze_kept() -> None:
    assert gc.get_freeze_count() == 0, "nothing in the test process freezes objects"
    with older_objects_frozen():
        assert gc.get_freeze_count() > 0
    assert gc.get_freeze_count() == 0
    gc.freeze()
    try:
        held = gc.get_freeze_count()
        with older_objects_frozen():
            pass
        assert gc.get_freeze_count() == held  # the caller's freeze stays
    finally:
        gc.unfreeze()
