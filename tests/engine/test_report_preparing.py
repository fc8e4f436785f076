"""A report plugin's optional ``preparing()`` wraps the writing of results.json and the render
(docs/vendor-plugins.md): entered before the results are written, left after ``render``."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from aatest.engine.run import session


class _Report:
    def __init__(self, events: list[str]) -> None:
        self.events = events

    @contextlib.contextmanager
    def preparing(self) -> Iterator[None]:
        self.events.append("enter")
        yield
        self.events.append("exit")

    def render(self, results: Any, run_dir: Path, template_dir: Path | None) -> Path:
        self.events.append("render")
        return run_dir / "report.txt"


def test_preparing_wraps_the_results_file_and_the_render(monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    events: list[str] = []
    report = _Report(events)
    monkeypatch.setattr(session.registry, "load",
                        lambda kind, name: SimpleNamespace(target=lambda config: report))
    monkeypatch.setattr(session.registry, "configure", lambda info, options: None)
    monkeypatch.setattr(session, "write_results",
                        lambda results, run_dir: events.append("results.json"))
    out = session._render(object(), tmp_path, "fake", None, False)  # type: ignore[arg-type]
    assert out == tmp_path / "report.txt"
    assert events == ["enter", "results.json", "render", "exit"]
