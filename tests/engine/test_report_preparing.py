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


class _FromRecord(_Report):
    """A report whose render reads only the record: results.json is written meanwhile."""

    renders_from_record = True

    def __init__(self, events: list[str], run_dir: Path, fail: bool = False) -> None:
        super().__init__(events)
        self.run_dir, self.fail = run_dir, fail

    def render(self, results: Any, run_dir: Path, template_dir: Path | None) -> Path:
        if self.fail:
            raise session.InputError("the template is broken")
        return super().render(results, run_dir, template_dir)


def _use(monkeypatch: pytest.MonkeyPatch, report: Any) -> None:
    monkeypatch.setattr(session.registry, "load",
                        lambda kind, name: SimpleNamespace(target=lambda config: report))
    monkeypatch.setattr(session.registry, "configure", lambda info, options: None)


def test_results_written_meanwhile_are_the_same_bytes(monkeypatch: pytest.MonkeyPatch,
                                                      tmp_path: Path) -> None:
    from contract_results import typed_results

    from aatest.engine.analysis.results_file import RESULTS_FILE, write_results

    events: list[str] = []
    _use(monkeypatch, _FromRecord(events, tmp_path))
    (tmp_path / "before").mkdir()
    write_results(typed_results(), tmp_path / "before")
    session._render(typed_results(), tmp_path, "fake", None, False)
    assert events == ["enter", "render", "exit"]
    assert (tmp_path / RESULTS_FILE).read_bytes() == \
        (tmp_path / "before" / RESULTS_FILE).read_bytes()


def test_results_stand_when_the_render_fails(monkeypatch: pytest.MonkeyPatch,
                                             tmp_path: Path) -> None:
    from contract_results import typed_results

    from aatest.engine.analysis.results_file import RESULTS_FILE

    _use(monkeypatch, _FromRecord([], tmp_path, fail=True))
    with pytest.raises(session.InputError, match="broken"):
        session._render(typed_results(), tmp_path, "fake", None, False)
    assert (tmp_path / RESULTS_FILE).is_file()


def test_a_failed_write_meanwhile_is_raised(monkeypatch: pytest.MonkeyPatch,
                                            tmp_path: Path) -> None:
    from contract_results import typed_results

    def refuse(document: Any, run_dir: Path) -> Path:
        raise OSError("disk full")

    _use(monkeypatch, _FromRecord([], tmp_path))
    monkeypatch.setattr(session, "write_results", refuse)
    with pytest.raises(OSError, match="disk full"):
        session._render(typed_results(), tmp_path, "fake", None, False)
