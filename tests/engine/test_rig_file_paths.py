"""A file a rig file names lies beside the rig file, wherever ``aatest`` is run from.

Before, ``--rig rigs/rig.yaml`` naming ``model: twin.yaml`` read ``./twin.yaml``: from any
other directory the run failed ("cannot read file"), or read another model that happened to
sit there. The check: the table's envelope comes from the model beside the rig file (its
inner-axis acceleration limit, 123 °/s²), not from a decoy of the same name in the working
directory (456 °/s²), for ``prepare`` (what ``validate`` and ``run`` call) and ``validate``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine import registry
from aatest.engine.run.session import prepare
from aatest.plugins.sensors.sr207 import SR207
from aatest.twin.defaults import realistic_rig_model

PROCEDURE = """\
procedure: beside-the-rig
sensor: {model: sr207, serial: "A1234"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 1}
steps:
  - sine: {axis: inner, frequency_hz: 1.0, accel_dps2: 100, snap: coherent}
analysis: [sync]
"""


def _model(path: Path, inner_accel_dps2: float) -> None:
    model = realistic_rig_model(SR207().datasheet())
    table = model.table.model_copy(update={"inner": model.table.inner.model_copy(
        update={"accel_limit_dps2": inner_accel_dps2})})
    data = model.model_copy(update={"table": table}).model_dump(mode="json")
    path.write_text(yaml.safe_dump(data), encoding="utf-8")


@pytest.fixture
def rig_elsewhere(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """``rigs/rig.yaml`` naming ``twin.yaml`` (beside it); run from ``elsewhere/``, which
    holds a different ``twin.yaml``. Returns the rig file's path relative to the CWD."""
    (tmp_path / "rigs").mkdir()
    (tmp_path / "elsewhere").mkdir()
    _model(tmp_path / "rigs" / "twin.yaml", 123.0)
    _model(tmp_path / "elsewhere" / "twin.yaml", 456.0)
    (tmp_path / "rigs" / "rig.yaml").write_text(
        "turntable: {plugin: sim, model: twin.yaml}\ndaq: {plugin: sim, model: twin.yaml}\n",
        encoding="utf-8")
    (tmp_path / "elsewhere" / "p.yaml").write_text(PROCEDURE, encoding="utf-8")
    monkeypatch.chdir(tmp_path / "elsewhere")
    return Path("..") / "rigs" / "rig.yaml"


def test_the_model_beside_the_rig_file_is_the_one_read(rig_elsewhere: Path) -> None:
    prepared = prepare(Path("p.yaml"), rig_elsewhere)
    assert prepared.envelope.inner.accel_dps2 == 123.0


def test_validate_refuses_by_the_model_beside_the_rig_file(rig_elsewhere: Path) -> None:
    """A sine above the rig-adjacent model's limit (but within the decoy's) is refused."""
    Path("p.yaml").write_text(PROCEDURE.replace("accel_dps2: 100", "accel_dps2: 200"),
                              encoding="utf-8")
    result = CliRunner().invoke(app, ["validate", "p.yaml", "--rig", str(rig_elsewhere)])
    assert result.exit_code == 2, result.output
    assert "123" in result.output, result.output


def test_a_logger_file_option_lies_beside_the_rig_file_too(tmp_path: Path) -> None:
    info = registry.load("daq", "can")
    config = registry.configure(info, {"dbc_file": "frames.dbc"}, tmp_path)
    assert config.dbc_file == tmp_path / "frames.dbc"  # type: ignore[attr-defined]
    absolute = registry.configure(info, {"dbc_file": "/srv/frames.dbc"}, tmp_path)
    assert absolute.dbc_file == Path("/srv/frames.dbc")  # type: ignore[attr-defined]
