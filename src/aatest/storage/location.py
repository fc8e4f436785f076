"""A run directory or recording named by a local path or by an fsspec URL.

:func:`locate` turns what a user typed (``runs/r1``, ``file:///data/r1``, ``s3://lab/runs/r1``)
into a :class:`pathlib.Path` for anything local — so local runs take exactly the code path they
always took — or a :class:`RemotePath` for an object store. :class:`RemotePath` offers the part
of the :class:`pathlib.Path` interface that the bundle code uses (join, name, parent, open,
exists, read/write), so signing, verification and the recording reader work on either without
knowing which. Reads go through fsspec file objects: seeks and ranged reads of a block size
chosen per use (:data:`RANDOM_BLOCK_BYTES` for MCAP chunk reads, :data:`SEQUENTIAL_BLOCK_BYTES`
for hashing), never a download of the whole object to disk.

Filesystem options come from fsspec's own configuration and the usual environment (AWS
credentials for S3), plus two variables of aatest: ``AATEST_S3_ENDPOINT`` (else
``AWS_ENDPOINT_URL``), the endpoint of an S3-compatible server, and
``AATEST_STORAGE_OPTIONS``, a JSON object of further options for the filesystem.
"""

from __future__ import annotations

import json
import os
import posixpath
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, cast

from aatest.engine.errors import InputError

#: environment variable naming the endpoint of an S3-compatible server (e.g. MinIO)
S3_ENDPOINT_ENV = "AATEST_S3_ENDPOINT"
#: environment variable holding a JSON object of further fsspec filesystem options
OPTIONS_ENV = "AATEST_STORAGE_OPTIONS"
#: block (bytes) of ranged reads for random access: one MCAP chunk or index at a time
RANDOM_BLOCK_BYTES = 256 << 10
#: block (bytes) of ranged reads when a whole object is read in order (hashing, copying)
SEQUENTIAL_BLOCK_BYTES = 8 << 20
_LOCAL_PROTOCOLS = ("file", "local")


class StorageError(InputError):
    """A URL that names no reachable object: bad scheme, missing bucket or object, refused
    credentials (exit 2, naming the URL)."""


def is_url(target: str | Path) -> bool:
    """True for ``scheme://…`` text naming a non-local fsspec filesystem."""
    text = str(target) if isinstance(target, str) else ""
    if "://" not in text:
        return False
    return text.split("://", 1)[0].lower() not in _LOCAL_PROTOCOLS


def locate(target: str | Path | RemotePath) -> Path | RemotePath:
    """A local :class:`Path` (``file://`` URLs included), or a :class:`RemotePath`.

    Raises
    ------
    StorageError
        The scheme is unknown to fsspec or its filesystem package is not installed.
    """
    if isinstance(target, RemotePath | Path):
        return target
    text = str(target)
    if "://" in text and not is_url(text):
        return Path(text.split("://", 1)[1])
    if not is_url(text):
        return Path(text)
    protocol, rest = text.split("://", 1)
    return RemotePath(protocol.lower(), rest.rstrip("/"))


def filesystem(protocol: str) -> Any:
    """The fsspec filesystem of ``protocol`` with aatest's options (see the module docs)."""
    import fsspec  # type: ignore[import-untyped]

    options: dict[str, Any] = {}
    if extra := os.environ.get(OPTIONS_ENV):
        try:
            options.update(json.loads(extra))
        except ValueError as exc:
            raise StorageError(f"{OPTIONS_ENV}: not a JSON object: {exc}") from exc
    if protocol in ("s3", "s3a"):
        endpoint = os.environ.get(S3_ENDPOINT_ENV) or os.environ.get("AWS_ENDPOINT_URL")
        if endpoint:
            options.setdefault("client_kwargs", {}).setdefault("endpoint_url", endpoint)
        options.setdefault("use_listings_cache", False)  # another writer may add objects
    try:
        return fsspec.filesystem(protocol, **options)
    except ImportError as exc:
        raise StorageError(f"the filesystem package of {protocol}:// is not installed "
                           f"({exc}); install aatest[s3] for s3://") from exc
    except ValueError as exc:
        raise StorageError(f"unknown storage scheme {protocol!r} ({exc})") from exc


@contextmanager
def translated(url: str) -> Iterator[None]:
    """Backend failures become a :class:`StorageError` naming ``url``; a missing object stays
    a :class:`FileNotFoundError` (callers test for it), its message naming the URL."""
    try:
        yield
    except FileNotFoundError as exc:
        raise FileNotFoundError(f"{url}: no such object ({exc})") from exc
    except StorageError:
        raise
    except (OSError, ValueError, RuntimeError) as exc:
        raise StorageError(f"{url}: {type(exc).__name__}: {exc}") from exc
    except Exception as exc:
        if type(exc).__module__.split(".")[0] in _BACKEND_MODULES:
            raise StorageError(f"{url}: {type(exc).__name__}: {exc}") from exc
        raise


#: packages whose own exceptions (not OSError) say a storage backend failed: the S3 client's,
#: and aiohttp's (a server that closes the connection mid-response raises its
#: ``ServerDisconnectedError``, which is no OSError)
_BACKEND_MODULES = ("botocore", "aiobotocore", "s3fs", "aiohttp")


@contextmanager
def reading(url: str) -> Iterator[None]:
    """Failures while an open object is read are a :class:`StorageError` naming ``url``
    (exit 2): an object that vanishes after it was opened is no missing file a caller could
    handle, but unreadable input, as is a server that stops answering mid-read."""
    try:
        with translated(url):
            yield
    except FileNotFoundError as exc:
        raise StorageError(f"{url}: the object disappeared while it was read ({exc})") from exc


class RemotePath:
    """A file or directory prefix on an fsspec filesystem, with the :class:`Path` methods
    the bundle code calls. ``str()`` is its URL; equality is by URL."""

    def __init__(self, protocol: str, path: str, fs: Any = None) -> None:
        self.protocol, self.path = protocol, path
        self._fs = fs

    @property
    def fs(self) -> Any:
        """The filesystem, made on first use (so a bad URL fails where it is used)."""
        if self._fs is None:
            try:
                self._fs = filesystem(self.protocol)
            except StorageError as exc:
                raise StorageError(f"{self}: {exc}") from exc
        return self._fs

    def __str__(self) -> str:
        return f"{self.protocol}://{self.path}"

    def __repr__(self) -> str:
        return f"RemotePath({str(self)!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, RemotePath) and str(self) == str(other)

    def __hash__(self) -> int:
        return hash(str(self))

    def _at(self, path: str) -> RemotePath:
        return RemotePath(self.protocol, path, self._fs)

    def joinpath(self, *parts: str) -> RemotePath:
        """``self / part / …`` (POSIX names, as object keys are)."""
        return self._at(posixpath.join(self.path, *parts))

    def __truediv__(self, part: str) -> RemotePath:
        return self.joinpath(part)

    @property
    def name(self) -> str:
        """The last part of the key, as :attr:`Path.name`."""
        return posixpath.basename(self.path)

    @property
    def suffix(self) -> str:
        """The extension of :attr:`name` (``.mcap``), as :attr:`Path.suffix`."""
        return posixpath.splitext(self.name)[1]

    @property
    def parent(self) -> RemotePath:
        """The prefix one level up (the bucket is its own parent)."""
        return self._at(posixpath.dirname(self.path) or self.path)

    def with_name(self, name: str) -> RemotePath:
        """A sibling named ``name``, as :meth:`Path.with_name`."""
        return self.parent / name

    def resolve(self) -> RemotePath:
        """Itself: a URL is already absolute."""
        return self

    def exists(self) -> bool:
        """Whether an object or a prefix with objects below it exists here."""
        with translated(str(self)):
            return bool(self.fs.exists(self.path))

    def is_file(self) -> bool:
        """Whether an object exists at exactly this key."""
        with translated(str(self)):
            return bool(self.fs.isfile(self.path))

    def is_dir(self) -> bool:
        """Whether objects exist below this prefix (object stores have no empty directory)."""
        with translated(str(self)):
            return bool(self.fs.isdir(self.path))

    def is_symlink(self) -> bool:
        """Always False: object stores have no symbolic links."""
        return False

    def size_bytes(self) -> int:
        """The object's size (bytes), from its metadata: nothing is read."""
        with translated(str(self)):
            return int(self.fs.size(self.path))

    def open(self, mode: str = "rb", block_bytes: int = RANDOM_BLOCK_BYTES) -> IO[Any]:
        """A file object: ranged reads of ``block_bytes`` with seeks, or a whole-object write."""
        if "b" not in mode:
            raise ValueError(f"{self}: open in binary mode, not {mode!r}")
        with translated(str(self)):
            handle = self.fs.open(self.path, mode, block_size=block_bytes,
                                  cache_type="readahead")
        return cast("IO[Any]", _Counted(handle, str(self)) if "r" in mode else handle)

    def read_bytes(self) -> bytes:
        """The whole object (for small files: results, signatures, run state)."""
        with translated(str(self)):
            return bytes(self.fs.cat_file(self.path))

    def read_text(self, encoding: str = "utf-8") -> str:
        """The whole object decoded as text."""
        return self.read_bytes().decode(encoding)

    def write_bytes(self, data: bytes) -> int:
        """Replace the object with ``data`` in one PUT (atomic per object); its length."""
        with translated(str(self)):
            self.fs.pipe_file(self.path, data)
        return len(data)

    def write_text(self, text: str, encoding: str = "utf-8") -> int:
        """Replace the object with ``text`` encoded; the number of bytes written."""
        return self.write_bytes(text.encode(encoding))

    def unlink(self, missing_ok: bool = False) -> None:
        """Delete the object (a missing one is FileNotFoundError unless ``missing_ok``)."""
        if missing_ok and not self.exists():
            return
        with translated(str(self)):
            self.fs.rm_file(self.path)

    def mkdir(self, parents: bool = False, exist_ok: bool = False) -> None:
        """Object stores have no directories: only check that the bucket is reachable."""
        del parents, exist_ok
        bucket = self.path.split("/", 1)[0]
        with translated(str(self)):
            if not self.fs.exists(bucket):
                raise StorageError(f"{self}: bucket {bucket!r} does not exist")

    def members(self) -> list[str]:
        """Relative POSIX names of every object below this prefix, sorted."""
        with translated(str(self)):
            found = self.fs.find(self.path)
        prefix = self.path.rstrip("/") + "/"
        return sorted(f[len(prefix):] for f in found if f.startswith(prefix))


#: bytes fetched from object storage by every read handle closed so far (see :class:`_Counted`)
FETCHED = {"bytes": 0, "handles": 0}


class _Counted:
    """A read handle that adds the bytes its cache fetched to :data:`FETCHED` when closed —
    how tests and the bench show that a partial read fetches part of an object. Its reads
    and seeks fail as a :class:`StorageError` naming ``url`` (see :func:`reading`)."""

    def __init__(self, handle: Any, url: str) -> None:
        self._handle, self._url = handle, url

    def __getattr__(self, name: str) -> Any:
        return getattr(self._handle, name)

    def __enter__(self) -> _Counted:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __iter__(self) -> Iterator[bytes]:
        return iter(self._handle)

    def read(self, size: int = -1) -> bytes:
        with reading(self._url):
            return bytes(self._handle.read(size))

    def readinto(self, buffer: Any) -> int:
        with reading(self._url):
            return int(self._handle.readinto(buffer))

    def readline(self, size: int = -1) -> bytes:
        with reading(self._url):
            return bytes(self._handle.readline(size))

    def seek(self, offset: int, whence: int = 0) -> int:
        with reading(self._url):
            return int(self._handle.seek(offset, whence))

    def close(self) -> None:
        if not self._handle.closed:
            cache = getattr(self._handle, "cache", None)
            FETCHED["bytes"] += int(getattr(cache, "total_requested_bytes", 0))
            FETCHED["handles"] += 1
        self._handle.close()


def require(where: Path | RemotePath, what: str = "object or prefix") -> Path | RemotePath:
    """``where`` when it exists; else a :class:`StorageError` naming the URL (exit 2).

    A local path passes unchecked: the local commands name their own missing files.
    """
    if isinstance(where, RemotePath):
        bucket = where.path.split("/", 1)[0]
        with translated(str(where)):
            if not where.fs.exists(bucket):
                raise StorageError(f"{where}: bucket {bucket!r} does not exist")
        if not where.exists():
            raise StorageError(f"{where}: no such {what}")
    return where
