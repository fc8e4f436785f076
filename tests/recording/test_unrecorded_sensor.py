"""A recording whose steps lack a sensor channel its metadata names is bad input, named.

Made as the station made it before it ran the preflight: the three-axis sr207-aamu through a
twin whose model file holds one sensor (``v_sz``), run by a library call that skips the
preflight's "sensor channels" check. The analysis of ``v_sy`` then ended in ``KeyError:
'v_sy'`` — an internal error (exit 4), in ``run`` and in every later ``analyze`` and ``batch``
of the recording. It is a recording that does not hold what its metadata states: exit 2,
naming the step and the channels; every recorded step is kept.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from one_sensor_twin import one_sensor_twin
from typer.testing import CliRunner

from aatest.cli import app
from aatest.engine.errors import EXIT_BAD_INPUT, RecordingError
from aatest.engine.run import session

PROCEDURE = """\
procedure: three-axes-one-logged
sensor: {model: sr207-aamu, serial: "U1"}
rig: {turntable: sim, daq: sim, chamber: none}
sampling: {rate_hz: 2000, samples: 4000, settle_s: 0.5}
steps:
  - static: {inner_deg: 0, outer_deg: 0}
  - static: {inner_deg: 0, outer_deg: 180}
analysis: [sync, noise]
"""
SAYS = ("step s001-static-i0-o0 logged the sensor channel(s) v_sz, not v_sy, v_sx, which the "
        "run metadata names")


def test_a_sensor_channel_the_steps_lack_is_a_recording_error(tmp_path: Path) -> None:
    rig = one_sensor_twin(tmp_path)
    (tmp_path / "p.yaml").write_text(PROCEDURE, encoding="utf-8")
    with pytest.raises(RecordingError) as raised:
        session.run(tmp_path / "p.yaml", rig, tmp_path / "run", False, 0, None, False,
                    confirm_prompts="auto")
    assert raised.value.exit_code == EXIT_BAD_INPUT and SAYS in str(raised.value)
    assert (tmp_path / "run" / "recording.mcap").is_file()  # the recording is kept
    again = CliRunner().invoke(app, ["analyze", str(tmp_path / "run"), "--out",
                                     str(tmp_path / "again")])
    assert again.exit_code == EXIT_BAD_INPUT and SAYS in again.output, again.output
