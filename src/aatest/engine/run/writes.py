"""Step files written one step behind the rig, on a worker thread.

Why: writing a step (encoding its blocks, zstd, fsync) is a sizeable share of the record
phase's CPU time (≈ 31 ms a stepped-sine step, ≈ 12 % of the record phase's samples, measured
with ``bench/step_writer.py`` and py-spy; ≈ 40 % when this thread was added), while the rig
(the twin, or a real table recording in real time) does nothing else for that step.
Encoding, compression and fsync release the GIL for most of their time, so the write of step
k overlaps the recording of step k + 1 on the second core. The step files are the same bytes
as a write in the loop makes (each depends only on its own step), and a write's error (a full
disk: :class:`~aatest.engine.errors.StorageFault`) is raised in the step loop no later than
the next step's write, the next streamed step or the end of the run — before any step after
it is written, so the files on disk still end at the last good step and
``--resume`` records the rest.
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

from aatest.engine.logs import SampledLog
from aatest.engine.steps import PlannedStep


class BackgroundWrites:
    """At most one step write in flight, on one worker thread.

    Parameters
    ----------
    recorder
        The run's recorder (its ``write_step`` is called on the worker, one call at a time;
        the loop calls no other recorder method while a write is in flight: :meth:`wait`).
    """

    def __init__(self, recorder: Any) -> None:
        self._recorder = recorder
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="aatest-write")
        self._pending: Future[Any] | None = None

    def submit(self, step: PlannedStep, table: SampledLog, daq: SampledLog) -> None:
        """Write the step's file in the background, after the previous write has finished
        (whose error, if any, is raised here instead)."""
        self.wait()
        self._pending = self._pool.submit(self._recorder.write_step, step, table, daq)

    def wait(self) -> None:
        """Return when no write is in flight; raise the last write's error if it failed."""
        pending, self._pending = self._pending, None
        if pending is not None:
            pending.result()

    def close(self, raising: bool = True) -> None:
        """Finish the write in flight and stop the worker.

        With ``raising`` False (another error is on its way: a rig fault during the next step
        must not be hidden by a write's) the write's own error is dropped; its step is then
        simply not on disk.
        """
        try:
            if raising:
                self.wait()
            else:
                pending, self._pending = self._pending, None
                if pending is not None:
                    pending.exception()  # waits for it; the first error is the one reported
        finally:
            self._pool.shutdown(wait=True)
