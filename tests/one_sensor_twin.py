"""A rig whose twin is built from a model file of one sensor (``v_sz``), as a model written
for the single-axis sr207 is: a three-axis unit (sr207-aamu) on it has two channels the DAQ
does not record."""

from __future__ import annotations

from pathlib import Path

import yaml

from aatest.plugins.sensors.sr207 import SR207
from aatest.twin.defaults import realistic_rig_model


def one_sensor_twin(directory: Path) -> Path:
    """Write ``twin.yaml`` (the realistic sr207 model) and ``rig.yaml`` naming it for the
    simulated table and DAQ into ``directory``; return the rig file."""
    model = realistic_rig_model(SR207().datasheet())
    (directory / "twin.yaml").write_text(yaml.safe_dump(model.model_dump(mode="json")))
    rig = directory / "rig.yaml"
    rig.write_text("turntable: {plugin: sim, model: twin.yaml}\n"
                   "daq: {plugin: sim, model: twin.yaml}\n")
    return rig
