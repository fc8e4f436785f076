"""Every channel of the sensor under test, against the channels the DAQ records.

Why before anything moves: the sensor plugin's datasheet names the unit's channels (the
three-axis sr207-aamu: ``v_sz``, ``v_sy``, ``v_sx``) and the analyses measure each of them,
but the DAQ records only the channels it declares (``Daq.channels()``: a CAN logger's
``channels`` option, a twin's rig-model file with one sensor). A channel the DAQ does not
record was measured by nothing: the run recorded a whole campaign, then its analysis failed
on the missing channel as an internal error (exit 4). Refused at the procedure's
``sensor.model`` (exit 2), naming the channels that would not be recorded.
"""

from __future__ import annotations

from typing import Any

from aatest.engine.errors import Problem
from aatest.engine.run.rig import sensor_datasheet
from aatest.positioned_yaml import locate


def sensor_channel_problems(prepared: Any) -> tuple[list[Problem], str]:
    """A located problem when the DAQ records not every sensor channel (see the module)."""
    sensor = prepared.plan.sensor
    sheet = sensor_datasheet(sensor)[0]
    wanted = [info.channel for info in sheet.sensor_infos(sensor.serial)]
    recorded = set(prepared.daq_channels)
    missing = [channel for channel in wanted if channel not in recorded]
    daq = prepared.rig_config.daq.plugin
    if not missing:
        return [], f"{sensor.model}: {', '.join(wanted)}, each recorded by daq plugin {daq!r}"
    proc = prepared.procedure
    where = ("sensor", "model")
    line, column = locate(proc.source_tree, where) if proc.source_tree is not None else (1, 1)
    message = (f"sensor {sensor.model!r} has the channels {', '.join(wanted)}, but daq plugin "
               f"{daq!r} records {', '.join(prepared.daq_channels) or 'none'}: "
               f"{', '.join(missing)} would not be recorded (give the DAQ "
               f"{'those channels' if len(missing) > 1 else 'that channel'}, or name a sensor "
               "model with the channels it records)")
    return [Problem(proc.source_file or f"<{proc.procedure}>", line, column,
                    ".".join(where), message)], "a sensor channel would not be recorded"
