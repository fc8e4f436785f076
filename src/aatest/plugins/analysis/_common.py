"""Helpers every analysis shares: which acceleration a sensor sees, DFT bins, options.

Figures are drawn and rendered by :mod:`aatest.presentation.figures`, like every other figure
of aatest; the projections of motion and gravity live in :mod:`.geometry`.

Frames (docs/interfaces.md §4): the sensors ride on the inner axis. A sensor on I sees inner-axis
motion; outer-axis motion at inner angle ψ lies along O·cos ψ + P·sin ψ of the table top, so a
sensor on O sees ``cos ψ`` and one on P ``sin ψ`` of the outer acceleration.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import TypeVar

import numpy as np
from pydantic import BaseModel
from scipy import stats

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext
from aatest.engine.steps import PlannedStep
from aatest.plugins.analysis.geometry import axis_weights, nominal_weight
from aatest.plugins.analysis.sync import SyncedSteps, SyncOutput
from aatest.recording.dataset import SensorInfo

#: a sensor counts as excited by a step when its projection of the motion exceeds this
_EXCITED_WEIGHT = 0.5


def is_excited(step: PlannedStep, sensor: SensorInfo) -> bool:
    """True when the step's motion lies (mostly) along the sensor's sensitive axis."""
    return abs(nominal_weight(step, sensor.axis)) >= _EXCITED_WEIGHT


#: the table channels :func:`input_accel_dps2` reads (an analysis that needs nothing else of the
#: table asks the lazy steps for only these: ``SyncedSteps.only``)
INPUT_ACCEL_CHANNELS = ("inner_accel_dps2", "outer_accel_dps2", "inner_position_deg")


def input_accel_channels(step: PlannedStep) -> tuple[str, ...]:
    """The table channels :func:`input_accel_dps2` reads of ``step`` (of
    :data:`INPUT_ACCEL_CHANNELS`): the moving axis' acceleration estimate and the inner
    position (the outer axis' weight). Why: the sync pass's watches then leave the other
    axis' estimate of every sine step undecoded."""
    return (f"{_moving_axis(step.axis)}_accel_dps2", "inner_position_deg")


def _moving_axis(axis: str) -> str:
    """The axis whose acceleration estimate a step's input is (inner unless outer moves)."""
    return axis if axis in ("inner", "outer") else "inner"


def input_accel_dps2(synced: SyncedStep, sensor_axis: str,
                     accel: np.ndarray | None = None) -> np.ndarray:
    """Table-estimated acceleration along a sensor axis, °/s², on the synced time grid.

    ``accel`` replaces the moving axis' logged estimate (e.g. a smoothed reference). Where the
    axis weight is exactly one, the array returned is that estimate itself (read-only when
    decoded from a recording): treat it as read-only.
    """
    step = synced.step
    moving = _moving_axis(step.axis)
    base = synced.table[f"{moving}_accel_dps2"] if accel is None else accel
    psi = synced.table.get("inner_position_deg", np.full(len(synced), step.inner_deg))
    weight = axis_weights(sensor_axis, np.mean(psi) if moving == "outer" else 0.0)[moving]
    if isinstance(weight, float) and weight == 1.0:  # the logged record itself (x·1 = x):
        return np.asarray(base, dtype=np.float64)  # its spectrum is the evidence's one
    return np.asarray(base, dtype=np.float64) * weight


def whole_cycles(n_samples: int, frequency_hz: float, fs_hz: float) -> tuple[int, int]:
    """Longest sample count holding (to half a sample) an integer number of cycles, and it.

    For a coherent record (docs/method.md §4.4) this is the whole record.
    """
    if not (0 < frequency_hz < fs_hz / 2 and math.isfinite(fs_hz)):
        raise AnalysisError(f"{frequency_hz:g} Hz cannot be analysed in samples at {fs_hz:g} Hz "
                            "(it must be above 0 and below half the sample rate)")
    per_cycle = fs_hz / frequency_hz
    cycles = int(np.floor(n_samples / per_cycle + 1e-6))
    if cycles < 1:
        raise AnalysisError(f"record of {n_samples} samples holds no full cycle at "
                            f"{frequency_hz:g} Hz ({per_cycle:.4g} samples per cycle)")
    return min(round(cycles * per_cycle), n_samples), cycles


def fundamental(x: np.ndarray, frequency_hz: float, fs_hz: float) -> complex:
    """One-sided complex amplitude of ``x`` at ``frequency_hz`` (mean removed).

    Projection onto ``exp(−j2πft)`` over the whole-cycle part of the record: for a coherent
    record this is exactly ``2·X[c]/N`` at the excitation DFT bin (docs/method.md §4.4).
    """
    n, _ = whole_cycles(x.size, frequency_hz, fs_hz)
    seg = np.asarray(x[:n], dtype=np.float64)
    phasor = np.exp(-2j * np.pi * frequency_hz * np.arange(n) / fs_hz)
    return complex(2.0 * np.dot(seg - seg.mean(), phasor) / n)


def t95(dof: int) -> float:
    """Two-sided 95 % Student-t coverage factor for ``dof`` degrees of freedom."""
    return float(stats.t.ppf(0.975, max(dof, 1)))


def group_of(step: PlannedStep) -> str:
    """The test-group label of a step (``accel-100`` style if the plan gave none)."""
    if step.group:
        return step.group
    if step.accel_dps2 is not None:
        return f"accel-{step.accel_dps2:g}"
    return "default"


def json_floats(values: Iterable[float]) -> list[float]:
    """Plain Python floats for results.json."""
    return [float(v) for v in values]


def steps_of(context: AnalysisContext, kind: str | None = None) -> SyncedSteps:
    """The synchronised steps from the ``sync`` output (of one step ``kind`` if given).

    A view that synchronises a step when it is read (one step in memory at a time); filter
    it with ``.where(predicate on the PlannedStep)`` rather than a list comprehension, which
    would synchronise every step to look at its ``.step``.

    Raises
    ------
    AnalysisError
        When the ``sync`` analysis produced nothing (it failed, or was not required).
    """
    out = context.upstream.get("sync")
    if not isinstance(out, SyncOutput) or not isinstance(out.steps, SyncedSteps):
        raise AnalysisError("no synchronised steps: the sync analysis failed or is not required")
    return out.steps if kind is None else out.steps.where(lambda step: step.kind == kind)


def select(steps: Sequence[SyncedStep], keep: Callable[[PlannedStep], bool]
           ) -> Sequence[SyncedStep]:
    """The steps whose planned step passes ``keep``, synchronising none of the others.

    On the lazy view of ``sync`` this is a view again (nothing synchronised yet); on a plain
    list, a list.
    """
    if isinstance(steps, SyncedSteps):
        return steps.where(keep)
    return [s for s in steps if keep(s.step)]


def scale_in_use(context: AnalysisContext, sensor: SensorInfo) -> float:
    """V per °/s²: the calibrated scale factor when ``scale_factor`` is required and produced
    one for this channel, else the datasheet's."""
    out = context.upstream.get("scale_factor")
    calibrated = out.result.get(sensor.channel) if out is not None else None
    if calibrated is None:
        return float(sensor.nominal_scale_v_per_dps2)
    return float(calibrated.scale_v_per_dps2)


OptionsT = TypeVar("OptionsT", bound=BaseModel)


def options_of(context: AnalysisContext, model: type[OptionsT]) -> OptionsT:
    """The context's options as ``model`` (its defaults when the context carries none)."""
    return as_options(context.options, model)


def as_options(given: BaseModel | None, model: type[OptionsT]) -> OptionsT:
    """Options ``given`` (e.g. the pass's by plugin name) as ``model``; its defaults when
    none were given."""
    if isinstance(given, model):
        return given
    return model.model_validate(given.model_dump() if given is not None else {})
