"""The method of a batch: what re-analysing a recording means, and its hash.

Two re-analyses are the same result only when they ran the same analysis on the same
recording: the same mode (``analyze`` or ``diagnose``), the same code and the same reference
correction. :func:`method_of` states that; :func:`method_hash` is its SHA-256, the key (with
the recording's subject) under which a result is stored, so a re-run skips exactly the
recordings already done with this method — and a changed analysis, a new aatest release or a
correction re-analyses everything.

The code is identified by the aatest version, the distribution and version of every
installed analysis plugin, and a SHA-256 over the source of the packages that compute a
result (analyses, uncertainty, verdicts, diagnose): a development tree changes its code without
changing its version number.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import aatest
from aatest.batch.correction import ReferenceCorrection

Mode = Literal["analyze", "diagnose"]

#: packages (relative to the aatest package) whose source decides a re-analysis' result
_RESULT_CODE = ("engine/analysis", "metrology", "recording",
                "plugins/analysis", "diagnose", "results", "clocksync", "batch/correction.py",
                "batch/task.py")


@lru_cache(maxsize=1)
def code_sha256() -> str:
    """SHA-256 over the source files that compute a result (sorted by relative path)."""
    root = Path(aatest.__file__).parent
    digest = hashlib.sha256()
    for part in _RESULT_CODE:
        path = root / part
        files = sorted(path.rglob("*.py")) if path.is_dir() else [path] if path.is_file() else []
        for file in files:
            digest.update(file.relative_to(root).as_posix().encode() + b"\0")
            digest.update(file.read_bytes())
    return digest.hexdigest()


def _analysis_plugins() -> dict[str, str]:
    """``name → distribution version`` of every installed analysis plugin."""
    from aatest.engine import registry

    found = {}
    for entry in registry.entry_points("analysis"):
        info = registry.load("analysis", entry.name)
        found[info.name] = f"{info.distribution} {info.version}"
    return dict(sorted(found.items()))


def method_of(mode: Mode, correction: ReferenceCorrection | None) -> dict[str, Any]:
    """The method as stored beside each result (plain JSON)."""
    return {
        "mode": mode,
        "aatest_version": aatest.__version__,
        "code_sha256": code_sha256(),
        "analysis_plugins": _analysis_plugins(),
        "correction": None if correction is None else correction.model_dump(mode="json"),
    }


def method_hash(method: dict[str, Any]) -> str:
    """SHA-256 hex of the method's canonical JSON (sorted keys)."""
    body = json.dumps(method, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(body.encode("utf-8")).hexdigest()
