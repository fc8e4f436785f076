"""Recorded data: runs in MCAP, measured-data import/export, and reading either back.

This is the one entry point the engine and the CLI use:

- :class:`RunRecorder` writes a run crash-safely (atomic per-step files under ``steps/``,
  merged into ``recording.mcap`` by :meth:`RunRecorder.finalize`);
- :func:`read_dataset` turns a run directory, a recording file or a measured-data import
  directory into a :class:`~aatest.recording.dataset.Dataset`.

The file format — topics, schemas, block layout, timestamps, metadata records — is documented
in :mod:`aatest.recording.format` so that anyone with an MCAP reader and protobuf can
decode a recording without aatest. Modules, in the order data flows through them when writing:

- ``codec``     a SampledLog ↔ protobuf ``SampleBlock`` messages (exact integer codes or floats);
- ``proto``     the ``SampleBlock`` message and its descriptor set (the MCAP schema data);
- ``format``    format constants, topics, run time line, metadata record helpers;
- ``mcap_io``   the MCAP writer with caller-chosen ids and verbatim chunk copying;
- ``stream``    a long record's DAQ chunks spooled as they arrive, then written as its step file;
- ``writer``    RunRecorder: atomic step files, the merge, storage faults, corrupt-file checks;
- ``reader``    read_dataset: dispatches each topic on its schema encoding (v2, or v1 through
  ``legacy_v1``);
- ``preview``   the 200 ms preview topics a generic MCAP viewer plots.

Beside them: ``dataset`` (the :class:`~aatest.recording.dataset.Dataset` every analysis reads,
with lazily decoded steps), ``data/`` (measured data in and out: the CSV import format, NI TDMS
and ASAM MF4 logger files) and ``temperatures`` (the logged-temperature summary written into
the results when a run is analysed).
"""

from __future__ import annotations

from aatest.recording.format import BLOCK_SAMPLES, ENCODING, FORMAT
from aatest.recording.reader import read_dataset
from aatest.recording.writer import RECORDING_NAME, STEPS_DIR, RunRecorder

__all__ = [
    "BLOCK_SAMPLES",
    "ENCODING",
    "FORMAT",
    "RECORDING_NAME",
    "STEPS_DIR",
    "RunRecorder",
    "read_dataset",
]
