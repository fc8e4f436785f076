"""Every figure of aatest is rendered by one module, and every kind renders reproducibly.

Before, five modules wrote SVG with their own ``savefig`` and two of them left matplotlib's
random id salt in place, so re-rendering the same data gave different bytes. Now
:mod:`aatest.presentation.figures` is the only place that saves a figure; each kind below —
an analysis figure, a report figure, a diagnosis figure, a fleet control chart and a history
trend — is drawn twice from the same data and must give identical bytes.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

import aatest
from aatest.diagnose.figures import per_step_bars
from aatest.fleet.control import control_chart
from aatest.fleet.figures import control_plot
from aatest.plugins.report.figures import diagnosis_bars
from aatest.presentation.figures import new_figure, to_svg
from aatest.records.models import CalibrationRecord, QuantityRecord
from aatest.records.trend import _plot

SOURCE = Path(aatest.__file__).parent
T0 = datetime(2026, 1, 5, tzinfo=UTC)
#: a date in matplotlib's SVG metadata (it stamps one unless told not to)
_DATE = re.compile(r"<dc:date>")


def _analysis() -> str:
    fig, ax = new_figure(2)
    ax[0, 0].plot(np.arange(10.0), 0.5 * np.arange(10.0), "o", ms=3)
    ax[1, 0].semilogx(np.arange(1.0, 10.0), np.sqrt(np.arange(1.0, 10.0)))
    return to_svg(fig)


def _report() -> str:
    svg = diagnosis_bars({"candidates": [{"effect": "scale_temperature", "delta_bic": -42.0,
                                          "accepted": True},
                                         {"effect": "time_delay", "delta_bic": 3.5}],
                          "gain": {"rmse_v_before": 2e-3, "rmse_v_after": 5e-4}})
    assert svg is not None
    return svg


def _diagnosis() -> str:
    rows = [{"step": f"s{i:03d}", "rms_v_nominal": 1e-3 * (i + 1), "rms_v_extended": 2e-4}
            for i in range(1, 6)]
    return per_step_bars({"per_step": rows}, "v_sz")


def _record(i: int, value: float) -> CalibrationRecord:
    when = T0 + timedelta(days=30 * i)
    return CalibrationRecord(
        id=i, model="SR207", serial="S1", certificate_number=None, supersedes_id=None,
        superseded_by=None, command="run", procedure="p", procedure_sha256=None,
        operator=None, lab="L", calibrated_utc=when, registered_utc=when,
        overall_verdict="pass", verdicts=[], bundle=f"/b/{i}", key_fingerprint=None,
        files={}, quantities={"bias.v_sz": QuantityRecord(value=value, unit="V",
                                                          expanded_uncertainty=1e-3)},
        rig={}, plugin_versions={})


def _fleet() -> str:
    values = np.array([2.500, 2.501, 2.499, 2.502, 2.500, 2.530, 2.501, 2.500])
    moments = [T0 + timedelta(days=7 * i) for i in range(values.size)]
    chart = control_chart("bias.v_sz", "SR207", None, moments,
                          [f"S{i}" for i in range(values.size)], values.tolist())
    assert chart is not None
    return control_plot(chart, "Bias", "V")


def _history() -> str:
    records = [_record(i, 2.5 + 1e-3 * i) for i in range(4)]
    svg, _caption = _plot(records, "bias.v_sz", (2.4, 2.6), T0 + timedelta(days=400))
    return str(svg)


KINDS: dict[str, Callable[[], str]] = {"analysis": _analysis, "report": _report,
                                       "diagnosis": _diagnosis, "fleet": _fleet,
                                       "history": _history}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_each_figure_kind_renders_to_the_same_bytes_twice(kind: str) -> None:
    """The same data give the same SVG: ids salted by content, no date stamped."""
    first, again = KINDS[kind](), KINDS[kind]()
    assert "<svg" in first
    assert first == again
    assert not _DATE.search(first)


def test_only_the_figures_module_saves_figures() -> None:
    """No module but aatest.presentation.figures calls ``savefig`` (a new SVG writer would
    bypass the reproducible ids)."""
    writers = sorted(str(p.relative_to(SOURCE)) for p in SOURCE.rglob("*.py")
                     if "savefig(" in p.read_text(encoding="utf-8"))
    assert writers == ["presentation/figures.py"]
