"""A static record longer than the table's log through the ``acutrol`` pair (issue 25): the
driver configures and arms only the log's head, and the simulator streams the CAN logger's
timed record from its twin while the head is logged, as the in-process rig does.

Sources of the transcript lines as in ``test_acutrol_transcripts.py``: [SIM] aatest's
simulator-side ``:XLOG`` convention, [WS] williamsea/Acutrol, [MIT] AcutronicRobotics/acutrol.
"""

from __future__ import annotations

import socket
import time

import numpy as np
import pytest

from aatest.engine.interfaces import TableEnvelope
from aatest.engine.logs import TABLE_CHANNELS
from aatest.engine.procedure.envelope import head_step
from aatest.engine.steps import PlannedStep
from aatest.plugins.turntable.acutrol import AcutrolTurntable
from aatest.testing.transcript import TranscriptServer
from aatest.twin.model import RigModel
from aatest.twin.servers.acutrol_server import acutrol_server
from aatest.twin.synthesis import concatenate_logs
from aatest.twin.world import World


def reply(text: str) -> bytes:
    """A reply as the simulator frames it: 8 header bytes [MIT], payload, CR LF [MIT]."""
    return f"#{len(text):07d}{text}\r\n".encode()


OK = reply("OK")  # [MIT] every command answers "OK"
HEAD_SAMPLES = 20_000
ENVELOPE = TableEnvelope(log_capacity_samples=HEAD_SAMPLES)
LONG = PlannedStep(id="up", kind="static", samples=180_000, sample_rate_hz=1000.0, settle_s=2.0)


def test_a_streamed_static_step_configures_and_arms_only_the_head() -> None:
    """180 000 samples on a log of 20 000: ``:XLOG:CONFIG`` asks for the head (the controller
    refuses a log beyond its capacity), armed in ``begin_motion`` before the DAQ's trigger."""
    transcript = [
        (b"*IDN?\r\n", reply("ACUTRONIC,ACUTROL3000,A-1234,6.1")),  # [488.2]
        (b":XLOG:STATE?\r\n", reply("IDLE")),  # [SIM]
        *[(line, OK) for line in (  # [WS] limits per mode and axis; [MIT] interlocks
            b":LIMIT:RATE P,1,1200;:LIMIT:ACCELERATION P,1,1000\r\n",
            b":LIMIT:RATE R,1,1200;:LIMIT:ACCELERATION R,1,1000\r\n",
            b":LIMIT:RATE S,1,1200;:LIMIT:ACCELERATION S,1,1000\r\n",
            b":LIMIT:RATE P,2,500;:LIMIT:ACCELERATION P,2,200\r\n",
            b":LIMIT:RATE R,2,500;:LIMIT:ACCELERATION R,2,200\r\n",
            b":LIMIT:RATE S,2,500;:LIMIT:ACCELERATION S,2,200\r\n",
            b":INTERLOCK:RESET;:INTERLOCK:CLOSE 1;:INTERLOCK:CLOSE 2\r\n")],
        (b":XLOG:CONFIG 1000,20000,2,up\r\n", OK),  # [SIM] the head: the log's capacity
        (b":XLOG:ARM\r\n", OK),  # [SIM] a static step starts holding here
        (b":XLOG:STATE?\r\n", reply("ARMED")),  # [SIM]
    ]
    with TranscriptServer(transcript) as server:
        config = AcutrolTurntable.Config(port=server.port, timeout_s=2.0, envelope=ENVELOPE)
        table = AcutrolTurntable(config, None)
        table.start()
        table.begin_motion(LONG)
        table.close()


@pytest.fixture
def simulator() -> object:
    with acutrol_server(model=RigModel(), seed=3) as server:
        yield server


def test_simulator_streams_the_timed_record_and_logs_its_head(simulator: object) -> None:
    """The simulator makes the World calls the in-process rig makes for a streamed step (the
    same seed gives the same generator draws, so the logs are equal sample for sample): the
    DAQ record of 30 000 samples after the trigger, lazily in chunks, and the table's head of
    2000 from the same trigger. Nothing is queued for the STOP-ended path."""
    controller = simulator.protocol.controller  # type: ignore[attr-defined]
    queued: list[object] = []
    controller.on_daq_log = queued.append
    step = LONG.model_copy(update={"samples": 30_000, "settle_s": 1.0})
    head = head_step(step, TableEnvelope(log_capacity_samples=2000))
    with socket.create_connection(("127.0.0.1", simulator.port), timeout=10) as sock:  # type: ignore[attr-defined]
        replies = sock.makefile("rb")

        def ask(line: str) -> str:
            sock.sendall(line.encode() + b"\r\n")
            return replies.readline()[8:-2].decode()

        assert ask(":I:C 1;:I:C 2;:XLOG:CONFIG 1000,2000,1,up;:XLOG:ARM") == "OK"
        chunks = list(controller.daq_stream(step.samples))
        with pytest.raises(ValueError, match="a record already running"):
            controller.daq_stream(step.samples)
        deadline = time.monotonic() + 30.0
        while ask(":XLOG:STATE?") != "DONE":
            assert time.monotonic() < deadline
            time.sleep(0.01)
        log_id, samples, rate_hz, _t0 = ask(":XLOG:HEADER?").split(",")
    assert (log_id, int(samples), float(rate_hz)) == ("1", 2000, 1000.0)
    assert queued == []

    world = World(RigModel(), 3)  # the in-process rig: table, then the streaming DAQ
    world.motor_on = True
    world.begin_motion(step)
    world.start_daq()
    reference = concatenate_logs(list(world.stream_daq(4)))
    reference_head = world.table_record(head)

    daq = concatenate_logs(chunks)
    assert len(daq) == len(reference)
    assert int(np.argmax(daq["trigger"] > 0.5)) + step.samples <= len(daq)
    for name in daq.channels:
        np.testing.assert_array_equal(daq[name], reference[name], err_msg=name)
    table = controller.log.table
    np.testing.assert_array_equal(table.time_s, reference_head.time_s)
    for name in TABLE_CHANNELS:
        np.testing.assert_array_equal(table[name], reference_head[name], err_msg=name)


def test_simulator_refuses_a_timed_record_without_a_step(simulator: object) -> None:
    controller = simulator.protocol.controller  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="no step in motion"):
        controller.daq_stream(1000)
