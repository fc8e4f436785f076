"""Wire transcripts of the ``espec`` and ``simserv`` chamber drivers (request → reply), each
line citing its public source, and the simulators answering the same requests.

Sources: [CCL] EspecNorthAmerica/ChamberConnectLibrary (MIT): ``especinteract.py`` (``\\r\\n``
terminated ASCII over TCP, port 10001, ``NA:`` error replies), ``p300.py`` (``ROM?``, ``TEMP?``
→ PV,SP,HIGH,LOW, ``TEMP, S%0.1f``, ``MODE,CONSTANT``, ``MODE,STANDBY``). [VT]
SengerM/VotschTechnik-climate-chamber-Python: SIMSERV fields separated by byte 0xB6, ``\\r``
terminated, chamber index 1, port 2049, reply's first field 1 = success; 99997 info, 11001
set point, 11002 read set point, 11004 read temperature, 11007/11009 input limits, 14001
manual mode on/off. [SIM] aatest's simulator-only commands (never sent to hardware).
"""

from __future__ import annotations

import math

import pytest

from aatest.engine.errors import EnvelopeRefused, RigFault
from aatest.plugins.chamber.espec import EspecChamber
from aatest.plugins.chamber.simserv import SimservChamber
from aatest.testing.transcript import TranscriptServer
from aatest.twin.model import RigModel
from aatest.twin.servers.acutrol_server import chamber_server
from aatest.twin.servers.chamber_sim import SimChamberCore
from aatest.twin.world import World

ESPEC_SESSION = [
    (b"ROM?\r\n", b"P300 ROM 2.30\r\n"),  # [CCL] p300.read_rom: 'ROM?'
    (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # [CCL] p300.read_temp: PV,SP,HIGH,LOW
    (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # limits before a set point [CCL] read_temp
    (b"TEMP, S35.0\r\n", b"OK: TEMP, S35.0\r\n"),  # [CCL] p300.write_temp 'TEMP, S%0.1f'
    (b"MODE,CONSTANT\r\n", b"OK: MODE,CONSTANT\r\n"),  # [CCL] p300.write_mode_constant
    (b"TEMP?\r\n", b"35.1,35.0,100.0,-40.0\r\n"),  # in band, no soak: stable [CCL] read_temp
    (b"MODE,STANDBY\r\n", b"OK: MODE,STANDBY\r\n"),  # [CCL] p300.write_mode_standby
]

SIMSERV_SESSION = [
    (b"99997\xb61\xb61\r", b"1\xb6VT 4002\r\n"),  # [VT] 'GET CHAMBER INFO' 99997, arg 1
    (b"11004\xb61\xb61\r", b"1\xb622.00\r\n"),  # [VT] GET CONTROL_VARIABLE ACTUAL_VALUE
    (b"11002\xb61\xb61\r", b"1\xb622.00\r\n"),  # [VT] GET CONTROL_VARIABLE SET_POINT
    (b"11007\xb61\xb61\r", b"1\xb6-40.00\r\n"),  # [VT] INPUT_LIMIT_MIN
    (b"11009\xb61\xb61\r", b"1\xb6100.00\r\n"),  # [VT] INPUT_LIMIT_MAX
    (b"11001\xb61\xb61\xb635.00\r", b"1\r\n"),  # [VT] SET CONTROL_VARIABLE SET_POINT
    (b"14001\xb61\xb61\xb61\r", b"1\r\n"),  # [VT] START MANUAL_MODE, 1 = on (chamber.start)
    (b"11004\xb61\xb61\r", b"1\xb634.95\r\n"),  # [VT] ACTUAL_VALUE, in band
    (b"11002\xb61\xb61\r", b"1\xb635.00\r\n"),  # [VT] SET_POINT
    (b"14001\xb61\xb61\xb60\r", b"1\r\n"),  # [VT] START MANUAL_MODE, 0 = off (chamber.stop)
]


def _session(chamber: EspecChamber | SimservChamber) -> float:
    chamber.start()
    chamber.set_temperature(35.0)
    temperature = chamber.wait_stable(0.0)
    chamber.off()
    chamber.close()
    return temperature


def test_espec_driver_sends_exactly_the_public_commands() -> None:
    with TranscriptServer(ESPEC_SESSION) as server:
        chamber = EspecChamber(EspecChamber.Config(port=server.port, timeout_s=2.0))
        assert _session(chamber) == pytest.approx(35.1)
    assert not chamber.simulated  # the ROM reply does not say SIMULATOR


def test_simserv_driver_sends_exactly_the_public_commands() -> None:
    with TranscriptServer(SIMSERV_SESSION) as server:
        chamber = SimservChamber(SimservChamber.Config(port=server.port, timeout_s=2.0))
        assert _session(chamber) == pytest.approx(34.95)
    assert not chamber.simulated


def test_espec_error_reply_is_a_rig_fault_naming_the_chamber() -> None:
    transcript = [
        (b"ROM?\r\n", b"P300 ROM 2.30\r\n"),  # [CCL] read_rom
        (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # [CCL] read_temp
        (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # [CCL] read_temp (limits)
        (b"TEMP, S35.0\r\n", b"NA:PROTECT ON\r\n"),  # [CCL] ERROR_DESCIPTIONS 'PROTECT ON'
    ]
    with TranscriptServer(transcript) as server:
        chamber = EspecChamber(EspecChamber.Config(port=server.port))
        chamber.start()
        with pytest.raises(RigFault, match=r"ESPEC chamber 127\.0\.0\.1:\d+: .*PROTECT ON"):
            chamber.set_temperature(35.0)
        chamber.close()


def test_set_point_outside_the_chamber_limits_is_refused_before_sending() -> None:
    transcript = [
        (b"ROM?\r\n", b"P300 ROM 2.30\r\n"),  # [CCL] read_rom
        (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # [CCL] read_temp
        (b"TEMP?\r\n", b"22.0,22.0,100.0,-40.0\r\n"),  # [CCL] read_temp: HIGH 100, LOW -40
    ]
    with TranscriptServer(transcript) as server:
        chamber = EspecChamber(EspecChamber.Config(port=server.port))
        chamber.start()
        with pytest.raises(EnvelopeRefused, match=r"150 °C outside .*\[-40, 100\]"):
            chamber.set_temperature(150.0)
        chamber.close()


def _core() -> SimChamberCore:
    return SimChamberCore(World(RigModel(), 0), setpoint_c=22.0)


@pytest.mark.parametrize(("kind", "session"), [("espec", ESPEC_SESSION),
                                               ("simserv", SIMSERV_SESSION)])
def test_simulator_answers_the_public_requests_in_the_same_format(
        kind: str, session: list[tuple[bytes, bytes | None]]) -> None:
    """The simulator parses every request of the transcript and answers with the same shape
    (values differ: the simulated sensor lags the set point with τ = 300 s)."""
    import socket

    with chamber_server(kind, _core()) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=5) as sock:
        replies = sock.makefile("rb")
        for request, expected in session:
            sock.sendall(request)
            reply = replies.readline()
            assert expected is not None
            if kind == "espec":
                assert not reply.startswith(b"NA:"), (request, reply)
                assert reply.count(b",") == expected.count(b","), (request, reply)
                if expected.startswith(b"OK:"):  # a write is echoed after OK:
                    assert reply == expected
            else:
                assert reply.strip().split(b"\xb6")[0] == b"1", (request, reply)
                assert reply.count(b"\xb6") == expected.count(b"\xb6"), (request, reply)


@pytest.mark.parametrize(("kind", "request_bytes", "error"), [
    ("espec", b"TEMP, S500.0\r\n", b"NA:DATA OUT OF RANGE\r\n"),  # beyond HIGH
    ("espec", b"TEMP, X1\r\n", b"NA:PARA ERR\r\n"),  # malformed parameter
    ("espec", b"HELLO\r\n", b"NA:CMD ERR\r\n"),  # unknown command
    ("simserv", b"11001\xb61\xb61\xb6500\r", b"-8\r\n"),  # beyond the input limit
    ("simserv", b"11001\xb61\xb61\r", b"-6\r\n"),  # missing value
    ("simserv", b"12345\xb61\r", b"-5\r\n"),  # unknown command
])
def test_simulator_rejects_malformed_and_out_of_limit_requests(
        kind: str, request_bytes: bytes, error: bytes) -> None:
    import socket

    with chamber_server(kind, _core()) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=5) as sock:
        sock.sendall(request_bytes)
        assert sock.makefile("rb").readline() == error


@pytest.mark.parametrize("plugin", [EspecChamber, SimservChamber])
def test_soak_against_the_simulator_matches_the_twin_chamber(plugin: type) -> None:
    """Stabilisation through the protocol ends when the in-process chamber's does, within
    one poll (5 s) later, and within the PV resolution (0.005 °C at the 0.2 °C band edge of an
    exponential with τ = 300 s: τ·ln(1.025) = 7.4 s) either way."""
    core = _core()
    twin = World(RigModel(), 0)
    twin.set_temperature(35.0)
    reference_c = twin.wait_stable(600.0)
    with chamber_server(plugin.kind.lower(), core) as server:
        chamber = plugin(plugin.Config(port=server.port, poll_interval_s=5.0))
        chamber.start()
        assert chamber.simulated
        chamber.set_temperature(35.0)
        measured_c = chamber.wait_stable(600.0)
        chamber.off()
        chamber.close()
    resolution_s = 300.0 * math.log(1 + 0.005 / 0.2)
    assert -resolution_s <= core.world.lab_time_s - twin.lab_time_s <= 5.0 + resolution_s
    assert abs(measured_c - 35.0) <= 0.2 + 1e-9 and abs(reference_c - 35.0) <= 0.2 + 1e-9
    assert core.mode == "STANDBY"
