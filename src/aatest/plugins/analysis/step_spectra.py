"""A synchronised step's channel spectra, transformed once for every reduction that reads them.

Why: the sync pass feeds each sine step to several reductions (:mod:`sync_watches`) that
transform the same two records, the table's acceleration along a sensor and the sensor's
volts: the FRF point (:func:`aatest.plugins.analysis.frf.analyse_tone`, the record's DFT) and
the transfer function's cross-correlation (:mod:`aatest.plugins.analysis.tf_xcorr`). Inside
:func:`shared` each record's centred real FFT is made once and handed to both; outside it
(a reduction computed on its own) every call transforms anew. Nothing is kept after the scope:
a spectrum of 2^17 samples is 1 MB.
"""

from __future__ import annotations

from collections.abc import Hashable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np

from aatest.clocksync.relation import SyncedStep
from aatest.engine.datasheet import SensorInfo

#: the spectra of the reductions in progress, by (record key, samples); None: not shared
_SHARED: ContextVar[dict[tuple[Hashable, int], np.ndarray] | None] = ContextVar(
    "step_spectra", default=None)


@contextmanager
def shared() -> Iterator[None]:
    """Share the spectra :func:`centred_rfft` makes until the scope ends (one step's watches)."""
    token = _SHARED.set({})
    try:
        yield
    finally:
        _SHARED.reset(token)


def centred_rfft(values: np.ndarray, key: Hashable | None = None) -> np.ndarray:
    """``rfft(x − mean(x))`` of ``values`` as float64 (unscaled, ``x.size // 2 + 1`` bins).

    ``key`` names the record ``values`` holds (with its length, the memo's key): inside
    :func:`shared`, a second call with the same key and length returns the first call's
    spectrum (read-only), so a key must name one set of values for the whole scope (e.g. the
    step's identity and the channel). Outside it, or without a key, nothing is kept.
    """
    memo = None if key is None else _SHARED.get()
    found = None if memo is None else memo.get((key, int(np.size(values))))
    if found is not None:
        return found
    x = np.asarray(values, dtype=np.float64)
    spectrum = np.fft.rfft(x - x.mean())
    if memo is not None:
        spectrum.flags.writeable = False
        memo[(key, x.size)] = spectrum
    return spectrum


def input_key(synced: SyncedStep, sensor: SensorInfo) -> Hashable:
    """The key of a step's input along ``sensor``'s axis
    (:func:`~aatest.plugins.analysis._common.input_accel_dps2`): one set of values while the
    synchronised step lives."""
    return (id(synced), "input", sensor.axis)


def output_key(synced: SyncedStep, sensor: SensorInfo) -> Hashable:
    """The key of ``sensor``'s synchronised volts of a step."""
    return (id(synced), "daq", sensor.channel)
