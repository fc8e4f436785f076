"""The traceability block: what was run, on what, by whom, with which software and data.

Everything here is read from ``results.json`` (metadata written by the runner) except the
recording hash, which is computed from ``run_dir/recording.mcap`` at render time so the
certificate names the exact raw data it was derived from.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import aatest
from aatest.engine.run.signing import file_sha256
from aatest.engine.uncertainty import access as ex

RECORDING_FILE = "recording.mcap"


@dataclass(frozen=True)
class Traceability:
    """Fields of the traceability block ('—' where the run did not record them)."""

    procedure: str
    procedure_sha256: str
    procedure_text: str
    rig: Mapping[str, Any]
    plugins: list[tuple[str, str]]
    sensors: list[Mapping[str, Any]]
    table_serial: str
    operator: str
    started_utc: str
    environment_c: float | None
    software_version: str
    recording_sha256: str
    seed: Any
    extra: Mapping[str, Any] = field(default_factory=dict)
    #: chamber set-points the run stepped through (°C), empty without a chamber
    chamber_setpoints_c: list[float] = field(default_factory=list)


def _plugins(meta: Mapping[str, Any]) -> list[tuple[str, str]]:
    """``(role, "name distribution version")`` pairs from whatever form the runner used."""
    listed = meta.get("plugins") or meta.get("plugin_versions") or {}
    rows = []
    if isinstance(listed, Mapping):
        for role, info in sorted(listed.items()):
            if isinstance(info, Mapping):
                keys = ("name", "distribution", "version")
                text = " ".join(str(info[k]) for k in keys if k in info)
            else:
                text = str(info)
            rows.append((str(role), text))
    return rows


def _environment_c(results: Mapping[str, Any], meta: Mapping[str, Any]) -> float | None:
    for key in ("ambient_c", "environment_c", "temperature_c"):
        value = ex.as_float(meta.get(key))
        if value is not None:
            return value
    env = meta.get("environment")
    if isinstance(env, Mapping):
        return ex.as_float(env.get("temperature_c"))
    return None


def _table_serial(results: Mapping[str, Any], meta: Mapping[str, Any]) -> str:
    for source in (meta, meta.get("rig") or {}, results.get("rig") or {}):
        if isinstance(source, Mapping):
            for key in ("table_serial", "turntable_serial"):
                if source.get(key):
                    return str(source[key])
            table = source.get("turntable")
            if isinstance(table, Mapping) and table.get("serial"):
                return str(table["serial"])
    return "—"


def recording_hash(run_dir: Path) -> str:
    """SHA-256 of the run's recording, or a plain statement that there is none."""
    path = Path(run_dir) / RECORDING_FILE
    return file_sha256(path) if path.is_file() else "no recording.mcap in the run directory"


def traceability(results: Mapping[str, Any], run_dir: Path) -> Traceability:
    """Collect the traceability block of a report."""
    meta = results.get("metadata") or {}
    text = str(meta.get("procedure_text") or "")
    computed = hashlib.sha256(text.encode()).hexdigest() if text else "—"
    sha = str(meta.get("procedure_sha256") or computed)
    return Traceability(
        procedure=str(results.get("procedure") or meta.get("procedure") or "—"),
        procedure_sha256=sha,
        procedure_text=text,
        rig=results.get("rig") or meta.get("rig") or {},
        plugins=_plugins(meta),
        sensors=list(ex.sensors(results).values()),
        table_serial=_table_serial(results, meta),
        operator=str(meta.get("operator") or "—"),
        started_utc=str(meta.get("started_utc") or "—"),
        environment_c=_environment_c(results, meta),
        chamber_setpoints_c=ex.step_values(ex.steps_of_kind(results, "chamber"), "temperature_c"),
        software_version=str(meta.get("aatest_version") or aatest.__version__),
        recording_sha256=recording_hash(run_dir),
        seed=meta.get("seed", "—"),
        extra={"lab_duration_s": results.get("lab_duration_s"),
               "wall_duration_s": results.get("wall_duration_s")},
    )
