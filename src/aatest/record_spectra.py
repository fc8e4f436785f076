"""A record's centred real spectrum, transformed once for every reduction of it that asks.

Why: while the analysis pass decodes a sine step, several reductions transform the same
records: the uncertainty evidence (:mod:`aatest.metrology.uncertainty.evidence`) the table's
acceleration, the FRF point (:mod:`aatest.plugins.analysis.frf`) that acceleration and the
sensor's synchronised volts, the transfer function's cross-correlation
(:mod:`aatest.plugins.analysis.tf_xcorr`) both again. :func:`centred_rfft` makes each such
spectrum once:

- a read-only view of a read-only array that owns its data (a decoded recording's channel:
  nobody can change its values) is known by its memory; its spectrum is kept while that
  array lives, for the last :data:`KEPT` such arrays only (a few MB, whatever holds the
  decoded steps), and handed out again only to the same values: the table's acceleration,
  which the evidence transforms before the sync pass's watches run;
- any other record is known by the ``key`` its caller names it by, and only inside
  :func:`shared` (one step's reductions): the sensor's volts resampled for the step.

A caller that names no key shares nothing. A spectrum handed out twice is read-only.
"""

from __future__ import annotations

import threading
import weakref
from collections import OrderedDict
from collections.abc import Hashable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np

#: spectra of the reductions in progress, by (record key, samples); None: not shared
_SHARED: ContextVar[dict[tuple[Hashable, int], np.ndarray] | None] = ContextVar(
    "record_spectra", default=None)
#: spectra of read-only records still alive, by memory (:func:`_memory_key`), newest last
_KEPT: OrderedDict[tuple[int, ...], tuple[np.ndarray, np.ndarray]] = OrderedDict()
#: read-only records whose spectra are kept at most (the records of the step in progress)
KEPT = 4
#: the key of a record to be known by its memory only (when read-only; else nothing is kept)
BY_MEMORY = "record_spectra.by_memory"


@contextmanager
def shared() -> Iterator[None]:
    """Share the spectra of keyed records :func:`centred_rfft` makes until the scope ends."""
    token = _SHARED.set({})
    try:
        yield
    finally:
        _SHARED.reset(token)


def centred_rfft(values: np.ndarray, key: Hashable | None = None) -> np.ndarray:
    """``rfft(x − mean(x))`` of ``values`` as float64 (unscaled, ``x.size // 2 + 1`` bins).

    ``key`` None: transformed, nothing kept. Else made once (see the module docstring): a
    read-only record by its memory, whatever the key; any other record, inside
    :func:`shared`, by ``key`` and its length (a key must name one set of values for the
    whole scope, e.g. a step's identity and the channel; :data:`BY_MEMORY`: never by key).
    """
    x = np.asarray(values, dtype=np.float64)
    if key is None:
        return _rfft_centred(x)
    memory = _memory_key(x)
    memo = None if memory is not None or key == BY_MEMORY else _SHARED.get()
    found = _kept(memory, x) if memory is not None else \
        None if memo is None else memo.get((key, x.size))
    if found is not None:
        return found
    spectrum = _rfft_centred(x)
    if memory is not None:
        spectrum.flags.writeable = False
        _keep(memory, spectrum, x)
    elif memo is not None:
        spectrum.flags.writeable = False
        memo[(key, x.size)] = spectrum
    return spectrum


#: each thread's buffer for the centred values, reused from record to record
_SCRATCH = threading.local()


def _rfft_centred(x: np.ndarray) -> np.ndarray:
    """``rfft(x − x.mean())``, the centred values written into this thread's scratch buffer.

    Why a buffer: a fresh megabyte for the centred values of each record (four a sine step)
    came from pages the allocator had handed back to the system, so every one of them was
    faulted in and zeroed again before being written; the same operations into one buffer
    give the same values without that.
    """
    buffer: np.ndarray | None = getattr(_SCRATCH, "buffer", None)
    if buffer is None or buffer.size < x.size:
        buffer = _SCRATCH.buffer = np.empty(x.size)
    centred = buffer[:x.size]
    np.subtract(x, x.mean(), out=centred)
    return np.fft.rfft(centred)


def _memory_key(x: np.ndarray) -> tuple[int, ...] | None:
    """Who ``x``'s values are: its owner's identity, first byte, length and stride, when
    ``x`` is a one-dimensional read-only view of a read-only array owning its data; else
    None (values someone may still change are not known by their memory)."""
    owner = x if x.base is None else x.base
    if (x.ndim != 1 or x.flags.writeable or not isinstance(owner, np.ndarray)
            or owner.base is not None or owner.flags.writeable):
        return None
    return (id(owner), x.__array_interface__["data"][0], x.size, x.strides[0])


def _kept(memory: tuple[int, ...], x: np.ndarray) -> np.ndarray | None:
    """The spectrum kept for the values ``x`` at ``memory``, if those are still its values.

    Why compare: read-only is a promise the owner of an array could take back (a decoder
    reusing its buffers); a copy of the values and one comparison (a tenth of an FFT) make
    a stale spectrum impossible.
    """
    found = _KEPT.get(memory)
    if found is None or not np.array_equal(found[1], x):
        return None
    return found[0]


def _keep(memory: tuple[int, ...], spectrum: np.ndarray, x: np.ndarray) -> None:
    """Keep ``spectrum`` (and a copy of the values it is of) under ``memory`` until the
    values' owner dies or :data:`KEPT` newer come."""
    owner = x if x.base is None else x.base
    _KEPT[memory] = (spectrum, x.copy())
    weakref.finalize(owner, _KEPT.pop, memory, None)
    while len(_KEPT) > KEPT:
        try:
            _KEPT.popitem(last=False)
        except KeyError:  # emptied meanwhile by an owner's finalizer
            break
