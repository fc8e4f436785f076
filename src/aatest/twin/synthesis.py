"""Lazy synthesis of one recorded step: table log, DAQ log and the truth behind both.

Everything is computed on whole arrays from the World's record of the step: the real motion of
each axis (analytic in lab time), the DAQ clock and the sensor temperature. The table log is
sampled on the table clock from the trigger on (:mod:`aatest.twin.table_log`); the DAQ log,
here, on its own crystal clock from ``start_lead_s`` before the trigger to ``stop_lag_s`` after
the table log ends.

How a step's pieces are spread over two threads with the numbers a serial synthesis draws:
:mod:`aatest.twin.step_synthesis`. A long record computes the next block's rigid motion (no
random draw) on a worker while a block draws (:func:`daq_blocks`), and joins it before the
last block is returned (no thread outlives a record, so the analysis may fork afterwards).
"""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import ExitStack
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy import signal

from aatest.engine.logs import DAQ, DAQ_AUX_CHANNELS, SampledLog
from aatest.twin.clocks import TIMESTAMP_TICK_S, DaqClock
from aatest.twin.daq import antialias_filter, noiseless, quantise_adc
from aatest.twin.drawn_ahead import normal_uniforms
from aatest.twin.fastmath import standard_normal
from aatest.twin.grid import Grid
from aatest.twin.model import DaqModel, SensorModel, TableModel
from aatest.twin.rigid_motion import (
    OuterPart,
    RigidBlock,
    rigid_block,
    sensor_delay_s,
    top_motion,
    top_rate,
    with_floor,
)
from aatest.twin.sensor import (
    ChannelState,
    SensorInputs,
    lowpass_carry,
    output_volts,
)
from aatest.twin.step_setup import LazyTruth, StepSetup, read_only
from aatest.twin.table import _band_filter as band_filter


def _daq_samples(setup: StepSetup) -> int:
    """Number of DAQ samples: lead + the table record's span on the DAQ clock + stop lag."""
    step, clock = setup.step, setup.clock
    table_span_daq_s = step.samples / step.sample_rate_hz / clock.scale
    lag = setup.stop_lag_s
    return setup.trigger_index + int(np.ceil((table_span_daq_s + lag) * clock.sample_rate_hz))


#: records longer than this are generated in blocks of :data:`GENERATION_BLOCK` samples
SINGLE_BLOCK_MAX = 2**18
#: generation block of a long record (≈ 65.5 s at 2 kHz); the state of every filter, noise
#: process and random stream carries over from one block to the next
GENERATION_BLOCK = 2**17


def generation_block(n: int) -> int:
    """Samples per generation block of an ``n``-sample DAQ record (the whole of a short one).

    Why blocks: memory of a long record is bounded by one block; why a fixed block: a record
    generated block by block is the same whether it is delivered at once or streamed in chunks
    of whole blocks (:func:`daq_blocks`).
    """
    return n if n <= SINGLE_BLOCK_MAX else GENERATION_BLOCK


@dataclass
class _DaqState:
    """What one DAQ record carries from block to block: filter states and drift states."""

    floor_zi: np.ndarray | None = None
    sensors: dict[str, ChannelState] = field(default_factory=dict)


def daq_record_samples(setup: StepSetup) -> int:
    """Number of samples of the step's DAQ record (lead + table span + stop lag)."""
    return _daq_samples(setup)


def daq_units(setup: StepSetup) -> tuple[dict[str, str], dict[str, tuple[float, float]]]:
    """(units, quantisation) of the step's DAQ log: volts of every sensor and the ADC codes."""
    model = setup.model
    volts = [s.channel for s in model.sensors if s.channel.startswith("v_")]
    units = dict.fromkeys(volts, "V") | dict(DAQ_AUX_CHANNELS)
    lo_v, hi_v = model.daq.adc_range_v  # ADC codes: volts = code·LSB + low end (daq.quantise_adc)
    adc = dict.fromkeys(volts, ((hi_v - lo_v) / 2**model.daq.adc_bits, lo_v))
    return units, {"time_s": (TIMESTAMP_TICK_S, 0.0), **adc}


def daq_blocks(setup: StepSetup, rng: np.random.Generator, truth: LazyTruth | None = None,
               drift_rng: np.random.Generator | None = None,
               ahead: BlockAhead | None = None) -> Iterator[SampledLog]:
    """The step's DAQ log, generated block by block (:func:`generation_block`).

    Every random draw comes from ``rng`` in block order and every stateful stage (the floor's
    band-pass, the sensor dynamics, the anti-alias filter, the bias drift) continues across
    blocks, so the concatenated blocks do not depend on how a consumer groups them. ``truth``
    (one-shot synthesis of a short record) receives the deferred noise-free entries;
    ``drift_rng`` draws the sensors' bias drift (``SensorModel.bias_drift``). The next block's
    rigid motion (no random draw) is computed on a worker thread while a block draws; a
    one-block record computes it in line (no thread). ``ahead``: what a one-block record's
    caller computes and draws on another thread (:class:`BlockAhead`); ``rng`` is then unused.
    """
    clock = setup.clock
    n = _daq_samples(setup)
    block = generation_block(n)
    units, quanta = daq_units(setup)
    drift = drift_rng if drift_rng is not None else np.random.default_rng(0)
    state = _DaqState(sensors={s.channel: ChannelState(drift_rng=drift)
                               for s in setup.model.sensors})
    starts = range(0, max(n, 1), block)
    with ExitStack() as stack:
        pool = (stack.enter_context(ThreadPoolExecutor(
            max_workers=1, thread_name_prefix="aatest-twin")) if len(starts) > 1 else None)
        rigid = _rigid_soon(pool, setup, 0, min(block, n),
                            ahead.outer if ahead is not None else None)
        for start in starts:
            grid = _block_grid(clock, start, min(block, n - start))
            current = rigid.result()
            if start + block < n:  # the next block's rigid motion, while this one draws
                rigid = _rigid_soon(pool, setup, start + block, min(block, n - start - block))
            for carried in state.sensors.values():  # the last block ends every filter
                carried.final = start + block >= n
            channels = _daq_block(setup, grid, start,
                                  ahead.record.result() if ahead is not None else rng, state,
                                  truth if block == n else None, current, ahead)
            del current
            stamps = (ahead.stamps.result() if ahead is not None
                      else _stamped(clock, start, grid.n, rng))
            yield SampledLog(DAQ, clock.sample_rate_hz, stamps, read_only(channels), units,
                             quanta)


def _rigid_soon(pool: ThreadPoolExecutor | None, setup: StepSetup, first: int, m: int,
                part: Future[OuterPart] | None = None) -> Future[RigidBlock]:
    """:func:`rigid_block` of DAQ samples ``first``… on ``pool``, or now without one."""
    grid = _block_grid(setup.clock, first, m)
    if pool is not None:
        return pool.submit(rigid_block, setup, grid)
    done: Future[RigidBlock] = Future()
    done.set_result(rigid_block(setup, grid, part))
    return done


def _block_grid(clock: DaqClock, first: int, m: int) -> Grid:
    """Lab-time grid of the ``m`` DAQ samples from sample ``first`` on."""
    return Grid(clock.t0_s + first * clock.lab_dt_s, clock.lab_dt_s, m)


@dataclass(frozen=True)
class BlockAhead:
    """What a one-block DAQ record takes from another thread: the outer axis and temperature
    (:func:`outer_part`), the floor's rocking (:func:`floor_rocking_block`), the time stamps
    (:func:`_stamped`) and the uniforms of the channels' noise (:func:`record_uniforms`)."""

    outer: Future[OuterPart]
    floor: Future[tuple[np.ndarray | None, np.ndarray | None]]
    stamps: Future[np.ndarray]
    record: Future[np.random.Generator]


def _daq_block(setup: StepSetup, grid: Grid, first: int, rng: np.random.Generator,
               state: _DaqState, truth: LazyTruth | None, rigid: RigidBlock,
               ahead: BlockAhead | None = None) -> dict[str, np.ndarray]:
    """Channels of one generation block starting at DAQ sample ``first``."""
    model, clock = setup.model, setup.clock
    temperature = rigid.temperature_c
    channels: dict[str, np.ndarray] = {}
    motion: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    floor, state.floor_zi = (ahead.floor.result() if ahead is not None else floor_rocking_block(
        model.table, grid.n, clock.lab_dt_s, rng, state.floor_zi))
    # time since the trigger: read by plugin effects only (one array for every channel)
    since_trigger = (grid.times - setup.trigger_time_s
                     if any(s.plugin_effects for s in model.sensors) else None)
    for sensor in model.sensors:
        delay = sensor_delay_s(model, sensor)
        if delay not in motion:
            motion[delay] = with_floor(rigid.motion[delay], floor)
        alpha, up = motion[delay]
        rate = (top_rate(setup, grid.shifted(-delay)) if sensor.rotor_stiction is not None
                else None)
        inp = SensorInputs(alpha, up, temperature, setup.axes[sensor.channel], clock.lab_dt_s,
                           since_trigger, rate)
        carried = state.sensors.setdefault(sensor.channel, ChannelState())
        clean = output_volts(sensor, inp, model.t_ref_c, carried)
        channels[sensor.channel] = _record_block(clean, sensor, model.daq, clock.lab_dt_s, rng,
                                                 carried)
        if truth is not None:
            truth.defer(f"volts_{sensor.channel}",
                        partial(_noiseless_truth, clean_v=clean, daq=model.daq,
                                dt_s=clock.lab_dt_s))
    if truth is not None:
        for sensor in model.sensors:  # true acceleration along each sensitive axis, undelayed
            truth.defer(f"alpha_{sensor.channel}",
                        partial(_alpha_truth, axis_z=setup.axes[sensor.channel][:, 2],
                                setup=setup, grid=grid, motion=motion, floor=floor))
        truth.defer("sensor_accel_dps2", partial(
            _accel_truth, channels=[s.channel for s in model.sensors]))
    index = np.arange(first, first + grid.n)
    channels["sync_pulse"] = clock.sync_level(index / clock.sample_rate_hz)
    channels["trigger"] = (index >= setup.trigger_index).astype(np.float64)
    channels["temperature_c"] = np.round(temperature, 2)
    return channels


def _stamped(clock: DaqClock, first: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Logged time stamps of DAQ samples ``first``…``first + n − 1`` (s, DAQ clock): the
    nominal times plus white jitter on the time-stamp counter's ticks, as
    :meth:`DaqClock.stamped` for the whole record."""
    t = np.arange(first, first + n) / clock.sample_rate_hz
    if not clock.jitter_s:
        return t
    return np.round((t + clock.jitter_s * standard_normal(rng, n)) / TIMESTAMP_TICK_S) \
        * TIMESTAMP_TICK_S


def stamp_uniforms(clock: DaqClock, n: int) -> int:
    """Uniforms :func:`_stamped` draws for ``n`` samples."""
    return normal_uniforms(n) if clock.jitter_s else 0


def floor_rocking_block(table: TableModel, n: int, dt_s: float, rng: np.random.Generator,
                        zi: np.ndarray | None) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Building vibration (2, n) °/s² of the next block, continuing the band-pass state ``zi``
    (:func:`aatest.twin.table.floor_rocking` block by block); None when switched off."""
    if table.floor_vibration_rms_dps2 <= 0.0:
        return None, None
    b, a, gain = band_filter(*table.floor_vibration_band_hz, round(dt_s, 15))
    white = standard_normal(rng, 2 * n).reshape(2, n)
    start = zi if zi is not None else np.zeros((2, max(len(a), len(b)) - 1))
    rocking, state = signal.lfilter(b, a, white, axis=1, zi=start)
    return rocking * (table.floor_vibration_rms_dps2 / gain), state


def floor_uniforms(table: TableModel, n: int) -> int:
    """Uniforms :func:`floor_rocking_block` draws for ``n`` samples."""
    return normal_uniforms(2 * n) if table.floor_vibration_rms_dps2 > 0.0 else 0


def record_uniforms(sensor: SensorModel, daq: DaqModel, n: int) -> int:
    """Uniforms :func:`_record_block` draws for ``n`` samples of a channel."""
    extra = any(x is not None and x.rms_v for x in (sensor.excess_noise, daq.slip_ring))
    return normal_uniforms(n) * ((1 if sensor.noise_rms_v else 0) + (1 if extra else 0))


def _record_block(clean_v: np.ndarray, sensor: SensorModel, daq: DaqModel, dt_s: float,
                  rng: np.random.Generator, state: ChannelState) -> np.ndarray:
    """Logged volts of one block of a channel: (clean + noise) through the pre-sample filter
    (continued from the previous block), extra white noise (slip ring, ``excess_noise``), the
    logger's own gain and offset error, then the ADC."""
    signal_v = clean_v
    gain = 1.0
    if daq.antialias_hz is not None:
        b, a, gain = antialias_filter(float(daq.antialias_hz), round(dt_s, 15))
    if sensor.noise_rms_v:
        signal_v = clean_v + (sensor.noise_rms_v / gain) * standard_normal(rng, clean_v.size)
    filtered = signal_v
    if daq.antialias_hz is not None:
        filtered = lowpass_carry(signal_v, b, a, "antialias", state)
    extra = [n.rms_v for n in (sensor.excess_noise, daq.slip_ring) if n is not None and n.rms_v]
    if extra:
        filtered = filtered + float(np.hypot.reduce(extra)) * standard_normal(rng, clean_v.size)
    if daq.logger_error is not None:  # the logger's own gain and offset error (drawn)
        filtered = (1.0 + daq.logger_error.gain_error) * filtered + daq.logger_error.offset_v
    return quantise_adc(filtered, daq)


def _noiseless_truth(_: LazyTruth, clean_v: np.ndarray, daq: DaqModel,
                     dt_s: float) -> np.ndarray:
    """Truth entry: the clean output (V) after the pre-sample filter (sample spacing s)."""
    return noiseless(clean_v, daq, dt_s)


def _alpha_truth(_: LazyTruth, axis_z: np.ndarray, setup: StepSetup, grid: Grid,
                 motion: dict[float, tuple[np.ndarray, np.ndarray]],
                 floor: np.ndarray | None) -> np.ndarray:
    """Truth entry: acceleration along a sensitive axis, undelayed (°/s²)."""
    return np.asarray(axis_z @ _undelayed(setup, grid, motion, floor))


def _daq_time_truth(_: LazyTruth, grid: Grid, trigger_s: float) -> np.ndarray:
    """Truth entry: lab time of each DAQ sample since the trigger (s)."""
    return grid.times - trigger_s


def _accel_truth(truth: LazyTruth, channels: list[str]) -> dict[str, np.ndarray]:
    """Truth entry: channel → acceleration along its sensitive axis (°/s²)."""
    return {ch: truth[f"alpha_{ch}"] for ch in channels}


def _daq_log(setup: StepSetup, rng: np.random.Generator,
             drift_rng: np.random.Generator | None = None,
             ahead: BlockAhead | None = None) -> tuple[SampledLog, LazyTruth]:
    """The whole DAQ log at once: the concatenation of :func:`daq_blocks`."""
    clock = setup.clock
    n = _daq_samples(setup)
    truth = LazyTruth()
    truth.defer("daq_time_s", partial(_daq_time_truth, grid=Grid(clock.t0_s, clock.lab_dt_s, n),
                                      trigger_s=setup.trigger_time_s))
    blocks = list(daq_blocks(setup, rng, truth, drift_rng, ahead))
    return concatenate_logs(blocks), truth


def concatenate_logs(blocks: list[SampledLog]) -> SampledLog:
    """One log of consecutive blocks of the same logger (same channels, units, quantisation)."""
    if len(blocks) == 1:
        return blocks[0]
    first = blocks[0]
    channels = {name: np.concatenate([b.channels[name] for b in blocks])
                for name in first.channels}
    return SampledLog(first.source, first.sample_rate_hz,
                      np.concatenate([b.time_s for b in blocks]), read_only(channels),
                      dict(first.units), dict(first.quantisation))


def _undelayed(setup: StepSetup, grid: Grid, motion: dict[float, tuple[np.ndarray, np.ndarray]],
               floor: np.ndarray | None) -> np.ndarray:
    if 0.0 not in motion:
        motion[0.0] = top_motion(setup, grid, floor)
    return motion[0.0][0]
