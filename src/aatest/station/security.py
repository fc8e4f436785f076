"""Who may talk to the station: loopback by default, a token otherwise, same origin always.

- A non-loopback address needs a token of at least :data:`MIN_TOKEN_CHARS` printable ASCII
  characters, read from ``--token-file`` or ``AATEST_STATION_TOKEN``; without one the station
  refuses to start (exit 2).
- A request or websocket whose ``Host`` is not the station's own name (:class:`HostRule`:
  ``127.0.0.1``, ``localhost`` or ``[::1]`` on its port, the bound address, ``--allow-host``
  names) gets 403. A browser sends the name of the site it loaded, so a page whose DNS name was
  re-pointed at 127.0.0.1 (DNS rebinding) is refused although its requests reach the station.
- A request or websocket whose ``Origin`` is not the station's own (``Host``) gets 403, so a
  page on another site cannot drive the rig through the operator's browser; a state-changing
  request a browser marks cross-site (``Sec-Fetch-Site``) is refused even without ``Origin``.
- With a token, every request and websocket carries it as ``Authorization: Bearer <token>`` or
  as the session cookie set by opening ``/?token=<token>`` once; anything else gets 401. Tokens
  are compared as bytes in constant time.
- Every response says it may not be framed (``frame-ancestors 'none'``, ``X-Frame-Options``),
  so another site cannot overlay the page and trick the operator into clicking (clickjacking).
"""

from __future__ import annotations

import ipaddress
import os
import secrets
from collections.abc import Awaitable, Callable, Iterable, MutableMapping
from dataclasses import dataclass
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
    if not (token.isascii() and token.isprintable()) or any(c in token for c in ' ;,"\\'):
        raise InputError("the station token must be printable ASCII without spaces, ';', ',', "
                         "'\"' or '\\' (it travels in a header and a cookie)")
    return token


#: names that reach this machine only (the station's port is required with them)
LOOPBACK_NAMES = frozenset({"127.0.0.1", "localhost", "::1"})
#: the port a Host without one means
HTTP_PORT = 80
_WILDCARD = frozenset({"0.0.0.0", "::", ""})


def _split_host(value: str) -> tuple[str, int | None] | None:
    """``(lower-case name without brackets, port or None)`` of a Host value; None if malformed."""
    if not value or any(c in value for c in "/?#@ \t\\"):
        return None
    try:
        parts = urlsplit(f"//{value}")
        name, port = parts.hostname, parts.port
    except ValueError:
        return None
    return (name, port) if name else None


@dataclass(frozen=True)
class HostRule:
    """The ``Host`` names the station answers to.

    ``127.0.0.1``, ``localhost`` and ``[::1]`` on the station's ``port`` (any port when the
    port is 0, chosen by the system), the address it is bound to when that is a single address,
    and the ``--allow-host`` names: ``NAME`` on any port (behind a proxy the port differs), or
    ``NAME:PORT`` on that port only.
    """

    port: int
    named: frozenset[tuple[str, int | None]] = frozenset()

    @classmethod
    def build(cls, bind_host: str, port: int, allow: Iterable[str] = ()) -> HostRule:
        """The rule for a station bound to ``bind_host:port`` with extra ``allow`` names.

        Raises InputError (exit 2) for an ``--allow-host`` value that is not a host name.
        """
        named = set()
        for value in allow:
            split = _split_host(value.strip())
            if split is None or "*" in value:
                raise InputError(f"--allow-host {value!r}: give a host name, NAME or NAME:PORT")
            named.add(split)
        bound = _split_host(bind_host if ":" not in bind_host else f"[{bind_host}]")
        if bound is not None and bound[0] not in _WILDCARD:
            named.add((bound[0], port or None))
        return cls(port, frozenset(named))

    def allows(self, host_header: str | None) -> bool:
        """Whether a request with this ``Host`` header is addressed to the station."""
        split = _split_host(host_header or "")
        if split is None:
            return False
        name, port = split
        if (name, None) in self.named or (name, port) in self.named:
            return True
        if name in LOOPBACK_NAMES or (name, self.port or None) in self.named:
            return self.port in (0, port) or (port is None and self.port == HTTP_PORT)
        return False


#: sent with every response: never framed, no type sniffing, no referrer to other sites
FRAME_HEADERS = (
    (b"content-security-policy", b"frame-ancestors 'none'"),
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"no-referrer"),
)
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}


def _same_origin(scope: Scope, headers: dict[str, str]) -> bool:
    """Whether the request comes from the station's own page (or from no browser page at all).

    ``Origin`` must name the ``Host`` itself (``null``, sent by sandboxed frames and files, never
    does). Without ``Origin`` (same-origin GETs, command-line clients) a state-changing request
    is still refused when the browser marks it cross-site.
    """
    origin = headers.get("origin")
    if origin is None:
        unsafe = scope["type"] == "websocket" or scope.get("method", "GET") not in _SAFE_METHODS
        return not (unsafe and headers.get("sec-fetch-site") in ("cross-site", "same-site"))
    try:
        parts = urlsplit(origin)
    except ValueError:
        return False
    host = headers.get("host", "")
    return parts.scheme in ("http", "https") and bool(host) and parts.netloc.lower() == host.lower()


def _presented(scope: Scope, headers: dict[str, str]) -> tuple[bytes | None, bytes | None]:
    """(token from header or cookie, token from the ``?token=`` query), as bytes.

    Header values arrive as bytes (decoded here as latin-1, so encoding back gives the bytes
    sent); the query's percent-escapes are UTF-8.
    """
    auth = headers.get("authorization", "")
    bearer = auth[len("Bearer "):] if auth.startswith("Bearer ") else None
    try:
        cookie = SimpleCookie(headers.get("cookie", ""))
        from_cookie = cookie[COOKIE].value if COOKIE in cookie else None
    except Exception:  # noqa: BLE001 - http.cookies raises CookieError and others on junk
        from_cookie = None
    query = parse_qs(scope.get("query_string", b"").decode("latin-1")).get("token", [None])[0]
    held = bearer or from_cookie
    return (held.encode("latin-1", "replace") if held is not None else None,
            query.encode("utf-8", "replace") if query is not None else None)


class Guard:
    """ASGI middleware enforcing the Host allow-list, the origin check and, if set, the token."""

    def __init__(self, app: Asgi, token: str | None, hosts: HostRule | None = None) -> None:
        self._app = app
        self._token = token.encode("ascii") if token is not None else None
        self._hosts = hosts if hosts is not None else HostRule(8671)

    def _valid(self, candidate: bytes | None) -> bool:
        return self._token is None or (
            candidate is not None and secrets.compare_digest(candidate, self._token)
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Refuse foreign hosts and origins (403), missing tokens (401); cookie on ``?token=``."""
        if scope["type"] not in ("http", "websocket"):
            await self._app(scope, receive, send)
            return
        send = _framed(send)
        headers = _headers(scope)
        if not self._hosts.allows(headers.get("host")):
            await _refuse(scope, receive, send, 403, "this station answers only to its own name")
            return
        if not _same_origin(scope, headers):
            await _refuse(scope, receive, send, 403, "requests from other origins are refused")
            return
        held, query = _presented(scope, headers)
        if self._valid(held):
            await self._app(scope, receive, send)
        elif scope["type"] == "http" and scope["path"] == "/" and self._valid(query):
            await _set_cookie(send, (query or b"").decode("ascii"))
        else:
            await _refuse(scope, receive, send, 401, "a valid station token is required")


def _framed(send: Send) -> Send:
    """``send`` adding :data:`FRAME_HEADERS` to every HTTP response that does not set its own."""

    async def sending(message: Message) -> None:
        if message["type"] == "http.response.start":
            present = {k.lower() for k, _ in message.get("headers", [])}
            extra = [(k, v) for k, v in FRAME_HEADERS if k not in present]
            message["headers"] = [*message.get("headers", []), *extra]
        await send(message)

    return sending


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
