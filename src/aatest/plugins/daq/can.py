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
from collections.abc import Sequence
from pathlib import Path
from typing import Literal

import can
from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import RigFault, rig_boundary
from aatest.engine.interfaces import RigContext
from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, SampledLog
from aatest.engine.steps import PlannedStep
from aatest.protocols import can_frames as cf
from aatest.protocols.can_bus import open_bus, send
from aatest.rig_defaults import LOG_RATE_HZ

log = logging.getLogger("aatest.daq.can")


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
        elif msg.arbitration_id == self.status_id:
            status = cf.parse_status(msg.data)
            if status.session not in self.sessions:
                self.foreign += 1
                return
            self.last_rx = time.monotonic()
            self.simulated = status.simulated
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
        dbc_file: Path | None = Field(None, description="decode sample frames with cantools")

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
        """Start the logger (its trigger line starts the table log)."""
        self._rx.samples = []
        self._rx.status = queue.Queue()
        self._rx.active = True
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
            decoded = cf.fill_gaps(decoded, index, len(payloads) + lost,
                                   self.config.sample_rate_hz)
        return self._to_log(decoded)

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

    def _to_log(self, decoded: cf.DecodedSamples) -> SampledLog:
        channels = {ch: decoded.volts[:, i] for i, ch in enumerate(self._channels)}
        channels.update(sync_pulse=decoded.sync_pulse, trigger=decoded.trigger,
                        temperature_c=decoded.temperature_c)
        units = {ch: "V" for ch in self._channels} | dict(DAQ_AUX_CHANNELS)
        return SampledLog(DAQ, self.config.sample_rate_hz, decoded.time_s, channels, units)

    def close(self) -> None:
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None
