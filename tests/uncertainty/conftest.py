"""Fixtures of the uncertainty tests: contract-shaped results."""

from __future__ import annotations

import copy
from typing import Any

import pytest
from contract_results import make_results


@pytest.fixture
def results() -> dict[str, Any]:
    """Fresh contract-shaped results (tests may mutate their copy)."""
    return copy.deepcopy(make_results())
