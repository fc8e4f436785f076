"""``aatest station``: check the options (address, token, directories), then serve with uvicorn."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from aatest.engine.errors import InputError
from aatest.engine.storage import RemotePath, locate
from aatest.station.app import create_app
from aatest.station.catalogue import Procedures, history_for
from aatest.station.security import Asgi, HostRule, load_token

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
    #: wall seconds over which a recorded step's samples are replayed to the live plot
    replay_s: float = Field(2.0, ge=0.0, le=10.0)
    #: further ``Host`` names the station answers to (``--allow-host``), NAME or NAME:PORT
    allow_hosts: tuple[str, ...] = ()
    #: fsspec URL each finished run is also uploaded below (``--archive``, docs/storage.md)
    archive: str | None = None


def build(options: StationOptions) -> Asgi:
    """The guarded application for ``options``; bad options raise InputError (exit 2)."""
    token = load_token(options.host, options.token_file)
    hosts = HostRule.build(options.host, options.port, options.allow_hosts)
    if options.lab_dir is not None and not options.lab_dir.is_dir():
        raise InputError(f"--lab {options.lab_dir}: not a directory")
    options.runs_dir.mkdir(parents=True, exist_ok=True)
    history = history_for(options.records, options.runs_dir)
    uploads = options.runs_dir / STATION_DIR / "uploads"
    return create_app(Procedures(options.lab_dir, uploads), history, options.rig_file, token,
                      options.replay_s, options.records, hosts, _archive(options.archive))


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
    uvicorn.run(app, host=options.host, port=options.port, log_level="warning")
