"""The station answers only to itself: Host allow-list, Origin, framing, websocket messages.

A DNS-rebinding page reaches the loopback station with its own name in ``Host`` (and, from
script, the same name in ``Origin``); every route and the websocket must refuse it with 403,
while the names of this machine on the station's port keep working.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from starlette.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from aatest.engine.errors import InputError
from aatest.engine.run.run_state import RunState
from aatest.station import StationOptions, build

STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"
EVIL = "rebind.evil.example:8671"
TOKEN = "r" * 16 + "0123456789abcdef"  # 32 characters
QUICK = Path(__file__).parent / "data" / "quick-scale-factor.yaml"

#: every HTTP route of the station: (method, path)
ROUTES = [
    ("GET", "/"), ("GET", "/api/procedures"), ("GET", "/api/runs"),
    ("GET", "/api/validate?id=shipped/scale-factor.yaml"),
    ("POST", "/api/upload?name=q.yaml"), ("GET", "/runs/some-run/report.html"),
    ("GET", "/static/station.js"),
]


def _client(tmp_path: Path, **options: Any) -> TestClient:
    return TestClient(build(StationOptions(runs_dir=tmp_path / "runs", **options)),
                      base_url=STATION_URL)


def _request(client: TestClient, method: str, path: str, **headers: str) -> Any:
    body = QUICK.read_bytes() if method == "POST" else None
    return client.request(method, path, content=body, headers=headers)


def _fake_run(runs: Path, name: str, report: str = "<p>report</p>") -> Path:
    run = runs / name
    run.mkdir(parents=True)
    RunState("quick", "0" * 64, 1, finished=True).save(run)
    (run / "report.html").write_text(report)
    return run


@pytest.mark.parametrize(("method", "path"), ROUTES)
def test_rebinding_request_gets_403_on_every_route(tmp_path: Path, method: str, path: str) -> None:
    client = _client(tmp_path)
    rebound = _request(client, method, path, Host=EVIL, Origin=f"http://{EVIL}")
    assert rebound.status_code == 403
    assert _request(client, method, path, Host=EVIL).status_code == 403
    assert not (tmp_path / "runs" / ".station" / "uploads").exists()  # nothing was kept
    own = _request(client, method, path)
    assert own.status_code != 403


def test_rebinding_websocket_gets_no_control(tmp_path: Path) -> None:
    client = _client(tmp_path)
    for headers in ({"host": EVIL, "origin": f"http://{EVIL}"}, {"host": EVIL}):
        with pytest.raises(WebSocketDisconnect) as refused, client.websocket_connect(
            f"ws://{EVIL}/ws", headers=headers
        ) as ws:
            ws.receive_json()
        assert refused.value.code == 4403
    with client.websocket_connect(STATION_WS) as ws:
        assert ws.receive_json()["type"] == "snapshot"
        assert ws.receive_json() == {"type": "role", "role": "control"}


@pytest.mark.parametrize(("host", "allowed"), [
    ("127.0.0.1:8671", True), ("localhost:8671", True), ("[::1]:8671", True),
    ("LOCALHOST:8671", True), ("127.0.0.1:8672", False), ("127.0.0.1", False),
    ("localhost.:8671", False), ("127.0.0.2:8671", False), ("evil@127.0.0.1:8671", False),
    ("127.0.0.1:8671/x", False), ("127.0.0.1:99999", False), ("", False),
    ("0.0.0.0:8671", False), ("[::1:8671", False),
])
def test_host_allow_list(tmp_path: Path, host: str, allowed: bool) -> None:
    status = _client(tmp_path).get("/api/runs", headers={"Host": host}).status_code
    assert (status == 200) is allowed, status


def test_allow_host_names_more_hosts(tmp_path: Path) -> None:
    client = _client(tmp_path, allow_hosts=("Station.Lab.Example", "bench-7:9000"))
    for host, status in (("station.lab.example", 200), ("station.lab.example:443", 200),
                         ("bench-7:9000", 200), ("bench-7:8671", 403), ("bench-8:9000", 403)):
        assert client.get("/api/runs", headers={"Host": host}).status_code == status, host


@pytest.mark.parametrize("name", ["evil.example/x", "*.example", "a b", "", "user@host"])
def test_allow_host_must_be_a_host_name(tmp_path: Path, name: str) -> None:
    with pytest.raises(InputError, match="--allow-host"):
        build(StationOptions(runs_dir=tmp_path / "runs", allow_hosts=(name,)))


def test_bound_address_is_its_own_name(tmp_path: Path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN)
    client = TestClient(build(StationOptions(host="192.0.2.7", port=9100, token_file=token_file,
                                             runs_dir=tmp_path / "runs")))
    bearer = {"Authorization": f"Bearer {TOKEN}"}
    assert client.get("/api/runs", headers={**bearer, "Host": "192.0.2.7:9100"}).status_code == 200
    assert client.get("/api/runs", headers={**bearer, "Host": "192.0.2.7:80"}).status_code == 403
    assert client.get("/api/runs", headers={**bearer, "Host": "lan-name:9100"}).status_code == 403


@pytest.mark.parametrize("origin", [
    "http://evil.example", "null", "http://127.0.0.1:8672", "file://", "ftp://127.0.0.1:8671",
    "http://127.0.0.1:8671.evil.example", "http://[::1",
])
def test_foreign_origin_cannot_change_state(tmp_path: Path, origin: str) -> None:
    client = _client(tmp_path)
    assert _request(client, "POST", "/api/upload?name=q.yaml", Origin=origin).status_code == 403
    assert not (tmp_path / "runs" / ".station" / "uploads").exists()
    with pytest.raises(WebSocketDisconnect) as refused, client.websocket_connect(
        STATION_WS, headers={"origin": origin}
    ) as ws:
        ws.receive_json()
    assert refused.value.code == 4403


def test_cross_site_post_without_origin_is_refused(tmp_path: Path) -> None:
    client = _client(tmp_path)
    headers = {"Sec-Fetch-Site": "cross-site"}
    assert _request(client, "POST", "/api/upload?name=q.yaml", **headers).status_code == 403
    same = _request(client, "POST", "/api/upload?name=q.yaml", Origin=STATION_URL,
                    **{"Sec-Fetch-Site": "same-origin"})
    assert same.status_code == 200 and same.json()["ok"]


@pytest.mark.parametrize("path", ["/", "/api/runs", "/static/station.css", "/nowhere"])
def test_every_response_forbids_framing(tmp_path: Path, path: str) -> None:
    client = _client(tmp_path)
    for response in (client.get(path), client.get(path, headers={"Host": EVIL})):
        assert "frame-ancestors 'none'" in response.headers["content-security-policy"]
        assert response.headers["x-frame-options"] == "DENY"


def test_page_and_report_policies(tmp_path: Path) -> None:
    _fake_run(tmp_path / "runs", "run-1", "<script>alert(1)</script>")
    client = _client(tmp_path)
    page = client.get("/").headers["content-security-policy"]
    assert "default-src 'self'" in page and "object-src 'none'" in page
    report = client.get("/runs/run-1/report.html")
    assert report.status_code == 200
    policy = report.headers["content-security-policy"]
    assert "sandbox" in policy and "script-src" not in policy and "default-src 'none'" in policy


@pytest.mark.parametrize("bearer", ["Bearer é" + "x" * 31, "Bearer \u2603", "Bearer \xff\xfe"])
def test_non_ascii_bearer_token_gets_401(tmp_path: Path, bearer: str) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN)
    client = TestClient(build(StationOptions(host="0.0.0.0", token_file=token_file,
                                             runs_dir=tmp_path / "runs")),
                        base_url=STATION_URL, raise_server_exceptions=True)
    raw = bearer.encode("utf-8")
    assert client.get("/api/runs", headers={"Authorization": raw}).status_code == 401
    cookie = {"Cookie": b"aatest_station=\xc3\xa9"}
    assert client.get("/api/runs", headers=cookie).status_code == 401
    assert client.get("/?token=%C3%A9%FF", follow_redirects=False).status_code == 401
    assert client.get("/api/runs", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200


@pytest.mark.parametrize("token", ["é" * 32, "a" * 31 + " b", "x" * 32 + ";y"])
def test_token_must_be_plain_ascii(tmp_path: Path, token: str) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(token, encoding="utf-8")
    with pytest.raises(InputError, match="printable ASCII"):
        build(StationOptions(host="0.0.0.0", token_file=token_file, runs_dir=tmp_path / "runs"))


MALFORMED: list[str | bytes] = [
    "not json", "[1, 2]", "null", '"start"', '{"type": "start"}',
    '{"type": "start", "procedure": 5}', '{"type": "explode"}', '{"procedure": "x"}',
    '{"type": "answer", "step": ["a"]}', '{"type": "abort", "operator": {"x": 1}}',
    '{"type": "abort", "operator": "' + "o" * 500 + '"}', "[" * 100_000, b"\x00\x01",
]


@pytest.mark.parametrize("message", MALFORMED, ids=range(len(MALFORMED)))
def test_malformed_message_closes_the_socket_and_hands_control_on(
    tmp_path: Path, message: str | bytes
) -> None:
    client = _client(tmp_path)
    with client.websocket_connect(STATION_WS) as first, \
            client.websocket_connect(STATION_WS) as second:
        assert second.receive_json()["type"] == "snapshot"
        assert second.receive_json() == {"type": "role", "role": "watch"}
        # the first is told its role when it joins and again when the second joins
        assert [first.receive_json()["type"] for _ in range(3)] == ["snapshot", "role", "role"]
        if isinstance(message, bytes):
            first.send_bytes(message)
        else:
            first.send_text(message)
        with pytest.raises(WebSocketDisconnect) as closed:
            first.receive_json()
        assert closed.value.code == 1008
        assert second.receive_json() == {"type": "role", "role": "control"}
        second.send_text(json.dumps({"type": "answer", "step": "none"}))
        assert second.receive_json() == {"type": "error", "message": "no such prompt is waiting"}


def test_unreadable_or_broken_runs_are_left_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    runs = tmp_path / "runs"
    _fake_run(runs, "good")
    (_fake_run(runs, "bad-state") / "run_state.json").write_text("{not json")
    (_fake_run(runs, "bad-results") / "results.json").write_text("[1, 2")
    (_fake_run(runs, "odd-state") / "run_state.json").write_text('{"unexpected": 1}')
    _fake_run(runs, "no-permission")
    load = RunState.load

    def load_or_deny(run_dir: Path) -> RunState:
        if run_dir.name == "no-permission":  # as a directory of another user would be
            raise PermissionError(13, "Permission denied", str(run_dir / "run_state.json"))
        return load(run_dir)

    monkeypatch.setattr(RunState, "load", staticmethod(load_or_deny))
    doc = _client(tmp_path).get("/api/runs")
    assert doc.status_code == 200
    rows = {row["name"]: row for row in doc.json()["runs"]}
    # a run whose results.json is broken is still a run: listed, its error shown, not hidden
    assert sorted(rows) == ["bad-results", "good"]
    assert "results_error" in rows["bad-results"] and "results_error" not in rows["good"]


def test_symlinked_runs_and_files_are_never_served(tmp_path: Path) -> None:
    runs = tmp_path / "runs"
    secret = tmp_path / "secret.html"
    secret.write_text("private")
    outside = _fake_run(tmp_path / "elsewhere", "outside", "outside the runs")
    real = _fake_run(runs, "real")
    (runs / "linked").symlink_to(outside, target_is_directory=True)
    (real / "results.json").symlink_to(secret)
    other = _fake_run(runs, "other")
    (other / "report.html").unlink()
    (other / "report.html").symlink_to(real / "report.html")
    client = _client(tmp_path)
    assert client.get("/runs/real/report.html").text == "<p>report</p>"
    for path in ("/runs/linked/report.html", "/runs/real/results.json",
                 "/runs/other/report.html", "/runs/real/run_state.json"):
        response = client.get(path)
        assert response.status_code == 404, path
        assert "private" not in response.text and "outside" not in response.text
    names = sorted(row["name"] for row in client.get("/api/runs").json()["runs"])
    assert names == ["other", "real"]
