"""The traceability block: what was run, on what, by whom, with which software and data.

Everything here is read from the typed results (metadata written by the runner) except the
recording hash, which is computed from ``run_dir/recording.mcap`` at render time so the
certificate names the exact raw data it was derived from.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import aatest
from aatest.results import RunResults
from aatest.results.root import RunMetadata
from aatest.results.sensor import SensorInfo

RECORDING_FILE = "recording.mcap"


@dataclass(frozen=True)
class Traceability:
    """Fields of the traceability block ('—' where the run did not record them)."""

    procedure: str
    procedure_sha256: str
    procedure_text: str
    rig: list[tuple[str, str]]
    plugins: list[tuple[str, str]]
    sensors: list[SensorInfo]
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


def _plugins(meta: RunMetadata) -> list[tuple[str, str]]:
    """``(role, "name distribution version")`` pairs of the plugins the run used."""
    return [(role, text) for role, text in sorted(meta.plugin_versions.items())]


def _rig(results: RunResults) -> list[tuple[str, str]]:
    """``(role, plugin and options)`` of the rig, as a person reads it (no Python repr)."""
    rows = []
    for role, stated in sorted(results.rig.items()):
        if isinstance(stated, Mapping):
            plugin = stated.get("plugin")
            options = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in sorted(stated.items())
                                if k != "plugin" and not isinstance(v, Mapping | list))
            text = " ".join(str(x) for x in (plugin, f"({options})" if options else "") if x)
        else:
            text = str(stated)
        rows.append((role, text or "—"))
    return rows


def _environment_c(meta: RunMetadata) -> float | None:
    """The ambient temperature the run recorded, °C (imports may state one)."""
    for key in ("ambient_c", "environment_c", "temperature_c"):
        value = meta.recorded(key)
        if isinstance(value, int | float) and math.isfinite(value):
            return float(value)
    return None


def _table_serial(results: RunResults) -> str:
    if results.metadata.table_serial:
        return results.metadata.table_serial
    table = results.rig.get("turntable")
    if isinstance(table, Mapping) and table.get("serial"):
        return str(table["serial"])
    return "—"


@contextlib.contextmanager
def hashed_ahead(run_dir: Path) -> Iterator[None]:
    """Hash ``run_dir``'s recording on a thread now (:func:`aatest.bundle.manifest.hash_soon`,
    unless that file is hashed or being hashed already); :func:`recording_hash` takes that
    digest.

    Why: the report states the recording's SHA-256, and hashing a stepped-sine recording
    (168 MB) takes ≈ 0.12 s. ``hashlib`` releases the GIL while it hashes, so started when
    the render is prepared, the digest is made on the other core while results.json is
    encoded (pure Python JSON) and the view model built. The same digest: the same bytes
    hashed by the same function, and it is taken only while the file's identity (device,
    inode, size, modification time) is the one hashed.
    The thread it started ends before the block does (a process that forks workers, which
    refuses to fork while another thread runs, never sees it after the block).
    """
    from aatest.bundle.manifest import hash_soon  # imported here, not on the thread

    thread = hash_soon(Path(run_dir) / RECORDING_FILE)
    try:
        yield
    finally:
        if thread is not None:
            thread.join()


def recording_hash(run_dir: Path) -> str:
    """SHA-256 of the run's recording, or a plain statement that there is none (a digest
    made ahead, :func:`hashed_ahead`, when the file is still the one it hashed)."""
    path = Path(run_dir) / RECORDING_FILE
    from aatest.bundle.signing import file_sha256  # lazily: the render child needs none

    return file_sha256(path) if path.is_file() else "no recording.mcap in the run directory"


def traceability(results: RunResults, run_dir: Path) -> Traceability:
    """Collect the traceability block of a report."""
    meta = results.metadata
    text = str(meta.recorded("procedure_text") or "")
    computed = hashlib.sha256(text.encode()).hexdigest() if text else "—"
    seed = meta.recorded("seed")
    return Traceability(
        procedure=results.procedure or meta.procedure or "—",
        procedure_sha256=meta.procedure_sha256 or computed,
        procedure_text=text,
        rig=_rig(results),
        plugins=_plugins(meta),
        sensors=list(meta.sensors),
        table_serial=_table_serial(results),
        operator=meta.operator or "—",
        started_utc=meta.started_utc or "—",
        environment_c=_environment_c(meta),
        chamber_setpoints_c=[s.temperature_c for s in results.steps_of_kind("chamber")
                             if s.temperature_c is not None],
        software_version=str(meta.recorded("aatest_version") or aatest.__version__),
        recording_sha256=recording_hash(run_dir),
        seed=seed if seed is not None else "—",
        extra={"lab_duration_s": results.lab_duration_s,
               "wall_duration_s": results.wall_duration_s},
    )
