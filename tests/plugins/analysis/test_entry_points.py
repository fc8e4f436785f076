"""Each built-in analysis is found where its name says: entry point ``NAME`` → module ``NAME``.

Why: a reader (or a traceback) that meets the ``drift`` analysis looks for ``drift.py``; an entry
point into another module (``drift`` once pointed into ``noise.py``) hides where the code is.
"""

from __future__ import annotations

import importlib
import tomllib
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[3] / "pyproject.toml"


def test_every_analysis_entry_point_names_its_own_module() -> None:
    """The module of each ``aatest.analyses`` entry point is the analysis name, and it loads."""
    project = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["project"]
    analyses = project["entry-points"]["aatest.analyses"]
    assert "drift" in analyses and "sync" in analyses  # the table is the one we mean
    for name, target in analyses.items():
        module, _, attribute = target.partition(":")
        assert module == f"aatest.plugins.analysis.{name}", (name, target)
        assert callable(getattr(importlib.import_module(module), attribute)), (name, target)
