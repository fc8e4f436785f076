"""Wire transcripts of the ``acutrol`` table driver (request → reply) through PyVISA's
``TCPIP::host::port::SOCKET`` session, each line citing its public source, and the simulator's
command language (short forms, case, ``;`` chaining, errors, limits, interlocks).

Sources: [MIT] AcutronicRobotics/acutrol (MIT licence), ``acutrol.py``/``ac117.json``: TCP,
``\\r\\n`` after each command, every reply preceded by 8 bytes the driver skips
(``recv(1024)[8:]``), ``OK`` after a command, ``:interlock:close 1``, ``:interlock:reset 1``,
``:mode:position 1``, ``:mode:rate 1``, ``:demand:position 1, x``, ``:demand:rate 1, x``,
``:read:position 1``, ``:mode:off 1``, ``:interlock:open 1``. [WS] williamsea/Acutrol
(``Form1.cs``): short forms ``:M:P 1``, ``:M:S 1`` (synthesis), ``:D:O 1, amp, freq, phase``,
``:L :R P 1 v`` / ``:L :A P 1 v`` (limits per mode and axis), ``:I:C 1``, ``:I:O 1``,
``:R:P 1``, chained ``:u:f f ; :R:P 1``. [488.2] IEEE 488.2 common commands (``*IDN?``
→ maker,model,serial,firmware; ``*STB?``; ``*OPC?``). [SCPI] SCPI-99 error numbers and
header chaining after ``;``. [SIM] aatest's simulator-side ``:XLOG`` log convention (not in
the public command set).
"""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import AxisLimits, TableEnvelope
from aatest.engine.steps import PlannedStep
from aatest.plugins.turntable.acutrol import AcutrolTurntable
from aatest.testing.transcript import TranscriptServer
from aatest.twin.model import RigModel
from aatest.twin.servers.acutrol_server import acutrol_server


def reply(text: str) -> bytes:
    """A reply as the simulator frames it: 8 header bytes [MIT], payload, CR LF [MIT]."""
    return f"#{len(text):07d}{text}\r\n".encode()


OK = reply("OK")  # [MIT] ac117.json: every startup/shutdown command answers "OK"
ENVELOPE = TableEnvelope(inner=AxisLimits(rate_dps=720.0, accel_dps2=900.0),
                         outer=AxisLimits(rate_dps=300.0, accel_dps2=150.0))
START = [
    (b"*IDN?\r\n", reply("ACUTRONIC,ACUTROL3000,A-1234,6.1")),  # [488.2] *IDN?
    (b":XLOG:STATE?\r\n", reply("IDLE")),  # [SIM] the reference log path exists
    # [WS] SetAllLimits ':L :R P 1 v', ':L :A P 1 v' for P, R and S modes (long forms)
    (b":LIMIT:RATE P,1,720;:LIMIT:ACCELERATION P,1,900\r\n", OK),
    (b":LIMIT:RATE R,1,720;:LIMIT:ACCELERATION R,1,900\r\n", OK),
    (b":LIMIT:RATE S,1,720;:LIMIT:ACCELERATION S,1,900\r\n", OK),
    (b":LIMIT:RATE P,2,300;:LIMIT:ACCELERATION P,2,150\r\n", OK),
    (b":LIMIT:RATE R,2,300;:LIMIT:ACCELERATION R,2,150\r\n", OK),
    (b":LIMIT:RATE S,2,300;:LIMIT:ACCELERATION S,2,150\r\n", OK),
    # [MIT] startup: ':interlock:reset 1', ':interlock:close 1' (both axes, one line [SCPI])
    (b":INTERLOCK:RESET;:INTERLOCK:CLOSE 1;:INTERLOCK:CLOSE 2\r\n", OK),
]
MOVE = [
    (b":MODE:POSITION 1;:MODE:POSITION 2\r\n", OK),  # [MIT] command_position ':mode:position 1'
    # [MIT] ':demand:position 1, x' for each axis
    (b":DEMAND:POSITION 1,0.000000;:DEMAND:POSITION 2,90.000000\r\n", OK),
    # [MIT] status() ':read:position 1'; [SCPI] the second header continues :READ
    (b":READ:POSITION? 1;POSITION? 2\r\n", reply("0.000000;90.000000")),
]
SAFE_STOP = [  # [MIT] shutdown: ':mode:off 1', ':interlock:open 1' (both axes, one line)
    (b":MODE:OFF 1;:MODE:OFF 2;:INTERLOCK:OPEN 1;:INTERLOCK:OPEN 2\r\n", OK),
]


def _table(port: int, **options: object) -> AcutrolTurntable:
    config = AcutrolTurntable.Config(port=port, timeout_s=2.0, envelope=ENVELOPE, **options)
    return AcutrolTurntable(config, None)


def _step_through(transcript: list[tuple[bytes, bytes | None]], step: PlannedStep) -> None:
    """Start the driver against ``transcript`` and run ``step`` through its whole motion (the
    server fails the test on any line out of order)."""
    with TranscriptServer(transcript) as server:
        table = _table(server.port)
        table.start()
        table.begin_motion(step)
        table.end_motion()
        table.close()


def test_start_move_and_safe_stop_send_exactly_the_public_commands() -> None:
    with TranscriptServer(START + MOVE + SAFE_STOP) as server:
        table = _table(server.port)
        table.start()
        table.move_to(0.0, 90.0)
        table.safe_stop()
        table.close()
    assert not table.simulated and table.serial == "A-1234"
    assert table.resource == f"TCPIP::127.0.0.1::{server.port}::SOCKET"


def test_sine_step_uses_synthesis_mode_and_the_oscillation_demand() -> None:
    step = PlannedStep(id="s001-sine", kind="sine", axis="inner", frequency_hz=2.0,
                       amplitude_deg=1.5, samples=4000, sample_rate_hz=2000.0, settle_s=1.0)
    transcript = [
        *START,
        (b":XLOG:CONFIG 2000,4000,1,s001-sine\r\n", OK),  # [SIM] log rate, samples, settle
        (b":MODE:SYNTHESIS 1\r\n", OK),  # [WS] SelectMode ':M:S 1'
        (b":DEMAND:OSCILLATION 1,1.5,2,0\r\n", OK),  # [WS] ':D:O 1, magn, freq, phase'
        (b":XLOG:ARM\r\n", OK),  # [SIM] armed: starts with the DAQ trigger
        (b":XLOG:STATE?\r\n", reply("ARMED")),  # [SIM]
        (b":MODE:POSITION 1;:MODE:POSITION 2\r\n", OK),  # end of motion [WS] ':M:P 1'
    ]
    _step_through(transcript, step)


def test_gpib_style_framing_is_a_setting() -> None:
    """Without acknowledgements and header (GPIB, [WS]: writes get no answer), commands are
    written and only queries read."""
    transcript = [
        (b"*IDN?\n", b"ACUTRONIC,ACUTROL3000,A-1234,6.1\n"),  # [488.2]
        (b":XLOG:STATE?\n", b"IDLE\n"),  # [SIM]
        *[(line.replace(b"\r\n", b"\n"), None) for line, _ in START[2:]],
    ]
    with TranscriptServer(transcript) as server:
        table = _table(server.port, reply_header_bytes=0, acknowledged_writes=False,
                       write_termination="\n", read_termination="\n")
        table.start()
        table.close()


def test_error_reply_is_a_rig_fault_naming_the_controller() -> None:
    transcript = [
        *START,
        (b":MODE:POSITION 1;:MODE:POSITION 2\r\n", OK),  # [MIT]
        (b":DEMAND:POSITION 1,0.000000;:DEMAND:POSITION 2,90.000000\r\n",
         reply('ERR -221,"Settings conflict; interlock of axis 2 open"')),  # [SCPI] -221
    ]
    with TranscriptServer(transcript) as server:
        table = _table(server.port)
        table.start()
        with pytest.raises(RigFault, match=r"ACUTROL controller TCPIP::127\.0\.0\.1::\d+::"
                                           r"SOCKET: .*refused: -221"):
            table.move_to(0.0, 90.0)
        table.close()


def test_controller_without_the_log_path_is_refused_at_start() -> None:
    transcript = [
        (b"*IDN?\r\n", reply("ACUTRONIC,ACUTROL3000,A-1234,6.1")),  # [488.2]
        (b":XLOG:STATE?\r\n", reply('ERR -113,"Undefined header"')),  # [SCPI] -113
    ]
    with TranscriptServer(transcript) as server:
        table = _table(server.port)
        with pytest.raises(RigFault, match=r"no table log \(:XLOG, the reference path "
                                           r"'controller-log'\)"):
            table.start()
        table.close()


# --- the simulator's command language ----------------------------------------------------
@pytest.fixture
def ask() -> Iterator:
    with acutrol_server(model=RigModel()) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
        replies = sock.makefile("rb")

        def exchange(line: str) -> str:
            sock.sendall(line.encode() + b"\r\n")
            raw = replies.readline()
            assert raw.endswith(b"\r\n") and raw[:1] == b"#"  # [MIT] 8-byte header, CR LF
            assert int(raw[1:8]) == len(raw) - 10
            return raw[8:-2].decode()

        yield exchange


def test_simulator_identifies_itself_as_simulated(ask) -> None:
    maker, model, serial, _firmware = ask("*IDN?").split(",")  # [488.2] four fields
    assert maker == "ACUTRONIC" and "SIMULATOR" in model and serial


@pytest.mark.parametrize("line", [":MODE:POSITION 1", ":mode:position 1", ":M:P 1",
                                  ":Mo:Pos 1", ":m:p 1"])
def test_long_short_and_lowercase_forms_are_one_command(ask, line: str) -> None:
    assert ask(":M:R 1") == "OK"  # [WS] ':M:R 1'
    assert ask(line) == "OK"  # [MIT] long lowercase, [WS] short forms
    assert ask(":MODE? 1") == "P"


def test_interlock_gates_motion_and_chained_reads(ask) -> None:
    assert ask(":D:P 1,10.5").startswith("ERR -221")  # interlock open: refused [SCPI] -221
    assert ask(":SYST:ERR?").startswith("-221,")  # [SCPI] error queue
    assert ask("*STB?") == "0"  # [488.2] queue read empty, interlocks open
    assert ask(":I:C 1;:I:C 2") == "OK"  # [WS] ':I:C 1'
    assert ask(":D:P 1,10.5") == "OK"  # issue 25: ':D:P 1,10.5'
    assert ask(":READ:POS? 1;RATE? 1;ACC? 1") == "10.500000;0.000000;0.000000"  # [SCPI] chain
    assert ask("*OPC?") == "1"  # [488.2]


@pytest.mark.parametrize(("line", "code"), [
    (":FOO 1", "-113"),  # undefined header [SCPI]
    (":D:P", "-109"),  # missing axis [SCPI] missing parameter
    (":D:P 3,1", "-222"),  # axis out of range [SCPI] data out of range
    (":D:P 1,abc", "-104"),  # [SCPI] data type error
    (":M 1", "-113"),  # incomplete header
    (":XLOG:CONFIG 2000,300000,1,x", "-222"),  # beyond the log capacity (230000) [SIM]
    (":XLOG:CONFIG 4000,2000,1,x", "-222"),  # beyond the log rate (2 kHz) [SIM]
])
def test_malformed_commands_answer_scpi_errors(ask, line: str, code: str) -> None:
    assert ask(":I:C 1;:I:C 2") == "OK"
    assert ask(line).startswith(f"ERR {code},")


def test_limits_refuse_demands_beyond_them(ask) -> None:
    assert ask(":I:C 1;:I:C 2;:M:S 1") == "OK"
    assert ask(":L :R S 1 100") == "OK"  # [WS] ':L :R S 1 v' with blanks
    assert ask(":LIMIT:RATE? S,1") == "100"
    # 10° at 2 Hz peaks at 2π·2·10 = 125.7 °/s > 100 °/s: refused [SCPI] -222
    assert ask(":D:O 1,10,2,0").startswith("ERR -222,")
    assert ask(":D:O 1,5,2,0") == "OK"  # 62.8 °/s, 790 °/s² < 1000 °/s² factory
    assert ask(":L:R S,1,5000").startswith("ERR -222,")  # beyond the factory 1200 °/s
    assert ask(":L:R R,1,100") == "OK"  # the rate-mode limit, comma separated
    assert ask(":M:R 1;:D:R 1,150").startswith("ERR -222,")  # 150 °/s > 100 °/s
    assert ask(":MODE? 1") == "R"  # the mode before the refused demand was carried out
    assert ask(":READ:RATE? 1") == "0.000000"  # the refused demand was not


# --- the operator's mounting on the simulator ([SIM] :XLOG:MOUNTING) ----------------------
PIVOTED = {"kind": "static", "samples": 4000, "sample_rate_hz": 2000.0, "settle_s": 1.0,
           "mounting": {"pivoted": True, "remount": "both"}}
SIM_IDN = reply("ACUTRONIC,ACUTROL SIMULATOR,SIM-0001,aatest 0")  # [SIM] *IDN? of the simulator
STATIC_TAIL = [
    (b":XLOG:ARM\r\n", OK),  # [SIM] a static step starts holding here
    (b":XLOG:STATE?\r\n", reply("ARMED")),  # [SIM]
]


@pytest.mark.parametrize("simulator", [True, False])
def test_a_pivoted_step_tells_only_the_simulator_its_mounting(simulator: bool) -> None:
    """On a real table the operator pivots and re-mounts at the prompt and the controller hears
    nothing of it; the simulator, which has no operator, gets the step's mounting."""
    step = PlannedStep(id="static-i0-o0-pivoted-r1", **PIVOTED)
    mounting = [(b":XLOG:MOUNTING 1,both\r\n", OK)] if simulator else []  # [SIM]
    transcript = [
        (START[0][0], SIM_IDN if simulator else START[0][1]), *START[1:],
        (b":XLOG:CONFIG 2000,4000,1,static-i0-o0-pivoted-r1\r\n", OK),  # [SIM]
        *mounting, *STATIC_TAIL,
    ]
    with TranscriptServer(transcript) as server:
        table = _table(server.port)
        table.start()
        table.begin_motion(step)
        table.close()
    assert table.simulated is simulator


@pytest.mark.parametrize(("line", "code"), [
    (":XLOG:MOUNTING 1", "-109"),  # [SCPI] missing parameter
    (":XLOG:MOUNTING 2,none", "-224"),  # [SCPI] illegal parameter value: pivoted is 0 or 1
    (":XLOG:MOUNTING 0,glued", "-224"),  # no such re-mount
])
def test_malformed_mounting_answers_scpi_errors(ask, line: str, code: str) -> None:
    assert ask(line).startswith(f"ERR {code},")


def test_simulator_pivots_and_remounts_its_twin_for_one_log() -> None:
    """``:XLOG:MOUNTING 1,both`` pivots the twin's unit and draws a new block and seat error
    for the next log, as the in-process twin's step would; a new ``:XLOG:CONFIG`` is the
    original mounting again (pivot undone, the re-mount kept: the unit stays where it sits)."""
    with acutrol_server(model=RigModel()) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
        world = server.protocol.controller.world  # type: ignore[attr-defined]
        replies = sock.makefile("rb")

        def ask(line: str) -> str:
            sock.sendall(line.encode() + b"\r\n")
            return replies.readline()[8:-2].decode()

        before = world.block_error.copy()
        assert ask(":I:C 1;:I:C 2;:XLOG:CONFIG 2000,100,0,p1;:XLOG:M 1,Both;:XLOG:ARM") == "OK"
        assert world.pivoted
        assert not (world.block_error == before).all()
        remounted = world.block_error.copy()
        assert ask(":D:P 1,0") == "OK"  # the next step's move ends the hold
        assert ask(":XLOG:CONFIG 2000,100,0,p2;:XLOG:ARM") == "OK"
        assert not world.pivoted
        assert (world.block_error == remounted).all()


# --- the sensors the simulator serves (--sensor) -------------------------------------------
def test_simulator_serves_the_sensors_of_the_named_model() -> None:
    """``--sensor sr207-aamu``: one twin sensor per datasheet channel, on its seat axis, as the
    in-process twin builds from the same datasheet; none named: the reference sensor."""
    from aatest.plugins.sensors.sr207 import SR207Unit
    from aatest.twin.defaults import realistic_rig_model
    from aatest.twin.servers.sensor_models import sensor_rig_model

    unit = sensor_rig_model("sr207-aamu")
    assert [(s.channel, s.axis) for s in unit.sensors] == [("v_sz", "I"), ("v_sy", "O"),
                                                           ("v_sx", "P")]
    assert unit == realistic_rig_model(SR207Unit().datasheet())
    assert [s.channel for s in sensor_rig_model(None).sensors] == ["v_sz"]


def test_unknown_sensor_model_is_bad_input() -> None:
    from typer.testing import CliRunner

    from aatest.cli import app

    result = CliRunner().invoke(app, ["sim-server", "acutrol", "--port", "0", "--sensor",
                                      "sr999", "--can-interface", "none"])
    assert result.exit_code == 2
    assert "no sensor plugin named 'sr999' (installed: " in result.output


# --- a static step held with the motor off (motor_on: false) ------------------------------
MOTOR_OFF = {"kind": "static", "samples": 4000, "sample_rate_hz": 2000.0, "settle_s": 1.0,
             "motor_on": False}


def test_a_motor_off_step_opens_the_interlocks_and_closes_them_after() -> None:
    """``motor_on: false``: the interlocks open (the public set's motor off, [MIT] shutdown
    ':interlock:open 1') before the hold is armed, and close again ([MIT] startup) before the
    table is next commanded."""
    step = PlannedStep(id="s01-off", **MOTOR_OFF)
    transcript = [
        *START,
        (b":XLOG:CONFIG 2000,4000,1,s01-off\r\n", OK),  # [SIM]
        (b":INTERLOCK:OPEN 1;:INTERLOCK:OPEN 2\r\n", OK),  # [MIT] ':interlock:open 1'
        *STATIC_TAIL,
        (b":INTERLOCK:RESET;:INTERLOCK:CLOSE 1;:INTERLOCK:CLOSE 2\r\n", OK),  # [MIT] startup
        (b":MODE:POSITION 1;:MODE:POSITION 2\r\n", OK),  # end of motion [WS] ':M:P 1'
    ]
    _step_through(transcript, step)


def test_simulator_holds_still_with_the_motor_off_and_refuses_motion() -> None:
    """Through the driver: the simulator's twin holds the motor-off step without the servo
    (its truth has the motor off on both axes), the motor is on again after it; with the
    interlocks open an armed sine is refused (motion needs the motor)."""
    with acutrol_server(model=RigModel()) as server:
        world = server.protocol.controller.world  # type: ignore[attr-defined]  # behind the wire
        table = _table(server.port)
        table.start()
        table.move_to(0.0, 0.0)
        step = PlannedStep(id="s01-off", **MOTOR_OFF)
        table.begin_motion(step)
        assert not world.motor_on
        assert world._motion[1].motor_on is False and world._motion[2].motor_on is False
        server.protocol.controller.daq_start()  # type: ignore[attr-defined]  # the trigger
        log = table.record(step)  # a whole record with the motor off
        assert len(log) == step.samples and not world.motor_on
        table.end_motion()
        assert world.motor_on
        table.move_to(0.0, 0.0)  # the next step's move is accepted
        table.write(":M:S 1;:D:O 1,1,2,0")  # a sine demanded with the motor on
        table.write(":I:O 1;:I:O 2;:XLOG:CONFIG 2000,100,0,x")  # motor off, demand kept
        with pytest.raises(RigFault, match=r"-221,.*interlock open"):
            table.write(":XLOG:ARM")
        table.safe_stop()
        table.close()
