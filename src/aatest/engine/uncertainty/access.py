"""The one place that reads and writes the results: contract keys strictly, extras tolerantly.

The analysis plugins promise the keys of docs/interfaces.md §1 and may add more. A contract key
is read with :func:`require` / :func:`require_float` (absent: :class:`ResultsContractError`, so a
broken analysis cannot silently lose its budget or verdict); optional extras are read with the
tolerant helpers, which return ``None`` or an empty container. :func:`certify` writes the
certified fields (:class:`aatest.results.base.Certified`) the uncertainty stage adds.

The results are today's ``results.json`` dict; when they become the typed
``aatest.results.RunResults`` these accessors are the functions to switch to attribute access.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from aatest.engine.errors import InputError

#: an interval is a pair of bounds; a mean needs at least two values
PAIR = 2
#: two-sided 95 % quantile of the normal distribution (ci95 half-width → standard uncertainty)
Z95 = 1.959963984540054


class ResultsContractError(InputError, LookupError):
    """The results lack a key docs/interfaces.md §1 promises."""


def require(entry: Mapping[str, Any], key: str, where: str) -> Any:
    """``entry[key]`` for a contract key; its absence is an error naming ``where``."""
    if not isinstance(entry, Mapping) or key not in entry:
        raise ResultsContractError(f"results.json: {where}: missing contract key {key!r}")
    return entry[key]


def require_float(entry: Mapping[str, Any], key: str, where: str) -> float | None:
    """A contract number: error when absent, ``None`` when stated as null/NaN (not estimated)."""
    return as_float(require(entry, key, where))


def channel_entry(results: Mapping[str, Any], key: str, channel: str) -> Any:
    """``results["analysis"][key][channel]`` or None when that analysis or channel is absent."""
    block = analysis(results, key)
    return block.get(channel) if isinstance(block, Mapping) else None


def frf_points(results: Mapping[str, Any], channel: str) -> list[dict[str, Any]]:
    """The FRF points of one channel (``analysis.frf[CH]``), empty without an FRF."""
    points = channel_entry(results, "frf", channel) or []
    return [p for p in points if isinstance(p, dict)]


def misalignment_scenarios(results: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """``analysis.misalignment.scenarios``: scenario → sensor → entry (empty when absent)."""
    block = analysis(results, "misalignment")
    scenarios = require(block, "scenarios", "analysis.misalignment") if block else {}
    return {str(s): dict(sensors or {}) for s, sensors in sorted(scenarios.items())}


def misalignment_sets(results: Mapping[str, Any]) -> dict[str, Any]:
    """``analysis.misalignment.sets``: set label → sensor → entry (empty when absent)."""
    block = analysis(results, "misalignment")
    return dict(require(block, "sets", "analysis.misalignment")) if block else {}


def certify(entry: dict[str, Any], evaluation: Any, prefix: str = "", unit_suffix: str = ""
            ) -> None:
    """Write an evaluation's U, k, coverage probability and budget into a result entry.

    Without ``prefix`` the generic fields of :class:`aatest.results.base.Certified` are
    written; with one (``gain``, ``phase``, ``g_sensitivity``, …) the quantity's own
    ``<prefix>_expanded_uncertainty<unit_suffix>`` and ``<prefix>_budget``.
    """
    budget = [row.model_dump(mode="json") for row in evaluation.rows]
    if prefix:
        entry[f"{prefix}_expanded_uncertainty{unit_suffix}"] = evaluation.expanded_uncertainty
        entry[f"{prefix}_budget"] = budget
        entry[f"{prefix}_measurand"] = evaluation.definition
        return
    entry.update(expanded_uncertainty=evaluation.expanded_uncertainty,
                 coverage_factor=evaluation.k,
                 coverage_probability=evaluation.coverage_probability, budget=budget,
                 measurand=evaluation.definition)


def as_float(value: Any) -> float | None:
    """A finite float, or None for missing/NaN/non-numeric values."""
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def analysis(results: Mapping[str, Any], key: str) -> Any:
    """``results["analysis"][key]`` or None."""
    block = results.get("analysis") or {}
    return block.get(key) if isinstance(block, Mapping) else None


def stated_instruments(results: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """The rig description's ``instruments`` block as recorded with the run, or None."""
    for rig in ((results.get("metadata") or {}).get("rig"), results.get("rig")):
        if isinstance(rig, Mapping) and isinstance(rig.get("instruments"), Mapping):
            return rig["instruments"]  # type: ignore[no-any-return]
    return None


def sensors(results: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Sensor descriptions from the metadata, by channel name."""
    listed = (results.get("metadata") or {}).get("sensors") or []
    return {str(s["channel"]): dict(s) for s in listed if isinstance(s, Mapping) and "channel" in s}


def steps_of_kind(results: Mapping[str, Any], kind: str) -> list[Mapping[str, Any]]:
    """Step summaries of one kind (``static``, ``sine``, ``constant_rate``, ``chamber``)."""
    steps = results.get("steps") or []
    return [s for s in steps if isinstance(s, Mapping) and s.get("kind") == kind]


def step_values(steps: Sequence[Mapping[str, Any]], key: str) -> list[float]:
    """The finite values of ``key`` over step summaries."""
    values = (as_float(s.get(key)) for s in steps)
    return [v for v in values if v is not None]


def ci_std(ci: Any, index: int | str | None = None) -> float | None:
    """Standard uncertainty from a 95 % interval: ``[lo, hi]``, a half-width, or a container.

    ``ci`` may be the interval itself, a list indexed by coefficient order, or a mapping by
    parameter name; the standard uncertainty is the half-width / 1.96 (large-sample fits).
    """
    if index is not None:
        if isinstance(ci, Mapping):
            ci = ci.get(index if isinstance(index, str) else str(index))
        elif isinstance(ci, Sequence) and not isinstance(ci, str) and isinstance(index, int):
            ci = ci[index] if 0 <= index < len(ci) else None
        else:
            return None
    if isinstance(ci, Sequence) and not isinstance(ci, str) and len(ci) == PAIR:
        lo, hi = as_float(ci[0]), as_float(ci[1])
        return abs(hi - lo) / (2 * Z95) if lo is not None and hi is not None else None
    half = as_float(ci)
    return abs(half) / Z95 if half is not None else None


def repetition_values(entry: Mapping[str, Any], key: str) -> list[float]:
    """Per-repetition values of ``key`` when the analysis reports them (``repetitions``)."""
    reps = entry.get("repetitions") if isinstance(entry, Mapping) else None
    if not isinstance(reps, Sequence):
        return []
    values = (as_float(r.get(key)) if isinstance(r, Mapping) else as_float(r) for r in reps)
    return [v for v in values if v is not None]


def std_of_mean(values: Sequence[float]) -> float | None:
    """Type A standard uncertainty of the mean, s/√n (None below two values)."""
    if len(values) < PAIR:
        return None
    return float(np.std(values, ddof=1) / math.sqrt(len(values)))


def noise_rms_v(results: Mapping[str, Any], channel: str) -> tuple[float, str]:
    """Sensor output noise (V RMS) and where it came from: measured, metadata or datasheet."""
    noise = analysis(results, "noise")
    if isinstance(noise, Mapping) and isinstance(noise.get(channel), Mapping):
        for key in ("rms_v", "noise_rms_v", "std_v"):
            value = as_float(noise[channel].get(key))
            if value is not None:
                return value, "measured (noise analysis)"
    bias = analysis(results, "bias")
    if isinstance(bias, Mapping) and isinstance(bias.get(channel), Mapping):
        for key in ("noise_rms_v", "std_v"):
            value = as_float(bias[channel].get(key))
            if value is not None:
                return value, "measured (static records)"
    value = as_float(sensors(results).get(channel, {}).get("noise_rms_v"))
    if value is not None:
        return value, "sensor datasheet"
    return 0.003, "datasheet limit (docs/method.md §1.3)"


#: per-temperature value key → the key of its own temperature list in columnar results
_COLUMN_TEMPERATURES = {"bias_v": ("temperatures_c",),
                        "scale_v_per_dps2": ("scale_temperatures_c", "temperatures_c")}


def temperature_points(entry: Mapping[str, Any], value_key: str = "bias_v"
                       ) -> list[Mapping[str, Any]]:
    """Per-temperature points ``{temperature_c, <value_key>, branch}`` of a temperature result.

    Accepts a list of point mappings (``points``) or columns (``temperatures_c`` with
    ``bias_v``; ``scale_temperatures_c`` with ``scale_v_per_dps2``; optional ``branch``).
    """
    if not isinstance(entry, Mapping):
        return []
    listed = entry.get("points")
    if isinstance(listed, Sequence):
        return [p for p in listed if isinstance(p, Mapping) and "temperature_c" in p
                and as_float(p.get(value_key)) is not None]
    values = entry.get(value_key)
    temps = next((entry[k] for k in _COLUMN_TEMPERATURES.get(value_key, ()) if
                  isinstance(entry.get(k), Sequence) and len(entry[k]) == len(values or [])), None)
    if not isinstance(values, Sequence) or temps is None:
        return []
    stated = entry.get("branch")
    named: list[Any] = list(stated) if isinstance(stated, Sequence) else []
    branches: list[Any] = named if len(named) == len(values) else ["all"] * len(values)
    return [{"temperature_c": t, value_key: v, "branch": b}
            for t, v, b in zip(temps, values, branches, strict=True)
            if as_float(t) is not None and as_float(v) is not None]
