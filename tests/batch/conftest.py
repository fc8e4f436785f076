"""Batch fixtures: seeded twin archives with known truth (built once per module)."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _no_user_lab(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AATEST_LAB", raising=False)
    monkeypatch.delenv("AATEST_SIGNING_KEY", raising=False)
