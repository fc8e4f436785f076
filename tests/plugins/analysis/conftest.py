"""Fixtures of the analysis tests (the twin rig models)."""

from __future__ import annotations

from typing import Any

import pytest


@pytest.fixture(scope="session")
def realistic_unit() -> Any:
    """The measured-behaviour rig (docs/method.md §1.2–1.3) with the three-sensor unit."""
    from aatest.plugins.sensors.sr207 import SR207Unit
    from aatest.twin.api import realistic_rig_model

    return realistic_rig_model(SR207Unit().datasheet())
