"""Keep the objects that exist before a long computation out of the garbage collector's scans.

Why: a full cyclic collection walks every tracked object, and after the imports (NumPy,
SciPy, matplotlib, pydantic, the plugins) and a loaded dataset that is ≈ 150 000 objects
that are never garbage. The analysis pass collects after each plugin (≈ 90 ms a collection on
the stepped sine) and a diagnosis allocates enough for two or three (≈ 0.3 s each on the
16-step blind dataset, a tenth of its CPU time). :func:`gc.freeze` moves them to a permanent
generation for the duration; the computation's own objects are collected as before.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def older_objects_frozen() -> Iterator[None]:
    """Freeze every object that exists now (:func:`gc.freeze`) and hand them back to the
    collector (:func:`gc.unfreeze`) on leaving; an enclosing freeze is left as it was."""
    if gc.get_freeze_count() > 0:
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


@contextmanager
def frozen_for_children() -> Iterator[None]:
    """Freeze every object that exists now for the processes forked inside the block: their
    collections then leave the inherited objects, and so the pages they share with this
    process, alone (no copy-on-write of this heap). Inside an enclosing freeze (the analysis
    pass), whose end releases them all, the garbage made since it froze is collected first
    (a cheap collection: the rest is frozen) and this block's freeze is left to it."""
    outer = gc.get_freeze_count() > 0
    if outer:
        gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        if not outer:
            gc.unfreeze()
