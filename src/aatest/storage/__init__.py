"""Run directories and recordings on object storage (any fsspec URL) beside local paths.

- ``location``  :func:`locate` a path or URL; :class:`RemotePath`, the :class:`~pathlib.Path`
  subset the bundle code uses, over fsspec (streamed, ranged reads);
- ``staging``   bundles bound for a URL are written locally, then uploaded, signature last.

docs/storage.md says what is supported and what was tested against which server.
"""

from __future__ import annotations

from pathlib import Path

from aatest.storage.location import (
    FETCHED,
    RemotePath,
    StorageError,
    is_url,
    locate,
    require,
)
from aatest.storage.staging import (
    publish,
    published,
    publishing,
    staged,
    staging_dir,
    upload_dir,
)

#: a local path or a location on object storage
Where = Path | RemotePath

__all__ = [
    "FETCHED",
    "RemotePath",
    "StorageError",
    "Where",
    "is_url",
    "locate",
    "publish",
    "published",
    "publishing",
    "require",
    "staged",
    "staging_dir",
    "upload_dir",
]
