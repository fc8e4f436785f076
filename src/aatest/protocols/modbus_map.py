"""The Modbus TCP register map of the two-axis turntable controller (map version 1).

One module is the single source of truth for both peers: the driver
(:mod:`aatest.plugins.turntable.modbus`) and the simulated controller
(:mod:`aatest.twin.servers.modbus_controller`) import the same addresses, bit
assignments and codecs, and ``docs/modbus-register-map.md`` documents them for a vendor.

Conventions (explicit, because Modbus leaves them open):

* all data lives in holding registers (function codes 3, 6, 16 and 23), 16-bit words;
* multi-word values are big-endian *words* and big-endian bytes inside a word ("ABCD"):
  the first (lower-addressed) register holds the most significant 16 bits;
* ``f32``/``f64`` are IEEE 754 single/double precision over 2/4 registers, in the unit the
  name says (degrees, °/s, °/s², Hz, s); ``u32`` is unsigned over 2 registers. Floats carry
  engineering units directly, with no scaling factor, so no resolution is lost (positions and
  sine frequencies are f64: 0.01″ at 1000° and a coherent 1.007080078 Hz need it);
* log bits (sync pulse) are packed 16 samples per register, sample k in bit k mod 16.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

MAP_VERSION = 1
#: registers one FC 23 read may return (Modbus limit 125); the log window size
WINDOW_REGISTERS = 120
#: registers of the log label (32 ASCII characters), stored in the log header
LABEL_REGISTERS = 16
#: registers of the controller identification string (32 ASCII characters)
IDENTITY_REGISTERS = 16


class Reg(enum.IntEnum):
    """Holding-register addresses (0-based protocol addresses)."""

    # --- identification and live status (read-only) ---
    MAP_VERSION = 0
    STATUS = 1  # u16, Status bits
    FAULT = 2  # u16, Fault bits (latched until CLEAR_FAULTS)
    MODE_ACTIVE = 3  # u16, Mode in force
    HEARTBEAT = 4  # u16, increments on every read (wraps): the controller is alive
    CONTROLLER_TIME_S = 6  # f64, controller clock since power-on
    INNER_POSITION_DEG = 10  # f64, position estimate
    INNER_RATE_DPS = 14  # f32
    OUTER_POSITION_DEG = 16  # f64
    OUTER_RATE_DPS = 20  # f32
    LOG_RECORDED = 22  # u32, samples in the log buffer so far
    LOG_CAPACITY = 24  # u32, samples the buffer holds
    LOG_RATE_MAX_HZ = 26  # f32
    INNER_RATE_LIMIT_DPS = 28  # f32, factory limits
    INNER_ACCEL_LIMIT_DPS2 = 30  # f32
    OUTER_RATE_LIMIT_DPS = 32  # f32
    OUTER_ACCEL_LIMIT_DPS2 = 34  # f32
    MAX_FREQUENCY_HZ = 36  # f32
    AXES = 38  # u16, number of axes (2)
    REFUSAL = 39  # u16, Refusal code of the last refused command
    SIMULATED = 40  # u16, 1: a simulator answers (no physical table), 0: a real controller
    IDENTITY = 41  # IDENTITY_REGISTERS registers, ASCII: maker and model of the controller
    # --- demands (read/write) ---
    MODE = 64  # u16, Mode applied by START_MOTION
    INNER_POSITION_DEMAND_DEG = 66  # f64, hold/start position
    OUTER_POSITION_DEMAND_DEG = 70  # f64
    INNER_RATE_DEMAND_DPS = 74  # f32, constant-rate mode
    OUTER_RATE_DEMAND_DPS = 76  # f32
    INNER_SINE_AMPLITUDE_DEG = 78  # f64, sine-synthesis mode
    INNER_SINE_FREQUENCY_HZ = 82  # f64
    OUTER_SINE_AMPLITUDE_DEG = 86  # f64
    OUTER_SINE_FREQUENCY_HZ = 90  # f64
    INNER_RATE_USER_LIMIT_DPS = 96  # f32, user limits (≤ factory; 0 = factory)
    INNER_ACCEL_USER_LIMIT_DPS2 = 98  # f32
    OUTER_RATE_USER_LIMIT_DPS = 100  # f32
    OUTER_ACCEL_USER_LIMIT_DPS2 = 102  # f32
    SETTLE_S = 104  # f64, time a profile runs after START_MOTION before Status.SETTLED
    # --- freeze pulse, trigger and log configuration (read/write) ---
    FP_INPUT = 128  # u16, digital input wired to the DAQ sync pulse (1..8)
    FP_EDGE = 129  # u16, Edge that latches the freeze pulse
    TRIGGER_INPUT = 130  # u16, digital input wired to the DAQ trigger (1..8)
    TRIGGER_EDGE = 131  # u16, Edge that starts the log
    LOG_START = 132  # u16, LogStart
    LOG_RATE_HZ = 134  # f32
    LOG_SAMPLES = 136  # u32
    LOG_LABEL = 140  # LABEL_REGISTERS registers, ASCII, 2 characters per register, NUL padded
    # --- command handshake (read/write) ---
    COMMAND = 160  # u16, Command; written together with COMMAND_SEQ (FC 16)
    COMMAND_SEQ = 161  # u16, driver-chosen sequence number
    COMMAND_ACK = 162  # u16, controller echo of the last executed COMMAND_SEQ (read-only)
    COMMAND_RESULT = 163  # u16, Refusal code of that command, 0 = accepted (read-only)
    # --- log header (read-only; valid when Status.LOG_DONE) ---
    LOG_ID = 180  # u16, increments with every completed log
    LOG_SAMPLES_DONE = 181  # u32, samples in the completed log
    LOG_T0_S = 184  # f64, table-clock time of the first sample
    LOG_RATE_DONE_HZ = 188  # f32
    # --- log download window ---
    WINDOW_CHANNEL = 200  # u16, LogChannel code (write, with WINDOW_START, in one FC 23)
    WINDOW_START = 202  # u32, first sample index of the window
    WINDOW = 208  # WINDOW_REGISTERS registers, read-only


READ_ONLY = (range(0, 64), range(162, 164), range(180, 200),
             range(Reg.WINDOW, Reg.WINDOW + WINDOW_REGISTERS))
REGISTER_COUNT = Reg.WINDOW + WINDOW_REGISTERS


class Status(enum.IntFlag):
    """Bits of ``Reg.STATUS``."""

    READY = 1 << 0
    MOTOR_ON = 1 << 1
    IN_POSITION = 1 << 2
    MOVING = 1 << 3
    LOG_ARMED = 1 << 4
    LOG_RECORDING = 1 << 5
    LOG_DONE = 1 << 6
    FAULT = 1 << 7
    INTERLOCK_CLOSED = 1 << 8
    TRIGGER_SEEN = 1 << 9
    SETTLED = 1 << 10


class Fault(enum.IntFlag):
    """Bits of ``Reg.FAULT``; any bit stops motion and switches the motor off."""

    EMERGENCY_STOP = 1 << 0
    INTERLOCK_OPEN = 1 << 1
    RATE_LIMIT = 1 << 2
    ACCEL_LIMIT = 1 << 3
    POSITION_LIMIT = 1 << 4
    SERVO_ERROR = 1 << 5
    AMPLIFIER = 1 << 6
    LOG_OVERFLOW = 1 << 7
    WATCHDOG = 1 << 8


class Mode(enum.IntEnum):
    """Motion modes (docs/method.md §1.2, §3)."""

    HOLD = 0
    POSITION = 1
    RATE = 2
    SINE = 3


class Command(enum.IntEnum):
    """Values written to ``Reg.COMMAND``."""

    NONE = 0
    CLEAR_FAULTS = 1
    MOTOR_ON = 2
    MOTOR_OFF = 3
    START_MOTION = 4  # apply MODE and the demands
    STOP = 5  # end the profile, return to its start position and hold there
    ARM_LOG = 6  # log LOG_SAMPLES at LOG_RATE_HZ, started per LOG_START
    ABORT_LOG = 7
    EMERGENCY_STOP = 8  # stop at the limits and switch the motor off


class Refusal(enum.IntEnum):
    """Why a command was refused (``Reg.COMMAND_RESULT`` and ``Reg.REFUSAL``)."""

    ACCEPTED = 0
    UNKNOWN_COMMAND = 1
    FAULT_ACTIVE = 2
    MOTOR_OFF = 3
    RATE_LIMIT = 4
    ACCEL_LIMIT = 5
    LOG_CAPACITY = 6
    LOG_RATE = 7
    BUSY = 8


class Edge(enum.IntEnum):
    RISING = 0
    FALLING = 1
    BOTH = 2


class LogStart(enum.IntEnum):
    IMMEDIATE = 0
    TRIGGER = 1


@dataclass(frozen=True)
class LogChannel:
    """One downloadable log channel: its code, ``SampledLog`` name and register encoding."""

    code: int
    name: str
    encoding: str  # "f64", "f32" or "bits" (16 samples per register, LSB first)

    @property
    def samples_per_window(self) -> int:
        per_register = {"f64": 0.25, "f32": 0.5, "bits": 16.0}[self.encoding]
        return int(WINDOW_REGISTERS * per_register)


#: the downloadable channels; code order is the download order
LOG_CHANNELS: tuple[LogChannel, ...] = (
    LogChannel(0, "time_s", "f64"),
    LogChannel(1, "inner_position_deg", "f64"),
    LogChannel(2, "inner_rate_dps", "f32"),
    LogChannel(3, "inner_accel_dps2", "f32"),
    LogChannel(4, "outer_position_deg", "f64"),
    LogChannel(5, "outer_rate_dps", "f32"),
    LogChannel(6, "outer_accel_dps2", "f32"),
    LogChannel(7, "inner_feedback_deg", "f64"),
    LogChannel(8, "outer_feedback_deg", "f64"),
    LogChannel(9, "sync_pulse", "bits"),
    LogChannel(10, "fp_latch_s", "f32"),
)
CHANNEL_BY_CODE = {c.code: c for c in LOG_CHANNELS}

_WORDS = {"f32": 2, "f64": 4, "u32": 2}
_NUMPY = {"f32": ">f4", "f64": ">f8", "u32": ">u4"}
#: ``Reg`` members that hold a multi-word value, and its type; the rest are u16
WIDE: dict[Reg, str] = {
    **{r: "f64" for r in (Reg.CONTROLLER_TIME_S, Reg.INNER_POSITION_DEG, Reg.OUTER_POSITION_DEG,
                          Reg.INNER_POSITION_DEMAND_DEG, Reg.OUTER_POSITION_DEMAND_DEG,
                          Reg.INNER_SINE_AMPLITUDE_DEG, Reg.INNER_SINE_FREQUENCY_HZ,
                          Reg.OUTER_SINE_AMPLITUDE_DEG, Reg.OUTER_SINE_FREQUENCY_HZ, Reg.SETTLE_S,
                          Reg.LOG_T0_S)},
    **{r: "f32" for r in (Reg.INNER_RATE_DPS, Reg.OUTER_RATE_DPS, Reg.LOG_RATE_MAX_HZ,
                          Reg.INNER_RATE_LIMIT_DPS, Reg.INNER_ACCEL_LIMIT_DPS2,
                          Reg.OUTER_RATE_LIMIT_DPS, Reg.OUTER_ACCEL_LIMIT_DPS2,
                          Reg.MAX_FREQUENCY_HZ, Reg.INNER_RATE_DEMAND_DPS,
                          Reg.OUTER_RATE_DEMAND_DPS, Reg.INNER_RATE_USER_LIMIT_DPS,
                          Reg.INNER_ACCEL_USER_LIMIT_DPS2, Reg.OUTER_RATE_USER_LIMIT_DPS,
                          Reg.OUTER_ACCEL_USER_LIMIT_DPS2, Reg.LOG_RATE_HZ,
                          Reg.LOG_RATE_DONE_HZ)},
    **{r: "u32" for r in (Reg.LOG_RECORDED, Reg.LOG_CAPACITY, Reg.LOG_SAMPLES,
                          Reg.LOG_SAMPLES_DONE, Reg.WINDOW_START)},
}


def width(reg: Reg) -> int:
    """Number of registers ``reg`` occupies."""
    return _WORDS.get(WIDE.get(reg, "u16"), 1)


def encode(reg: Reg, value: float) -> list[int]:
    """Registers (ABCD word order) that carry ``value`` at ``reg``."""
    kind = WIDE.get(reg, "u16")
    if kind == "u16":
        return [int(value) & 0xFFFF]
    return encode_array(np.asarray([value]), kind)


def decode(reg: Reg, registers: Sequence[int]) -> float:
    """The value at ``reg`` from its registers (inverse of :func:`encode`)."""
    kind = WIDE.get(reg, "u16")
    if kind == "u16":
        return int(registers[0])
    return float(decode_array(registers, kind)[0])


def encode_array(values: np.ndarray, kind: str) -> list[int]:
    """Registers for an array of ``f32``/``f64``/``u32`` values, ABCD order, vectorised."""
    raw = np.ascontiguousarray(np.asarray(values).astype(_NUMPY[kind])).tobytes()
    return np.frombuffer(raw, dtype=">u2").astype(int).tolist()


def decode_array(registers: Sequence[int], kind: str) -> np.ndarray:
    """Values from ABCD-ordered registers (inverse of :func:`encode_array`), native float/int."""
    raw = np.asarray(registers, dtype=">u2").tobytes()
    return np.frombuffer(raw, dtype=_NUMPY[kind]).astype(np.float64 if kind != "u32" else np.int64)


def encode_bits(bits: np.ndarray) -> list[int]:
    """Pack 0/1 samples 16 per register, sample k in bit k mod 16 (LSB first)."""
    flat = np.asarray(bits, dtype=np.uint8) != 0
    padded = np.zeros(-(-flat.size // 16) * 16, dtype=bool)
    padded[: flat.size] = flat
    packed = np.packbits(padded.reshape(-1, 16), axis=1, bitorder="little")
    return (packed[:, 0].astype(int) | (packed[:, 1].astype(int) << 8)).tolist()


def decode_bits(registers: Sequence[int], count: int) -> np.ndarray:
    """Unpack ``count`` 0/1 samples packed by :func:`encode_bits`."""
    regs = np.asarray(registers, dtype=np.uint16)
    pairs = np.stack([regs & 0xFF, regs >> 8], axis=1).astype(np.uint8)
    return np.unpackbits(pairs, axis=1, bitorder="little").reshape(-1)[:count].astype(np.uint8)


def encode_channel_window(values: np.ndarray, channel: LogChannel, start: int) -> list[int]:
    """The ``Reg.WINDOW`` contents for ``channel`` from sample ``start`` (zero padded)."""
    chunk = values[start: start + channel.samples_per_window]
    regs = encode_bits(chunk) if channel.encoding == "bits" else encode_array(chunk,
                                                                              channel.encoding)
    return regs + [0] * (WINDOW_REGISTERS - len(regs))


def decode_channel_window(registers: Sequence[int], channel: LogChannel, count: int) -> np.ndarray:
    """``count`` samples of ``channel`` from one window read."""
    if channel.encoding == "bits":
        return decode_bits(registers, count)
    words = _WORDS[channel.encoding]
    return decode_array(registers[: count * words], channel.encoding)



def encode_label(text: str, registers: int = LABEL_REGISTERS) -> list[int]:
    """``Reg.LOG_LABEL`` (or ``Reg.IDENTITY``) registers for ``text`` (ASCII, first character
    in the high byte, NUL padded to ``registers``)."""
    raw = text.encode("ascii", errors="replace")[: 2 * registers]
    raw = raw.ljust(2 * registers, b"\0")
    return np.frombuffer(raw, dtype=">u2").astype(int).tolist()


def decode_label(registers: Sequence[int]) -> str:
    """The text stored by :func:`encode_label`."""
    return np.asarray(registers, dtype=">u2").tobytes().rstrip(b"\0").decode("ascii", "replace")
