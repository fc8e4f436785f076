"""Transfer-function models of the sensor from the stepped-sine FRF (docs/method.md §4.4).

Per sensor and test group (the groups of every sensor fitted side by side on forked workers,
or taken as the early-analysis child made them while the run recorded: :mod:`.tf_early`):
the chosen discrete model of the group's FRF points (:mod:`.tf_models`: n = 0..5 poles,
m ≤ n zeros, with and without the cross-correlation delay of :mod:`.tf_xcorr`) with its Bode
figure, which extrapolates to 500 Hz, and a physical model K·ωn²/(s² + 2ζωn·s + ωn²)·e^{−sτ}
(the twin's and diagnose's vocabulary) fitted with a fractional delay, the logger's
pre-sample filter de-embedded. A sensor's headline model is that of its best group (the
highest median SNR).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel
from scipy import signal

from aatest.clocksync.freeze_pulse import SyncedStep
from aatest.engine.errors import AnalysisError
from aatest.engine.interfaces import AnalysisContext, AnalysisOutput
from aatest.engine.requirements import Requirement
from aatest.engine.steps import PlannedStep
from aatest.parallel.forked import parallel_map
from aatest.plugins.analysis import needs
from aatest.plugins.analysis._common import (
    as_options,
    group_of,
    is_excited,
    options_of,
    select,
    steps_of,
)
from aatest.plugins.analysis.frf import FrfOptions
from aatest.plugins.analysis.tf_bode import bode_svg
from aatest.plugins.analysis.tf_early import (
    GroupInputs,
    complete_groups,
    fit_digest,
    group_inputs,
    offer_fits,
    taken_fits,
)
from aatest.plugins.analysis.tf_models import (
    MIN_POINTS,
    Pieces,
    TransferFunctionOptions,
    continuous_equivalent,
    estimate_in_pieces,
    run_through,
)
from aatest.plugins.analysis.tf_xcorr import rated_xcorr, watch_xcorr
from aatest.plugins.analysis.tfest import (
    DiscreteTf,
    second_order_delay_fit,
)
from aatest.presentation.figures import Drawing, DrawnFigures, drawn
from aatest.recording.dataset import Dataset, SensorInfo
from aatest.results.frf import FrfPoint
from aatest.results.transfer_function import TransferFunctionResult

log = logging.getLogger("aatest.analysis")
def _pairs(values: np.ndarray) -> list[list[float]]:
    return [[float(v.real), float(v.imag)] for v in np.asarray(values, dtype=complex)]


def antialias_response(f_hz: np.ndarray, corner_hz: float | None, order: int = 2) -> np.ndarray:
    """Response of the logger's analogue Butterworth pre-sample filter (1 when unknown)."""
    if not corner_hz:
        return np.ones(np.shape(f_hz), dtype=complex)
    b, a = signal.butter(order, 2 * np.pi * corner_hz, analog=True)
    return signal.freqs(b, a, 2 * np.pi * np.asarray(f_hz))[1]


def logger_antialias_hz(data: Dataset, context: AnalysisContext) -> float | None:
    """The DAQ pre-sample filter corner to de-embed, from (in order) the option
    ``antialias_hz``, the rig model stored with a simulated dataset, the DAQ options in the run
    metadata, the simulated DAQ's default; otherwise none (nothing is de-embedded)."""
    return antialias_of(data, options_of(context, TransferFunctionOptions))


def antialias_of(data: Dataset, options: TransferFunctionOptions) -> float | None:
    """:func:`logger_antialias_hz` for these options (the early fits have no context)."""
    value = options.antialias_hz
    if value != "auto":
        return None if value == "none" or not value else float(value)
    model = data.metadata.get("model")
    if isinstance(model, dict) and model.get("daq", {}).get("antialias_hz"):
        return float(model["daq"]["antialias_hz"])
    rig = data.metadata.get("rig")
    daq = rig.get("daq", {}) if isinstance(rig, dict) else {}
    if isinstance(daq, dict) and daq.get("antialias_hz"):
        return float(daq["antialias_hz"])
    if isinstance(daq, dict) and daq.get("plugin") == "sim":
        from aatest.twin.model import DaqModel

        corner = DaqModel().antialias_hz
        return float(corner) if corner else None
    return None


def _group_frf(points: list[FrfPoint]) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies (Hz) and complex responses of a group's FRF points."""
    return (np.array([p.frequency_hz for p in points]),
            np.array([complex(p.re, p.im) for p in points]))


def _bode_title(values: Mapping[str, Any], channel: str) -> str:
    """The title of the Bode figure (:func:`bode_svg`) of a group's chosen discrete model
    (:func:`_discrete_fit`'s ``values``)."""
    return f"{channel} n={values['n']} m={values['m']}"


def _discrete_fit(f: np.ndarray, h: np.ndarray, xcorr: tuple[dict[str, float], float],
                  options: TransferFunctionOptions | None
                  ) -> tuple[dict[str, Any], DiscreteTf]:
    """A group's values (every one but the physical model's) and its chosen discrete model,
    from its FRF ``f``, ``h`` (:func:`_group_frf`) and ``xcorr`` (its :func:`rated_xcorr`)."""
    return run_through(_discrete_fit_in_pieces(f, h, xcorr, options))


def _discrete_fit_in_pieces(f: np.ndarray, h: np.ndarray, xcorr: tuple[dict[str, float], float],
                            options: TransferFunctionOptions | None
                            ) -> Pieces[tuple[dict[str, Any], DiscreteTf]]:
    """:func:`_discrete_fit` in pieces (:func:`estimate_in_pieces`)."""
    xc, fs = xcorr
    dt = 1.0 / fs
    model, rows, k = yield from estimate_in_pieces(f, h, dt, xc, options)
    best = rows[k]
    values = {
        "poles": _pairs(model.poles()), "zeros": _pairs(model.zeros()),
        "delay_s": model.delay_samples * dt, "fit_pct": best["fit_pct"],
        "nAIC": best["nAIC"], "FPE": best["FPE"], "num": model.num.tolist(),
        "den": model.den.tolist(), "dt": dt, "n": best["n"], "m": best["m"],
        "delay_samples": model.delay_samples, "delay_source": best["delay_source"],
        "fit_id_pct": best["fit_id_pct"], "zeros_outside_unit_circle":
        best["zeros_outside_unit_circle"], "xcorr": xc,
        "continuous": continuous_equivalent(model), "candidates": rows,
    }
    return values, model


def _physical_model(f: np.ndarray, h: np.ndarray, xcorr: tuple[dict[str, float], float],
                    antialias_hz: float | None) -> dict[str, Any]:
    """The group's second-order-plus-delay fit, the logger's pre-sample filter de-embedded."""
    return second_order_delay_fit(f, h / antialias_response(f, antialias_hz),
                                  xcorr[0]["delay_s"]) | {"deembedded_antialias_hz": antialias_hz}


#: the work items of :func:`sensor_models` by kind, the longest first (an estimate is
#: ≈ 0.2 s of CPU on the stepped sine, a physical model ≈ 0.05 s)
_ITEM_ORDER = {"estimate": 0, "physical": 1}
#: the fits made while the run records (:func:`early_fits`): no figure, hence no matplotlib
#: in the early-analysis child (its import alone ≈ 0.5 s of CPU there)
EARLY_KINDS = ("estimate", "physical")


def _fit(kind: str, f: np.ndarray, h: np.ndarray, xcorr: tuple[dict[str, float], float],
         channel: str, options: TransferFunctionOptions, antialias_hz: float | None) -> Any:
    """One fit of a group: its discrete models' ``estimate`` (values and chosen model) or its
    ``physical`` model; a work item of :func:`sensor_models` in its workers, or made early."""
    if kind == "estimate":
        return _discrete_fit(f, h, xcorr, options)
    return _physical_model(f, h, xcorr, antialias_hz)


def early_fits(inputs: GroupInputs, options: TransferFunctionOptions,
               antialias_hz: float | None) -> Pieces[dict[str, Any]]:
    """The :data:`EARLY_KINDS` fits of a group made while the run records, by
    :func:`fit_digest`, in pieces (see :mod:`aatest.plugins.analysis.tf_early`): those of
    :func:`estimate_in_pieces`, then the physical model (≈ 50 ms) in one."""
    args = (inputs.f_hz, inputs.h, inputs.xcorr, inputs.sensor.channel, options, antialias_hz)
    estimated = yield from _discrete_fit_in_pieces(inputs.f_hz, inputs.h, inputs.xcorr, options)
    yield
    physical = _physical_model(inputs.f_hz, inputs.h, inputs.xcorr, antialias_hz)
    return {fit_digest("estimate", *args): estimated, fit_digest("physical", *args): physical}


def _with_physical(values: dict[str, Any], physical: dict[str, Any]) -> dict[str, Any]:
    return {**values, "second_order_delay": physical}


def _frf_points(context: AnalysisContext) -> dict[str, list[FrfPoint]]:
    """The FRF points by channel, from the ``frf`` analysis this one requires."""
    out = context.upstream.get("frf")
    if out is None:
        raise AnalysisError("transfer function: the frf analysis produced no points")
    return dict(out.result.root)


def _in_group(group: str, sensor: SensorInfo) -> Callable[[PlannedStep], bool]:
    """Whether a planned step belongs to ``group`` and excites ``sensor``."""
    return lambda p: group_of(p) == group and is_excited(p, sensor)


def _fitted_groups(points: list[FrfPoint], options: TransferFunctionOptions) -> list[str]:
    """The groups of a sensor's FRF points with enough points to fit."""
    return [g for g in sorted({p.group for p in points})
            if sum(p.group == g for p in points) >= options.min_points]


def _channel_row(points: list[FrfPoint], sensor: SensorInfo, fitted: list[str],
                 made: list[tuple[dict[str, Any], Drawing]]
                 ) -> tuple[dict[str, Any] | None, dict[str, Drawing]]:
    """A sensor's models (the best group's first) and figures from its fitted groups."""
    groups = {g: values for g, (values, _) in zip(fitted, made, strict=True)}
    figures = {f"tf_{sensor.channel}_{g}": svg for g, (_, svg) in zip(fitted, made, strict=True)}
    if not groups:
        return None, figures
    snr = {g: np.median([p.snr_db for p in points if p.group == g]) for g in groups}
    main = max(groups, key=lambda g: snr[g])
    return {**groups[main], "group": main, "groups": groups}, figures


def channel_models(points: list[FrfPoint], steps: Sequence[SyncedStep], sensor: SensorInfo,
                   antialias_hz: float | None, options: TransferFunctionOptions
                   ) -> tuple[dict[str, Any] | None, DrawnFigures]:
    """The models of every group with enough points, the best group's first; and figures."""
    row, figures = sensor_models({sensor.channel: points}, steps, [sensor], antialias_hz,
                                 options)[sensor.channel]
    return row, DrawnFigures(figures)


def sensor_models(points: Mapping[str, list[FrfPoint]], steps: Sequence[SyncedStep],
                  sensors: Sequence[SensorInfo], antialias_hz: float | None,
                  options: TransferFunctionOptions, ready: Mapping[str, Any] | None = None
                  ) -> dict[str, tuple[dict[str, Any] | None, dict[str, Drawing]]]:
    """:func:`channel_models` of every sensor, by channel; ``ready``: fits made while the run
    recorded by :func:`~aatest.plugins.analysis.tf_early.fit_digest` (taken when the digest
    of a fit's inputs here is one of them: the same inputs bit for bit).

    The groups of all sensors are fitted side by side on forked workers in one
    :func:`parallel_map` (each group's candidate scan and physical model depend only on that
    group): the stepped sine's five groups took ≈ 3.5 s of the analysis phase in one
    process, and one map over both sensors' groups keeps both workers busy to the end (a map
    per sensor left one idle on each sensor's odd group). The figures are :func:`drawn`
    (aside, while the report goes on, when a process draws aside): each is its SVG's
    ``result()``.
    """
    fitted = {s.channel: _fitted_groups(points.get(s.channel, []), options) for s in sensors}
    groups = [(i, g) for i, s in enumerate(sensors) for g in fitted[s.channel]]
    # each group is two items, its discrete models (≈ 4× the CPU) and its physical model,
    # the long ones first: the map's workers then end together, where five whole groups on
    # two workers left one idle for a group's time (measured: ≈ 0.5 s); a group's Bode
    # figure is drawn aside (aatest.presentation.figures.drawn) once its model is chosen
    # both items of a group read its correlation: summed here once (the sync pass made the
    # steps' terms, and hands each out once), the workers inherit it
    xcorrs = {(i, g): rated_xcorr(select(steps, _in_group(g, sensors[i])), sensors[i])
              for i, g in groups}
    frfs = {(i, g): _group_frf([p for p in points.get(sensors[i].channel, []) if p.group == g])
            for i, g in groups}
    # fits made while the run recorded (tf_early) of these very inputs are taken as they are:
    # a group whose fits were made needs only its figure drawn
    offered = ready or {}
    early = {(kind, i, g): offered[digest] for kind in EARLY_KINDS for i, g in groups
             if offered and (digest := fit_digest(kind, *frfs[i, g], xcorrs[i, g],
                                                  sensors[i].channel, options, antialias_hz))
             in offered}
    items = sorted(((kind, i, g) for kind in EARLY_KINDS for i, g in groups
                    if (kind, i, g) not in early), key=lambda item: _ITEM_ORDER[item[0]])
    log.debug("transfer function: %d of %d group fits made while the run recorded",
              len(early), len(EARLY_KINDS) * len(groups))

    def work(item: tuple[str, int, str]) -> Any:
        kind, i, g = item
        return _fit(kind, *frfs[i, g], xcorrs[i, g], sensors[i].channel, options, antialias_hz)

    done = early | dict(zip(items, parallel_map(work, items) if items else [], strict=True))
    out = {}
    for i, s in enumerate(sensors):
        mine = []
        for g in fitted[s.channel]:
            values, model = done["estimate", i, g]
            mine.append((_with_physical(values, done["physical", i, g]),
                         drawn(bode_svg, *frfs[i, g], model, _bode_title(values, s.channel))))
        out[s.channel] = _channel_row(points.get(s.channel, []), s, fitted[s.channel], mine)
    return out


class TransferFunctionAnalysis:
    """Discrete transfer-function models per sensor (best group) and per test group."""

    key: ClassVar[str] = "transfer_function"
    requires: ClassVar[tuple[str, ...]] = ("sync", "frf")
    #: what the plan must hold (checked by ``validate``; aatest.engine.requirements)
    requirements: ClassVar[tuple[Requirement, ...]] = needs.sine_points(MIN_POINTS)
    #: the acceptance quantities it produces (judged when it is listed)
    judges: ClassVar[tuple[str, ...]] = ()
    Options: ClassVar[type[TransferFunctionOptions]] = TransferFunctionOptions
    Result: ClassVar[type[TransferFunctionResult]] = TransferFunctionResult

    def applies_to(self, data: Dataset) -> bool:
        return len([p for p in data.planned if p.kind == "sine"]) >= MIN_POINTS

    def watch_steps(self, data: Dataset, options: BaseModel) -> None:
        """Register the cross-correlations with the sync pass (:func:`watch_xcorr`)."""
        tf_options = (options if isinstance(options, TransferFunctionOptions) else
                      TransferFunctionOptions.model_validate(options.model_dump()))
        watch_xcorr(data, tf_options.min_points)

    @staticmethod
    def early_ready(data: Dataset, made: Mapping[int, Mapping[str, Any]],
                    chosen: Mapping[str, BaseModel]) -> dict[str, Callable[[], Any]]:
        """The fits of every group whose steps the early-analysis child has all made
        (``made``: its results by step index of ``data``; ``chosen``: the pass's options by
        plugin), by group, each made when called (:mod:`~aatest.plugins.analysis.tf_early`)."""
        options = as_options(chosen.get("transfer_function"), TransferFunctionOptions)
        harmonics = as_options(chosen.get("frf"), FrfOptions).harmonics
        antialias_hz = antialias_of(data, options)

        def work(sensor: SensorInfo, group: str, indices: list[int]
                 ) -> Callable[[], Pieces[dict[str, Any]]]:
            def fits() -> Pieces[dict[str, Any]]:
                inputs = group_inputs(sensor, group, indices, made, harmonics)
                if inputs is None:
                    return {}
                return (yield from early_fits(inputs, options, antialias_hz))
            return fits

        return {f"{sensor.channel}:{group}": work(sensor, group, indices)
                for sensor, group, indices in complete_groups(data, made, options.min_points)}

    @staticmethod
    def take_early_done(data: Dataset, key: str, fits: Any) -> None:
        """Have the pass over ``data`` take the fits :meth:`early_ready`'s work ``key`` made."""
        if isinstance(fits, dict):
            offer_fits(data, fits)

    def run(self, data: Dataset, context: AnalysisContext
            ) -> AnalysisOutput[TransferFunctionResult]:
        steps = steps_of(context, "sine")
        options = options_of(context, TransferFunctionOptions)
        antialias_hz = logger_antialias_hz(data, context)
        points = _frf_points(context)
        values: dict[str, Any] = {}
        figures: dict[str, Drawing] = {}
        models = sensor_models(points, steps, list(data.sensors), antialias_hz, options,
                               taken_fits(data))
        for sensor in data.sensors:
            row, figs = models[sensor.channel]
            figures |= figs
            if row is not None:
                values[sensor.channel] = row
        return AnalysisOutput(TransferFunctionResult.model_validate(values),
                              DrawnFigures(figures))
