"""Which runs are simulations: a simulation is never a calibration.

Every rig plugin declares ``simulated`` (the digital twin's plugins always; a driver of a
simulator server — ``aatest sim-server`` — from the server's identification, read when it
starts). The run records the simulated parts in its metadata (:data:`SIMULATED_PARTS_KEY`),
and a run with any simulated part is a *simulation*: its report is titled
:data:`SIMULATION_TITLE` and marked on every page, its number comes from the separate
:data:`SIMULATION_PREFIX` series, and the records store keeps it as ``kind = simulation``,
out of a unit's history, trends and due dates. Nothing (lab profile, option) turns it into a
calibration.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    from aatest.results import RunResults

#: run-metadata key: ``KIND:PLUGIN`` of every simulated part of the rig (empty: a real rig)
SIMULATED_PARTS_KEY = "simulated_parts"
#: results metadata key the engine sets on every analysed run: ``calibration | simulation``
KIND_KEY = "kind"
#: certificate-number prefix of simulations (``SIM-2026-000001``); no lab may use it
SIMULATION_PREFIX = "SIM"
SIMULATION_TITLE = "Simulation report — not a calibration certificate"
#: plugin names that were the digital twin before plugins declared ``simulated`` (recordings
#: written without :data:`SIMULATED_PARTS_KEY`)
_TWIN_PLUGINS = frozenset({"sim"})

Kind = Literal["calibration", "simulation"]


def simulated_parts(metadata: Mapping[str, Any]) -> list[str]:
    """The simulated parts named by a run's metadata.

    Recordings older than the declaration name none; for them every rig part whose plugin
    is the digital twin (``sim``) counts, so an old twin recording is no calibration either.
    """
    declared = metadata.get(SIMULATED_PARTS_KEY)
    if isinstance(declared, list):
        return [str(p) for p in declared]
    rig = metadata.get("rig") or {}
    return [f"{kind}:{spec.get('plugin')}" for kind, spec in sorted(rig.items())
            if isinstance(spec, Mapping) and spec.get("plugin") in _TWIN_PLUGINS]


def kind_of(metadata: Mapping[str, Any]) -> Kind:
    """``simulation`` when any part of the run's rig was simulated, else ``calibration``."""
    stated = metadata.get(KIND_KEY)
    if stated == "simulation" or simulated_parts(metadata):
        return "simulation"
    return "calibration"


def metadata_of(results: RunResults | Mapping[str, Any]) -> Mapping[str, Any]:
    """The run metadata as recorded: of the typed record (its recorded keys, e.g. the rig and
    the simulated parts, are free-form) or of a stored ``results.json`` document."""
    if isinstance(results, Mapping):
        metadata = results.get("metadata") or {}
        return metadata if isinstance(metadata, Mapping) else {}
    return results.metadata.model_dump(mode="json")


def is_simulation(results: RunResults | Mapping[str, Any]) -> bool:
    """Whether a run (the typed record, or a stored ``results.json`` document — the records
    migration reads those) is a simulation."""
    return kind_of(metadata_of(results)) == "simulation"
