"""Station security without a browser: bind address, token, cookie, origin, run files."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from aatest.engine.errors import InputError
from aatest.station import StationOptions, build
from aatest.station.security import COOKIE

#: the station as a browser on this machine names it (its default port)
STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"

TOKEN = "t" * 16 + "0123456789abcdef"  # 32 characters


@pytest.fixture
def guarded(tmp_path: Path) -> TestClient:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN + "\n")
    app = build(StationOptions(host="0.0.0.0", token_file=token_file, runs_dir=tmp_path / "runs"))
    return TestClient(app, base_url=STATION_URL)


def test_non_loopback_without_token_exits_2(tmp_path: Path) -> None:
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-m", "aatest.cli", "station", "--host", "0.0.0.0", "--port", "0",
         "--runs", str(tmp_path / "runs")],
        capture_output=True, text=True, env=env, timeout=60, check=False,
    )
    assert done.returncode == 2
    assert "not loopback" in done.stderr and "AATEST_STATION_TOKEN" in done.stderr


def test_short_token_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AATEST_STATION_TOKEN", "x" * 31)
    with pytest.raises(InputError, match="at least 32"):
        build(StationOptions(host="0.0.0.0", runs_dir=tmp_path / "runs"))


def test_request_without_token_gets_401(guarded: TestClient) -> None:
    assert guarded.get("/").status_code == 401
    assert guarded.get("/api/procedures").status_code == 401
    assert guarded.get("/", headers={"Authorization": "Bearer " + "y" * 32}).status_code == 401


def test_request_with_bearer_token_gets_the_page(guarded: TestClient) -> None:
    page = guarded.get("/", headers={"Authorization": f"Bearer {TOKEN}"})
    assert page.status_code == 200
    assert "<title>aatest station</title>" in page.text


def test_token_query_sets_a_cookie_that_authorises(guarded: TestClient) -> None:
    first = guarded.get(f"/?token={TOKEN}", follow_redirects=False)
    assert first.status_code == 303 and first.headers["location"] == "/"
    assert "HttpOnly" in first.headers["set-cookie"]
    assert guarded.cookies.get(COOKIE) == TOKEN
    assert guarded.get("/api/procedures").status_code == 200


def test_other_origin_is_refused(guarded: TestClient) -> None:
    bearer = {"Authorization": f"Bearer {TOKEN}"}
    foreign = guarded.get("/api/runs", headers={**bearer, "Origin": "http://evil.example"})
    assert foreign.status_code == 403
    same = guarded.get("/api/runs", headers={**bearer, "Origin": STATION_URL})
    assert same.status_code == 200


def test_websocket_needs_token_and_origin(guarded: TestClient) -> None:
    from starlette.websockets import WebSocketDisconnect

    with pytest.raises(WebSocketDisconnect) as refused, guarded.websocket_connect(STATION_WS):
        pass
    assert refused.value.code == 4401
    bearer = {"Authorization": f"Bearer {TOKEN}"}
    with pytest.raises(WebSocketDisconnect) as foreign, guarded.websocket_connect(
        STATION_WS, headers={**bearer, "Origin": "http://evil.example"}
    ):
        pass
    assert foreign.value.code == 4403
    with guarded.websocket_connect(STATION_WS, headers=bearer) as ws:
        assert ws.receive_json()["type"] == "snapshot"
        assert ws.receive_json() == {"type": "role", "role": "control"}


def test_second_browser_watches_and_cannot_control(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    with client.websocket_connect(STATION_WS) as first, \
            client.websocket_connect(STATION_WS) as second:
        assert [first.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        assert second.receive_json()["type"] == "snapshot"
        assert second.receive_json() == {"type": "role", "role": "watch"}
        second.send_json({"type": "start", "procedure": "shipped/scale-factor.yaml"})
        assert second.receive_json()["type"] == "error"
    assert not any((tmp_path / "runs").iterdir())


def test_no_path_from_the_browser(tmp_path: Path) -> None:
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    assert client.get("/api/validate", params={"id": "/etc/passwd"}).status_code == 404
    assert client.get("/api/validate", params={"id": "shipped/../../x.yaml"}).status_code == 404
    assert client.get("/runs/..%2F..%2Fetc/passwd").status_code == 404
    listed = client.get("/api/validate", params={"id": "shipped/scale-factor.yaml"}).json()
    assert listed["ok"] and listed["steps"][0]["kind"] == "sine"


def test_validation_shows_located_problems(tmp_path: Path) -> None:
    lab = tmp_path / "lab"
    lab.mkdir()
    broken = Path(__file__).parents[1] / "data" / "procedures" / "broken-unknown-key.yaml"
    (lab / "broken.yaml").write_text(broken.read_text())
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs", lab_dir=lab)),
                        base_url=STATION_URL)
    doc = client.get("/api/validate", params={"id": "lab/broken.yaml"}).json()
    assert not doc["ok"]
    assert all(p.startswith(str(lab / "broken.yaml") + ":") for p in doc["problems"])
    assert all(len(p.split(":")) >= 4 for p in doc["problems"])
