"""Batch fixtures: a seeded twin archive with known truth (built once per session)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from batch_units import ARCHIVE_UNITS
from postgres_db import throwaway_database

from aatest.batch.archive import record_run, register_references


@pytest.fixture(autouse=True)
def _no_user_lab(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AATEST_LAB", raising=False)
    monkeypatch.delenv("AATEST_SIGNING_KEY", raising=False)


@pytest.fixture(scope="session")
def twin_archive(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(folder of the run directories, records store file) of :data:`ARCHIVE_UNITS`.

    Tests that write re-analyses work on a copy of the store (:func:`store_copy`).
    """
    root = tmp_path_factory.mktemp("batch-archive")
    database = root / "records.sqlite"
    url = f"sqlite:///{database}"
    register_references(url, ["ENC-2"], ["LOG-9", "LOG-10"])
    for unit in ARCHIVE_UNITS:
        record_run(unit, root, url)
    return root, database


@pytest.fixture
def store_copy(twin_archive: tuple[Path, Path], tmp_path: Path) -> str:
    """A records URL of this test's own copy of the archive's store (same bundles)."""
    copy = tmp_path / "records.sqlite"
    shutil.copyfile(twin_archive[1], copy)
    return f"sqlite:///{copy}"


@pytest.fixture(params=["sqlite", "postgres"])
def empty_store_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """A new, empty store on SQLite and, when ``.ci/postgres`` runs a cluster, PostgreSQL."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path / 'empty.sqlite'}"
        return
    with throwaway_database("batch") as url:
        yield url
