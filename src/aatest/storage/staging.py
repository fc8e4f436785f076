"""Writing a bundle to object storage: record and render locally, then upload the result.

Report plugins and the recorder write files into a local directory (their interfaces take a
:class:`~pathlib.Path`), and an object store has no rename, so nothing is written to a URL
piece by piece. :func:`staged` gives the writer a local directory and uploads what it wrote
once it has finished, signature files last: a bundle on the store with its ``.sig`` is whole,
and a failed upload leaves the local copy in place (nothing recorded is lost).

``aatest run --out URL`` records into :func:`staging_dir` — a local directory that depends only
on the URL, so ``aatest run --resume --out URL`` after an interruption finds the steps already
recorded — and removes it only after the finished bundle was uploaded.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from aatest.storage.location import SEQUENTIAL_BLOCK_BYTES, RemotePath, translated

#: environment variable naming the local directory that stages runs bound for a URL
STAGING_ENV = "AATEST_STAGING"
#: patterns uploaded last, after the files they cover
_LAST_SUFFIXES = (".sig",)
#: files of a run in progress that never go to the store
_LOCAL_ONLY = ("run.lock",)
#: staging directory → the URL its finished bundle goes to (set by :func:`publishing`)
_DESTINATIONS: ContextVar[dict[Path, RemotePath] | None] = ContextVar(
    "aatest_publish_destinations", default=None)


def staging_dir(url: RemotePath) -> Path:
    """The local directory that stages the run bound for ``url`` (same URL, same directory)."""
    from platformdirs import user_data_dir

    root = Path(os.environ.get(STAGING_ENV) or Path(user_data_dir("aatest")) / "staging")
    digest = hashlib.sha256(str(url).encode()).hexdigest()[:16]
    return root / f"{url.name or 'run'}-{digest}"


def upload_dir(local: Path, remote: RemotePath) -> list[str]:
    """Put every file below ``local`` at the same relative name below ``remote``.

    Each object is written whole (an object store's PUT is atomic per object); signature files
    go last. Returns the relative names uploaded.
    """
    names = sorted((p.relative_to(local).as_posix() for p in local.rglob("*") if p.is_file()),
                   key=lambda n: (n.endswith(_LAST_SUFFIXES), n))
    names = [n for n in names if n not in _LOCAL_ONLY]
    for name in names:
        target = remote.joinpath(*name.split("/"))
        with translated(str(target)):
            remote.fs.put_file(str(local / name), target.path,
                               block_size=SEQUENTIAL_BLOCK_BYTES)
    return names


@contextmanager
def staged(where: Path | RemotePath) -> Iterator[Path]:
    """A local directory to write into; for a URL, uploaded there when the block succeeds.

    A local ``where`` is yielded as it is: local bundles are written exactly as before.
    """
    if isinstance(where, Path):
        where.mkdir(parents=True, exist_ok=True)
        yield where
        return
    where.mkdir()  # the bucket must exist before anything is computed for it
    local = Path(tempfile.mkdtemp(prefix="aatest-stage-"))
    try:
        yield local
        upload_dir(local, where)
    finally:
        shutil.rmtree(local, ignore_errors=True)


def published(local_file: Path, local_dir: Path, where: Path | RemotePath) -> Path | RemotePath:
    """Where ``local_file`` (written in ``local_dir`` by :func:`staged`) now lives."""
    if isinstance(where, Path):
        return local_file
    return where.joinpath(*local_file.relative_to(local_dir).parts)


@contextmanager
def publishing(local_dir: Path, remote: RemotePath | None) -> Iterator[None]:
    """Inside the block, a bundle finished in ``local_dir`` is uploaded to ``remote`` by
    :func:`publish` (``aatest run --out URL``); ``None`` publishes nothing."""
    if remote is None:
        yield
        return
    token = _DESTINATIONS.set({**(_DESTINATIONS.get() or {}), local_dir.resolve(): remote})
    try:
        yield
    finally:
        _DESTINATIONS.reset(token)


def publish(report: Path | RemotePath) -> Path | RemotePath:
    """Upload the finished bundle around ``report`` when :func:`publishing` names a URL for
    its directory; return where the report now lives (``report`` itself otherwise)."""
    if isinstance(report, RemotePath):
        return report
    remote = (_DESTINATIONS.get() or {}).get(report.parent.resolve())
    if remote is None:
        return report
    upload_dir(report.parent, remote)
    return remote / report.name
