"""``aatest station``: check the options (address, token, directories, key), then serve.

Signing at the station: the key is the station's configuration, exactly as for ``aatest run``
— ``--sign-key KEY`` or ``AATEST_SIGNING_KEY``, its passphrase from
``AATEST_SIGNING_PASSPHRASE`` in the station's environment. The key is loaded (and so the
passphrase checked) before the station starts listening: a wrong passphrase or a key readable
by others is exit 2 at start, not a failed signature after a two-hour run. Neither the key nor
its passphrase ever crosses the wire: no command or request accepts them, with or without a
token (a passphrase typed into a page would travel, and be kept, where a station's TLS and
access control cannot be assumed); the page only shows the key's fingerprint.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import InputError
from aatest.station.app import Signer, create_app
from aatest.station.catalogue import Procedures, history_for
from aatest.station.security import Asgi, HostRule, load_token
from aatest.storage import RemotePath, locate

#: the station's own directory inside the runs directory (uploaded procedures live there)
STATION_DIR = ".station"


class StationOptions(BaseModel):
    """What ``aatest station`` was given on its command line."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    host: str = "127.0.0.1"
    port: int = Field(8671, ge=0, le=65535)
    records: str | None = None
    token_file: Path | None = None
    runs_dir: Path = Path("runs")
    lab_dir: Path | None = None
    rig_file: Path | None = None
    #: further ``Host`` names the station answers to (``--allow-host``), NAME or NAME:PORT
    allow_hosts: tuple[str, ...] = ()
    #: fsspec URL each finished run is also uploaded below (``--archive``, docs/storage.md)
    archive: str | None = None
    #: the key that signs the station's reports (else ``AATEST_SIGNING_KEY``; none: unsigned)
    sign_key: Path | None = None


def load_signer(explicit: Path | None) -> Signer | None:
    """The station's signing key checked now (passphrase from the environment), or None.

    Raises the engine's InputError (exit 2) for a key that cannot be read or decrypted, as
    ``aatest run --sign-key`` does before anything moves.
    """
    import os

    from aatest.bundle import signing
    from aatest.bundle.signing_key import PASSPHRASE_ENV, signing_key

    key_path = signing_key(explicit)
    if key_path is None:
        return None
    private = signing.load_private_key(key_path, os.environ.get(PASSPHRASE_ENV))
    return Signer(key_path, signing.key_fingerprint(private.public_key()))


def build(options: StationOptions) -> Asgi:
    """The guarded application for ``options``; bad options raise InputError (exit 2)."""
    token = load_token(options.host, options.token_file)
    hosts = HostRule.build(options.host, options.port, options.allow_hosts)
    signer = load_signer(options.sign_key)
    if options.lab_dir is not None and not options.lab_dir.is_dir():
        raise InputError(f"--lab {options.lab_dir}: not a directory")
    options.runs_dir.mkdir(parents=True, exist_ok=True)
    history = history_for(options.records, options.runs_dir)
    uploads = options.runs_dir / STATION_DIR / "uploads"
    return create_app(Procedures(options.lab_dir, uploads), history, options.rig_file, token,
                      options.records, hosts, signer=signer,
                      archive=_archive(options.archive))


def _archive(url: str | None) -> RemotePath | None:
    """The ``--archive`` location, its bucket checked now (exit 2 naming it otherwise)."""
    if url is None:
        return None
    where = locate(url)
    if not isinstance(where, RemotePath):
        raise InputError(f"--archive {url}: not an object-storage URL (s3://…); a local "
                         "directory is --runs")
    where.mkdir()
    return where


def serve(options: StationOptions) -> None:
    """Serve the station until interrupted; refuses to start on bad options (exit 2)."""
    import uvicorn

    app = build(options)
    print(f"aatest station on http://{options.host}:{options.port}/", flush=True)
    signer = load_signer(options.sign_key)
    print(f"reports signed with key {signer.fingerprint}" if signer else
          "reports unsigned (no --sign-key or AATEST_SIGNING_KEY)", flush=True)
    uvicorn.run(app, host=options.host, port=options.port, log_level="warning")
