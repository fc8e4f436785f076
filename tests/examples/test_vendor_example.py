"""The example vendor package inside this process (light-weight install): its envelope, the
simulated controller holding it to that envelope, and errors that name the distribution.

The real install (pip, fresh venv, the aatest CLI) is ``test_vendor_install.py``.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from aatest.engine import registry
from aatest.engine.errors import EnvelopeRefused, PluginError
from aatest.engine.interfaces import RigContext
from aatest.engine.steps import PlannedStep, SensorRef

#: aatest's public plugin API: all a vendor package may import from aatest
#: (``aatest.effects``: the effect-plugin API of group ``aatest.effects``; ``aatest.results``:
#: the typed record a report plugin receives, with its quantity names)
PUBLIC_API = {"aatest.engine.interfaces", "aatest.engine.errors", "aatest.engine.steps",
              "aatest.engine.logs", "aatest.engine.registry", "aatest.effects",
              "aatest.testing.conformance", "aatest.results", "aatest.results.quantities"}


def _table(**options: Any) -> Any:
    """The SR-1 constructed as the engine does, for the example's own sensor."""
    sensor = registry.load("sensor", "acme-mems-aa")
    sheet = sensor.target(registry.configure(sensor, {}), None).datasheet()
    info = registry.load("turntable", "acme-single-axis")
    context = RigContext(sensor=SensorRef(model="acme-mems-aa"), datasheet=sheet, seed=7)
    return info.target(registry.configure(info, options), context)


def _rate_step(rate_dps: float, axis: str = "inner") -> PlannedStep:
    return PlannedStep(id=f"rate-{axis}-{rate_dps:g}", kind="constant_rate", axis=axis,
                       duration_s=0.5, settle_s=1.0, samples=1000, rate_dps=rate_dps)


def _aatest_imports(source: str) -> set[str]:
    """Every ``aatest`` module a source imports (``from aatest.engine import registry`` counts
    as ``aatest.engine.registry``)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module == "aatest.engine":
            names.update(f"aatest.engine.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return {name for name in names if name.split(".")[0] == "aatest"}


def test_imports_only_the_public_plugin_api(example_dir: Path) -> None:
    modules = sorted((example_dir / "src").rglob("*.py"))
    assert len(modules) == 6  # package, turntable, sensor, effect, conformance rig, report
    used = set().union(*(_aatest_imports(m.read_text()) for m in modules))
    assert used - PUBLIC_API == set()
    assert "aatest.engine.registry" in used  # the turntable loads the simulator by name


@pytest.mark.usefixtures("vendor_example")
def test_declares_its_own_envelope() -> None:
    envelope = _table().envelope()
    assert (envelope.inner.rate_dps, envelope.inner.accel_dps2) == (720.0, 1500.0)
    assert envelope.max_frequency_hz == 20.0
    assert envelope.axes == ("inner",)  # the outer axis declared absent, not as 1e-9 limits


@pytest.mark.usefixtures("vendor_example")
def test_declares_its_capabilities_and_identifies_itself_on_start() -> None:
    table = _table()
    before = table.capabilities()
    assert before.encoder_resolution_counts_per_rev == 2**24
    # one count of a 24-bit encoder: 360·3600″ / 2²⁴ = 0.0772″
    assert 360 * 3600 / before.encoder_resolution_counts_per_rev == pytest.approx(0.0772,
                                                                                   abs=5e-5)
    assert (before.trigger_input, before.pulse_latch, before.model) == (True, True, "ACME SR-1")
    assert before.serial is None  # not identified before start
    table.start()
    try:
        assert table.capabilities().serial == "SR1-0042"
    finally:
        table.safe_stop()
        table.close()


@pytest.mark.usefixtures("vendor_example")
@pytest.mark.parametrize(("options", "rate_dps", "refused"), [
    ({}, 700.0, False),
    ({}, 800.0, True),  # within the twin's own 1200 °/s, beyond the SR-1's 720 °/s
    ({"rate_limit_dps": 900.0}, 800.0, False),
], ids=["within", "beyond-sr1", "configured-limit"])
def test_simulated_controller_enforces_the_declared_limits(
        options: dict[str, float], rate_dps: float, refused: bool) -> None:
    table = _table(**options)
    table.start()
    try:
        if refused:
            with pytest.raises(EnvelopeRefused, match="controller limit"):
                table.begin_motion(_rate_step(rate_dps))
        else:
            table.begin_motion(_rate_step(rate_dps))  # accepted: no EnvelopeRefused
            table.end_motion()
    finally:
        table.close()


@pytest.mark.usefixtures("vendor_example")
def test_refuses_the_missing_outer_axis_itself() -> None:
    table = _table()
    table.start()
    with pytest.raises(EnvelopeRefused, match="ACME SR-1 has no outer axis"):
        table.begin_motion(_rate_step(10.0, axis="outer"))
    with pytest.raises(EnvelopeRefused, match=r"no outer axis \(asked for 90°\)"):
        table.move_to(0.0, 90.0)
    table.close()


@pytest.mark.usefixtures("vendor_example")
def test_bad_options_name_the_distribution() -> None:
    info = registry.load("turntable", "acme-single-axis")
    with pytest.raises(PluginError, match=r"\(aatest-vendor-example\): bad options: "
                                          r"rate_limit_dps: Input should be greater than 0"):
        registry.configure(info, {"rate_limit_dps": -1})


def test_broken_vendor_plugins_are_named(install: Callable[..., None]) -> None:
    install("acme-broken", "2.0", {
        "aatest.turntables": {
            "no-methods": "aatest_vendor_example.sensor:MemsAngularAccelerometer"},
        "aatest.sensors": {"no-module": "acme_missing.sensor:Nothing"}})
    with pytest.raises(PluginError, match="turntable plugin 'no-methods' from distribution "
                                          "'acme-broken' lacks required method"):
        registry.load("turntable", "no-methods")
    with pytest.raises(PluginError, match="'no-module' from distribution 'acme-broken' "
                                          "failed to import"):
        registry.load("sensor", "no-module")


@pytest.mark.usefixtures("vendor_example")
def test_report_plugin_reads_the_typed_record(tmp_path: Path) -> None:
    """The vendor's report gets the typed results and names quantities as aatest does."""
    from contract_results import decided, make_results

    results = decided(make_results())
    info = registry.load("report", "acme-summary")
    page = info.target(registry.configure(info, {"title": "SR-1 summary"})).render(
        results, tmp_path, None).read_text(encoding="utf-8")
    assert "<h1>SR-1 summary</h1>" in page and f"<b>{results.overall}</b>" in page
    assert "Scale-factor deviation from nominal" in page and "V/(°/s²)" in page
    assert "scale_factor_deviation_pct" not in page and "scale_v_per_dps2" not in page
    assert page.count("<tr>") == len(results.verdicts) + 1  # a row per judged quantity
