"""Observers of a bundle being written: how the records store hears of results and reports.

The engine must not import the records package (it imports the engine), so the CLI installs an
observer around a command with :func:`observing` and the session calls :func:`before_signing`
and :func:`after_signing` at the two points that matter. Without an observer both do nothing.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any, Protocol

from aatest.storage import RemotePath


class BundleObserver(Protocol):
    """Told about a bundle before its results are written and once it is signed."""

    def before_signing(self, results: Any) -> None:
        """Complete ``results`` (e.g. a certificate number) before they are written and signed.

        ``results`` is the typed record (:class:`aatest.results.RunResults`) the session
        writes.
        """

    def after_signing(self, results: Any, report: Path | RemotePath) -> None:
        """The bundle around ``report`` is final (written and, with a key, signed)."""


_OBSERVER: ContextVar[BundleObserver | None] = ContextVar("aatest_bundle_observer", default=None)


@contextmanager
def observing(observer: BundleObserver) -> Iterator[BundleObserver]:
    """Install ``observer`` for the bundles written inside the ``with`` block."""
    token = _OBSERVER.set(observer)
    try:
        yield observer
    finally:
        _OBSERVER.reset(token)


def before_signing(results: Any) -> None:
    """Let the observer, if any, complete ``results`` before they are written."""
    observer = _OBSERVER.get()
    if observer is not None:
        observer.before_signing(results)


def after_signing(results: Any, report: Path | RemotePath) -> None:
    """Tell the observer, if any, that the bundle around ``report`` is final."""
    observer = _OBSERVER.get()
    if observer is not None:
        observer.after_signing(results, report)
