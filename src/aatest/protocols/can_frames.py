"""CAN framing of the on-table sensor logger: sample frames, commands, status, loss detection.

Identifiers (11-bit, ``n`` = logger node id 1..15):

* ``0x100 + n`` COMMAND to the logger, classic 8 bytes: ``u8 opcode`` (1 PING, 2 START,
  3 STOP, 4 TIMED_START), ``u16 session`` (the host's session tag, 0 = none), then for
  TIMED_START ``u32 samples`` (the span the logger records after its trigger) and one zero
  byte, else 5 bytes zero.
* ``0x180 + n`` SAMPLE, CAN FD, one frame per sample, little-endian (Intel) layout
  :data:`SAMPLE_HEADER` followed by ``n_channels`` float32 volts, padded to a valid FD length:
  ``u16 seq`` (sample counter, wraps at 65536), ``u8 flags`` (bit 0 sync pulse, bit 1
  trigger), ``u8 n_channels``, ``i64 time_ns`` (logger clock, ns), ``i16 temperature``
  (0.01 °C), ``u16 session``.
* ``0x700 + n`` STATUS from the logger, classic 8 bytes: ``u8 state`` (0 idle, 1 logging,
  2 end of record, 3 chunk mark, 4 fault; bit 7 set by a simulated logger, e.g.
  ``aatest sim-server``), ``u8`` error flags (:class:`LoggerError`), ``u16 session``, ``u32``
  sample frames sent in the record (so a lost tail is detected too).

Layout version 2 put the session tag into bytes that version 1 reserved as zero: a host picks a
random non-zero tag, sends it in every command, and the logger echoes the tag of the session it
serves in its STATUS and sample frames, so two hosts sharing one bus keep only their own frames
(a version-1 logger answers with tag 0, which a host then accepts).

A timed record (TIMED_START) is ended by the logger itself: it records its lead, raises the
trigger, records ``samples`` more and its stop lag, sending a CHUNK status after every block
of sample frames with the number sent so far and END_OF_RECORD with the total, so a host
accounts for every frame chunk by chunk and never holds the whole record. A logger that
cannot go on (its buffer overran, or it refuses the record) sends a FAULT status whose error
flags (:class:`LoggerError`) say why.

Decoding is vectorised: payloads are joined and read as one numpy structured array. A gap in
``seq`` (or fewer frames than the logger says it sent) is never silent: :func:`find_gaps`
reports it (at the start, in the middle or at the end of a record) and the DAQ plugin raises
or records it explicitly.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

COMMAND_BASE = 0x100
SAMPLE_BASE = 0x180
STATUS_BASE = 0x700
SEQ_MODULO = 1 << 16
#: a classic CAN frame carries at most 8 data bytes; a longer payload needs CAN FD
CLASSIC_PAYLOAD_BYTES = 8
FD_LENGTHS = (CLASSIC_PAYLOAD_BYTES, 12, 16, 20, 24, 32, 48, 64)
FLAG_SYNC, FLAG_TRIGGER = 0x01, 0x02
#: the sync and trigger inputs are 0/1 levels: above half is high
LOGIC_HIGH_ABOVE = 0.5
#: SocketCAN error-frame class bit for bus-off (linux/can/error.h CAN_ERR_BUSOFF)
CAN_ERR_BUSOFF = 0x040

SAMPLE_HEADER = np.dtype([("seq", "<u2"), ("flags", "u1"), ("n_channels", "u1"),
                          ("time_ns", "<i8"), ("temperature_cc", "<i2"), ("session", "<u2")])
STATUS_FORMAT = np.dtype([("state", "u1"), ("errors", "u1"), ("session", "<u2"),
                          ("frames_sent", "<u4")])
#: version of the frame layout (2: session tag in the former reserved bytes)
LAYOUT_VERSION = 2
#: session tag of a host or logger that does not tag (layout version 1)
NO_SESSION = 0
SESSION_MODULO = 1 << 16
#: bytes of the session tag in a sample frame (the header's last u16) and in a command
SAMPLE_SESSION_BYTES = slice(14, 16)
COMMAND_SESSION_BYTES = slice(1, 3)
#: the byte of a sample frame saying how many voltage channels it carries
N_CHANNELS_BYTE = 3  # after the u16 seq and the u8 flags of SAMPLE_HEADER
#: STATUS state byte: bit 7 says a simulator answers, no physical logger (a run on it is a
#: simulation); bits 0–3 carry the state (a version-1 logger leaves bit 7 clear)
IDENTITY_SIMULATED = 0x80
STATE_MASK = 0x0F


class Opcode(enum.IntEnum):
    PING = 1
    START = 2
    STOP = 3
    #: a record of a given length that the logger ends itself, streamed in chunks
    TIMED_START = 4


class LoggerState(enum.IntEnum):
    IDLE = 0
    LOGGING = 1
    END_OF_RECORD = 2
    #: in a timed record: every sample frame up to ``frames_sent`` has been sent
    CHUNK = 3
    #: the logger stopped the record; the error flags say why
    FAULT = 4


class LoggerError(enum.IntFlag):
    """Error flags of a STATUS frame (its second byte)."""

    #: the logger's own buffer overran: it lost samples and ended the record
    OVERRUN = 0x01
    #: the logger cannot make the record asked for (busy, or not this length)
    REFUSED = 0x02


#: bytes of the record length (u32 samples) in a TIMED_START command
COMMAND_SAMPLES_BYTES = slice(3, 7)


def sample_dtype(n_channels: int) -> np.dtype:
    """Structured dtype of one sample frame with ``n_channels`` voltages, FD-padded."""
    fields = [*list(SAMPLE_HEADER.descr), ("volts", "<f4", (n_channels,))]
    size = SAMPLE_HEADER.itemsize + 4 * n_channels
    length = next((n for n in FD_LENGTHS if n >= size), None)
    if length is None:
        raise ValueError(f"{n_channels} channels do not fit one CAN FD frame (max 12)")
    if length > size:
        fields.append(("pad", "u1", (length - size,)))
    return np.dtype(fields)


def encode_samples(time_s: np.ndarray, volts: np.ndarray, sync: np.ndarray, trigger: np.ndarray,
                   temperature_c: np.ndarray, first_seq: int = 0,
                   session: int = NO_SESSION) -> list[bytes]:
    """Sample-frame payloads for a record (vectorised build, one ``bytes`` per frame).

    Parameters
    ----------
    time_s
        Logger-clock time stamps (s), shape (n,).
    volts
        Sensor voltages (V), shape (n, channels).
    sync, trigger
        0/1 levels, shape (n,).
    temperature_c
        Sensor temperature (°C), shape (n,).
    first_seq
        Sequence number of the first frame.
    session
        Session tag of the host the record is for (0: untagged).
    """
    volts = np.atleast_2d(np.asarray(volts, dtype=np.float64).T).T
    n, channels = volts.shape
    frames = np.zeros(n, dtype=sample_dtype(channels))
    frames["seq"] = (first_seq + np.arange(n)) % SEQ_MODULO
    high_sync = np.asarray(sync) > LOGIC_HIGH_ABOVE
    high_trigger = np.asarray(trigger) > LOGIC_HIGH_ABOVE
    frames["flags"] = (high_sync * FLAG_SYNC) | (high_trigger * FLAG_TRIGGER)
    frames["n_channels"] = channels
    frames["time_ns"] = np.round(np.asarray(time_s, dtype=np.float64) * 1e9).astype(np.int64)
    frames["temperature_cc"] = np.round(np.asarray(temperature_c) * 100.0).astype(np.int16)
    frames["session"] = session
    frames["volts"] = volts
    raw = frames.tobytes()
    size = frames.dtype.itemsize
    return [raw[i: i + size] for i in range(0, len(raw), size)]


@dataclass(frozen=True)
class DecodedSamples:
    """Sample frames decoded into arrays (logger clock, volts, 0/1 levels, °C)."""

    seq: np.ndarray
    time_s: np.ndarray
    volts: np.ndarray  # (n, channels)
    sync_pulse: np.ndarray
    trigger: np.ndarray
    temperature_c: np.ndarray


def decode_samples(payloads: Sequence[bytes], n_channels: int) -> DecodedSamples:
    """Inverse of :func:`encode_samples` for a list of received payloads.

    Raises
    ------
    ValueError
        The frames carry another number of channels than ``n_channels`` (a logger wired for
        another sensor), or a frame's length does not fit its channel count.
    """
    dtype = sample_dtype(n_channels)
    first = payloads[0] if payloads else b""
    if len(first) > N_CHANNELS_BYTE and first[N_CHANNELS_BYTE] != n_channels:
        # checked before the buffer is cut into frames of the expected size
        raise ValueError(f"sample frames carry {first[N_CHANNELS_BYTE]} voltage channels, "
                         f"expected {n_channels}")
    if sum(map(len, payloads)) != len(payloads) * dtype.itemsize:
        raise ValueError(f"sample frames of {n_channels} channels must be {dtype.itemsize} "
                         f"bytes long; received lengths {sorted(set(map(len, payloads)))}")
    frames = np.frombuffer(b"".join(payloads), dtype=dtype) if payloads else np.zeros(0, dtype)
    if frames.size and np.any(frames["n_channels"] != n_channels):
        raise ValueError(f"sample frames carry {int(frames['n_channels'][0])} channels, "
                         f"expected {n_channels}")
    return DecodedSamples(
        seq=frames["seq"].astype(np.int64),
        time_s=frames["time_ns"].astype(np.float64) * 1e-9,
        volts=frames["volts"].astype(np.float64).reshape(frames.size, n_channels),
        sync_pulse=((frames["flags"] & FLAG_SYNC) > 0).astype(np.float64),
        trigger=((frames["flags"] & FLAG_TRIGGER) > 0).astype(np.float64),
        temperature_c=frames["temperature_cc"].astype(np.float64) / 100.0,
    )


@dataclass(frozen=True)
class Gap:
    """``lost`` consecutive sample frames missing from record frame index ``first`` on."""

    first: int
    lost: int


def frame_index(seq: np.ndarray, start: int = 0) -> np.ndarray:
    """Record frame index of every received frame, unwrapping the 16-bit counter.

    A record starts at ``seq`` 0, so the first received frame's index is its ``seq`` (a loss at
    the start shows); later indices add the forward steps modulo 65 536 (vectorised). A chunk
    of a timed record that starts at frame index ``start`` is unwrapped from there (fewer than
    65 536 frames lost at its start, which the logger's frame count bounds).
    """
    if seq.size == 0:
        return np.zeros(0, dtype=np.int64)
    steps = np.mod(np.diff(seq.astype(np.int64)), SEQ_MODULO)
    first = start + (int(seq[0]) - start) % SEQ_MODULO
    return np.concatenate([[first], first + np.cumsum(steps)])


def find_gaps(index: np.ndarray, sent: int) -> list[Gap]:
    """Runs of frames missing among the ``sent`` the logger reports (start, middle, end)."""
    total = max(sent, int(index[-1]) + 1 if index.size else 0)
    edges = np.concatenate([[-1], index, [total]])
    runs = np.flatnonzero(np.diff(edges) > 1)
    return [Gap(int(edges[i] + 1), int(edges[i + 1] - edges[i] - 1)) for i in runs]


def fill_gaps(decoded: DecodedSamples, index: np.ndarray, total: int,
              sample_rate_hz: float) -> DecodedSamples:
    """The record on its full frame grid, NaN where frames were lost, so gaps stay visible.

    Time stamps of lost samples are interpolated between received ones (extrapolated at the
    nominal sample period before the first and after the last).
    """
    grid = np.arange(total)
    time_s = np.interp(grid, index, decoded.time_s)
    before, after = grid < index[0], grid > index[-1]
    time_s[before] = decoded.time_s[0] + (grid[before] - index[0]) / sample_rate_hz
    time_s[after] = decoded.time_s[-1] + (grid[after] - index[-1]) / sample_rate_hz

    def _spread(values: np.ndarray) -> np.ndarray:
        out = np.full((total, *values.shape[1:]), np.nan)
        out[index] = values
        return out

    return DecodedSamples(seq=grid % SEQ_MODULO, time_s=time_s, volts=_spread(decoded.volts),
                          sync_pulse=_spread(decoded.sync_pulse), trigger=_spread(decoded.trigger),
                          temperature_c=_spread(decoded.temperature_c))


def command_payload(opcode: Opcode, session: int = NO_SESSION) -> bytes:
    return bytes([int(opcode)]) + session.to_bytes(2, "little") + bytes(5)


def timed_command_payload(samples: int, session: int = NO_SESSION) -> bytes:
    """TIMED_START: a record of ``samples`` after the trigger, ended by the logger itself."""
    if not 0 < samples < 1 << 32:
        raise ValueError(f"a timed record of {samples} samples does not fit the u32 field")
    return (bytes([int(Opcode.TIMED_START)]) + session.to_bytes(2, "little")
            + samples.to_bytes(4, "little") + bytes(1))


def command_samples(payload: bytes | bytearray) -> int:
    """Record length (samples after the trigger) of a TIMED_START command."""
    return int.from_bytes(bytes(payload[COMMAND_SAMPLES_BYTES]), "little")


def command_session(payload: bytes | bytearray) -> int:
    """Session tag of a COMMAND frame (0 from a version-1 host)."""
    return int.from_bytes(bytes(payload[COMMAND_SESSION_BYTES]), "little")


def sample_session(payload: bytes | bytearray) -> int:
    """Session tag of a SAMPLE frame, read without decoding the frame."""
    return int.from_bytes(bytes(payload[SAMPLE_SESSION_BYTES]), "little")


def status_payload(state: LoggerState, frames_sent: int, errors: int = 0,
                   session: int = NO_SESSION, simulated: bool = False) -> bytes:
    record = np.zeros(1, dtype=STATUS_FORMAT)
    record["state"] = int(state) | (IDENTITY_SIMULATED if simulated else 0)
    record["errors"], record["frames_sent"] = errors, frames_sent
    record["session"] = session
    return record.tobytes()


@dataclass(frozen=True)
class Status:
    """A decoded STATUS frame."""

    state: LoggerState
    errors: int
    frames_sent: int
    session: int
    simulated: bool = False


def status_simulated(payload: bytes | bytearray) -> bool:
    """Whether the logger sending this STATUS frame declares itself a simulator."""
    return parse_status(payload).simulated


def parse_status(payload: bytes | bytearray) -> Status:
    """State, error flags, frames sent, session tag and identity of a STATUS frame."""
    record = np.frombuffer(bytes(payload[:8]), dtype=STATUS_FORMAT)[0]
    state = int(record["state"])
    return Status(LoggerState(state & STATE_MASK), int(record["errors"]),
                  int(record["frames_sent"]), int(record["session"]),
                  bool(state & IDENTITY_SIMULATED))


def dbc_text(channels: Sequence[str], node_id: int = 1) -> str:
    """A DBC description of the sample frame (for cantools and vendor tools)."""
    frame_id = SAMPLE_BASE + node_id
    length = sample_dtype(len(channels)).itemsize
    signals = [
        ' SG_ seq : 0|16@1+ (1,0) [0|65535] "" Vector__XXX',
        ' SG_ sync_pulse : 16|1@1+ (1,0) [0|1] "" Vector__XXX',
        ' SG_ trigger : 17|1@1+ (1,0) [0|1] "" Vector__XXX',
        ' SG_ n_channels : 24|8@1+ (1,0) [0|12] "" Vector__XXX',
        ' SG_ time_ns : 32|64@1- (1,0) [0|0] "ns" Vector__XXX',
        ' SG_ temperature_c : 96|16@1- (0.01,0) [-327.68|327.67] "degC" Vector__XXX',
        ' SG_ session : 112|16@1+ (1,0) [0|65535] "" Vector__XXX',
    ]
    signals += [f' SG_ {ch} : {128 + 32 * i}|32@1- (1,0) [0|5] "V" Vector__XXX'
                for i, ch in enumerate(channels)]
    valtypes = [f"SIG_VALTYPE_ {frame_id} {ch} : 1;" for ch in channels]
    return "\n".join([
        'VERSION ""', "", "NS_ :", "", "BS_:", "", "BU_: LOGGER", "",
        f"BO_ {frame_id} SAMPLE: {length} LOGGER", *signals, "",
        'BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","reserved",'
        '"reserved","reserved","reserved","reserved","reserved","reserved","reserved",'
        '"reserved","reserved","reserved","StandardCAN_FD","ExtendedCAN_FD";',
        'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";',
        f'BA_ "VFrameFormat" BO_ {frame_id} 14;', "", *valtypes, "",
    ])


def decode_with_dbc(dbc_file: str | Path, payloads: Sequence[bytes], channels: Sequence[str],
                    frame_id: int) -> DecodedSamples:
    """Decode sample frames with cantools from a DBC file (one Python call per frame: slower
    than :func:`decode_samples`, for loggers whose layout is only known as a DBC)."""
    import cantools

    # A DBC file always loads as a CAN database; without choices every signal value is a number.
    database = cast("cantools.database.can.Database", cantools.database.load_file(str(dbc_file)))
    message = database.get_message_by_frame_id(frame_id)
    rows = [
        cast("dict[str, float]", message.decode(p, decode_choices=False, scaling=True))
        for p in payloads
    ]

    def col(name: str) -> np.ndarray:
        return np.array([float(r[name]) for r in rows], dtype=np.float64)

    volts = np.column_stack([col(c) for c in channels]) if rows else np.zeros((0, len(channels)))
    return DecodedSamples(seq=col("seq").astype(np.int64), time_s=col("time_ns") * 1e-9,
                          volts=volts, sync_pulse=col("sync_pulse"), trigger=col("trigger"),
                          temperature_c=col("temperature_c"))
