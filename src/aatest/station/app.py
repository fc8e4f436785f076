"""The station's ASGI application: the page, a small JSON API and one websocket.

- ``GET /`` the page; ``/static/…`` its script, style and the vendored uPlot
- ``GET /api/procedures`` listed procedures (id, group, title, description), the installed
  sensor models and whether reports are signed; ``GET /api/validate?id=…`` problems or steps
- ``POST /api/upload?name=FILE.yaml`` a procedure's text as the body: validated like a file on
  disk (problems, or the planned steps and the new id ``upload/…``); kept only when valid
- ``GET /api/runs`` recent runs; ``GET /runs/{name}/{file}`` a run's report, PDF or results
- ``GET /units/{serial}`` a unit's page; ``GET /api/units/{serial}`` its history and trend
- ``WS /ws`` live events to every browser; commands (start, resume, answer, abort) are taken
  only from the controlling browser (the first connected; the next one when it leaves). A
  message that is not a command object closes that browser's socket and so hands control on.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from aatest.engine.errors import AatestError, InputError
from aatest.engine.run.session import UnitName
from aatest.fleet.station import fleet_page
from aatest.run_operator import default_operator
from aatest.station.catalogue import RUN_FILES, History, Procedures, sensor_models, validation
from aatest.station.control import RunController
from aatest.station.security import Asgi, Guard, HostRule
from aatest.station.units import check_serial, unit_history
from aatest.station.uploads import MAX_UPLOAD_BYTES, UploadError, Uploads
from aatest.storage import RemotePath

STATIC = Path(str(resources.files("aatest.station") / "static"))
HISTORY_ROWS = 20
#: the page loads only its own scripts, styles and websocket, and may not be framed
PAGE_POLICY = ("default-src 'self'; connect-src 'self'; img-src 'self' data: blob:; "
               "style-src 'self' 'unsafe-inline'; object-src 'none'; base-uri 'none'; "
               "form-action 'self'; frame-ancestors 'none'")
#: a run's report is a document: no script runs in it (sandbox), nothing is fetched
REPORT_POLICY = ("default-src 'none'; style-src 'unsafe-inline'; img-src data:; "
                 "font-src data:; sandbox; frame-ancestors 'none'")
#: the commands a browser may send over the websocket, with their string fields
COMMANDS = {"start": ("procedure",), "resume": ("run",), "answer": ("step",), "abort": ()}
#: optional string fields of a command (the unit named on the page; empty: the procedure's)
OPTIONAL = {"start": ("serial", "model")}
#: optional boolean fields of a command
FLAGS = {"start": ("pdf",)}
#: the longest string field a command may carry (ids, names: a few dozen characters)
MAX_FIELD_CHARS = 200
#: websocket close code for a message that is not a command (RFC 6455 "policy violation")
POLICY_VIOLATION = 1008


@dataclass(frozen=True)
class Signer:
    """The station's signing key: its file (read at each signing) and its fingerprint."""

    key_path: Path
    fingerprint: str


@dataclass
class Hub:
    """The connected browsers; the first in the list controls, the others watch."""

    clients: list[WebSocket] = field(default_factory=list)
    loop: asyncio.AbstractEventLoop | None = None

    def publish(self, event: dict[str, Any]) -> None:
        """Send ``event`` to every browser; callable from the run's worker thread."""
        if self.loop is not None:
            self.loop.call_soon_threadsafe(lambda: self.loop and self.loop.create_task(
                self._send_all(event)))

    async def _send_all(self, event: dict[str, Any]) -> None:
        for ws in list(self.clients):
            try:
                await ws.send_json(event)
            except (RuntimeError, WebSocketDisconnect):
                await self.leave(ws)

    async def announce_roles(self) -> None:
        """Tell each browser whether it controls or watches."""
        for i, ws in enumerate(list(self.clients)):
            try:
                await ws.send_json({"type": "role", "role": "control" if i == 0 else "watch"})
            except (RuntimeError, WebSocketDisconnect):
                await self.leave(ws)

    async def leave(self, ws: WebSocket) -> None:
        """Forget a browser; the next one takes control."""
        if ws in self.clients:
            self.clients.remove(ws)
            await self.announce_roles()


def parse_command(message: Mapping[str, Any]) -> dict[str, Any] | None:
    """The command object in one websocket message, or None when it is anything else.

    A command is a JSON object whose ``type`` is one of :data:`COMMANDS`, with that command's
    fields, its :data:`OPTIONAL` fields and an optional ``operator`` as strings (at most
    :data:`MAX_FIELD_CHARS` each) and its :data:`FLAGS` as booleans, nothing else. No command
    carries a key, a passphrase or a path: signing is the station's configuration.
    """
    text = message.get("text")
    if not isinstance(text, str) or len(text) > 64 * 1024:
        return None
    try:
        msg = json.loads(text)
    except (ValueError, RecursionError):  # deep nesting exhausts the decoder's recursion
        return None
    if not isinstance(msg, dict) or msg.get("type") not in COMMANDS:
        return None
    return msg if _fields_ok(msg, msg["type"]) else None


def _fields_ok(msg: dict[str, Any], kind: str) -> bool:
    """Only the command's fields; required strings present, strings short, flags booleans."""
    known = {"type", "operator", *COMMANDS[kind], *OPTIONAL.get(kind, ()), *FLAGS.get(kind, ())}
    if not set(msg) <= known:  # e.g. a key or passphrase: never taken from the browser
        return False
    if any(not isinstance(msg.get(name), str) for name in COMMANDS[kind]):
        return False
    for name in (*COMMANDS[kind], *OPTIONAL.get(kind, ()), "operator"):
        value = msg.get(name)
        if value is not None and (not isinstance(value, str) or len(value) > MAX_FIELD_CHARS):
            return False
    return all(isinstance(msg.get(name, False), bool) for name in FLAGS.get(kind, ()))


async def _command(controller: RunController, hub: Hub, ws: WebSocket, msg: dict[str, Any]) -> None:
    """Run one command from a browser; only the controlling one may act."""
    if not hub.clients or hub.clients[0] is not ws:
        await ws.send_json({"type": "error", "message": "this page is watching; another controls"})
        return
    who = msg.get("operator") or default_operator()
    kind = msg.get("type")
    try:
        if kind == "start":
            serial = (msg.get("serial") or "").strip()
            unit = UnitName(check_serial(serial) if serial else None,
                            (msg.get("model") or "").strip() or None)
            controller.start(msg["procedure"], who, unit, pdf=bool(msg.get("pdf")))
        elif kind == "resume":
            controller.resume(msg["run"], who)
        elif kind == "answer" and not controller.answer(msg["step"], who):
            await ws.send_json({"type": "error", "message": "no such prompt is waiting"})
        elif kind == "abort":
            controller.abort(who)
    except AatestError as exc:
        await ws.send_json({"type": "error", "message": str(exc)})


async def _body(request: Request, limit_bytes: int) -> bytes:
    """The request body, refused (413) as soon as it exceeds ``limit_bytes``."""
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > limit_bytes:
        raise UploadError(f"upload of {declared} bytes; at most {limit_bytes}", status=413)
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit_bytes:
            raise UploadError(f"upload over {limit_bytes} bytes", status=413)
        chunks.append(chunk)
    return b"".join(chunks)


def served_file(history: History, name: str, file: str) -> Path:
    """The run file to send: a listed name in a real run directory, no link on the way.

    The file's resolved path must be exactly ``RUNS/NAME/FILE``: a symbolic link (the run
    directory or the file) that leads anywhere, even inside the runs directory, is refused
    with InputError, so nothing outside the runs the station wrote is ever sent.
    """
    if file not in RUN_FILES:
        raise InputError(f"{file!r} is not a run file the station serves")
    run_dir = history.run_dir(name)
    target = run_dir / file
    try:
        resolved = target.resolve(strict=True)
        expected = history.runs_dir.resolve(strict=True) / name / file
    except (OSError, RuntimeError) as exc:
        raise InputError(f"run {name!r}: no file {file!r}") from exc
    if resolved != expected or not resolved.is_file():
        raise InputError(f"run {name!r}: {file!r} is not a plain file of the run")
    return resolved


def unit_routes(records_url: str | None, history: History) -> list[Route]:
    """``/units/{serial}`` (the page) and ``/api/units/{serial}`` (its history and trend)."""

    async def unit_page(request: Request) -> Response:
        return FileResponse(STATIC / "unit.html",
                            headers={"content-security-policy": PAGE_POLICY})

    async def unit_json(request: Request) -> Response:
        try:
            doc = await asyncio.to_thread(unit_history, records_url, history.runs_dir,
                                          request.path_params["serial"])
        except AatestError as exc:
            return JSONResponse({"ok": False, "problems": [str(exc)]}, status_code=404)
        return JSONResponse(doc)

    return [Route("/units/{serial}", unit_page), Route("/api/units/{serial}", unit_json)]


def create_app(procedures: Procedures, history: History, rig_file: Path | None,
               token: str | None, records_url: str | None = None,
               hosts: HostRule | None = None, *, signer: Signer | None = None,
               archive: RemotePath | None = None) -> Asgi:
    """Build the station application (wrapped in the host/origin/token guard).

    ``signer`` is the station's signing key (its fingerprint shown on the page); without one
    the station's reports are unsigned and the page says so.
    """
    hub = Hub()
    controller = RunController(procedures, history, rig_file, hub.publish,
                               records_url, signer.key_path if signer else None,
                               archive=archive)

    async def page(request: Request) -> Response:
        return FileResponse(STATIC / "index.html",
                            headers={"content-security-policy": PAGE_POLICY})

    async def list_procedures(request: Request) -> Response:
        entries = await asyncio.to_thread(procedures.entries)
        signing = ({"signed": True, "fingerprint": signer.fingerprint} if signer
                   else {"signed": False})
        return JSONResponse({"procedures": entries, "models": sensor_models(),
                             "signing": signing})

    async def validate(request: Request) -> Response:
        try:
            path = procedures.path(request.query_params.get("id", ""))
        except AatestError as exc:
            return JSONResponse({"ok": False, "problems": [str(exc)]}, status_code=404)
        return JSONResponse(await asyncio.to_thread(validation, path, rig_file))

    async def upload(request: Request) -> Response:
        name = request.query_params.get("name", "")
        if procedures.upload_dir is None:
            return JSONResponse({"ok": False, "problems": ["uploads are off"]}, status_code=404)
        try:
            body = await _body(request, MAX_UPLOAD_BYTES)
            result = await asyncio.to_thread(
                Uploads(procedures.upload_dir).accept, name, body, rig_file)
        except UploadError as exc:
            return JSONResponse({"ok": False, "problems": [str(exc)]}, status_code=exc.status)
        return JSONResponse(result)

    async def runs(request: Request) -> Response:
        rows = await asyncio.to_thread(history.recent, HISTORY_ROWS)
        return JSONResponse({"runs": rows, **history.source()})

    async def run_file(request: Request) -> Response:
        name, file = request.path_params["name"], request.path_params["file"]
        try:
            target = served_file(history, name, file)
        except AatestError:
            return Response("no such file in this run", status_code=404)
        policy = REPORT_POLICY if RUN_FILES[file] == "text/html" else "frame-ancestors 'none'"
        return FileResponse(target, media_type=RUN_FILES[file],
                            headers={"content-security-policy": policy})

    async def fleet(request: Request) -> Response:
        return await fleet_page(request, records_url, REPORT_POLICY)

    async def websocket(ws: WebSocket) -> None:
        hub.loop = asyncio.get_running_loop()
        await ws.accept()
        hub.clients.append(ws)
        await ws.send_json(controller.snapshot.as_json())
        await hub.announce_roles()
        try:
            while True:
                message = await ws.receive()
                if message["type"] == "websocket.disconnect":
                    break
                command = parse_command(message)
                if command is None:
                    await ws.close(POLICY_VIOLATION, "not a station command")
                    break
                await _command(controller, hub, ws, command)
        except WebSocketDisconnect:
            pass
        finally:
            await hub.leave(ws)

    app = Starlette(routes=[
        Route("/", page), Route("/api/procedures", list_procedures),
        *unit_routes(records_url, history),
        Route("/api/validate", validate), Route("/api/runs", runs),
        Route("/api/upload", upload, methods=["POST"]),
        Route("/runs/{name}/{file}", run_file), WebSocketRoute("/ws", websocket),
        Route("/fleet", fleet),
        Mount("/static", StaticFiles(directory=STATIC)),
    ])
    return Guard(app, token, hosts)
