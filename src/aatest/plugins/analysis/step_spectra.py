"""The keys of a synchronised step's records for :func:`aatest.record_spectra.centred_rfft`.

Why: the sync pass's watches (:mod:`sync_watches`) reduce one synchronised step inside
:func:`~aatest.record_spectra.shared`; the FRF point and the cross-correlation transform the
same input and output of it, and name them by these keys so that each is transformed once.
"""

from __future__ import annotations

from collections.abc import Hashable

from aatest.clocksync.relation import SyncedStep
from aatest.engine.datasheet import SensorInfo
from aatest.record_spectra import centred_rfft, shared

__all__ = ["centred_rfft", "input_key", "output_key", "shared"]


def input_key(synced: SyncedStep, sensor: SensorInfo) -> Hashable:
    """The key of a step's input along ``sensor``'s axis
    (:func:`~aatest.plugins.analysis._common.input_accel_dps2`): one set of values while the
    synchronised step lives."""
    return (id(synced), "input", sensor.axis)


def output_key(synced: SyncedStep, sensor: SensorInfo) -> Hashable:
    """The key of ``sensor``'s synchronised volts of a step."""
    return (id(synced), "daq", sensor.channel)
