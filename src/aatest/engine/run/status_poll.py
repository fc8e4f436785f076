"""The table's live status, polled while a step runs, for the operator's display.

A turntable with the optional ``status()`` (:class:`~aatest.engine.interfaces.StatusTable`) is
read about ten times a second in a thread of its own from the start of a step to its end; each
reading whose clock has moved on is handed to the run's observer (``table_status``), which the
station plots live. The step itself never waits for a poll, and nothing polled is recorded or
analysed: the recording is the table's own log.

The schedule is kept in the table's time: a point is passed on only when the reading's clock
advanced by at least ``period_s`` since the last one. A real controller's clock runs with the
wall clock, so that is one point per poll; the digital twin's lab clock jumps forward by events
(a settle, a generated block of a record) far faster than real time, and a reading of a clock
that stood still adds nothing. The observer methods are optional (an observer written before
them keeps working); a table without ``status()`` is reported once per step through
``table_status_unavailable`` with :data:`NO_STATUS`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from aatest.engine.interfaces import TableStatus, reports_status, table_status
from aatest.engine.steps import PlannedStep

log = logging.getLogger("aatest.run.status")

#: wall seconds between two status reads (10 Hz: enough to watch a table, light on its link)
STATUS_PERIOD_S = 0.1
#: what the observer is told for a table without ``status()``
NO_STATUS = "this table reports no live status"


class StatusPoll:
    """Reads ``turntable.status()`` every ``period_s`` wall seconds until stopped.

    Parameters
    ----------
    turntable
        The rig's turntable plugin (with ``status()``).
    step
        The step the readings belong to (handed to the observer with each).
    observer
        The run's observer; its optional ``table_status(step, status)`` receives each reading
        whose clock advanced, ``table_status_unavailable(step, reason)`` a failed read.
    period_s
        Wall seconds between reads, and the least advance of the table's clock (s) between
        two readings passed on.
    """

    def __init__(self, turntable: object, step: PlannedStep, observer: object,
                 period_s: float = STATUS_PERIOD_S) -> None:
        self.turntable, self.step, self.observer = turntable, step, observer
        self.period_s = period_s
        self.points = 0
        self._last_s: float | None = None
        self._stop = threading.Event()
        #: held while a reading is judged and passed on; ``_closed`` ends the passing on
        self._passing = threading.Lock()
        self._closed = self._failed = False
        self._thread = threading.Thread(target=self._loop, daemon=True,
                                         name=f"status-poll-{step.id}")

    def start(self) -> StatusPoll:
        """Start polling (the first read is at once)."""
        self._thread.start()
        return self

    def stop(self, last_read: bool) -> None:
        """Stop polling; ``last_read`` takes one more reading first, in the caller's thread
        (the step ended well: show where it left the table). The step does not wait for the
        poll thread: a reading it is still taking is dropped."""
        self._stop.set()
        if last_read and not self._failed:
            self._read()
        with self._passing:
            self._closed = True

    def _loop(self) -> None:
        while not self._stop.is_set() and self._read():
            if self._stop.wait(self.period_s):
                return

    def _read(self) -> bool:
        """One reading, passed on when its clock moved on; False when reading failed."""
        try:
            status = table_status(self.turntable)
        except Exception as exc:  # noqa: BLE001 - a display must never end a step
            reason = f"live status read failed, polling stopped: {' '.join(str(exc).split())}"
            log.warning("step %s: %s", self.step.id, reason)
            self._failed = True
            with self._passing:
                if not self._closed:
                    _tell(self.observer, "table_status_unavailable", self.step, reason)
            return False
        if status is None:
            return False
        with self._passing:
            if self._closed:
                return False
            if self._last_s is None or status.time_s >= self._last_s + self.period_s:
                self._last_s = status.time_s
                self.points += 1
                _tell(self.observer, "table_status", self.step, status)
        return True


def _tell(observer: object, method: str, step: PlannedStep, value: TableStatus | str) -> None:
    """Call the observer's optional ``method``; an observer's error is logged, not raised."""
    handler = getattr(observer, method, None)
    if not callable(handler):
        return
    try:
        handler(step, value)
    except Exception:  # the display's fault must not end the step
        log.exception("observer %s.%s failed", type(observer).__name__, method)


@contextmanager
def polling_status(turntable: object, step: PlannedStep, observer: object,
                   period_s: float = STATUS_PERIOD_S) -> Iterator[StatusPoll | None]:
    """Poll the table's status every ``period_s`` seconds while the ``with`` body runs the
    step (None: no ``status()``, and the observer is told :data:`NO_STATUS`). A fault in the
    body stops the poll without a last read, before the rig's safe stop."""
    if not reports_status(turntable):
        _tell(observer, "table_status_unavailable", step, NO_STATUS)
        yield None
        return
    poll = StatusPoll(turntable, step, observer, period_s).start()
    try:
        yield poll
    except BaseException:
        poll.stop(last_read=False)
        raise
    poll.stop(last_read=True)
