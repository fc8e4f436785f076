"""Long static records: the DAQ streams in chunks, the table logs its full-rate head (its
log buffer; issues 14 item 3, 26 item 1).

Physical truths checked against the twin: a streamed record is the one-shot record sample for
sample (and the step file byte for byte); the envelope lets a long *static* record through only
with a streaming DAQ; a fault mid-record keeps the chunks already written and ``--resume``
records the step again.
"""

from __future__ import annotations

import textwrap
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from aatest.engine.errors import RigFault
from aatest.engine.interfaces import (
    SensorDatasheet,
    StreamingDaq,
    TableEnvelope,
    supports_streaming,
)
from aatest.engine.logs import SampledLog
from aatest.engine.procedure.envelope import head_step, step_violations, streams_record
from aatest.engine.steps import PlannedStep
from aatest.plugins.daq.sim import SimDaq
from aatest.recording import read_dataset
from aatest.recording.writer import RunRecorder
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.world import World

FS_HZ = 2000.0
#: 10 min of lab time: long enough for several generation blocks and stream chunks
TEN_MIN = PlannedStep(id="s001-static-long", kind="static", samples=int(600 * FS_HZ),
                      duration_s=600.0, settle_s=5.0, motor_on=False)


def _world(seed: int = 7) -> World:
    world = World(realistic_rig_model(), seed=seed)
    world.move_to(0.0, 0.0)
    world.begin_motion(TEN_MIN)
    world.start_daq()
    return world


def _table(world: World) -> SampledLog:
    return world.snapshot_log(head_step(TEN_MIN, TableEnvelope()))


def test_streamed_record_equals_the_one_shot_record() -> None:
    one_shot = _world().result().daq
    world = _world()
    chunks = list(world.stream_daq(1))
    assert len(chunks) > 5  # several chunks, each a whole number of generation blocks
    streamed_time = np.concatenate([c.time_s for c in chunks])
    assert np.array_equal(streamed_time, one_shot.time_s)
    for name, values in one_shot.channels.items():
        assert np.array_equal(np.concatenate([c[name] for c in chunks]), values), name
    # continuous noise state: no step at the chunk joints beyond the noise itself
    volts = one_shot["v_sz"]
    joints = np.cumsum([len(c) for c in chunks])[:-1]
    jumps = np.abs(volts[joints] - volts[joints - 1])
    assert jumps.max() < 6 * np.std(np.diff(volts))


def test_streamed_step_file_is_byte_identical_to_the_one_shot_file(tmp_path: Path) -> None:
    world = _world()
    daq = world.result().daq
    table = _table(world)  # after the record, as the runner asks for it
    meta = {"plan": [TEN_MIN.model_dump(mode="json")]}
    one = RunRecorder(tmp_path / "one")
    one.write_run_metadata(meta)
    one_file = one.write_step(TEN_MIN, table, daq)

    world = _world()
    streamed = RunRecorder(tmp_path / "streamed")
    streamed.write_run_metadata(meta)
    step = streamed.stream_step(TEN_MIN)
    for chunk in world.stream_daq(1):
        step.add(chunk)
    streamed_file = step.finish(_table(world))
    assert streamed_file.read_bytes() == one_file.read_bytes()
    assert not list(streamed_file.parent.glob("*.partial*"))  # the spool is gone
    back = read_dataset(streamed_file).steps[0]
    assert np.array_equal(back.daq["v_sz"], daq["v_sz"])
    # the table's full-rate head: its log buffer (230 000 samples), the freeze-pulse edges in it
    assert len(back.table) == 230_000 and back.table.sample_rate_hz == FS_HZ


def test_sim_daq_streams_chunks_of_about_the_asked_length() -> None:
    world = _world()
    daq = SimDaq.__new__(SimDaq)  # the plugin around this world (no session needed)
    daq.config, daq._twin = SimDaq.Config(), type("T", (), {"world": world})()
    assert isinstance(daq, StreamingDaq) and supports_streaming(daq)
    sizes = [len(c) for c in daq.stream_logging(TEN_MIN, 60.0)]
    assert all(s >= 60 * FS_HZ for s in sizes[:-1])
    assert sum(sizes) == len(_world().result().daq)


# --- envelope -----------------------------------------------------------------------------------

SHEET = SensorDatasheet(model="sr207")
TWO_HOURS = TEN_MIN.model_copy(update={"samples": int(7200 * FS_HZ), "duration_s": 7200.0})


def test_long_static_record_needs_a_streaming_daq() -> None:
    plain = TableEnvelope()
    refused = step_violations(TWO_HOURS, plain, SHEET)
    assert [v.limit for v in refused] == ["log_capacity_samples"]
    assert "streams" in refused[0].message and not refused[0].skippable
    streaming = plain.model_copy(update={"streaming_daq": True})
    assert step_violations(TWO_HOURS, streaming, SHEET) == []
    assert streams_record(TWO_HOURS, streaming) and not streams_record(TWO_HOURS, plain)
    table = head_step(TWO_HOURS, streaming)
    assert table.sample_rate_hz == FS_HZ and table.samples == streaming.log_capacity_samples


def test_dynamic_steps_keep_the_log_capacity_rule_with_a_streaming_daq() -> None:
    streaming = TableEnvelope(streaming_daq=True)
    sine = PlannedStep(id="s", kind="sine", axis="inner", frequency_hz=1.0, amplitude_deg=1.0,
                       accel_dps2=39.5, samples=400_000)
    assert "log_capacity_samples" in [v.limit for v in step_violations(sine, streaming, SHEET)]
    short = TEN_MIN.model_copy(update={"samples": 100_000})
    assert not streams_record(short, streaming)  # fits the table log: recorded as always


def test_the_head_is_as_long_as_the_log_buffer_holds() -> None:
    env = TableEnvelope(streaming_daq=True, log_capacity_samples=3600)
    table = head_step(TWO_HOURS, env)
    assert table.samples == 3600 and table.sample_rate_hz == FS_HZ


# --- fault mid-record and resume ----------------------------------------------------------------

PROCEDURE = textwrap.dedent("""\
    procedure: long-static-test
    sensor: {model: sr207, serial: "T-1"}
    rig: {turntable: sim, daq: sim, chamber: none}
    sampling: {rate_hz: 2000, settle_s: 5}
    steps:
      - static: {label: short, duration_s: 10}
      - static: {label: long, duration_s: 600, motor_on: false}
    analysis: [drift]
    report: {template: calibration-certificate, sign: false}
    """)


class _FaultingDaq:
    """The sim DAQ, faulting after ``after`` chunks of a streamed record."""

    def __init__(self, inner: Any, after: int) -> None:
        self._inner, self._after = inner, after

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def stream_logging(self, step: PlannedStep, chunk_s: float) -> Iterator[SampledLog]:
        for n, chunk in enumerate(self._inner.stream_logging(step, chunk_s)):
            if n == self._after:
                raise RigFault("CAN logger: bus-off")
            yield chunk


def test_fault_mid_record_keeps_the_chunks_and_resume_records_the_step(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from aatest.engine.run import session

    procedure = tmp_path / "long.yaml"
    procedure.write_text(PROCEDURE)
    out = tmp_path / "run"
    real_build = session.build_rig

    def faulting_rig(*args: Any, **kwargs: Any) -> Any:
        rig = real_build(*args, **kwargs)
        rig.daq = _FaultingDaq(rig.daq, after=3)
        return rig

    monkeypatch.setattr(session, "build_rig", faulting_rig)
    with pytest.raises(RigFault) as fault:
        session.run(procedure, None, out, False, 0, None, show_progress=False)
    spools = sorted((out / "steps").glob("*.partial*"))
    assert len(spools) == 1 and str(spools[0]) in str(fault.value)
    assert "bus-off" in str(fault.value)
    with open(spools[0], "rb") as stream:  # a complete MCAP file: the 3 chunks are intact
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        blocks = summary.statistics.message_count
    assert blocks == -(-3 * 2**17 // 4096)  # 3 chunks of one 2^17-sample block, 4096 per block
    assert [p.name for p in (out / "steps").glob("*.mcap")] == ["001-s001-static-short.mcap"]

    monkeypatch.setattr(session, "build_rig", real_build)
    session.run(procedure, None, out, True, 0, None, show_progress=False)
    assert spools[0].exists()  # the faulted attempt's samples are never dropped silently
    data = read_dataset(out)
    long = data.steps[1]
    assert long.step.id == "s002-static-long"
    trigger = int(np.flatnonzero(long.daq["trigger"] > 0.5)[0])
    assert (len(long.daq) - trigger) / FS_HZ == pytest.approx(600.4, abs=0.01)  # + stop lag
    assert len(long.table) == 230_000  # the table's head (its log buffer)


# --- the shipped 2-hour procedure, end to end (slow) --------------------------------------------


@pytest.mark.slow
def test_shipped_two_hour_drift_procedure_end_to_end(tmp_path: Path) -> None:
    import json

    from typer.testing import CliRunner

    import aatest
    from aatest.cli import app
    from aatest.twin.daq import antialias_filter
    from aatest.twin.defaults import REALISTIC_DRIFT

    procedure = Path(aatest.__file__).parent / "procedures" / "long-static-drift.yaml"
    out = tmp_path / "run"
    result = CliRunner().invoke(app, ["run", str(procedure), "--out", str(out)])
    assert result.exit_code == 0, result.output
    drift = json.loads((out / "results.json").read_text())["analysis"]["drift"]["v_sz"]
    assert drift["duration_s"] == pytest.approx(7200.0, rel=1e-3)
    assert drift["max_tau_s"] >= 1000.0
    assert len(drift["intervals"]) == 4  # bias and temperature every 30 min
    model = realistic_rig_model(SensorDatasheet(model="sr207"))
    sensor = model.sensors[0]
    gain = antialias_filter(float(model.daq.antialias_hz), 1.0 / FS_HZ)[2]
    white = sensor.noise_rms_v / gain / np.sqrt(FS_HZ) / sensor.scale_v_per_dps2
    assert drift["allan_fit"]["white_noise_dps2_sqrt_s"] == pytest.approx(white, rel=0.10)
    # steady drift 1e-4 V/h; the random walk (5e-7 V/√s) and the Gauss–Markov bias
    # instability (1e-5 V, 300 s) move a 2-h slope by a few 1e-5 V/h
    assert drift["drift_v_per_h"] == pytest.approx(REALISTIC_DRIFT.rate_v_per_h, abs=6e-5)
    assert (out / "report.html").exists()
