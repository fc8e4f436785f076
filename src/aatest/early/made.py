"""What the early-analysis child hands back, and what both sides check it against.

Shared by :mod:`aatest.early.analysis` (the run's side: starts the child, takes
its results) and :mod:`aatest.early.child` (the child's loop): the run's side
imports the child's loop to start it in a fork, so the loop must not import the run's side
(a module import cycle).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from aatest.early.handover import Handed
from aatest.recording.dataset import Dataset

#: the message asking the child to finish every step sent, then end (tests)
DRAIN = "drain"


@dataclass(frozen=True)
class StepSent:
    """A step file for the child; ``handed``: its logs come in shared memory too (the
    segment's descriptor is on the socket, sent just before this message), else None."""

    step_id: str
    path: str
    handed: Handed | None = None


@dataclass(frozen=True)
class Fitted:
    """The clock relation the run-time check fitted on a step's logged arrays (see
    :attr:`Handed.relation_inputs_exact` for when it is the child's own)."""

    step_id: str
    relation: Any


@dataclass(frozen=True)
class Idle:
    """The child has made every step it received (``received`` of them) and every item of
    later work offered, and waits for its next message: the run process then knows the
    pass will only take what it made (:attr:`aatest.early.analysis.EarlyResults.complete`)."""

    received: int


@dataclass(frozen=True)
class Warned:
    """A warning a step's analysis raised in the child, raised again where the pass takes
    that step (the pass computing the step itself would have raised it there)."""

    #: the warning's class, ``module.QualName`` (e.g. ``builtins.RuntimeWarning``)
    category: str
    message: str
    #: the source file and line that raised it (what the warning filters match and print)
    filename: str
    lineno: int


@dataclass(frozen=True)
class Made:
    """One step as the child analysed it."""

    #: :func:`~aatest.recording.step_chunks.step_digests` of the step file it decoded, or
    #: (a handed step) of the file the run process wrote the handed arrays to
    digest: str
    #: :func:`context_digest` of the dataset it registered the watches on
    context: str
    #: each plugin's ``early_step`` result, by plugin name
    results: dict[str, Any]
    #: the warnings those ``early_step`` calls raised, in order
    warned: tuple[Warned, ...] = ()


@dataclass(frozen=True)
class LaterMade:
    """Work an analysis plugin's ``early_ready`` offered once the steps it reads were all
    made (e.g. a test group's model fits), done by the child while it had no step to make;
    the pass hands ``value`` to the plugin's ``take_early_done(data, key, value)``."""

    #: the plugin's name
    plugin: str
    #: which of its work items (the key ``early_ready`` gave it)
    key: str
    #: :func:`context_digest` of the dataset the child made it in
    context: str
    value: Any


def context_digest(data: Dataset) -> str:
    """SHA-256 of what the watches of a pass depend on besides a step's own data: the planned
    steps, the sensors, the dataset's sample rate and the requested analyses."""
    doc = {"planned": [p.model_dump(mode="json") for p in data.planned],
           "sensors": [s.model_dump(mode="json") for s in data.sensors],
           "sample_rate_hz": data.sample_rate_hz,
           "analysis": list(data.metadata.get("analysis", []))}
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()
