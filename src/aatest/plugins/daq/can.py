"""DAQ plugin for an on-table sensor logger on a CAN (FD) bus, through python-can.

The logger streams one sample frame per sample (sequence counter, logger time stamp, sync
pulse and trigger bits, temperature, volts; see :mod:`aatest.protocols.can_frames`) and
answers PING/START/STOP commands with STATUS frames. Reception runs in a python-can
``Notifier`` thread; decoding is vectorised at the end of the record. Frame loss is never
silent: a gap in the sequence counter, or fewer frames than the logger reports sent, raises
:class:`~aatest.engine.errors.RigFault` (``on_frame_loss: fault``, the default) or is kept in
the record as NaN samples (``on_frame_loss: record``). A bus-off error frame, a failed send,
or a logger that stops talking raises RigFault with a one-line reason; any other error out
of python-can or the decoder is translated by :func:`~aatest.engine.errors.rig_boundary`.
Optionally the sample frames are decoded with cantools from a DBC file
(``can_frames.dbc_text`` writes one).

A static record longer than the table's log is streamed (:meth:`CanDaq.stream_logging`): a
TIMED_START asks the logger for a record it ends itself, and every chunk cut by the logger's
CHUNK marks is accounted for, decoded and handed on as it arrives (memory: one chunk); a
FAULT status, a lost frame or a silent logger ends it with RigFault after the frames before
the loss have been handed on, so the recording keeps them.

Every command carries this run's random session tag and the plugin keeps only STATUS and
sample frames echoing it, so two runs sharing one bus (or, off Linux, one udp_multicast port)
never record each other's frames; a logger answering PING with tag 0 predates the tag and is
accepted untagged.
"""

from __future__ import annotations

import logging
import queue
import secrets
import threading
import time
from collections.abc import Iterator, Sequence
from typing import Literal

import can
from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import RigFault, rig_boundary
from aatest.engine.interfaces import RigContext
from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.plugin_options import RigFilePath
from aatest.plugins.daq.can_stream import ChunkAccount, loss_message
from aatest.protocols import can_frames as cf
from aatest.protocols.can_bus import open_bus, send
from aatest.rig_defaults import LOG_RATE_HZ

log = logging.getLogger("aatest.daq.can")
#: STATUS states that cut a timed record's frames (the frames before them are accounted)
_MARKS = frozenset({cf.LoggerState.CHUNK, cf.LoggerState.END_OF_RECORD, cf.LoggerState.FAULT})
Mark = tuple[cf.Status, list[bytes]]


class _Collector(can.Listener):
    """Keeps sample payloads, STATUS answers and bus errors seen by the Notifier thread."""

    def __init__(self, node_id: int, session: int) -> None:
        self.sample_id, self.status_id = cf.SAMPLE_BASE + node_id, cf.STATUS_BASE + node_id
        #: session tags whose frames are this run's (own tag; 0 until the logger shows it tags)
        self.sessions = frozenset({session, cf.NO_SESSION})
        #: frames of this node carrying another session's tag, ignored
        self.foreign = 0
        self.samples: list[bytes] = []
        self.status: queue.Queue[cf.Status] = queue.Queue()
        self.bus_errors: list[str] = []
        self.last_rx = time.monotonic()
        self.active = False
        #: in a timed record the CHUNK/END/FAULT marks cut the frames received (in order, in
        #: this one thread, so each cut is exact) and queue them for the plugin
        self.timed = False
        self.marks: queue.Queue[Mark] = queue.Queue()
        #: most sample frames held here between two marks of a timed record
        self.peak_frames = 0
        #: the identity bit of the last STATUS frame: a simulated logger answers
        self.simulated = False

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame:
            if msg.arbitration_id & cf.CAN_ERR_BUSOFF:
                self.bus_errors.append("bus-off")
            return
        if msg.arbitration_id == self.sample_id:
            if cf.sample_session(msg.data) not in self.sessions:
                self.foreign += 1
            elif self.active:
                self.samples.append(bytes(msg.data))
                self.last_rx = time.monotonic()
                self.peak_frames = max(self.peak_frames, len(self.samples))
        elif msg.arbitration_id == self.status_id:
            status = cf.parse_status(msg.data)
            if status.session not in self.sessions:
                self.foreign += 1
                return
            self.last_rx = time.monotonic()
            self.simulated = status.simulated
            if self.timed and status.state in _MARKS:
                payloads, self.samples = self.samples, []
                self.active = status.state == cf.LoggerState.CHUNK
                self.marks.put((status, payloads))
                return
            self.status.put(status)

    def on_error(self, exc: Exception) -> None:
        self.bus_errors.append(f"receive error: {exc}")


class CanDaq:
    """Sensor logger on CAN: own clock, sensor volts, sync pulse, trigger, temperature."""

    class Config(BaseModel):
        """Bus, node and loss policy of the CAN logger."""

        model_config = ConfigDict(extra="forbid")
        interface: str = Field("virtual", description="python-can interface: virtual, "
                               "socketcan, udp_multicast, …")
        channel: str = "aatest"
        bitrate: int = Field(1_000_000, gt=0, description="nominal bit rate (bit/s)")
        fd: bool = True
        node_id: int = Field(1, ge=1, le=15)
        channels: list[str] | None = Field(None, description="sensor channel names in frame "
                                           "order; default the sensor datasheet's")
        sample_rate_hz: float = Field(LOG_RATE_HZ, gt=0, description="logger's nominal rate")
        response_timeout_s: float = Field(2.0, gt=0)
        frame_timeout_s: float = Field(5.0, gt=0, description="longest silence in a record")
        on_frame_loss: Literal["fault", "record"] = "fault"
        dbc_file: RigFilePath | None = Field(None, description="decode sample frames with cantools")

    def __init__(self, config: Config | None, context: RigContext | None) -> None:
        self.config = config if config is not None else self.Config()
        names = self.config.channels
        if names is None:
            names = list(context.datasheet.channels) if context is not None else ["v_sz"]
        self._channels = list(names)
        self._bus: can.BusABC | None = None
        self._notifier: can.Notifier | None = None
        #: this run's session tag (random, non-zero) sent in every command
        self.session = 1 + secrets.randbelow(cf.SESSION_MODULO - 1)
        self._rx = _Collector(self.config.node_id, self.session)
        self._lock = threading.Lock()
        self.gaps: list[cf.Gap] = []
        self._where = f"CAN logger node {self.config.node_id} on {self.config.interface} " \
                      f"{self.config.channel}"
        #: whether a simulated logger answers (its STATUS identity bit), known after start();
        #: a run with any simulated part is a simulation, never a calibration
        self.simulated = False
        #: bound on the sample frames of a timed record held at once: the most waiting for
        #: their chunk plus the most received between two marks (one chunk and one block)
        self.peak_buffered_frames = 0
        #: the rate of the record being logged (the step's; nominal until one starts)
        self._record_rate_hz = self.config.sample_rate_hz

    def channels(self) -> Sequence[str]:
        return [*self._channels, *DAQ_AUX_CHANNELS]

    @rig_boundary
    def start(self) -> None:
        """Open the bus, check that the logger answers a PING and read from the answer whether
        it is a simulator."""
        cfg = self.config
        self._bus = open_bus(cfg.interface, cfg.channel, cfg.fd, cfg.bitrate)
        self._notifier = can.Notifier(self._bus, [self._rx], timeout=0.05)
        self._command(cf.Opcode.PING)
        answer = self._expect(cf.LoggerState.IDLE, "answer to PING")
        if answer.session == self.session:  # a tagging logger: untagged frames are foreign
            self._rx.sessions = frozenset({self.session})
        else:
            log.info("%s: the logger does not tag its frames (layout version 1)", self._where)
        self.simulated = self._rx.simulated

    @property
    def foreign_frames(self) -> int:
        """Frames of this node id ignored so far because another session's tag was on them."""
        return self._rx.foreign

    def _command(self, opcode: cf.Opcode) -> None:
        if self._bus is None:
            raise RigFault(f"{self._where}: not started")
        self._check_bus()
        send(self._bus, cf.COMMAND_BASE + self.config.node_id,
             cf.command_payload(opcode, self.session), self.config.fd, self._where)

    def _check_bus(self) -> None:
        if self._rx.bus_errors:
            raise RigFault(f"{self._where}: {self._rx.bus_errors[0]}; logging stopped")

    def _expect(self, state: cf.LoggerState, what: str) -> cf.Status:
        """Wait for a STATUS frame of this session in ``state`` and return it."""
        deadline = time.monotonic() + self.config.response_timeout_s
        while True:
            self._check_bus()
            try:
                got: cf.Status | None = self._rx.status.get(timeout=0.05)
            except queue.Empty:
                got = None
            if got is not None and got.state == state:
                return got
            quiet = time.monotonic() - self._rx.last_rx
            if time.monotonic() > deadline and (state != cf.LoggerState.END_OF_RECORD
                                                 or quiet > self.config.frame_timeout_s):
                raise RigFault(f"{self._where}: no {what} (logger silent for {quiet:.1f} s)")

    @rig_boundary
    def start_logging(self, step: PlannedStep) -> None:
        """Start the logger (its trigger line starts the table log); the record it returns
        is labelled with the step's rate, the one the logger runs at (docs/interfaces.md §3),
        not the configured nominal rate."""
        self._rx.samples = []
        self._rx.status = queue.Queue()
        self._rx.active = True
        self._record_rate_hz = step.sample_rate_hz  # the logger runs at the step's rate
        self._command(cf.Opcode.START)
        self._expect(cf.LoggerState.LOGGING, "acknowledgement of START")

    @rig_boundary
    def stop_logging(self) -> SampledLog:
        """Stop, wait for the end-of-record status, decode, and account for every frame."""
        self._command(cf.Opcode.STOP)
        sent = self._expect(cf.LoggerState.END_OF_RECORD, "end of record").frames_sent
        self._rx.active = False
        payloads = self._rx.samples
        decoded = self._decode(payloads)
        index = cf.frame_index(decoded.seq)
        self.gaps = cf.find_gaps(index, sent)
        lost = sum(g.lost for g in self.gaps)
        if lost:
            where = ", ".join(f"{g.lost} from frame {g.first}" for g in self.gaps[:3])
            message = f"{self._where}: lost {lost} of {sent} sample frames ({where})"
            if self.config.on_frame_loss == "fault" or not payloads:
                raise RigFault(message)
            log.warning("%s; gaps kept as NaN samples", message)
            decoded = cf.fill_gaps(decoded, index, len(payloads) + lost, self._record_rate_hz)
        return self._to_log(decoded, self._record_rate_hz)

    def stream_logging(self, step: PlannedStep, chunk_s: float) -> Iterator[SampledLog]:
        """Ask the logger for a timed record of the step's span (TIMED_START: it ends the record
        itself, its lead and stop lag included) and yield it in chunks of about ``chunk_s``
        lab seconds as the logger's CHUNK marks account for them.

        Every frame of a chunk is accounted for against the logger's count; a loss ends the
        record with RigFault (``on_frame_loss: fault``) after the frames before it are yielded,
        or is yielded as NaN samples (``record``; a chunk with no frame at all is a fault). A
        FAULT status, bus-off or a logger silent for ``frame_timeout_s`` is a RigFault too. A
        record left early (fault, abort) is stopped at the logger.
        """
        rate_hz = step.sample_rate_hz  # the logger runs at the step's rate (docs/interfaces.md §3)
        account = ChunkAccount(self._decode, max(1, round(chunk_s * rate_hz)),
                               self.config.on_frame_loss == "record", rate_hz)
        self._start_timed(step)
        ended = False
        try:
            while not ended:
                try:
                    status, payloads = self._next_mark(account.sent)
                except RigFault:  # bus-off, silence: the frames marked so far are kept
                    yield from self._chunk(account, rate_hz)
                    raise
                ended = status.state != cf.LoggerState.CHUNK
                try:
                    account.add(status.frames_sent, payloads)
                except ValueError as exc:
                    raise RigFault(f"{self._where}: {exc}") from exc
                if account.due() or ended:
                    yield from self._chunk(account, rate_hz)
                self.peak_buffered_frames = max(self.peak_buffered_frames,
                                                account.peak_frames + self._rx.peak_frames)
                if status.state == cf.LoggerState.FAULT:
                    raise RigFault(f"{self._where}: {_fault_reason(status)}")
        finally:
            self._rx.timed = self._rx.active = False
            if not ended:
                self._stop_quietly()

    @rig_boundary
    def _start_timed(self, step: PlannedStep) -> None:
        self._rx.samples, self._rx.peak_frames = [], 0
        self._rx.status, self._rx.marks = queue.Queue(), queue.Queue()
        self._rx.timed = self._rx.active = True
        self.gaps, self.peak_buffered_frames = [], 0
        if self._bus is None:
            raise RigFault(f"{self._where}: not started")
        self._check_bus()
        send(self._bus, cf.COMMAND_BASE + self.config.node_id,
             cf.timed_command_payload(step.samples, self.session), self.config.fd, self._where)
        self._expect(cf.LoggerState.LOGGING, "acknowledgement of TIMED_START (a logger "
                     "without timed records cannot stream a long record)")

    @rig_boundary
    def _next_mark(self, sent: int) -> Mark:
        """The next CHUNK/END/FAULT mark of the timed record with the frames before it."""
        while True:
            try:  # the marks already received first: the frames before a bus-off are kept
                return self._rx.marks.get(timeout=0.05)
            except queue.Empty:
                self._check_bus()
                quiet = time.monotonic() - self._rx.last_rx
                if quiet > self.config.frame_timeout_s:
                    raise RigFault(f"{self._where}: logger silent for {quiet:.1f} s in a timed "
                                   f"record ({sent} sample frames accounted for)") from None

    def _chunk(self, account: ChunkAccount, rate_hz: float) -> Iterator[SampledLog]:
        """Decode the marked frames; yield what may be kept; raise on a loss (fault)."""
        try:
            chunk = account.take()
        except ValueError as exc:
            raise RigFault(f"{self._where}: {exc}; check 'channels'") from exc
        self.gaps += chunk.gaps
        if chunk.samples is not None and chunk.samples.seq.size:
            yield self._to_log(chunk.samples, rate_hz)
        if chunk.gaps:
            message = loss_message(self._where, self.gaps, account.sent)
            if chunk.samples is None or self.config.on_frame_loss == "fault":
                raise RigFault(f"{message}; the frames before the loss are recorded")
            log.warning("%s; gaps kept as NaN samples", message)

    def _stop_quietly(self) -> None:
        """Stop a timed record left early (best effort: the bus may be gone)."""
        try:
            self._command(cf.Opcode.STOP)
        except Exception as exc:  # noqa: BLE001 - the fault being raised matters more
            log.warning("%s: could not stop the timed record: %s", self._where, exc)

    def _decode(self, payloads: list[bytes]) -> cf.DecodedSamples:
        if self.config.dbc_file is None:
            try:
                return cf.decode_samples(payloads, len(self._channels))
            except ValueError as exc:
                raise RigFault(f"{self._where}: {exc} ({', '.join(self._channels)}); check "
                               "'channels' and the sensors the logger serves (a simulator's "
                               "--sensor)") from exc
        return cf.decode_with_dbc(self.config.dbc_file, payloads, self._channels,
                               cf.SAMPLE_BASE + self.config.node_id)

    def _to_log(self, decoded: cf.DecodedSamples, rate_hz: float | None = None) -> SampledLog:
        channels = {ch: decoded.volts[:, i] for i, ch in enumerate(self._channels)}
        channels.update(sync_pulse=decoded.sync_pulse, trigger=decoded.trigger,
                        temperature_c=decoded.temperature_c)
        units = {ch: "V" for ch in self._channels} | dict(DAQ_AUX_CHANNELS)
        rate = self.config.sample_rate_hz if rate_hz is None else rate_hz
        return SampledLog(DAQ, rate, decoded.time_s, channels, units)

    def close(self) -> None:
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None


def _fault_reason(status: cf.Status) -> str:
    """The logger's FAULT status in words."""
    flags = cf.LoggerError(status.errors)
    reasons = {cf.LoggerError.OVERRUN: "its buffer overran and it lost samples",
               cf.LoggerError.REFUSED: "it refused the timed record (busy, or not this length)"}
    said = "; ".join(text for flag, text in reasons.items() if flag in flags)
    return (f"the logger ended the timed record after {status.frames_sent} sample frames: "
            f"{said or f'error flags 0x{status.errors:02x}'}; the frames before are recorded")
