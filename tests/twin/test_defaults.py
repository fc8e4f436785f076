"""The twin's realistic rig is built from the datasheet it is handed, and imports no plugin."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from twin_steps import static_step

from aatest.engine.datasheet import SensorDatasheet
from aatest.twin.api import simulate_step
from aatest.twin.defaults import realistic_rig_model, realistic_sensor_models

SRC = Path(__file__).parents[2] / "src" / "aatest"


def _imported_modules(package: Path) -> dict[str, set[str]]:
    """File (relative to ``src/aatest``) → every module it imports, lazily or not."""
    found: dict[str, set[str]] = {}
    for path in sorted(package.rglob("*.py")):
        names: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module:
                names.add(node.module)
            elif isinstance(node, ast.Import):
                names.update(alias.name for alias in node.names)
        found[str(path.relative_to(SRC))] = names
    return found


def test_twin_core_imports_no_plugin() -> None:
    """Only the protocol servers (the twin behind a real driver's wire format) may reach into
    the plugins, for the register map and frame layout they serve."""
    offenders = {f: sorted(m for m in mods if m.startswith("aatest.plugins"))
                 for f, mods in _imported_modules(SRC / "twin").items()
                 if not f.startswith("twin/servers/")}
    assert {f: m for f, m in offenders.items() if m} == {}


def test_sensor_plugins_do_not_import_the_twin() -> None:
    offenders = {f: sorted(m for m in mods if m.startswith("aatest.twin"))
                 for f, mods in _imported_modules(SRC / "plugins" / "sensors").items()}
    assert {f: m for f, m in offenders.items() if m} == {}


def test_realistic_sensors_take_the_datasheet_nominals() -> None:
    sheet = SensorDatasheet(model="acme", range_dps2=2000.0, nominal_bias_v=1.25,
                            nominal_scale_v_per_dps2=0.001, channels={"a": "I", "b": "O"})
    models = realistic_sensor_models(sheet)
    assert [(s.channel, s.axis) for s in models] == [("a", "I"), ("b", "O")]
    for s in models:
        assert (s.scale_v_per_dps2, s.range_dps2) == (0.001, 2000.0)
        assert abs(s.bias_v - 1.25) <= 0.01  # an individual unit inside the datasheet band
        assert s.saturation is not None and s.saturation.limit_dps2 == pytest.approx(2100.0)
        assert s.resolution_dps2 == pytest.approx(0.00005 * 2000.0)  # 0.005 % FR
    assert [s.channel for s in realistic_rig_model(sheet).sensors] == ["a", "b"]


def test_simulated_output_at_rest_is_the_datasheet_bias() -> None:
    """Level and at rest, the sensor reads its bias (≈ the datasheet's) plus noise only."""
    sheet = SensorDatasheet(model="acme", nominal_bias_v=1.25, nominal_scale_v_per_dps2=0.001)
    sim = simulate_step(realistic_rig_model(sheet, drift_ppm=0.0), static_step(samples=8192), 3)
    volts = np.asarray(sim.daq["v_sz"])
    assert abs(float(np.mean(volts)) - 1.25) < 0.01


def test_rotor_stiction_is_opt_in_and_keeps_the_damping_at_400_dps2() -> None:
    """``stiction=True`` adds the rotor's gap and flattens the damping below 100 °/s² (the gap
    takes over the low-amplitude roll-off); at the scale-factor and transfer-function
    records' 400 °/s² the damping stays the default's (0.7318 vs 0.7300: ≈ 0.1 sample of lag).
    """
    from aatest.twin.defaults import REALISTIC_STICTION
    from aatest.twin.sensor import damping_of

    plain, gap = (realistic_rig_model(stiction=s).sensors[0] for s in (False, True))
    assert plain.rotor_stiction is None
    assert gap.rotor_stiction == REALISTIC_STICTION
    amps = np.array([1.0, 10.0, 100.0, 400.0])
    zeta = {}
    for name, s in (("plain", plain), ("gap", gap)):
        assert s.amplitude_damping is not None and s.sensor_dynamics is not None
        zeta[name] = damping_of(s.amplitude_damping, s.sensor_dynamics.damping, amps)
    # flat up to its floor: at 1, 10 and 100 °/s² the ratio is floor/reference = 100/100 = 1
    # exactly, log10(1) is exactly 0 in IEEE arithmetic and ζ = 0.78 + k·0 is the base bit for
    # bit on any machine: an exact computation, so no tolerance
    assert np.all(zeta["gap"][:3] == 0.78)
    assert zeta["gap"][3] == pytest.approx(zeta["plain"][3], abs=0.002)
