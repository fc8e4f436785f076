"""The sensor datasheet and the per-channel record: one definition, one source of numbers."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pydantic import ValidationError
from ruamel.yaml import YAML

from aatest.engine.datasheet import (
    REFERENCE_RANGE_DPS2,
    REFERENCE_SCALE_V_PER_DPS2,
    SensorDatasheet,
    SensorInfo,
    SensorNominals,
)
from aatest.engine.interfaces import RigContext, SharedResources
from aatest.engine.steps import SensorRef
from aatest.recording.data.importer import DatasetManifest

ROOT = Path(__file__).parents[2]
SRC = ROOT / "src" / "aatest"
# the reference sensor's numbers live with the per-channel sensor record (aatest.results.sensor;
# engine.datasheet re-exports them), so the typed results need not import the engine
DATASHEET_MODULE = SRC / "results" / "sensor.py"
#: the reference sensor's datasheet numbers, as literals (range ±10 rad/s², 0.23 V/(rad/s²))
REFERENCE_LITERALS = re.compile(r"(?<![\d.])(572\.958|0\.004014|4\.014e-3)(?!\d)")


def test_reference_numbers_are_stated_in_one_module_only() -> None:
    assert REFERENCE_LITERALS.search(DATASHEET_MODULE.read_text(encoding="utf-8"))
    offenders = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
                 for path in sorted(SRC.rglob("*.py")) if path != DATASHEET_MODULE
                 for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
                 if REFERENCE_LITERALS.search(line)]
    assert offenders == []


def _documented_sensor_entry() -> dict:
    """The ``sensors`` entry of the ``dataset.yaml`` example in docs/interfaces.md §3."""
    text = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8")
    section = text.split("## 3. Measured-data import", 1)[1]
    block = section.split("```yaml", 1)[1].split("```", 1)[0]
    manifest = YAML(typ="safe", pure=True).load(block)
    return dict(manifest["sensors"][0])


def test_import_format_accepts_the_documented_sensor_keys() -> None:
    entry = _documented_sensor_entry()
    assert set(entry) == {"channel", "axis", "nominal_bias_v", "nominal_scale_v_per_dps2",
                          "range_dps2"}
    manifest = DatasetManifest.model_validate({
        "sensors": [entry], "sample_rate_hz": 2000,
        "steps": [{"id": "s01", "kind": "static", "table": "t.csv", "daq": "d.csv"}]})
    sensor = manifest.sensors[0]
    assert {key: getattr(sensor, key) for key in entry} == entry


@pytest.mark.parametrize("key", ["scale_v_per_dps2", "colour"], ids=["datasheet-name", "unknown"])
def test_import_format_rejects_keys_outside_the_record(key: str) -> None:
    with pytest.raises(ValidationError, match=key):
        SensorInfo.model_validate({"channel": "v_sz", key: 0.004})


def test_datasheet_and_record_share_every_nominal_field() -> None:
    sheet = SensorDatasheet(model="acme", range_dps2=2000.0, nominal_bias_v=1.25,
                            nominal_scale_v_per_dps2=0.001, noise_rms_v=0.002,
                            bias_tolerance_v=0.02, scale_tolerance_pct=2.0,
                            bias_temperature_limit_v_per_c=0.001,
                            scale_temperature_limit_per_c=0.0003,
                            channels={"a": "I", "b": "P"})
    records = sheet.sensor_infos("SN-7")
    assert [(r.channel, r.axis, r.model, r.serial) for r in records] == [
        ("a", "I", "acme", "SN-7"), ("b", "P", "acme", "SN-7")]
    for name in SensorNominals.model_fields:
        assert all(getattr(r, name) == getattr(sheet, name) for r in records), name


def test_datasheet_reads_and_accepts_the_older_scale_name() -> None:
    sheet = SensorDatasheet(model="old", scale_v_per_dps2=0.002)
    assert sheet.nominal_scale_v_per_dps2 == sheet.scale_v_per_dps2 == 0.002
    with pytest.raises(ValidationError, match="not both"):
        SensorDatasheet(model="old", scale_v_per_dps2=0.002, nominal_scale_v_per_dps2=0.002)


def test_defaults_are_the_reference_sensor() -> None:
    sheet, record = SensorDatasheet(model="x"), SensorInfo(channel="v_sz")
    assert sheet.range_dps2 == record.range_dps2 == REFERENCE_RANGE_DPS2
    assert sheet.scale_v_per_dps2 == record.nominal_scale_v_per_dps2 == REFERENCE_SCALE_V_PER_DPS2
    # 0.23 V/(rad/s²) and ±10 rad/s² (docs/method.md §1.3)
    assert pytest.approx(0.23 * 3.141592653589793 / 180, rel=1e-4) == REFERENCE_SCALE_V_PER_DPS2
    assert pytest.approx(10 * 180 / 3.141592653589793, rel=1e-6) == REFERENCE_RANGE_DPS2


def test_record_reads_metadata_written_by_any_version() -> None:
    """A recording's ``sensors`` entry (older versions wrote the dataclass fields) reads back;
    keys this version does not know are ignored, missing ones take the defaults."""
    stored = {"channel": "v_sy", "axis": "O", "nominal_bias_v": 2.495,
              "nominal_scale_v_per_dps2": 0.00401, "range_dps2": 572.0, "model": "sr207-aamu",
              "serial": "U1", "noise_rms_v": 0.003, "written_by_a_future_version": True}
    info = SensorInfo.from_metadata(stored)
    assert (info.channel, info.axis, info.nominal_bias_v, info.serial) == ("v_sy", "O", 2.495, "U1")
    assert info.scale_tolerance_pct == SensorInfo(channel="x").scale_tolerance_pct
    assert SensorInfo.from_metadata(info.model_dump()) == info


class _Thing:
    pass


class _Other:
    pass


def test_shared_resources_are_keyed_by_type() -> None:
    resources = SharedResources()
    assert resources.get(_Thing) is None
    made = resources.setdefault(_Thing, _Thing)
    assert resources.setdefault(_Thing, _Thing) is made and resources.get(_Thing) is made
    assert resources.get(_Other) is None
    with pytest.raises(TypeError, match="_Other"):
        resources.setdefault(_Other, _Thing)  # type: ignore[arg-type]


def test_each_rig_context_has_its_own_resources() -> None:
    sheet = SensorDatasheet(model="x")
    one, two = (RigContext(sensor=SensorRef(model="x"), datasheet=sheet) for _ in range(2))
    one.resources.setdefault(_Thing, _Thing)
    assert two.resources.get(_Thing) is None
