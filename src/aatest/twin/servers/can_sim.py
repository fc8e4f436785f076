"""The simulated CAN sensor logger, fed by the twin inside the simulated Modbus controller.

It listens for PING/START/STOP on the bus like the real logger, tells the controller that
the DAQ (and so the trigger line) started, and streams the twin's DAQ log of the record as
sample frames (:mod:`aatest.protocols.can_frames`), then an end-of-record STATUS with the
number of frames sent. The table log and this stream come from the same World synthesis, so
the real drivers see one consistent rig. On a lossy transport (``udp_multicast``) the stream
is paced to ``frame_rate_hz`` as a real bus' bit rate would. :class:`CanFaultInjection` drops
frames or raises bus-off on purpose for the fault tests.

The logger serves one session at a time: a PING or START adopts the command's session tag,
which its STATUS and sample frames then carry; while a record streams, commands of another
session are ignored, so a second host on the same bus cannot restart or re-tag someone else's
stream (outside a stream the last host to command wins, so a crashed host never locks it).

A TIMED_START asks for a record the logger ends itself: the controller's ``daq_stream`` gives
the twin's DAQ log chunk by chunk, and the logger sends it with a CHUNK status after every
:data:`CHUNK_MARK_FRAMES` frames and END_OF_RECORD with the total (STOP ends it early). A
controller without ``daq_stream`` makes it refuse (FAULT, REFUSED).
"""

from __future__ import annotations

import logging
import os
import queue
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import can

from aatest.engine.logs import SampledLog
from aatest.protocols import can_frames as cf
from aatest.protocols.can_bus import open_bus, send, volts_matrix

log = logging.getLogger("aatest.sim.can")
_PACE_BATCH = 64
#: sample frames between two CHUNK marks of a timed record (4 s at 2 kHz)
CHUNK_MARK_FRAMES = 8192
#: environment variable: pace of the udp_multicast sample stream, frames/s (default 10 000); a
#: slower pace lets a loaded host's receive thread keep up (a real bus' bit rate sets it)
FRAME_RATE_ENV = "AATEST_SIM_CAN_FRAME_RATE_HZ"


@dataclass
class CanFaultInjection:
    """Faults the simulated logger produces on purpose (tests only)."""

    #: sample indices (within a record) that are never sent
    drop_frames: frozenset[int] = field(default_factory=frozenset)
    #: after this many sample frames: a bus-off error frame, then silence
    bus_off_after_frames: int | None = None
    #: the faults above hit every record, or only this one (1 = the first after START)
    record_number: int | None = None
    #: timed records: after this many sample frames the logger's buffer overruns (FAULT)
    overrun_after_frames: int | None = None
    #: timed records: CHUNK marks (1 = the first) that are never sent
    drop_marks: frozenset[int] = field(default_factory=frozenset)


class SimCanLogger:
    """A CAN logger node backed by a :class:`SimController`'s twin.

    Parameters
    ----------
    controller
        The simulated controller whose World produces the DAQ logs (``daq_start`` and
        ``on_daq_log`` hooks).
    interface, channel
        python-can bus (``virtual`` in one process, ``udp_multicast`` across processes).
    node_id
        Logger node id (1..15).
    frame_rate_hz
        Pace of the sample stream; ``None`` sends as fast as the bus takes frames.
    faults
        Optional fault injection.
    """

    def __init__(self, controller: Any, interface: str = "virtual", channel: str = "aatest",
                 node_id: int = 1, frame_rate_hz: float | None = None,
                 faults: CanFaultInjection | None = None) -> None:
        self.controller = controller
        self.interface, self.channel, self.node_id = interface, channel, node_id
        if frame_rate_hz is None and interface == "udp_multicast":
            frame_rate_hz = float(os.environ.get(FRAME_RATE_ENV, "10000"))
        self.frame_rate_hz = frame_rate_hz
        self.faults = faults or CanFaultInjection()
        #: the STATUS identity bit; a test of the real-rig path may clear it
        self.simulated = True
        self._bus: can.BusABC | None = None
        self._jobs: queue.Queue[tuple[str, SampledLog | None]] = queue.Queue()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._sent = 0
        self._records = 0
        self._dead = False
        self._streaming = threading.Event()
        #: a STOP arrived during a timed record: end it early
        self._end_timed = threading.Event()
        self._timed_jobs: queue.Queue[int] = queue.Queue()
        #: session tag of the host served (0: an untagged, version-1 host)
        self.session = cf.NO_SESSION
        #: commands ignored because another session's record was streaming
        self.foreign_commands = 0
        #: a timed record is running (STOP ends it rather than queueing an end of record)
        self._timed = False
        self._where = f"simulated CAN logger node {node_id}"

    def start(self) -> SimCanLogger:
        self._bus = open_bus(self.interface, self.channel, fd=True)
        self.controller.on_daq_log = lambda daq: self._jobs.put(("log", daq))
        for target in (self._listen, self._work, self._work_timed):
            thread = threading.Thread(target=target, daemon=True, name=f"sim-can-{target.__name__}")
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        """Stop both threads and release the bus; idempotent."""
        self._stop.set()
        self._jobs.put(("quit", None))
        self._timed_jobs.put(0)
        for thread in self._threads:
            thread.join(5.0)
        self._threads = []
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None

    def _status(self, state: cf.LoggerState, frames: int = 0, errors: int = 0) -> None:
        if self._bus is not None and not self._dead:
            payload = cf.status_payload(state, frames, errors, session=self.session,
                                        simulated=self.simulated)
            send(self._bus, cf.STATUS_BASE + self.node_id, payload, True, self._where)

    def _listen(self) -> None:
        command_id = cf.COMMAND_BASE + self.node_id
        while not self._stop.is_set() and self._bus is not None:
            msg = self._bus.recv(0.05)
            if msg is None or msg.is_error_frame or msg.arbitration_id != command_id:
                continue
            if msg.data[0] == cf.Opcode.TIMED_START:
                self._command_timed(cf.command_session(msg.data), cf.command_samples(msg.data))
            else:
                self._command(msg.data[0], cf.command_session(msg.data))

    def _command(self, opcode: int, session: int) -> None:
        if session != self.session and self._streaming.is_set():
            self.foreign_commands += 1
            log.warning("%s: ignored opcode %d of session %d during session %d's stream",
                        self._where, opcode, session, self.session)
            return
        if opcode == cf.Opcode.PING:  # the host re-initialised the bus: bus-off recovery
            self.session, self._dead = session, False
            self._status(cf.LoggerState.IDLE)
        elif opcode == cf.Opcode.START:
            self.session, self._sent, self._dead = session, 0, False
            self._records += 1
            self._status(cf.LoggerState.LOGGING)
            self.controller.daq_start()
        elif opcode == cf.Opcode.STOP and self._timed:
            self._end_timed.set()
        elif opcode == cf.Opcode.STOP:
            self._jobs.put(("stop", None))

    def _command_timed(self, session: int, samples: int) -> None:
        """TIMED_START: acknowledge, then stream the record from the worker thread."""
        if session != self.session and self._streaming.is_set():
            self.foreign_commands += 1
            return
        self.session, self._sent, self._dead = session, 0, False
        self._records += 1
        self._timed = True
        self._end_timed.clear()
        self._status(cf.LoggerState.LOGGING)
        self._timed_jobs.put(samples)

    def _work_timed(self) -> None:
        while not self._stop.is_set():
            samples = self._timed_jobs.get()
            if samples <= 0:
                continue
            self._streaming.set()
            try:
                self._stream_timed(samples)
            finally:
                self._timed = False
                self._streaming.clear()

    def _stream_timed(self, samples: int) -> None:
        """Send a timed record chunk by chunk with its marks; the logger ends it itself."""
        daq_stream = getattr(self.controller, "daq_stream", None)
        chunks: Iterable[SampledLog] | None = None
        try:
            chunks = daq_stream(samples) if daq_stream is not None else None
        except ValueError as exc:
            log.warning("%s: timed record refused: %s", self._where, exc)
        if chunks is None:
            self._status(cf.LoggerState.FAULT, 0, cf.LoggerError.REFUSED)
            return
        faults = (self.faults if self.faults.record_number in (None, self._records)
                  else CanFaultInjection())
        started, marks = time.monotonic(), 0
        for daq in chunks:
            payloads = cf.encode_samples(daq.time_s, volts_matrix(daq), daq["sync_pulse"],
                                         daq["trigger"], daq["temperature_c"],
                                         first_seq=self._sent, session=self.session)
            for payload in payloads:
                if self._stop.is_set() or self._bus is None or self._dead:
                    return
                if self._end_timed.is_set():
                    self._status(cf.LoggerState.END_OF_RECORD, self._sent)
                    return
                if self._sent == faults.overrun_after_frames:
                    self._status(cf.LoggerState.FAULT, self._sent, cf.LoggerError.OVERRUN)
                    return
                self._send_timed(payload, started, faults)
                if self._sent % CHUNK_MARK_FRAMES == 0:
                    marks += 1
                    if marks not in faults.drop_marks:
                        self._status(cf.LoggerState.CHUNK, self._sent)
        self._status(cf.LoggerState.END_OF_RECORD, self._sent)

    def _send_timed(self, payload: bytes, started: float, faults: CanFaultInjection) -> None:
        """One sample frame of a timed record (dropped on purpose when injected; paced)."""
        assert self._bus is not None
        index = self._sent
        if index == faults.bus_off_after_frames:
            self._bus_off()
            return
        self._sent += 1
        if index not in faults.drop_frames:
            send(self._bus, cf.SAMPLE_BASE + self.node_id, payload, True, self._where)
        if self.frame_rate_hz and index % _PACE_BATCH == 0:
            ahead = started + index / self.frame_rate_hz - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)

    def _work(self) -> None:
        while not self._stop.is_set():
            kind, daq = self._jobs.get()
            if kind == "log" and daq is not None:
                self._streaming.set()
                try:
                    self._stream(daq)
                finally:
                    self._streaming.clear()
            elif kind == "stop":
                self._status(cf.LoggerState.END_OF_RECORD, self._sent)

    def _stream(self, daq: SampledLog) -> None:
        """Send one record's sample frames (paced), honouring injected faults."""
        payloads = cf.encode_samples(daq.time_s, volts_matrix(daq), daq["sync_pulse"],
                                     daq["trigger"], daq["temperature_c"], session=self.session)
        sample_id, started = cf.SAMPLE_BASE + self.node_id, time.monotonic()
        faulty = self.faults.record_number in (None, self._records)
        bus_off_at = self.faults.bus_off_after_frames if faulty else None
        drop = self.faults.drop_frames if faulty else frozenset()
        for index, payload in enumerate(payloads):
            if self._stop.is_set() or self._bus is None:
                return
            if index == bus_off_at:
                self._bus_off()
                return
            self._sent += 1
            if index not in drop:
                send(self._bus, sample_id, payload, True, self._where)
            if self.frame_rate_hz and index % _PACE_BATCH == 0:
                ahead = started + index / self.frame_rate_hz - time.monotonic()
                if ahead > 0:
                    time.sleep(ahead)

    def _bus_off(self) -> None:
        assert self._bus is not None
        error = can.Message(arbitration_id=cf.CAN_ERR_BUSOFF, is_error_frame=True, dlc=8,
                            data=bytes(8))
        self._bus.send(error)
        self._dead = True
        log.warning("%s: injected bus-off after %d frames", self._where, self._sent)
