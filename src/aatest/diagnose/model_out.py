"""Write the extended rig model: the nominal replay model plus every finding, by contract name.

The model's effect fields are named exactly as the vocabulary (``aatest.twin.model``),
so each finding drops into its place: sensor effects into the channel's ``SensorModel``, table
effects into the inner axis, clock drift into the DAQ. An effect from an installed plugin
(entry-point group ``aatest.effects``) goes into its channel's ``plugin_effects`` with the
distribution that provides it, so the twin applies the plugin's forward model and a model
loaded where the plugin is missing says what to install. The logger's pre-sample filter the
replay assumed is kept, so re-running the same procedure on the twin with this model
reproduces the measured behaviour.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from aatest.effects import installed_effects
from aatest.engine.datasheet import (
    REFERENCE_BIAS_V,
    REFERENCE_RANGE_DPS2,
    REFERENCE_SCALE_V_PER_DPS2,
)
from aatest.twin import model as m

_SENSOR_EFFECTS = set(m.EFFECTS) - {"clock_drift", "rate_ripple", "motor_vibration"}


def _sensor(channel: str, axis: str, calib: dict[str, float], noise_v: float,
            range_dps2: float) -> m.SensorModel:
    return m.SensorModel(
        channel=channel, axis=axis, bias_v=calib.get("bias_v", REFERENCE_BIAS_V),
        scale_v_per_dps2=calib.get("scale_v_per_dps2", REFERENCE_SCALE_V_PER_DPS2),
        range_dps2=range_dps2, noise_rms_v=noise_v)


def extended_model(channels: list[dict[str, Any]], findings: list[dict[str, Any]],
                   antialias_hz: float | None, t_ref_c: float) -> m.RigModel:
    """Rig model with the calibrated nominals of each channel and the accepted effects.

    Parameters
    ----------
    channels
        Per channel: ``channel``, ``axis``, ``bias_v``, ``scale_v_per_dps2``,
        ``noise_rms_v``, ``range_dps2``.
    findings
        Contract findings (``effect``, ``parameters``, optional ``channel``, ``azimuth_deg``…).
    """
    sensors = {c["channel"]: _sensor(c["channel"], c["axis"], c, c.get("noise_rms_v", 0.001),
                                     c.get("range_dps2", REFERENCE_RANGE_DPS2)) for c in channels}
    table, daq = m.TableModel(), m.DaqModel(antialias_hz=antialias_hz)
    plugins = installed_effects()
    for f in findings:
        name, params = f["effect"], dict(f["parameters"])
        if name in plugins and (name not in m.EFFECTS or plugins[name].effect.shadows):
            if f.get("channel") in sensors:
                sensors[f["channel"]] = _plugin_effect(sensors[f["channel"]], name, params,
                                                       plugins[name].distribution)
        elif name == "clock_drift":
            daq = daq.model_copy(update={"clock_drift": m.ClockDrift(**params)})
        elif name in ("rate_ripple", "motor_vibration"):
            table = _table_effect(table, name, params, f)
        elif name in _SENSOR_EFFECTS and f.get("channel") in sensors:
            if name == "misalignment" and "azimuth_deg" in f:
                params["azimuth_deg"] = f["azimuth_deg"]
            if name == "excess_noise":
                params = {"rms_v": params["rms_v"]}
            ch = f["channel"]
            sensors[ch] = sensors[ch].model_copy(update={name: m.EFFECTS[name](**params)})
    return m.RigModel(t_ref_c=t_ref_c, sensors=list(sensors.values()), table=table, daq=daq)


def _plugin_effect(sensor: m.SensorModel, name: str, params: dict[str, float],
                   distribution: str) -> m.SensorModel:
    """The sensor with one plugin effect added (replacing an earlier one of the same name)."""
    kept = [pe for pe in sensor.plugin_effects or () if pe.effect != name]
    entry = m.PluginEffect(effect=name, distribution=distribution,
                           parameters={k: float(v) for k, v in params.items()})
    return sensor.model_copy(update={"plugin_effects": [*kept, entry]})


def _table_effect(table: m.TableModel, name: str, params: dict[str, float],
                  finding: dict[str, Any]) -> m.TableModel:
    axis = table.inner
    if name == "rate_ripple":
        ripple = m.RateRipple(**params, phase_rad=float(finding.get("phase_rad", 0.0)))
        axis = axis.model_copy(update={"rate_ripple": [*axis.rate_ripple, ripple]})
    else:
        band = float(finding.get("bandwidth_hz", 0.0))
        axis = axis.model_copy(update={"motor_vibration": m.MotorVibration(**params,
                                                                           bandwidth_hz=band)})
    return table.model_copy(update={"inner": axis})


def write_model(path: Path, model: m.RigModel) -> Path:
    """Dump the model YAML the twin loads (``aatest.twin.model.load_rig_model``)."""
    m.dump_rig_model(model, path)
    return Path(path)
