"""Option types a rig plugin's ``Config`` uses when a value means more than its text.

:data:`RigFilePath` is a file named in a rig file: a relative path is found beside that rig
file, not in whatever directory the operator runs ``aatest`` from. Why: a lab keeps a rig
description with what it names (``rigs/bench-3.yaml`` beside ``rigs/bench-3-twin.yaml``, the
model ``diagnose --model-out`` wrote), and ``--rig rigs/bench-3.yaml`` naming
``model: bench-3-twin.yaml`` read ``./bench-3-twin.yaml`` before — another file, or none.
The engine validates a plugin's options with the rig file's directory in pydantic's
validation context (:data:`RIG_DIR`, :func:`aatest.engine.registry.configure`); options
given without a rig file (a plugin built in code or a test) stay as written. ``~`` is the
user's home either way.

Example
-------
>>> from pydantic import BaseModel
>>> class Config(BaseModel):
...     model: RigFilePath | None = None
>>> Config.model_validate({"model": "twin.yaml"}, context={RIG_DIR: "/lab/rigs"}).model
PosixPath('/lab/rigs/twin.yaml')
>>> Config.model_validate({"model": "/srv/twin.yaml"}, context={RIG_DIR: "/lab/rigs"}).model
PosixPath('/srv/twin.yaml')
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import AfterValidator, ValidationInfo

#: the key of pydantic's validation context that holds the rig file's directory
RIG_DIR = "rig_dir"


def _beside_rig_file(value: Path, info: ValidationInfo) -> Path:
    path = value.expanduser()
    rig_dir = (info.context or {}).get(RIG_DIR)
    return path if rig_dir is None or path.is_absolute() else Path(rig_dir) / path


#: a file a rig plugin reads; relative to the rig file's directory (see the module's docstring)
RigFilePath = Annotated[Path, AfterValidator(_beside_rig_file)]
