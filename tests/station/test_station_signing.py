"""The station's key and what a browser may send: signing is configuration, never a message.

The key is loaded when the station is built (its passphrase from the environment), so a wrong
passphrase stops the station at start (exit 2); the page sees only the fingerprint. A command
carrying any field beyond its own (a key, a passphrase, a path) is not a command: the socket is
closed and nothing runs. A serial with control characters is refused before anything starts.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from aatest.bundle import signing
from aatest.engine.errors import AatestError
from aatest.station import StationOptions, build
from aatest.station.app import POLICY_VIOLATION, parse_command

STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"
PASSPHRASE = "station test passphrase"


@pytest.fixture
def key(tmp_path: Path) -> tuple[Path, str]:
    path = tmp_path / "keys" / "station.key"
    path.parent.mkdir()
    return path, signing.generate_keypair(path, PASSPHRASE)


def test_the_page_sees_the_fingerprint_only(
    key: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("AATEST_SIGNING_PASSPHRASE", PASSPHRASE)
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs", sign_key=key[0])),
                        base_url=STATION_URL)
    doc = client.get("/api/procedures").json()
    assert doc["signing"] == {"signed": True, "fingerprint": key[1]}
    assert PASSPHRASE not in json.dumps(doc) and str(key[0]) not in json.dumps(doc)
    titles = {p["title"]: p for p in doc["procedures"]}
    assert titles["scale-factor"]["group"] == "Shipped with aatest"
    assert titles["scale-factor"]["description"].startswith("Polynomial scale-factor fit")
    assert "sr207" in doc["models"]


def test_a_wrong_passphrase_stops_the_station_at_start(
    key: tuple[Path, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("AATEST_SIGNING_PASSPHRASE", "not the passphrase")
    with pytest.raises(AatestError) as raised:
        build(StationOptions(runs_dir=tmp_path / "runs", sign_key=key[0]))
    assert raised.value.exit_code == 2


def test_without_a_key_the_page_says_unsigned(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AATEST_SIGNING_KEY", raising=False)
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    assert client.get("/api/procedures").json()["signing"] == {"signed": False}


@pytest.mark.parametrize("extra", [{"passphrase": PASSPHRASE}, {"sign_key": "/tmp/k"},
                                   {"path": "/etc/passwd"}])
def test_a_command_with_a_foreign_field_is_not_a_command(extra: dict[str, str]) -> None:
    start = {"type": "start", "procedure": "shipped/scale-factor.yaml", "serial": "A1"}
    assert parse_command({"text": json.dumps(start)}) == start
    assert parse_command({"text": json.dumps({**start, **extra})}) is None
    assert parse_command({"text": json.dumps({**start, "pdf": "yes"})}) is None  # a flag


def test_a_foreign_field_closes_the_socket_and_starts_nothing(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    with client.websocket_connect(STATION_WS) as ws:
        assert [ws.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        ws.send_json({"type": "start", "procedure": "shipped/scale-factor.yaml",
                      "passphrase": PASSPHRASE})
        with pytest.raises(WebSocketDisconnect) as closed:
            ws.receive_json()
        assert closed.value.code == POLICY_VIOLATION
    assert not any((tmp_path / "runs").iterdir())


def test_a_serial_with_control_characters_is_refused(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    with client.websocket_connect(STATION_WS) as ws:
        assert [ws.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        ws.send_json({"type": "start", "procedure": "shipped/scale-factor.yaml",
                      "serial": "A1\nB2"})
        reply = ws.receive_json()
        assert reply["type"] == "error" and "serial" in reply["message"]
    assert not any((tmp_path / "runs").iterdir())
