"""Recording of runs in MCAP, and reading recordings (or import directories) back.

This is the one entry point the engine and the CLI use:

- :class:`RunRecorder` writes a run crash-safely (atomic per-step files under ``steps/``,
  merged into ``recording.mcap`` by :meth:`RunRecorder.finalize`);
- :func:`read_dataset` turns a run directory, a recording file or a measured-data import
  directory into a :class:`~aatest.engine.dataset.Dataset`.

The file format — topics, schemas, block layout, timestamps, metadata records — is documented
in :mod:`aatest.engine.recording.format` so that anyone with the plain ``mcap`` reader and NumPy
can decode a recording without aatest.
"""

from __future__ import annotations

from aatest.engine.recording.format import BLOCK_SAMPLES, ENCODING, FORMAT
from aatest.engine.recording.reader import read_dataset
from aatest.engine.recording.writer import RECORDING_NAME, STEPS_DIR, RunRecorder

__all__ = [
    "BLOCK_SAMPLES",
    "ENCODING",
    "FORMAT",
    "RECORDING_NAME",
    "STEPS_DIR",
    "RunRecorder",
    "read_dataset",
]
