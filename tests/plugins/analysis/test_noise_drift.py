"""The drift analysis of a long static record against the twin's known truth.

The twin's sensor carries a known steady drift and white noise; the record is streamed in
chunks exactly as a run records it. Tolerances: the white-noise coefficient within 10 % (its
Allan estimate at τ = 1…16 s on a 40-min record has a few % scatter), the drift slope within
3·10⁻⁵ V/h of 2·10⁻³ V/h (the small random walk moves it by ≈1.5·10⁻⁵ V/h), the rate ramp
within 20 %.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aatest.engine.interfaces import AnalysisContext, TableEnvelope
from aatest.engine.logs import SampledLog
from aatest.engine.procedure.envelope import head_step
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.drift import (
    BlockMeans,
    DriftAnalysis,
    DriftOptions,
    block_means,
    fit_allan,
    longest_static_index,
    reduce_record,
)
from aatest.recording import RunRecorder, read_dataset
from aatest.recording.dataset import Dataset, LazySteps, SensorInfo, StepData
from aatest.results.noise import DriftResult
from aatest.twin.daq import antialias_filter
from aatest.twin.defaults import realistic_rig_model
from aatest.twin.model import BiasDrift
from aatest.twin.synthesis import concatenate_logs
from aatest.twin.world import World

FS_HZ = 2000.0
MINUTES = 40
RATE_V_PER_H = 2e-3
WALK_V_PER_SQRT_S = 2e-7


def _long_record(seed: int, minutes: float = MINUTES, step_id: str = "s001-static-drift"
                 ) -> tuple[Dataset, World]:
    model = realistic_rig_model()
    drift = BiasDrift(rate_v_per_h=RATE_V_PER_H, random_walk_v_per_sqrt_s=WALK_V_PER_SQRT_S)
    model = model.model_copy(update={"sensors": [model.sensors[0].model_copy(
        update={"bias_drift": drift})]})
    step = PlannedStep(id=step_id, kind="static", samples=int(minutes * 60 * FS_HZ),
                       duration_s=minutes * 60.0, motor_on=False)
    world = World(model, seed=seed)
    world.move_to(0.0, 0.0)
    world.begin_motion(step)
    world.start_daq()
    daq = concatenate_logs(list(world.stream_daq(4)))
    table = world.snapshot_log(head_step(step, TableEnvelope(streaming_daq=True)))
    sensor = model.sensors[0]
    info = SensorInfo(channel=sensor.channel, axis="I",
                      nominal_scale_v_per_dps2=sensor.scale_v_per_dps2)
    data = Dataset(procedure="drift-test", sample_rate_hz=FS_HZ, sensors=(info,),
                   steps=(StepData(step, table, daq),), source=Path("memory"))
    return data, world


@pytest.fixture(scope="module")
def drift_result() -> tuple[DriftResult, World]:
    data, world = _long_record(seed=11)
    out = DriftAnalysis().run(data, AnalysisContext(options=DriftOptions()))
    return out.result, world


def test_white_noise_coefficient_matches_the_twin(drift_result: tuple[DriftResult, World]) -> None:
    result, world = drift_result
    sensor = world.model.sensors[0]
    gain = antialias_filter(float(world.model.daq.antialias_hz), 1.0 / FS_HZ)[2]
    # white noise injected before the pre-sample filter: σ_in = rms/gain per sample; its
    # low-frequency density gives σ_A(τ) = σ_in/√(fs·τ), i.e. N = σ_in/√fs
    truth = sensor.noise_rms_v / gain / np.sqrt(FS_HZ) / sensor.scale_v_per_dps2
    fitted = result["v_sz"].allan_fit.white_noise_dps2_sqrt_s
    assert fitted == pytest.approx(truth, rel=0.10)
    read = result["v_sz"].allan_dps2.white_noise_per_sqrt_hz
    assert read is not None and read == pytest.approx(truth, rel=0.15)


def test_bias_drift_matches_the_twin(drift_result: tuple[DriftResult, World]) -> None:
    result, world = drift_result
    channel = result["v_sz"]
    assert channel.drift_v_per_h == pytest.approx(RATE_V_PER_H, abs=3e-5)
    assert channel.drift_sigma_v_per_h < 3e-5
    # peak-to-peak of the 60 s means: the ramp over the record (plus a little noise)
    assert channel.peak_to_peak_v == pytest.approx(RATE_V_PER_H * MINUTES / 60, rel=0.15)
    scale = world.model.sensors[0].scale_v_per_dps2
    ramp = channel.allan_fit.rate_ramp_dps2_per_s
    assert ramp is not None and ramp == pytest.approx(RATE_V_PER_H / 3600 / scale, rel=0.2)
    sensor, t_ref_c = world.model.sensors[0], world.model.t_ref_c
    assert sensor.g_sensitivity is not None and sensor.bias_temperature is not None
    at_rest_v = (sensor.bias_v  # + 1 g along the upward I axis + temperature below T_ref
                 + sensor.g_sensitivity.coefficient_dps2_per_g * sensor.scale_v_per_dps2
                 + sensor.bias_temperature.coefficient_v_per_c * (22.0 - t_ref_c))
    assert channel.bias_v == pytest.approx(at_rest_v + RATE_V_PER_H * MINUTES / 120, abs=5e-5)


def test_allan_deviation_reaches_long_tau(drift_result: tuple[DriftResult, World]) -> None:
    result, _ = drift_result
    channel = result["v_sz"]
    assert channel.max_tau_s >= 1000.0  # 40 min at 1 s: octaves up to 1024 s (≥ 2 clusters)
    assert channel.average_s == 1.0 and channel.duration_s == pytest.approx(MINUTES * 60, rel=1e-3)
    assert len(channel.intervals) == 2  # 30-min reporting intervals
    assert channel.intervals[1].bias_v > channel.intervals[0].bias_v  # the drift is upwards


def test_block_means_and_the_allan_fit_on_known_curves() -> None:
    assert np.array_equal(block_means(np.arange(10.0), 3), [1.0, 4.0, 7.0])
    assert np.array_equal(block_means(np.arange(10.0), 3, origin=1.0), [0.0, 3.0, 6.0])
    # reduced a bounded number of rows at a time, each row exactly as on the whole array
    values = np.random.default_rng(4).normal(7200.0, 1.0, 3 * 2**20 + 5)
    whole = (values[: values.size // 2000 * 2000] - values[0]).reshape(-1, 2000).mean(1)
    assert block_means(values, 2000, origin=values[0]).tobytes() == whole.tobytes()
    taus = 2.0 ** np.arange(0, 12)
    n, k = 0.02, 1e-4
    fit = fit_allan(taus, np.sqrt(n**2 / taus + k**2 * taus / 3))
    assert fit["white_noise_dps2_sqrt_s"] == pytest.approx(n, rel=1e-6)
    assert fit["rate_random_walk_dps2_per_sqrt_s"] == pytest.approx(k, rel=1e-6)
    assert fit["bias_instability_dps2"] is None and fit["rate_ramp_dps2_per_s"] is None


def test_a_recorded_drift_run_decodes_only_what_the_drift_reads(tmp_path: Path) -> None:
    """From a recording, the longest static step is chosen by its sample count and only its
    trigger, sensor and temperature channels are decoded, piece by piece; the result is the
    in-memory one's, to the bit."""
    short, _ = _long_record(seed=3, minutes=1.0, step_id="s001-static-short")
    long, _ = _long_record(seed=4, minutes=3.0, step_id="s002-static-long")
    recorder = RunRecorder(tmp_path)
    recorder.write_run_metadata({"procedure": "drift-test", "sample_rate_hz": FS_HZ,
                                 "sensors": [vars(long.sensors[0])]})
    for data in (short, long):
        recorder.write_step(data.steps[0].step, data.steps[0].table, data.steps[0].daq)
    lazy = read_dataset(recorder.finalize())
    assert isinstance(lazy.steps, LazySteps)
    loads: list[tuple[str, int, str, object]] = []
    load, pieces = lazy.steps._load, lazy.steps._pieces
    assert pieces is not None

    def counting_load(index: int, source: str, channels: object) -> object:
        loads.append(("whole", index, source, channels))
        return load(index, source, channels)  # type: ignore[arg-type]

    def counting_pieces(index: int, source: str, channels: object) -> object:
        loads.append(("pieces", index, source, channels))
        return pieces(index, source, channels)  # type: ignore[arg-type]

    lazy.steps._load, lazy.steps._pieces = counting_load, counting_pieces  # type: ignore[assignment]
    assert longest_static_index(lazy) == 1 and not loads
    eager = Dataset(procedure="drift-test", sample_rate_hz=FS_HZ, sensors=lazy.sensors,
                    steps=(long.steps[0],), source=Path("memory"))
    from_file = DriftAnalysis().run(lazy, AnalysisContext(options=DriftOptions()))
    in_memory = DriftAnalysis().run(eager, AnalysisContext(options=DriftOptions()))
    assert from_file.result.model_dump() == in_memory.result.model_dump()
    assert from_file.result["v_sz"].record_step == "s002-static-long"
    # step 1 only, piece by piece: the trigger, then the sensor and the temperature
    assert [(kind, i, source) for kind, i, source, _ in loads] == [("pieces", 1, "daq")] * 2
    assert [list(channels) for *_, channels in loads] == [["trigger"], ["v_sz", "temperature_c"]]


def test_block_means_fed_in_pieces_equal_the_whole_record() -> None:
    """Pieces of any size, a start inside a piece: the reduction is the whole record's, bit
    for bit (the carried samples keep every block's rows as on the whole array)."""
    rng = np.random.default_rng(8)
    n = 50_017
    time_s = 3.0 + np.arange(n) / FS_HZ
    volts = 2.5 + rng.normal(0, 1e-3, n)
    temperature = np.round(22.0 + rng.normal(0, 0.01, n), 2)
    cuts = np.sort(rng.choice(np.arange(1, n), 40, replace=False))
    pieces = [SampledLog("daq", FS_HZ, t, {"v": v, "temperature_c": c})
              for t, v, c in zip(np.split(time_s, cuts), np.split(volts, cuts),
                                 np.split(temperature, cuts), strict=True)]
    start = int(cuts[3]) + 7
    reduced = reduce_record(pieces, ["v"], start, 1.0)
    assert reduced.samples == n - start and (reduced.stage, reduced.per) == (100, 2000)
    assert reduced.coarse_v["v"].tobytes() == block_means(volts[start:], 100).tobytes()
    expected_h = block_means(time_s[start:], 2000, origin=time_s[start]) / 3600.0
    assert reduced.time_h.tobytes() == expected_h.tobytes()
    assert reduced.temperature_c is not None
    assert reduced.temperature_c.tobytes() == block_means(temperature[start:], 2000).tobytes()
    fed = BlockMeans(3)
    for part in (np.arange(2.0), np.arange(2.0, 7.0), np.arange(7.0, 10.0)):
        fed.add(part)
    assert fed.means().tolist() == [1.0, 4.0, 7.0] and fed.samples == 10
