"""Fuzzing the station's HTTP routes and websocket messages.

Random Host and Origin headers, tokens, query parameters, upload names and bodies, and
websocket messages (JSON of any shape, text, bytes) must each get a deliberate answer — 2xx,
3xx, 4xx or a websocket close — never a server error or an exception in the application.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from fuzzing import budget
from hypothesis import given
from hypothesis import strategies as st
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from aatest.station import StationOptions, build

STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"
PATHS = ["/", "/api/procedures", "/api/runs", "/api/validate", "/api/upload", "/runs/x/report.html",
         "/runs/" + ".." + "/report.html", "/static/station.js", "/ws", "/nowhere"]

header_text = st.text(st.characters(min_codepoint=32, max_codepoint=255), max_size=40)
hosts = st.one_of(st.sampled_from(["127.0.0.1:8671", "localhost:8671", "[::1]:8671",
                                   "rebind.evil.example:8671", "127.0.0.1", "", "[::1"]),
                  header_text)
origins = st.one_of(st.none(), st.sampled_from([STATION_URL, "null", "http://evil.example"]),
                    header_text)
json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=10), inner,
                                                                 max_size=4),
    max_leaves=12)
commands = st.fixed_dictionaries(
    {"type": st.sampled_from(["start", "resume", "answer", "abort", "other"])},
    optional={"procedure": json_values, "run": json_values, "step": json_values,
              "operator": json_values})
messages = st.one_of(commands.map(json.dumps), json_values.map(json.dumps),
                     st.text(max_size=60), st.binary(max_size=60))


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    runs = tmp_path_factory.mktemp("station") / "runs"
    with TestClient(build(StationOptions(runs_dir=runs)), base_url=STATION_URL) as station:
        yield station


def request(client: TestClient, method: str, path: str, host: str, origin: str | None,
            params: dict[str, str], body: bytes) -> None:
    headers = {"host": host.encode("latin-1")} | (
        {"origin": origin.encode("latin-1")} if origin is not None else {})
    response = client.request(method, path, params=params, headers=headers,
                              content=body if method == "POST" else None)
    assert 200 <= response.status_code < 500, (response.status_code, response.text[:200])


def websocket(client: TestClient, sent: list[str | bytes]) -> None:
    try:
        with client.websocket_connect(STATION_WS) as ws:
            assert ws.receive_json()["type"] == "snapshot"
            for message in sent:
                if isinstance(message, bytes):
                    ws.send_bytes(message)
                else:
                    ws.send_text(message)
            ws.close()
    except WebSocketDisconnect as closed:
        assert closed.code in (1000, 1008), closed.code


http_case = {
    "method": st.sampled_from(["GET", "POST", "HEAD", "PUT", "DELETE"]),
    "path": st.sampled_from(PATHS), "host": hosts, "origin": origins,
    "params": st.dictionaries(st.sampled_from(["id", "name", "token"]), header_text, max_size=2),
    "body": st.binary(max_size=200),
}


@budget(150)
@given(**http_case)
def test_fuzz_http(client: TestClient, **case: Any) -> None:
    request(client, **case)


@pytest.mark.slow
@budget(150 * 20)
@given(**http_case)
def test_fuzz_http_long(client: TestClient, **case: Any) -> None:
    request(client, **case)


@budget(60)
@given(sent=st.lists(messages, min_size=1, max_size=4))
def test_fuzz_websocket(client: TestClient, sent: list[str | bytes]) -> None:
    websocket(client, sent)


@pytest.mark.slow
@budget(60 * 20)
@given(sent=st.lists(messages, min_size=1, max_size=6))
def test_fuzz_websocket_long(client: TestClient, sent: list[str | bytes]) -> None:
    websocket(client, sent)


def test_no_run_was_started_by_the_fuzzing(client: TestClient) -> None:
    """The fuzzed commands name no listed procedure (random text), so nothing ran."""
    assert client.get("/api/runs").json()["runs"] == []
