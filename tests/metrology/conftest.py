"""Fixtures of the uncertainty tests: the hand-made results as the typed record."""

from __future__ import annotations

import pytest
from contract_results import typed_results

from aatest.results import RunResults


@pytest.fixture
def results() -> RunResults:
    """Fresh typed results (tests may change their copy)."""
    return typed_results()
