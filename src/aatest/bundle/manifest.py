"""What a signature covers: every file of the bundle directory, or a stated reason why not.

A certificate is only worth what it proves, and a re-analysis of the bundle reads
``run_state.json`` and the per-step recordings under ``steps/`` as well as ``results.json`` and
``recording.mcap``. So the signed manifest lists the SHA-256 of every regular file below the
report's directory, by its relative POSIX name (``steps/0003-sine.mcap``), and states which
files are left out and why (:data:`EXCLUSIONS`, signed with the manifest). A file found at
verification that is neither signed nor matched by a signed exclusion is reported.

Names read from a signature are checked before use: an absolute name, a ``..`` part or a
backslash is refused, so a doctored signature cannot make ``verify`` read outside the bundle.
"""

from __future__ import annotations

import fnmatch
import hashlib
import os
import stat
import threading
from concurrent.futures import Future
from pathlib import Path, PurePosixPath

from aatest.engine.errors import InputError
from aatest.storage import RemotePath, Where
from aatest.storage.location import SEQUENTIAL_BLOCK_BYTES

_CHUNK_BYTES = 1 << 20
#: digests :func:`hash_soon` makes, by file identity (device, inode, size, mtime)
_SOON: dict[tuple[int, int, int, int], Future[str]] = {}
_SOON_LOCK = threading.Lock()
#: how many of them are kept
_SOON_KEPT = 16

#: pattern (of the relative name) → why such files are not signed; stated in the manifest
EXCLUSIONS: dict[str, str] = {
    "*.sig": "detached signatures: a signature cannot cover itself",
    "run.lock": "lock of a run in progress, removed when the run ends",
    "diagnosis.*": "written by `aatest diagnose` after the certificate; registered on its own",
    "*.tmp": "a file being written; replaced atomically once complete",
}


class UnsafeNameError(InputError):
    """A file name in a signature that points outside the bundle directory."""


def file_sha256(path: Where) -> str:
    """SHA-256 hex digest of a file, read in 1 MiB chunks (recordings can be large); an
    object on object storage is streamed in ranged reads, never downloaded whole. A local
    file :func:`hash_soon` began hashing is not read again while it is the file that was
    hashed (the same device, inode, size and modification time): its digest is waited for."""
    if isinstance(path, Path) and (key := _identity(path)) is not None:
        with _SOON_LOCK:
            soon = _SOON.get(key)
        if soon is not None:
            return soon.result()
    return _read_sha256(path)


def hash_soon(path: Path) -> threading.Thread | None:
    """Begin hashing the local file ``path`` on a thread, for :func:`file_sha256`; the caller
    joins the thread, or lets it end by itself. None: no such regular file, or this file (the
    same identity) is hashed or being hashed already, whose digest then serves.

    Why: a run's recording (168 MB for the stepped sine) is hashed for the certificate's
    traceability and the signed manifest, ≈ 0.13 s of CPU; hashed as soon as it is merged,
    on a core the analysis leaves idle, the report does not wait for it (``hashlib``
    releases the GIL while it hashes). The digest is kept for that file's identity only: a
    file changed since is hashed anew.
    """
    key = _identity(path)
    if key is None:
        return None
    soon: Future[str] = Future()
    with _SOON_LOCK:
        if key in _SOON:
            return None
        _SOON[key] = soon
        while len(_SOON) > _SOON_KEPT:  # a long-lived station: the oldest go
            del _SOON[next(iter(_SOON))]

    def run() -> None:
        failed = False
        try:
            soon.set_result(_read_sha256(path))
        except BaseException as exc:  # noqa: BLE001 - met by who waits on it
            soon.set_exception(exc)
            failed = True
        # not kept when it failed (a later call reads the file again and meets the error
        # itself) or the file changed while it was hashed (not this digest's file)
        if failed or _identity(path) != key:
            with _SOON_LOCK:
                _SOON.pop(key, None)

    thread = threading.Thread(target=run, name="aatest-hash-soon", daemon=True)
    thread.start()
    return thread


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    try:
        found = path.stat()
    except OSError:
        return None
    if not stat.S_ISREG(found.st_mode):
        return None
    return found.st_dev, found.st_ino, found.st_size, found.st_mtime_ns


def _read_sha256(path: Where) -> str:
    digest = hashlib.sha256()
    with (path.open("rb", SEQUENTIAL_BLOCK_BYTES) if isinstance(path, RemotePath)
          else path.open("rb")) as handle:
        for chunk in iter(lambda: handle.read(_CHUNK_BYTES), b""):
            digest.update(chunk)
    return digest.hexdigest()


def member_path(folder: Where, name: str) -> Where:
    """``folder / name`` for a relative POSIX ``name`` that stays inside ``folder``.

    Raises
    ------
    UnsafeNameError
        ``name`` is empty, absolute, contains ``..`` or a backslash.
    """
    pure = PurePosixPath(name)
    if (not name or "\\" in name or "\0" in name or pure.is_absolute()
            or any(part in ("..", ".", "") for part in name.split("/"))):
        raise UnsafeNameError(f"file name {name!r} points outside the bundle")
    return folder.joinpath(*pure.parts)


def excluded_by(name: str, exclusions: dict[str, str]) -> str | None:
    """The pattern of ``exclusions`` that ``name`` matches (on its last part), else ``None``."""
    last = name.rsplit("/", 1)[-1]
    for pattern in exclusions:
        if fnmatch.fnmatchcase(last, pattern) or fnmatch.fnmatchcase(name, pattern):
            return pattern
    return None


def bundle_members(folder: Where) -> tuple[list[str], list[str]]:
    """Relative names of the regular files below ``folder`` and of its symbolic links.

    Symbolic links are not followed (their target is outside the bundle's control); they are
    returned separately so the caller can refuse or report them. Object storage has none.
    """
    if isinstance(folder, RemotePath):
        return folder.members(), []
    files: list[str] = []
    links: list[str] = []
    for root, dirs, names in os.walk(folder, followlinks=False):
        base = Path(root).relative_to(folder)
        for name in sorted(names) + [d for d in sorted(dirs) if (Path(root) / d).is_symlink()]:
            relative = (base / name).as_posix()
            path = Path(root) / name
            if path.is_symlink():
                links.append(relative)
            elif path.is_file():
                files.append(relative)
    return sorted(files), sorted(links)


def manifest_hashes(folder: Where, exclusions: dict[str, str] | None = None) -> dict[str, str]:
    """SHA-256 of every file below ``folder`` that no ``exclusions`` pattern matches."""
    rules = EXCLUSIONS if exclusions is None else exclusions
    files, _links = bundle_members(folder)
    return {name: file_sha256(folder / name) for name in files
            if excluded_by(name, rules) is None}


def compare_members(folder: Where, signed: dict[str, str], exclusions: dict[str, str]) -> list[str]:
    """Every difference between the files below ``folder`` and the ``signed`` hashes."""
    reasons: list[str] = []
    for name, digest in sorted(signed.items()):
        try:
            member = member_path(folder, name)
        except UnsafeNameError as exc:
            reasons.append(f"signature is malformed: {exc}")
            continue
        if member.is_symlink() or not member.is_file():
            reasons.append(f"{name}: missing (it was signed)")
        elif file_sha256(member) != digest:
            reasons.append(f"{name}: modified (sha256 differs from the signed value)")
    files, links = bundle_members(folder)
    for name in files:
        if name not in signed and excluded_by(name, exclusions) is None:
            reasons.append(f"{name}: present but not covered by the signature")
    reasons += [f"{name}: symbolic link in the bundle (not signed, not followed)"
                for name in links if excluded_by(name, exclusions) is None]
    return reasons
