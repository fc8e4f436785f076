"""Procedure upload without a browser: validation like a file on disk, limits and security."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from starlette.testclient import TestClient

from aatest.station import StationOptions, build
from aatest.station.uploads import (
    MAX_STORED_UPLOADS,
    MAX_UPLOAD_BYTES,
    UploadError,
    clean_name,
    stored_name,
)

#: the station as a browser on this machine names it (its default port)
STATION_URL = "http://127.0.0.1:8671"
STATION_WS = "ws://127.0.0.1:8671/ws"

DATA = Path(__file__).parent / "data"
BROKEN = Path(__file__).parents[1] / "data" / "procedures" / "broken-unknown-key.yaml"
TOKEN = "u" * 16 + "0123456789abcdef"  # 32 characters


@pytest.fixture
def client(tmp_path: Path) -> TestClient:
    return TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)


def _upload(client: TestClient, name: str, body: bytes, **headers: str) -> tuple[int, dict]:
    answer = client.post("/api/upload", params={"name": name}, content=body, headers=headers)
    return answer.status_code, answer.json()


def _uploads(tmp_path: Path) -> list[str]:
    folder = tmp_path / "runs" / ".station" / "uploads"
    return sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []


def test_bad_upload_shows_the_validate_problems_under_its_own_name(
    client: TestClient, tmp_path: Path
) -> None:
    """Exactly the lines ``aatest validate`` prints, with the uploaded name as FILE."""
    status, doc = _upload(client, "broken.yaml", BROKEN.read_bytes())
    assert status == 200 and not doc["ok"] and doc["id"] is None
    (tmp_path / "broken.yaml").write_bytes(BROKEN.read_bytes())
    cli = subprocess.run([sys.executable, "-m", "aatest.cli", "validate", "broken.yaml"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False)
    assert cli.returncode == 2
    expected = [line for line in cli.stderr.splitlines() if line.startswith("broken.yaml:")]
    assert doc["problems"] == expected
    assert doc["problems"][0].startswith("broken.yaml:8:7: steps.0.sine.amplitde_deg:")
    assert _uploads(tmp_path) == []  # an invalid upload is not kept (nor listed)
    assert not any(p["id"].startswith("upload/") for p in client.get("/api/procedures").json()[
        "procedures"])


def test_good_upload_is_kept_listed_and_validates_by_id(client: TestClient, tmp_path: Path) -> None:
    text = (DATA / "quick-scale-factor.yaml").read_bytes()
    status, doc = _upload(client, "quick.yaml", text)
    assert status == 200 and doc["ok"] and doc["problems"] == []
    assert doc["procedure"] == "quick-scale-factor" and len(doc["steps"]) == 1
    assert doc["steps"][0]["kind"] == "sine" and doc["steps"][0]["lab_duration_s"] > 10
    assert doc["id"] == f"upload/{stored_name('quick.yaml', text.decode())}"
    assert _uploads(tmp_path) == [doc["id"].removeprefix("upload/")]
    listed = {p["id"]: p for p in client.get("/api/procedures").json()["procedures"]}
    assert listed[doc["id"]]["title"] == "quick-scale-factor"  # by its name, not its file
    assert listed[doc["id"]]["group"] == "Uploaded at this station"
    again = client.get("/api/validate", params={"id": doc["id"]}).json()
    assert again["ok"] and again["steps"] == doc["steps"]
    # the same text again is the same file; a changed text is a second one beside it
    assert _upload(client, "quick.yaml", text)[1]["id"] == doc["id"]
    changed = text.replace(b"samples: 20000", b"samples: 22000")
    assert _upload(client, "quick.yaml", changed)[1]["id"] != doc["id"]
    assert len(_uploads(tmp_path)) == 2


@pytest.mark.parametrize(
    ("name", "stored"),
    [("../../etc/cron.d/evil.yaml", "evil.yaml"), ("C:\\lab\\my proc.yml", "my-proc.yml"),
     ("..yaml.yaml", "yaml.yaml"), ("ünïcode run.yaml", "n-code-run.yaml"),
     ("Shouting.YAML", "Shouting.yaml"), ("mixed.YmL", "mixed.yml")],
)
def test_names_lose_every_path_part(name: str, stored: str) -> None:
    assert clean_name(name) == stored


@pytest.mark.parametrize("name", ["", "../", "procedure.txt", "passwd", ".yaml"])
def test_non_yaml_names_are_refused(name: str) -> None:
    with pytest.raises(UploadError):
        clean_name(name)


def test_path_in_the_name_never_reaches_the_disk(client: TestClient, tmp_path: Path) -> None:
    text = (DATA / "quick-scale-factor.yaml").read_bytes()
    status, doc = _upload(client, "../../outside.yaml", text)
    assert status == 200 and doc["ok"] and doc["name"] == "outside.yaml"
    assert not (tmp_path / "outside.yaml").exists()
    assert not (tmp_path / "runs" / "outside.yaml").exists()
    assert [p.name for p in tmp_path.rglob("outside*")] == _uploads(tmp_path)


def test_size_encoding_and_method_limits(client: TestClient, tmp_path: Path) -> None:
    big = b"# padding\n" * (MAX_UPLOAD_BYTES // 10 + 1)
    status, doc = _upload(client, "big.yaml", big)
    assert status == 413 and "at most" in doc["problems"][0]
    status, doc = _upload(client, "latin.yaml", "procedure: caf\xe9\n".encode("latin-1"))
    assert status == 400 and "not UTF-8" in doc["problems"][0]
    status, doc = _upload(client, "notes.txt", b"procedure: x\n")
    assert status == 400 and "*.yaml" in doc["problems"][0]
    assert client.get("/api/upload", params={"name": "x.yaml"}).status_code == 405
    assert _uploads(tmp_path) == []


def test_upload_needs_the_token_and_the_same_origin(tmp_path: Path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN)
    guarded = TestClient(build(StationOptions(host="0.0.0.0", token_file=token_file,
                                              runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    text = (DATA / "quick-scale-factor.yaml").read_bytes()
    refused = guarded.post("/api/upload", params={"name": "q.yaml"}, content=text)
    assert refused.status_code == 401
    bearer = {"Authorization": f"Bearer {TOKEN}"}
    foreign = guarded.post("/api/upload", params={"name": "q.yaml"}, content=text,
                           headers={**bearer, "Origin": "http://evil.example"})
    assert foreign.status_code == 403
    assert _uploads(tmp_path) == []
    status, doc = _upload(guarded, "q.yaml", text, **bearer)
    assert status == 200 and doc["ok"]


def test_uploaded_procedure_starts_from_the_websocket(tmp_path: Path) -> None:
    """Startable by its id like any listed procedure; the run is exactly ``aatest run``'s."""
    client = TestClient(build(StationOptions(runs_dir=tmp_path / "runs")), base_url=STATION_URL)
    _, doc = _upload(client, "quick.yaml", (DATA / "quick-scale-factor.yaml").read_bytes())
    with client.websocket_connect(STATION_WS) as ws:
        assert [ws.receive_json()["type"] for _ in range(2)] == ["snapshot", "role"]
        ws.send_json({"type": "start", "procedure": doc["id"], "operator": "Upload Tester"})
        while (event := ws.receive_json())["type"] not in ("finished", "stopped"):
            pass
    assert event["type"] == "finished", event
    assert event["overall"] == "pass"
    run_dir = tmp_path / "runs" / event["name"]
    assert (run_dir / "report.html").is_file()


def test_upload_cap_counts_files_whatever_their_case(client: TestClient, tmp_path: Path) -> None:
    """``.YAML`` uploads were neither counted nor listed, so the cap of 500 could be bypassed."""
    text = (DATA / "quick-scale-factor.yaml").read_bytes()
    status, doc = _upload(client, "Upper.YAML", text)
    assert status == 200 and doc["ok"] and doc["id"].endswith(".yaml")
    listed = [p["id"] for p in client.get("/api/procedures").json()["procedures"]]
    assert doc["id"] in listed
    folder = tmp_path / "runs" / ".station" / "uploads"
    for i in range(MAX_STORED_UPLOADS - 1):
        (folder / f"filler-{i}.{'YAML' if i % 2 else 'Yml'}").write_text("x")
    status, doc = _upload(client, "another.YAML", text.replace(b"20000", b"21000"))
    assert status == 507 and "at most 500" in doc["problems"][0]
