"""Which records database to use, and how to name it without leaking a password.

Order of precedence: an explicit ``--records URL``, else ``AATEST_RECORDS``, else one SQLite
file in the user's data directory (``platformdirs``). A plain ``postgresql://`` URL is mapped to
the psycopg 3 driver aatest installs, so a lab can paste the URL its DBA gave it.
"""

from __future__ import annotations

import os
from pathlib import Path

import platformdirs
from sqlalchemy.engine import URL, make_url
from sqlalchemy.exc import ArgumentError

from aatest.records.errors import RecordsError

RECORDS_ENV = "AATEST_RECORDS"
DEFAULT_FILE = "records.sqlite"
_PLAIN_POSTGRES = ("postgresql", "postgres")


def default_records_path() -> Path:
    """The default SQLite file: ``<user data dir>/aatest/records.sqlite``."""
    return Path(platformdirs.user_data_dir("aatest", appauthor=False)) / DEFAULT_FILE


def resolve_url(explicit: str | None = None) -> URL:
    """The SQLAlchemy URL of the records store (explicit, environment, default file).

    Raises
    ------
    RecordsError
        The URL cannot be parsed or names a database kind aatest does not support.
    """
    text = explicit or os.environ.get(RECORDS_ENV) or f"sqlite:///{default_records_path()}"
    try:
        url = make_url(text)
    except ArgumentError as exc:
        raise RecordsError(f"records URL {text!r} is not a database URL: {exc}") from exc
    if url.drivername in _PLAIN_POSTGRES:
        url = url.set(drivername="postgresql+psycopg")
    if url.get_backend_name() not in ("sqlite", "postgresql"):
        raise RecordsError(
            f"records URL {redacted(url)}: only sqlite:///FILE and postgresql://... are supported"
        )
    return url


def redacted(url: URL) -> str:
    """The URL as text with any password replaced by ``***`` (for messages and logs)."""
    return url.render_as_string(hide_password=True)


def is_default_missing(url: URL) -> bool:
    """True for a SQLite file that does not exist yet (a reader then has nothing to read)."""
    return url.get_backend_name() == "sqlite" and bool(url.database) and not Path(
        str(url.database)).exists()
