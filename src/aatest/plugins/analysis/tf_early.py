"""Transfer-function group fits made while the run still records (:mod:`aatest.early`).

Why: a stepped sine records its test groups one after another, and a group's models (its
candidate scan with the Bode figure, and its second-order-plus-delay fit) depend only on the
group's FRF points and cross-correlation terms — per-step results the early-analysis child
has already made. After the record phase the fits of the five groups were the largest item
of the analysis phase (≈ 0.8 s of wall on two workers, ≈ 1.5 s of CPU). So the child fits a
group as soon as it has made the group's last step, while the rig records the next groups
(:meth:`~aatest.plugins.analysis.transfer_function.TransferFunctionAnalysis.early_ready`),
and the pass takes a fit instead of making it when the fit's inputs are the pass's own bit
for bit: :func:`fit_digest` of the frequencies and complex responses (their bytes), the
group's correlation, the channel, the options and the de-embedded filter corner. A fit is a
function of exactly these, so a taken fit is the one the pass would make. Only the last
group, complete when the record phase ends, is always fitted after it.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any
from weakref import WeakKeyDictionary

import numpy as np
from pydantic import BaseModel

from aatest.plugins.analysis._common import group_of, is_excited
from aatest.plugins.analysis.frf import point_watch_name
from aatest.plugins.analysis.synced_steps import attempt_result
from aatest.plugins.analysis.tf_xcorr import summed_xcorr, xcorr_watch_name
from aatest.recording.dataset import Dataset, LazySteps, SensorInfo

#: the plugin whose per-step results (:func:`~aatest.plugins.analysis.synced_steps.attempt`)
#: hold the FRF points and correlation terms
SYNC_PLUGIN = "sync"
#: fits made while recording, by :func:`fit_digest`, for each recording's lazy steps
_OFFERED: WeakKeyDictionary[LazySteps, dict[str, Any]] = WeakKeyDictionary()


@dataclass(frozen=True)
class GroupInputs:
    """What one group's fits read: its FRF (sorted by frequency) and summed correlation."""

    sensor: SensorInfo
    group: str
    #: frequencies (Hz), as the pass's ``_group_frf`` makes them
    f_hz: np.ndarray
    #: complex responses (V per °/s²) at ``f_hz``
    h: np.ndarray
    #: :func:`~aatest.plugins.analysis.tf_xcorr.rated_xcorr` of the group
    xcorr: tuple[dict[str, Any], float]


def fit_digest(kind: str, f_hz: np.ndarray, h: np.ndarray, xcorr: tuple[dict[str, Any], float],
               channel: str, options: BaseModel, antialias_hz: float | None) -> str:
    """SHA-256 of everything a group's ``kind`` fit reads (``discrete`` or ``physical``).

    The arrays enter as bytes with their dtype and shape, the rest as JSON (floats by their
    shortest round-trip text): equal digests mean equal inputs to the last bit.
    """
    doc = {"kind": kind, "channel": channel, "xcorr": xcorr[0], "fs": xcorr[1],
           "options": options.model_dump(mode="json"), "antialias_hz": antialias_hz,
           "arrays": [(str(a.dtype), list(a.shape)) for a in (f_hz, h)]}
    digest = hashlib.sha256(json.dumps(doc, sort_keys=True, default=repr).encode("utf-8"))
    for array in (f_hz, h):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()


def complete_groups(data: Dataset, made: Mapping[int, Mapping[str, Any]], min_points: int
                    ) -> list[tuple[SensorInfo, str, list[int]]]:
    """``(sensor, group, step indices)`` of every group with ``min_points`` sine steps along a
    sensor, all of them in ``made`` (the child's results by step index of ``data``)."""
    out = []
    for sensor in data.sensors:
        groups: dict[str, list[int]] = {}
        for index, step in enumerate(data.planned):
            if step.kind == "sine" and is_excited(step, sensor):
                groups.setdefault(group_of(step), []).append(index)
        out += [(sensor, group, indices) for group, indices in groups.items()
                if len(indices) >= min_points and all(i in made for i in indices)]
    return out


def group_inputs(sensor: SensorInfo, group: str, indices: Sequence[int],
                 made: Mapping[int, Mapping[str, Any]], harmonics: int) -> GroupInputs | None:
    """A complete group's fit inputs from the steps' made results, as the pass forms them
    (points in frequency order, the correlation terms summed in step order); None when a
    step lacks its point or term, or the steps' rates differ (the pass fits that group)."""
    points = [attempt_result(made[i].get(SYNC_PLUGIN), point_watch_name(sensor, harmonics))
              for i in indices]
    terms = [attempt_result(made[i].get(SYNC_PLUGIN), xcorr_watch_name(sensor))
             for i in indices]
    if any(p is None for p in points) or any(t is None for t in terms) \
            or any(p["group"] != group for p in points) \
            or any(rate != terms[0][0] for rate, _ in terms):
        return None
    ordered = sorted(points, key=lambda p: p["frequency_hz"])  # stable, as the pass's sort
    f_hz = np.array([p["frequency_hz"] for p in ordered])
    h = np.array([complex(p["re"], p["im"]) for p in ordered])
    return GroupInputs(sensor, group, f_hz, h, summed_xcorr(terms))


def offer_fits(data: Dataset, fits: Mapping[str, Any]) -> None:
    """Hand the pass over ``data`` fits made while recording, by :func:`fit_digest`."""
    if isinstance(data.steps, LazySteps):
        _OFFERED.setdefault(data.steps, {}).update(fits)


def taken_fits(data: Dataset) -> dict[str, Any]:
    """The fits offered for ``data`` by :func:`fit_digest` (taken: a second call finds none)."""
    return _OFFERED.pop(data.steps, {}) if isinstance(data.steps, LazySteps) else {}
