"""Who may talk to the station: loopback by default, a token otherwise, same origin always.

- A non-loopback address needs a token of at least :data:`MIN_TOKEN_CHARS` characters, read from
  ``--token-file`` or ``AATEST_STATION_TOKEN``; without one the station refuses to start (exit 2).
- With a token, every request and websocket carries it as ``Authorization: Bearer <token>`` or
  as the session cookie set by opening ``/?token=<token>`` once; anything else gets 401.
- A request or websocket whose ``Origin`` is not the station's own (``Host``) gets 403, so a
  page on another site cannot drive the rig through the operator's browser.
"""

from __future__ import annotations

import ipaddress
import os
import secrets
from collections.abc import Awaitable, Callable, MutableMapping
from http.cookies import SimpleCookie
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from aatest.engine.errors import InputError

TOKEN_ENV = "AATEST_STATION_TOKEN"
MIN_TOKEN_CHARS = 32
COOKIE = "aatest_station"

Scope = MutableMapping[str, Any]
Message = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Message]]
Send = Callable[[Message], Awaitable[None]]
Asgi = Callable[[Scope, Receive, Send], Awaitable[None]]


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) only accepts connections from this machine."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def load_token(host: str, token_file: Path | None) -> str | None:
    """The access token for ``host``: from the file, else the environment; checked for length.

    Returns ``None`` on loopback without a configured token. Raises InputError (exit 2) when a
    non-loopback address has no token, or a token is shorter than 32 characters.
    """
    if token_file is not None:
        try:
            token: str | None = token_file.read_text(encoding="utf-8").strip()
        except OSError as exc:
            raise InputError(f"--token-file {token_file}: cannot read: {exc.strerror}") from exc
    else:
        token = os.environ.get(TOKEN_ENV, "").strip() or None
    if token is None:
        if is_loopback(host):
            return None
        raise InputError(
            f"--host {host} is not loopback: the station needs an access token of at least "
            f"{MIN_TOKEN_CHARS} characters (--token-file FILE or {TOKEN_ENV}); refusing to start"
        )
    if len(token) < MIN_TOKEN_CHARS:
        raise InputError(
            f"the station token has {len(token)} characters, at least {MIN_TOKEN_CHARS} are needed"
        )
    return token


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}


def _same_origin(headers: dict[str, str]) -> bool:
    origin = headers.get("origin")
    if origin is None:
        return True  # not sent by a browser for same-origin GETs, nor by command-line clients
    return urlsplit(origin).netloc == headers.get("host", "")


def _presented(scope: Scope, headers: dict[str, str]) -> tuple[str | None, str | None]:
    """(token from header or cookie, token from the ``?token=`` query)."""
    auth = headers.get("authorization", "")
    bearer = auth[len("Bearer "):] if auth.startswith("Bearer ") else None
    cookie = SimpleCookie(headers.get("cookie", ""))
    from_cookie = cookie[COOKIE].value if COOKIE in cookie else None
    query = parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token", [None])[0]
    return bearer or from_cookie, query


class Guard:
    """ASGI middleware enforcing the origin check and, when configured, the token."""

    def __init__(self, app: Asgi, token: str | None) -> None:
        self._app = app
        self._token = token

    def _valid(self, candidate: str | None) -> bool:
        return self._token is None or (
            candidate is not None and secrets.compare_digest(candidate, self._token)
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Refuse foreign origins (403) and missing tokens (401); set the cookie on ``?token=``."""
        if scope["type"] not in ("http", "websocket"):
            await self._app(scope, receive, send)
            return
        headers = _headers(scope)
        if not _same_origin(headers):
            await _refuse(scope, receive, send, 403, "requests from other origins are refused")
            return
        held, query = _presented(scope, headers)
        if self._valid(held):
            await self._app(scope, receive, send)
        elif scope["type"] == "http" and scope["path"] == "/" and self._valid(query):
            await _set_cookie(send, query or "")
        else:
            await _refuse(scope, receive, send, 401, "a valid station token is required")


async def _refuse(scope: Scope, receive: Receive, send: Send, status: int, text: str) -> None:
    if scope["type"] == "websocket":
        await receive()  # the websocket.connect message
        await send({"type": "websocket.close", "code": 4000 + status, "reason": text})
        return
    body = text.encode("utf-8")
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"text/plain; charset=utf-8"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


async def _set_cookie(send: Send, token: str) -> None:
    """Store the token in an HttpOnly same-site cookie and reload ``/`` without it in the URL."""
    cookie = f"{COOKIE}={token}; HttpOnly; SameSite=Strict; Path=/"
    await send({"type": "http.response.start", "status": 303,
                "headers": [(b"location", b"/"), (b"set-cookie", cookie.encode("latin-1")),
                            (b"content-length", b"0")]})
    await send({"type": "http.response.body", "body": b""})
